"""The Lagrange phase: the explicit Wilkins step of pure cells; mixed cells are plugged in
through one interface (``closure``)."""
