"""UFL forms of ale_xfem, written once for intervals, triangles and quadrilaterals and
compiled once per run (never inside the time loop).

- :mod:`forms.corner_forces`: the weak pressure force −∫_K σ:∇ψ_i dx with σ = −P I and P
  constant per cell, the force the explicit Wilkins loop evaluates in numpy.  It is the
  reference the numpy corner forces are checked against, and the volume term of the
  mixed-cell system that the implicit interface solve assembles.
"""
