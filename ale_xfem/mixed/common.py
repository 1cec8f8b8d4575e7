"""What the closures of mixed cells share (:class:`ale_xfem.lagrange.closure.MixedCellClosure`):
the pressure relaxation, the medium of a mixed cell's viscosity, the mixed cells at the
predicted positions, and the mixed-cell entries of the state a step ends with."""

from __future__ import annotations

import numpy as np

from ale_xfem.lagrange.breakdown import Breakdown
from ale_xfem.lagrange.closure import MixedCellClosure, MixedView
from ale_xfem.mixed.closure_kernels import viscosity_media
from ale_xfem.mixed.equilibrium import MixedCellFailure, PressureEquilibrium, cell_arrays
from ale_xfem.mixed.relaxation import PressureRelaxation
from ale_xfem.model.mixed_cells import MixedCells, material_names


class SharedClosure(MixedCellClosure):
    """The parts of a closure that do not depend on how the materials share the cell's
    deformation (subclasses: :mod:`ale_xfem.mixed.enriched`, :mod:`ale_xfem.mixed.single_velocity`)."""

    def __init__(self, mesh, materials, mixed: MixedCells):
        self.mesh, self.materials = mesh, materials
        self.bind(mixed)

    def bind(self, mixed: MixedCells) -> None:
        self.mixed = mixed
        self.equilibrium = PressureEquilibrium(mixed)
        self.relaxation = PressureRelaxation(self.equilibrium)

    def relax_start(self, state, in_place: bool = False):
        if not self.mixed.relaxation:
            return state, False
        try:
            return self.relaxation.relax_state(state, in_place)
        except MixedCellFailure as failure:
            raise self.breakdown("pressure relaxation", failure, state.node_position) from None

    def breakdown(self, quantity: str, failure: MixedCellFailure, node_position) -> Breakdown:
        """The diagnostic of a failed mixed-cell solve: the cell, where it is, its materials
        (α | β: slot 0 | slot 1; in 1D left | right) and what failed."""
        if failure.cell < 0:  # a mixed cell of another MPI rank, which reports it
            return Breakdown(quantity, -1, float("nan"), np.full(self.mesh.dimension, np.nan), detail=failure.detail)
        centroid = self.mesh.cell_centroids(node_position)[failure.cell]
        return Breakdown(quantity, failure.cell, float("nan"), centroid,
                         materials=material_names(self.mixed, failure.index), detail=failure.detail)

    def viscosity_medium(self, view: MixedView, volume, density, sound_speed, node_mass):
        """The viscosity of a mixed cell acts on the whole cell (both materials alike, so it
        does not upset their pressure balance).  Its sound speed is the larger of the two
        materials'; its density the volume-weighted harmonic mean 1/ρ = Σ f_α/ρ_α, which
        weights the material that takes the compression: with the mass-weighted mean, a
        light gas against a dense one is damped by the dense one's inertia and the mixed
        cell does not compress under a shock.  (Compiled:
        :func:`ale_xfem.mixed.closure_kernels.viscosity_media`.)"""
        cells = self.mixed.cells
        mixed_density, mixed_sound_speed = np.empty(cells.size), np.empty(cells.size)
        viscosity_media(*self.equilibrium.tables, self.equilibrium.sides[1], cells, volume, density[0],
                        sound_speed[0], *cell_arrays(cells.shape, view.volume_left, view.volume_right, view.mass_right,
                                                     view.energy_right), mixed_density, mixed_sound_speed)
        return mixed_density, mixed_sound_speed

    def predicted_pressure(self, state, first, strain, view: MixedView):
        """The stress of the mixed cells at the predicted positions (less q)."""
        return view.interface_pressure

    def predicted_view(self, state, first, x_pred, e_pred) -> MixedView:
        # Mixed cells are not advanced by the predictor; their materials are only needed
        # for the viscosity q*, taken with both materials strained alike.
        cells = self.mixed.cells
        e_pred[0, cells] = state.material_energy[0, cells]
        strain = self.mixed_volumes(x_pred) / first.volume[cells]
        view = MixedView.of(state, cells)
        predicted_pressure = self.predicted_pressure(state, first, strain, view)
        return MixedView(view.volume_left * strain, view.volume_right * strain,
                         view.mass_right, view.energy_right, predicted_pressure)

    def mixed_volumes(self, position):
        """Volumes of the mixed cells only (1D: x_b − x_a; 2D: their areas)."""
        if self.mixed.node_left is not None:
            return position[0, self.mixed.node_right] - position[0, self.mixed.node_left]
        return self.mesh.cell_geometry(position, self.mixed.cells)[0]

    def finish(self, step, state, solution, x_new, u_new, e_new, dt):
        """Assemble the new state: pure cells from the explicit update, mixed cells from the
        interface solve; every (S, n_cells) array is allocated once."""
        va, vb, details = solution
        cells = self.mixed.cells
        vb = self.mixed_volumes(x_new) - va  # the geometric cell volume takes the round-off
        interface_velocity = self.interface_velocity(state, x_new, va, dt)  # Γ's motion in the step
        try:
            va, vb, (ea, eb, pa, pb, rho_a, rho_b, c2a, c2b) = self.relaxation.relax_end(state, va, vb, details,
                                                                                         step.relax_end_state)
        except MixedCellFailure as failure:
            raise self.breakdown("pressure relaxation", failure, x_new) from None
        energy = e_new  # slot 0 from the explicit update
        energy[0, cells], energy[1, cells] = ea, eb
        interface_pressure = 0.5 * (pa + pb)
        view = MixedView(va, vb, state.material_mass[1, cells], eb, interface_pressure)
        final = step.evaluate(x_new, u_new, state.material_mass, energy, view, slots=2)
        volume = self.slot_volumes(step.two_slots, final.volume, va, vb)
        density, pressure, sound_speed = final.density, final.pressure, final.sound_speed
        density[1, cells], pressure[1, cells] = rho_b, pb
        sound_speed[1, cells] = np.sqrt(np.maximum(c2b, 0.0))
        new_state = state.evolved(
            time=state.time + dt, node_position=x_new, node_velocity=u_new, material_energy=energy,
            material_volume=volume, material_density=density, material_pressure=pressure,
            material_sound_speed=sound_speed, interface_pressure=interface_pressure,
            interface_velocity=interface_velocity)
        return new_state, final

    def slot_volumes(self, two_slots, cell_volume, va, vb):
        """The (2, n_cells) material volumes of a new state: each cell's volume in slot 0,
        the mixed cells' split (V_α, V_β) in slots 0 and 1."""
        cells = self.mixed.cells
        volumes = two_slots.take(cells)
        volumes[0] = cell_volume
        volumes[0, cells], volumes[1, cells] = va, vb
        return volumes

    def interface_velocity(self, state, x_new, va, dt):
        """The mixed cells' interface velocity over the step: in 1D Γ's displacement / dt
        (Γ = node a + V_α); 2D single-velocity cells rebuild Γ (PLIC), it has none of its own."""
        cells, a = self.mixed.cells, self.mixed.node_left
        if a is None:
            return np.zeros(cells.size)
        before = state.node_position[0, a] + state.material_volume[0, cells]
        return (x_new[0, a] + va - before) / dt

    def remapped_slots(self, step, solution, cell_volume, e_new, vb):
        """The mixed cells' part of the state a remap reads: their materials' energies put in
        ``e_new``'s two slots (in place), and the (2, n_cells) volumes (slot 1: ``vb``)."""
        cells = self.mixed.cells
        va, _, details = solution
        e_new[0, cells], e_new[1, cells] = details[0], details[1]
        return self.slot_volumes(step.two_slots, cell_volume, va, vb)

    def state_for_remap(self, step, state, solution, x_new, u_new, cell_volume, e_new, dt):
        cells = self.mixed.cells
        va, _, details = solution
        volumes = self.remapped_slots(step, solution, cell_volume, e_new, cell_volume[cells] - va)
        interface = dict(interface_pressure=0.5 * (details[2] + details[3]),
                         interface_velocity=self.interface_velocity(state, x_new, va, dt))
        return volumes, interface
