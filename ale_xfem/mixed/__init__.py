"""The mixed cells: the closures the Lagrange step plugs in (enriched, single-velocity), the
materials' pressure equilibrium and its relaxation, and the binding of the UFL forms."""
