"""The single-velocity closure of mixed cells (the baseline the paper improves on; 1D and
2D): one velocity field, both materials of a mixed cell strained alike, their pressures
equilibrated by the relaxation at the start of the next step."""

from __future__ import annotations

from ale_xfem.mixed.common import SharedClosure
from ale_xfem.mixed.equilibrium import start_values


class SingleVelocityClosure(SharedClosure):
    """Explicit: the mixed cells' stresses are in the forces of the step like any cell's.

    Both materials of a mixed cell take the cell's volume change in proportion to their
    volumes (equal strain).  Each works against its *own* pressure and the cell's viscosity,
    dE_α = −(p̄_α + q̄) ΔV_α, time-centred at the end of the step as the compatible work is
    (p̄_α = ½(p_α^n + p_α*), q̄ = ½(q^n + q*)); the rest of the cell's compatible work (the
    hourglass forces' dissipation, in 1D the relaxation's tolerance) is heat, shared by mass
    (the same specific energy for both).  Total energy is conserved: the two sum to the
    cell's work.  In 1D, where the compatible work is −(P̄ + q̄) ΔV with P̄ the cell's
    volume-weighted pressure, this is the same as sharing −(P̄ + q̄) ΔV by volume, to the
    relaxation's tolerance.

    (Shared by volume, the cell's whole work heated a trace of near-vacuum air against water
    in tension: a water–air tube at 30° to an Eulerian 60 × 60 mesh, water at 1e9 Pa,
    cavitating where Γ meets the wall — a cell's hourglass work, +20 a step where −P ΔV
    was −0.01, gave the air 0.7 % of it, 0.14 a step against its internal energy of 0.04,
    and the air's sound speed grew until the time step collapsed at step 40.  A gas's own
    pressure is never negative: expanding, it cools.)"""

    implicit = False

    def strained(self, state, strain, work_left, work_right, heat=None):
        """The mixed cells with both materials strained by ``strain`` (V_α = s V_α^n), each
        material's energy changed by its work pressure W_α, e_α = e_α^n − W_α ΔV_α / m_α,
        plus ``heat`` (per cell) by mass.  Returns (the volume-weighted pressure, (V_α, V_β,
        details)), details the materials' energies, pressures, densities and c²."""
        m_a, m_b, va0, vb0, ea0, eb0 = start_values(state, self.mixed.cells)
        va, vb = va0 * strain, vb0 * strain
        ea = ea0 - work_left * (va - va0) / m_a
        eb = eb0 - work_right * (vb - vb0) / m_b
        if heat is not None:
            specific_heat = heat / (m_a + m_b)
            ea += specific_heat
            eb += specific_heat
        pa, _, _, c2a = self.mixed.left_groups.eos_values(self.materials, m_a / va, ea)
        pb, _, _, c2b = self.mixed.right_groups.eos_values(self.materials, m_b / vb, eb)
        mean_pressure = (va * pa + vb * pb) / (va + vb)
        return mean_pressure, (va, vb, (ea, eb, pa, pb, m_a / va, m_b / vb, c2a, c2b))

    def _predicted(self, state, first, strain):
        """The predictor's state of the mixed cells: each material works against its own
        pressure at n and the cell's viscosity q^n."""
        cells = self.mixed.cells
        viscosity = first.viscosity[cells]
        return self.strained(state, strain, state.material_pressure[0, cells] + viscosity,
                             state.material_pressure[1, cells] + viscosity)

    def predicted_pressure(self, state, first, strain, view):
        mean_pressure, (_, _, details) = self._predicted(state, first, strain)
        # the materials' own predicted pressures p_α*, read by end_of_step of this step
        # (the step calls predicted_view, then end_of_step, on the same state)
        self._predicted_pressures = (state.time, details[2], details[3])
        return mean_pressure

    def implicit_solve(self, step, state, first, predicted, mean_force, dt, dt_over_node_mass):
        return None  # the mixed cells' forces are already in mean_force

    def end_of_step(self, state, first, predicted, x_new, e_new, solution):
        cells = self.mixed.cells
        # the cell's internal energy changes by the work of its corner forces on the nodes,
        # as in pure cells (compatible: total energy conserved)
        work = (e_new[0, cells] - state.material_energy[0, cells]) * state.material_mass[0, cells]
        time, pa_pred, pb_pred = self._predicted_pressures
        if time != state.time:
            raise RuntimeError("end_of_step without the predicted view of its step")
        viscosity = 0.5 * (first.viscosity[cells] + predicted.viscosity[cells])
        work_left = 0.5 * (state.material_pressure[0, cells] + pa_pred) + viscosity
        work_right = 0.5 * (state.material_pressure[1, cells] + pb_pred) + viscosity
        strain = self.mixed_volumes(x_new) / first.volume[cells]
        va0, vb0 = state.material_volume[0, cells], state.material_volume[1, cells]
        heat = work + work_left * va0 * (strain - 1.0) + work_right * vb0 * (strain - 1.0)
        return self.strained(state, strain, work_left, work_right, heat)[1]
