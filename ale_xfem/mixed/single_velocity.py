"""The single-velocity closure of mixed cells (the baseline the paper improves on; 1D and
2D): one velocity field, both materials of a mixed cell strained alike, their pressures
equilibrated by the relaxation at the start of the next step."""

from __future__ import annotations

from ale_xfem.mixed.common import SharedClosure
from ale_xfem.mixed.equilibrium import start_values


class SingleVelocityClosure(SharedClosure):
    """Explicit: the mixed cells' stresses are in the forces of the step like any cell's."""

    implicit = False

    def equal_strain(self, state, first, strain, energy_change=None):
        """Both materials of a mixed cell take the cell's volume change in proportion to
        their volumes (equal strain); their energies change by −P^n ΔV_α in the predictor,
        and at the end of the step share ``energy_change``, the cell's compatible work (in
        1D exactly −P̄ ΔV), in proportion to their volumes; the cell's stress is the
        volume-weighted mean of their pressures.  The pressure relaxation at the start of
        the next step then equilibrates them."""
        m_a, m_b, va0, vb0, ea0, eb0 = start_values(state, self.mixed.cells)
        va, vb = va0 * strain, vb0 * strain
        if energy_change is None:
            work = first.stress[self.mixed.cells]
            ea = ea0 - work * (va - va0) / m_a
            eb = eb0 - work * (vb - vb0) / m_b
        else:
            share = va0 / (va0 + vb0)
            ea = ea0 + energy_change * share / m_a
            eb = eb0 + energy_change * (1.0 - share) / m_b
        pa, _, _, c2a = self.mixed.left_groups.eos_values(self.materials, m_a / va, ea)
        pb, _, _, c2b = self.mixed.right_groups.eos_values(self.materials, m_b / vb, eb)
        mean_pressure = (va * pa + vb * pb) / (va + vb)
        return mean_pressure, (va, vb, (ea, eb, pa, pb, m_a / va, m_b / vb, c2a, c2b))

    def predicted_pressure(self, state, first, strain, view):
        return self.equal_strain(state, first, strain)[0]

    def implicit_solve(self, step, state, first, predicted, mean_force, dt, dt_over_node_mass):
        return None  # the mixed cells' forces are already in mean_force

    def end_of_step(self, state, first, x_new, e_new, solution):
        cells = self.mixed.cells
        # the cell's internal energy changes by the work of its corner forces on the nodes,
        # as in pure cells (compatible: total energy conserved), shared by strain
        change = (e_new[0, cells] - state.material_energy[0, cells]) * state.material_mass[0, cells]
        return self.equal_strain(state, first, self.mixed_volumes(x_new) / first.volume[cells],
                                 energy_change=change)[1]
