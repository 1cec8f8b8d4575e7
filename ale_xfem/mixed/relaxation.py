"""Pressure relaxation of mixed cells (paper §3): at the start of each step the materials of
a mixed cell are brought to one pressure at fixed cell volume, so both compress or expand
together and the interface cannot leave the cell during the predictor.  The solve is
:meth:`ale_xfem.mixed.equilibrium.PressureEquilibrium.relax` (a bracketed root in the volume
one material takes from the other) with the energy exchange dE_α = −p* dV_α (p* the final
common pressure): energy is conserved."""

from __future__ import annotations

import numpy as np

from ale_xfem.mixed.equilibrium import PressureEquilibrium, balanced_cells, cell_arrays, start_values
from ale_xfem.model.mixed_cells import MixedCells, with_mixed_state
from ale_xfem.model.state import State


class PressureRelaxation:
    """The relaxation of the mixed cells of ``equilibrium`` (only where the materials'
    pressures differ beyond what the solver leaves alone)."""

    def __init__(self, equilibrium: PressureEquilibrium):
        self.equilibrium = equilibrium

    @property
    def mixed(self) -> MixedCells:
        return self.equilibrium.mixed

    def relax_state(self, state: State, in_place: bool = False):
        """Pressure relaxation of the mixed cells at the start of a step (paper §3): only
        where the materials' pressures differ beyond the solver tolerance.  ``in_place``:
        change the state's arrays (a state just made by the remap) instead of copying.
        (A step relaxes the state it ends with already, before evaluating its forces —
        :meth:`relax_end` — so this finds work only in states made elsewhere.)"""
        cells = self.mixed.cells
        pa, pb = state.material_pressure[0, cells], state.material_pressure[1, cells]
        c2a, c2b = state.material_sound_speed[0, cells] ** 2, state.material_sound_speed[1, cells] ** 2
        if self.balanced(pa, pb, state.material_density[0, cells] * c2a, state.material_density[1, cells] * c2b):
            return state, False
        volume = state.material_volume[0, cells] + state.material_volume[1, cells]
        _, va, vb, details = self.relax(volume, start_values(state, cells), 0.5 * (pa + pb))
        return with_mixed_state(state, cells, va, vb, details, state.interface_velocity, in_place), True

    def balanced(self, pa, pb, bulk_a, bulk_b) -> bool:
        """Whether the materials' pressures agree within what the relaxation leaves alone:
        10 × interface_tolerance relative to the larger pressure or the smaller ρc²
        (compiled: :func:`ale_xfem.mixed.equilibrium.balanced_cells`)."""
        arrays = cell_arrays(np.shape(pa), pa, pb, bulk_a, bulk_b)
        if self.mixed.across_ranks is not None:  # all the ranks' mixed cells balanced, or all relaxed
            arrays = self.mixed.across_ranks.whole(arrays)
        return bool(balanced_cells(*arrays, self.mixed.tolerance))

    def relax(self, volume, start, guess):
        """The equilibrium at fixed volumes: (p*, V_α, V_β, details); raises
        :class:`MixedCellFailure`."""
        return self.equilibrium.relax(volume, start, guess)

    def relax_end(self, state, va, vb, details, relax_end_state: bool):
        """The relaxation that starts the next step, done on the mixed cells' new volumes,
        energies and pressures before the step evaluates the forces of its new state: that
        evaluation then serves the next step as it is (relaxing the finished state instead
        would change its pressures and call for a second evaluation of every cell).  The
        same solve on the same values as :meth:`relax_state` would do."""
        ea, eb, pa, pb, rho_a, rho_b, c2a, c2b = details
        if not (self.mixed.relaxation and relax_end_state) or self.balanced(pa, pb, rho_a * c2a,
                                                                            rho_b * c2b):
            return va, vb, details
        cells = self.mixed.cells
        start = (state.material_mass[0, cells], state.material_mass[1, cells], va, vb, ea, eb)
        _, va, vb, details = self.relax(va + vb, start, 0.5 * (pa + pb))
        return va, vb, details


