"""The enriched closure of mixed cells (the paper's method; 1D): one velocity field per
material, the external nodes massless, the interface pressure π = p_Γ^{n+1} solved
implicitly with trapezoidal stresses on the internal nodes (paper §2.2.1; the solve itself
is :mod:`ale_xfem.mixed.equilibrium`, in closed form, or the 2D cells' assembled system and
predictor/corrector on intervals, :mod:`ale_xfem.mixed.assembled_predictor`)."""

from __future__ import annotations

import numpy as np

from ale_xfem.mixed.assembled_predictor import AssembledPredictor
from ale_xfem.mixed.closure_kernels import cap_by_internal_nodes, interface_affine
from ale_xfem.mixed.common import SharedClosure
from ale_xfem.mixed.enriched_steps import take_steps
from ale_xfem.mixed.equilibrium import MixedCellFailure, cell_arrays, start_values
from ale_xfem.model.mixed_cells import MixedCells


class EnrichedClosure(SharedClosure):
    """Mixed cells with doubled velocities and an implicit interface pressure.
    ``assembled``: the solve is the FE system assembled from the UFL forms (compiled here,
    once per run) iterated by the 2D cells' predictor/corrector, not the closed form, its
    system bound by ``system`` (AssembledPredictor's)."""

    implicit = True

    def __init__(self, mesh, materials, mixed: MixedCells, assembled: bool = False,
                 petsc_options: dict | None = None, system=None):
        super().__init__(mesh, materials, mixed)
        self.assembled = None
        if assembled:  # on the mesh of the cells the solves take (on several MPI ranks: the serial mesh)
            ranks = mixed.across_ranks
            whole, cells = (mesh, mixed.cells) if ranks is None else (ranks.mesh, ranks.cells)
            self.assembled = AssembledPredictor(whole.dolfinx_mesh, cells, whole.n_nodes, petsc_options, system)

    def compiles_steps(self, step) -> bool:
        """1D mixed cells with the predictor in closed form, each step ending relaxed: the
        steps of a Lagrangian run go in compiled chunks (:mod:`ale_xfem.mixed.enriched_steps`)."""
        return self.assembled is None and self.mixed.node_left is not None and step.relax_end_state

    def steps(self, step, state, evaluation, clock, boundary_impulse):
        return take_steps(step, self, state, evaluation, clock, boundary_impulse)

    def implicit_solve(self, step, state, first, predicted, mean_force, dt, dt_over_node_mass):
        """The implicit interface solve; adds the mixed cells' n+1 stress to mean_force."""
        mixed = self.mixed
        a, b = mixed.node_left, mixed.node_right
        pi_n = state.interface_pressure
        # V(π) = A + Bπ (module docstring of ale_xfem.mixed.equilibrium): the internal nodes
        # move with the trapezoidal force ½(F^n + F*) − ½(π − π^n) ∂V/∂x_i; held nodes do
        # not move (ale_xfem.mixed.closure_kernels.interface_affine)
        n = mixed.cells.size
        mobility, offset, slope, work_offset = np.empty((2, n)), np.empty(n), np.empty(n), np.empty(n)
        interface_affine(dt, step.inverse_node_mass, step.free_nodes, mixed.cells, a, b, state.node_velocity,
                         mean_force, first.volume, *cell_arrays((n,), pi_n, first.mixed_viscosity,
                                                                predicted.mixed_viscosity),
                         mobility, offset, slope, work_offset)
        mobility_a, mobility_b = mobility
        start = start_values(state, mixed.cells)
        try:
            if self.assembled is None:
                pi, va, vb, details = self.equilibrium.solve(start, pi_n, (offset, slope),
                                                             (work_offset, np.full_like(pi_n, 0.5)))
            else:  # the 2D cells' system and predictor/corrector, on intervals
                pi, va, vb, details = self.assembled.solve(mixed, state, predicted, mean_force, dt, mobility_a,
                                                           mobility_b, start, 2.0 * work_offset)
        except MixedCellFailure as failure:
            raise self.breakdown("interface solve", failure, state.node_position) from None
        change = 0.5 * (pi - pi_n)
        mean_force[0, a] -= change
        mean_force[0, b] += change
        return va, vb, details

    def end_of_step(self, state, first, predicted, x_new, e_new, solution):
        return solution

    def viscosity_medium(self, view, volume, density, sound_speed, node_mass):
        """The shared medium (harmonic-mean density, the larger sound speed), its density
        capped so that the viscosity pushes the cell's internal nodes no harder than a pure
        cell pushes its own.  The velocity jump Δu relaxes under q at the rate
        λ = ρ_q Q (1/M_a + 1/M_b), Q = ∂q/∂Δu / ρ_q; a pure cell's nodes carry M ≈ ρ L,
        so λ = 2 Q / L, which its CFL step L / Q keeps inside the predictor–corrector's
        limit.  A mixed cell's internal nodes carry each material's mass alone (mass
        condensation): a sliver of light gas against water leaves one of them far lighter
        than ρ_q L, and the explicit q* overshot from step to step (air at 1e8 Pa against
        water, 6 % air in the cell, Eulerian mesh: the air node's velocity swung by
        ±1500 m/s and the air's energy went negative in 4 steps).  With
        ρ_q ≤ 2 / (L (1/M_a + 1/M_b)) the rate is a pure cell's."""
        density_q, speed = super().viscosity_medium(view, volume, density, sound_speed, node_mass)
        mixed = self.mixed
        cap_by_internal_nodes(mixed.cells, volume, node_mass, mixed.node_left, mixed.node_right, density_q)
        return density_q, speed
