"""Exact reference solutions: Riemann problems of stiffened gases, plate impact."""

from ale_xfem.exact.plate_impact import Plate, PlateImpactSolution
from ale_xfem.exact.riemann import GasState, RiemannSolution, StarState, VacuumError, star_state

__all__ = ["GasState", "Plate", "PlateImpactSolution", "RiemannSolution", "StarState",
           "VacuumError", "star_state"]
