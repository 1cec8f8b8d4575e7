"""UFL forms of ale_xfem, written once for intervals, triangles and quadrilaterals and
compiled once per run (never inside the time loop).

- :mod:`forms.corner_forces`: the weak pressure force −∫_K σ:∇ψ_i dx with σ = −P I and P
  constant per cell, the force the explicit Wilkins loop evaluates in numpy.  It is the
  reference the numpy corner forces are checked against.
- :mod:`forms.enriched_interface`: the implicit system of enriched mixed cells — each
  material's velocity on every node of the mixed cells (the doubled velocities), its
  linearised pressure, the interface condition (multiplier, bubbles or Nitsche; free slip
  or stick) — on the submesh of the mixed cells, intervals, triangles and quadrilaterals;
  in 1D it is the enriched closure's assembled predictor (``[interface] predictor =
  "assembled"``), in 2D the enriched mixed cells' system (measured on its own by
  ``ale-xfem study interface``; no scene runs it yet).
- :mod:`forms.cut_quadrature`: a measure of one material's part of cut cells (and of the
  interface in them), exact for the forms' integrands, in forms compiled once
  (moment-fitted weights refilled as the part moves).
- :mod:`forms.bound_system`: compiled forms bound to a mesh, with their matrix, vectors and
  KSP made once and a refined direct solve.
"""
