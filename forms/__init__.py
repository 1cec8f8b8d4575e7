"""UFL forms of ale_xfem, written once for intervals, triangles and quadrilaterals and
compiled once per run (never inside the time loop).

- :mod:`forms.corner_forces`: the weak pressure force −∫_K σ:∇ψ_i dx with σ = −P I and P
  constant per cell, the force the explicit Wilkins loop evaluates in numpy.  It is the
  reference the numpy corner forces are checked against.
- :mod:`forms.mixed_cell`: the predictor of the implicit interface solve — doubled P1
  velocities and a DG0 interface pressure on the submesh of the mixed cells, the
  linearised constitutive law, interface traction and normal-velocity continuity —
  assembled with DOLFINx and solved with PETSc (``[interface] predictor = "assembled"``).
- :mod:`forms.cut_quadrature`: a measure of one material's part of cut triangles, exact for
  P1 products, in forms compiled once (moment-fitted weights refilled as the part moves),
  for the 2D enriched mixed cells.
"""
