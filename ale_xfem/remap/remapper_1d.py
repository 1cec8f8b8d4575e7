"""The 1D transport phase of a run: after each Lagrange step, remap onto the regularised
mesh (Eulerian, smoothed, or following the interfaces) with the swept-region remap, or the
general intersection where the swept form does not apply."""

from __future__ import annotations

import numpy as np

from ale_xfem.model.cell_kernels import finite_where_occupied
from ale_xfem.model.mixed_cells import MixedCells
from ale_xfem.model.state import density_of, thermodynamics
from ale_xfem.remap.intersection_1d import remap_1d
from ale_xfem.remap.failure import RemapFailure
from ale_xfem.remap.pieces_1d import component_dot, deposit_kinetic_loss, lump_kinetic
from ale_xfem.remap.swept_1d import remap_1d_swept


class Remapper:
    """The transport phase of a run: after each Lagrange step, remap onto the regularised
    mesh (``eulerian``: the initial mesh; ``smoothed``: the Lagrangian mesh with each
    interior node moved half-way to the mean of its neighbours)."""

    def __init__(self, problem, motion: str, order: int):
        mesh = problem.mesh
        x0 = mesh.node_position[0]
        nodes = mesh.cell_nodes
        swap = x0[nodes[:, 0]] > x0[nodes[:, 1]]
        self.left_node = np.where(swap, nodes[:, 1], nodes[:, 0])
        self.right_node = np.where(swap, nodes[:, 0], nodes[:, 1])
        self.cell_order = np.argsort(0.5 * (x0[self.left_node] + x0[self.right_node]), kind="stable")
        self.node_order = np.argsort(x0, kind="stable")
        self.rank_of_node = np.empty_like(self.node_order)  # inverse of node_order
        self.rank_of_node[self.node_order] = np.arange(self.node_order.size)
        self.initial = x0.copy()
        self.motion, self.order = motion, order
        # the kinetic energy lost by the momentum remap goes to internal energy
        self.heat = problem.scene.numerics.remap_energy == "total"
        self.windows_remapped = 0  # interface-following motion: local remaps done
        # walls are applied after this remap (the 2D one applies its own: their impulse and
        # a piston's work then come from it)
        self.wall_impulse, self.wall_work = 0.0, 0.0
        self.general_remaps = 0  # steps remapped by the general intersection
        # remaps whose kinetic-energy deposit was limited (a material left outside its
        # equation of state's domain by the local deposit: deposit_kinetic_loss's positive_only)
        self.energy_limited = 0
        self.materials = problem.materials
        self.corner_mass = problem.corner_mass
        numerics = problem.scene.numerics
        interface = problem.scene.interface
        self.model = interface.model if interface is not None else "enriched"
        self.relaxation = interface is None or interface.relaxation
        self.solver_options = dict(tolerance=numerics.interface_tolerance,
                                   max_iterations=numerics.interface_max_iterations,
                                   nonlinear=interface is None or interface.solver == "nonlinear")

    def target(self, position):
        if self.motion == "interface":
            return position.copy()
        if self.motion == "eulerian":
            return self.initial.copy()
        x = position[self.node_order]
        smoothed = x.copy()
        smoothed[1:-1] += 0.5 * (0.5 * (x[:-2] + x[2:]) - x[1:-1])
        target = np.empty_like(position)
        target[self.node_order] = smoothed
        return target

    # Interface-following motion: a mixed cell whose interface comes closer to one of its
    # nodes than this fraction of the cell has that node moved so that Γ is back in the
    # middle of the cell (as far as the neighbouring cell keeps KEEP of its initial
    # length), and only the two cells sharing that node are remapped.
    FOLLOW_BAND = 0.2
    KEEP = 0.75  # the neighbour a moved node goes into keeps this fraction of its initial length

    def apply(self, state, layout, mixed):
        """Remap state; returns (new state, new layout, new mixed cells or None, new node
        masses, kinetic energy change)."""
        if self.motion == "interface":
            return self._follow_interfaces(state, layout, mixed)
        return self._remap_all(state, layout, mixed)

    def near_a_node(self, state, mixed) -> tuple[np.ndarray, np.ndarray]:
        """(each mixed cell's left material's fraction of it, the places among ``mixed`` of
        those whose interface is within FOLLOW_BAND of the cell from one of its nodes):
        what the interface-following motion looks at."""
        x = state.node_position[0]
        fraction = state.material_volume[0, mixed.cells] / (x[mixed.node_right] - x[mixed.node_left])
        return fraction, np.flatnonzero((fraction < self.FOLLOW_BAND) | (fraction > 1 - self.FOLLOW_BAND))

    def _follow_interfaces(self, state, layout, mixed):
        if mixed is None:
            return state, layout, mixed, None, 0.0
        cells = mixed.cells
        x = state.node_position[0]
        a, b = mixed.node_left, mixed.node_right
        fraction, near = self.near_a_node(state, mixed)
        if near.size == 0:
            return state, layout, mixed, None, 0.0
        # Only the few mixed cells whose interface nears a node this step are looked at:
        # nothing here runs over the whole mesh unless a window is remapped.
        moves = {}  # node → its target position
        windows = []
        for k in near:
            interface = x[a[k]] + state.material_volume[0, cells[k]]
            position = self.rank_of_node[a[k]]
            if fraction[k] < 0.5:  # move node a left, into the cell on its left
                if position == 0:
                    continue
                outer = self.node_order[position - 1]
                # Γ back to the middle of the cell, but the neighbour keeps at least KEEP
                # of its initial length (repeated moves would otherwise shrink it without
                # end, and the time step with it)
                limit = x[outer] + self.KEEP * (self.initial[a[k]] - self.initial[outer])
                moved = max(2.0 * interface - x[b[k]], limit)
                if moved >= x[a[k]]:
                    continue
                moves[a[k]] = moved
                windows.append((position - 1, position + 1))
            else:  # move node b right
                if position + 1 == self.node_order.size - 1:
                    continue
                outer = self.node_order[position + 2]
                limit = x[outer] - self.KEEP * (self.initial[outer] - self.initial[b[k]])
                moved = min(2.0 * interface - x[a[k]], limit)
                if moved <= x[b[k]]:
                    continue
                moves[b[k]] = moved
                windows.append((position, position + 2))
        if not windows:
            return state, layout, mixed, None, 0.0
        self.windows_remapped += len(windows)
        target = x.copy()
        target[list(moves)] = list(moves.values())
        return self._remap_windows(state, layout, mixed, target, windows)

    def _remap_windows(self, state, layout, mixed, target, windows):
        """Remap only the cells between sorted nodes (first, last) of each window; the
        window's end nodes stay, and their parts outside the window are untouched."""

        arrays = {k: getattr(state, k).copy() for k in (
            "material_mass", "material_energy", "material_volume", "node_velocity")}
        node_mass = np.bincount(self.left_node, self.corner_mass[0], target.size) + \
            np.bincount(self.right_node, self.corner_mass[1], target.size)
        corner_mass = self.corner_mass.copy()
        position = state.node_position[0]
        kinetic_change = 0.0
        sorted_cells = self.cell_order
        for first, last in windows:
            window_cells = sorted_cells[first:last]  # cells between the window's nodes
            window_nodes = self.node_order[first:last + 1]
            local = {int(n): i for i, n in enumerate(window_nodes)}
            left = np.array([local[int(n)] for n in self.left_node[window_cells]])
            right = np.array([local[int(n)] for n in self.right_node[window_cells]])
            in_window = np.isin(mixed.cells, window_cells)
            mixed_local = np.array([int(np.flatnonzero(window_cells == c)[0]) for c in mixed.cells[in_window]],
                                   dtype=np.int64)
            result = remap_1d(np.arange(window_cells.size), left, right, position[window_nodes],
                              target[window_nodes], layout.cell_material[:, window_cells],
                              arrays["material_mass"][:, window_cells],
                              arrays["material_energy"][:, window_cells],
                              arrays["material_volume"][:, window_cells], corner_mass[:, window_cells],
                              arrays["node_velocity"][:, window_nodes], mixed_local,
                              state.interface_velocity[in_window], len(self.materials), self.order,
                              condensed=mixed.model == "enriched", heat=self.heat)
            if result.mixed_cells.size != mixed_local.size or not np.array_equal(
                    np.sort(result.mixed_cells), np.sort(mixed_local)):
                raise RemapFailure("interface-following remap moved an interface out of its cell")
            # window nodes: momentum inside the window plus, for the two end nodes, their
            # untouched parts outside it
            old_inside = np.bincount(left, corner_mass[0, window_cells], window_nodes.size) + \
                np.bincount(right, corner_mass[1, window_cells], window_nodes.size)
            outside = node_mass[window_nodes] - old_inside
            u_old = arrays["node_velocity"][:, window_nodes]
            new_mass = result.node_mass + outside
            new_velocity = (result.node_momentum + outside * u_old) / new_mass
            kinetic_change += 0.5 * float(np.sum(new_mass * new_velocity**2) - np.sum(node_mass[window_nodes] * u_old**2))
            if self.heat:
                # The window's end nodes mix what the window gave them with their untouched
                # parts outside it: that kinetic energy goes to their corner inside.
                inside = result.node_mass
                mixing = lump_kinetic(inside, result.node_momentum) + 0.5 * (
                    outside * component_dot(u_old, u_old) - new_mass * component_dot(new_velocity, new_velocity))
                end_loss = np.zeros_like(mixing)
                end_loss[[0, -1]] = mixing[[0, -1]]
                deposit_kinetic_loss(end_loss, result.corner_mass, inside, left, right, result.cell_material,
                                     result.material_mass, result.material_energy, result.mixed_cells,
                                     condensed=mixed.model == "enriched")
            arrays["node_velocity"][:, window_nodes] = new_velocity
            node_mass[window_nodes] = new_mass
            corner_mass[:, window_cells] = result.corner_mass
            for key in ("material_mass", "material_energy", "material_volume"):
                arrays[key][:, window_cells] = getattr(result, key)
        self.corner_mass = corner_mass
        density = density_of(arrays["material_mass"], arrays["material_volume"])
        pressure, sound_speed = thermodynamics(self.materials, layout, density, arrays["material_energy"])
        new_state = state.evolved(node_position=target[None, :], material_density=density,
                                  material_pressure=pressure, material_sound_speed=sound_speed, **arrays)
        return new_state, layout, mixed, node_mass, kinetic_change

    def _remap_1d(self, arguments, condensed: bool, heat):
        """The swept form (the same result at a few passes over the cells), or the general
        intersection for the single-velocity closure and any step the swept form does not
        cover."""
        result = remap_1d_swept(*arguments, heat=heat) if condensed else None
        if result is None:
            result = remap_1d(*arguments, condensed=condensed, heat=heat)
            self.general_remaps += 1
        return result

    def _thermodynamics(self, layout, result):
        """(layout, density, pressure, sound speed) of a remap's result."""
        new_layout = layout.updated(result.cell_material)
        density = (result.material_density if result.material_density is not None
                   else density_of(result.material_mass, result.material_volume))
        return (new_layout, density,
                *thermodynamics(self.materials, new_layout, density, result.material_energy))

    def _remap_all(self, state, layout, mixed):
        cells = mixed.cells if mixed is not None else np.zeros(0, dtype=np.int64)
        interface_velocity = (state.interface_velocity if mixed is not None
                              else np.zeros(0))
        if mixed is not None:  # the solver reports mixed cells in any order: sort them
            order = np.argsort(state.node_position[0, self.left_node[cells]])
            cells, interface_velocity = cells[order], interface_velocity[order]
        target = self.target(state.node_position[0])
        arguments = (self.cell_order, self.left_node, self.right_node, state.node_position[0],
                     target, layout.cell_material, state.material_mass, state.material_energy,
                     state.material_volume, self.corner_mass, state.node_velocity, cells,
                     interface_velocity, len(self.materials), self.order)
        condensed = mixed is None or mixed.model == "enriched"
        result = self._remap_1d(arguments, condensed, self.heat)
        new_layout, density, pressure, sound_speed = self._thermodynamics(layout, result)
        if self.heat and not finite_where_occupied(sound_speed, result.material_mass):
            # The kinetic energy a node gained, taken from the cells around it, left a
            # material outside its equation of state's domain (cold air beside water at
            # 1e9 Pa): the remap is done again with only the losses deposited.
            self.energy_limited += 1
            result = self._remap_1d(arguments, condensed, "positive")
            new_layout, density, pressure, sound_speed = self._thermodynamics(layout, result)
        self.corner_mass = result.corner_mass
        new_mixed, interface_pressure, new_interface_velocity = None, None, None
        if result.mixed_cells.size:
            c = result.mixed_cells
            new_mixed = MixedCells(c, self.left_node[c], self.right_node[c],
                                         result.cell_material[0, c], result.cell_material[1, c],
                                         self.materials, **self.solver_options)
            new_mixed.model = mixed.model if mixed is not None else self.model
            new_mixed.relaxation = mixed.relaxation if mixed is not None else self.relaxation
            if mixed is not None:
                new_mixed.stats = mixed.stats
            interface_pressure = 0.5 * (pressure[0, c] + pressure[1, c])
            new_interface_velocity = (interface_velocity if interface_velocity.size == c.size
                                      else np.zeros(c.size))
        new_state = state.evolved(
            node_position=target[None, :], node_velocity=result.node_velocity,
            material_mass=result.material_mass, material_energy=result.material_energy,
            material_volume=result.material_volume, material_density=density,
            material_pressure=pressure, material_sound_speed=sound_speed,
            interface_pressure=interface_pressure, interface_velocity=new_interface_velocity)
        return new_state, new_layout, new_mixed, result.node_mass, result.kinetic_energy_change
