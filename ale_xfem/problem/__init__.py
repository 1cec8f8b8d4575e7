"""From a validated scene to a problem: mesh, materials, initial state, boundaries, the
exact reference when the scene has one, and the effects it switches on."""

from ale_xfem.problem.build import ExactReference, Problem, build_problem, side_boundaries, state_from_cells

__all__ = ["ExactReference", "Problem", "build_problem", "side_boundaries", "state_from_cells"]
