"""The 2D remap: material by material, by swept regions through the mesh's edges.

After a Lagrange step the nodes go from x (Lagrangian) to X (the regularised mesh:
``eulerian`` — back to the initial mesh — or ``smoothed`` — each interior node half-way to
the mean of its neighbours along edges, each boundary node half-way to the mean of its two
boundary neighbours along a straight boundary, corners kept — or, for enriched mixed cells
on a ``lagrangian`` mesh, X = x: nothing is swept, only what the materials carried across
the Lagrangian edges at Γ moves, and the interface is reconstructed in the cells it
reached).  Each edge a→b (counter-clockwise in the cell K₊ on its left) sweeps the
quadrilateral (x_a, X_a, X_b, x_b), of signed area S: S > 0 moves that volume from the
cell on its other side K₋ into K₊, S < 0 from K₊ into K₋.  The new cell areas are then
exact: A' = A + Σ_edges ±S.

What crosses an edge comes from its donor cell, material by material:

- a pure donor gives its material, with density and specific energy of the donor
  (order 1) or, at order 2, a linear density and energy density within the donor, the
  gradients from the node-averaged values through the corner gradients ∂A/∂x_i and limited
  so that the donor's reconstruction stays within its neighbours' range (Barth–Jespersen),
  evaluated at the swept region's centroid;
- a mixed donor gives of each material the part of the swept region inside that
  material's PLIC polygon (exact polygon clipping, ``ale_xfem.model.plic``), at the material's own
  density and energy (order 1): exact intersection only where the interface is.  The part
  of a region outside its donor (near a node, where the regions of its edges overlap) is
  split by the donor's PLIC line, extended beyond the donor.

Mass, material volumes and internal energies are conserved to round-off.  Nodal momentum
(one velocity field: single-velocity mixed cells) is remapped through the cells: each cell
holds the momentum of its corners, Σ_i (m_K/k) u_i, the edges carry mass flux × the donor
cell's velocity, and each node receives the change of momentum of its cells by corner
share: a mesh that does not move changes nothing, a uniform velocity stays uniform, and
momentum is conserved to round-off.  The kinetic energy this loses is returned to the
cells' internal energy by corner mass (``numerics.remap_energy = "total"``), so total
energy is conserved too — including what the walls take when they hold the remapped
velocities (done here, their impulse reported as ``wall_impulse``; a piston's imposed
velocity is boundary work, ``wall_work``).  Only the nodes' losses are deposited, scaled to
the total (a node can gain a little where its neighbours lose): cold gas is never cooled.
A cell that ends with a material below ``numerics.trace_fraction`` (10⁻⁴ by default) of
its area hands that material's mass and energy to the cell around it (sharing a node)
holding the most of it (the first of those holding as much to 10⁻⁹) — or, if none holds
more, to the cell around those holding the most — and its volume to its own largest material: each
material's mass and internal energy stay exact to round-off (reported as
``conservation["material_mass"]``) — except for a fleck with no larger cell within those two
rings, merged into its own cell's other material (``lone_traces``); a cell receiving a third
material stops the run with a diagnostic.

Where the two ends of an edge cross the target edge's line from opposite sides (every edge
that Γ cuts on an enriched cell's mesh: each end moves with its own material), the edge's
region is a bow-tie; beside a mixed cell, or between two materials, it is taken as its two
triangles about the crossing point P, (x_a, X_a, P) and (P, X_b, x_b), each from the cell
on its own side.  (As one region from one donor, the lobe going the other way was given
the donor's volume fractions: on the steady slip line, 40², where no cell's material
volumes should change, one step changed them by 8 × 10⁻² h² in all within 0.3 of the
centre, against 1.3 × 10⁻² h² with the lobes — the Lagrange phase's part 2 × 10⁻³ h².
Between two pure cells of one material the lobes would differ only by their donors'
densities, and twisted edges are common there — 4 700 of the 33 000 moving edges of the
rotated tube at 200², Eulerian, after 5 steps: they stay one region.)
"""

from __future__ import annotations

import numpy as np

from ale_xfem.model.cell_kernels import CELL_TYPE_CODES
from ale_xfem.model.mesh import mesh_edges, node_neighbour_cells
from ale_xfem.model.mixed_cells import MixedCells
from ale_xfem.remap import swept_kernels_2d
from ale_xfem.remap.failure import RemapFailure
from ale_xfem.remap.kinetic_energy import losses_only, made_kinetic_energy_factor
from ale_xfem.remap.scope import WholeMesh, first_cell
from ale_xfem.model.state import density_of, thermodynamics

# Traces.  A material that falls below ``numerics.trace_fraction`` of its cell's area in a remap
# leaves the cell (its mass and energy go to a neighbour holding more of it:
# Remapper2D._move_traces).  The default, 10⁻⁴, was measured on the shock on a
# heavy disk (80 × 40, smoothed mesh, before boundary nodes slid and losses were deposited
# only where lost, traces then merged into their cell's other material): 1e-6 left 453 mixed
# cells of debris, 1e-4 60, 1e-3 51; with 1e-4, traces moved to neighbours and the part of
# a swept region outside its mixed donor split by the donor's interface line
# (Remapper2D._mixed_donor_volumes) now: 54 mixed cells at the end, the disk's mass kept to the
# six digits the demo prints (it lost 0.04 % while traces merged in place) (`python
# demos/shock_disk.py --cells 80`); with traces moved so, 10⁻⁸ leaves as many (54) on the
# same mesh.  A larger fraction cleans more, but each trace moved perturbs the pressure of
# its cell's other material, which takes its volume, by about ρc² × its fraction: nothing for
# gases near their own pressure, but water (ρc² = 2.6 × 10⁹ Pa) beside air at 10⁵ Pa moves by
# up to 2.6 × 10⁵ Pa (an air disk carried through water by a uniform flow: 1.8 × 10⁵ Pa at
# 10⁻⁴, 53 Pa at 10⁻⁶, 10⁻⁴ Pa at 10⁻⁸; tests/test_enriched_2d_run.py), where a smaller
# fraction is the scene's choice (README, "traces": not more accurate everywhere).
# A material already below it before the remap (the set-up's exact areas leave such slivers
# on a curved interface) stays: moving it perturbed a disk at rest on an Eulerian 40 × 40
# mesh by 1.8e-3 in pressure by t = 0.01 (a remap onto an unmoved mesh must change nothing).
MAX_TRACE_PASSES = 8  # a trace moved onto a trace moves on, at most this many times a remap


# Cells that hold a trace's material alike to this relative tolerance are one choice for it
# (Remapper2D._move_traces): full cells of one material hold their areas, equal but for
# round-off, and which of them took a trace followed that round-off (a run whose interface
# system is shared out over 3 MPI ranks then ended 2.5 × 10⁻⁶ apart from the serial run).
HOLDING_ALIKE = 1e-9


def _holding_most(held):
    """(n,): the place in each row of ``held`` (n, width; −inf: no cell) of the first cell
    holding the most, to HOLDING_ALIKE."""
    most = held.max(axis=1, keepdims=True)
    return np.argmax(held >= most - HOLDING_ALIKE * np.abs(most), axis=1)


def _hand_over(quantity, source, target):
    """Move the entries ``source`` (material, cell) of ``quantity`` onto ``target``: taken
    out first, then added (a target that is also a source keeps what it receives)."""
    moved = quantity[source]
    quantity[source] = 0.0
    np.add.at(quantity, target, moved)


class Remapper2D:
    """The transport phase of a 2D run (see module docstring); ``apply`` has the signature
    of :class:`ale_xfem.remap.remapper_1d.Remapper`'s."""

    def __init__(self, problem, motion: str, order: int, mesh=None, boundaries=None, scope=None):
        """``mesh``, ``boundaries``, ``scope``: one MPI rank's share of the problem's mesh,
        the boundaries of the nodes it owns, and what it reaches beyond them
        (:mod:`ale_xfem.remap.scope`; by default the whole mesh)."""
        mesh = problem.mesh if mesh is None else mesh
        self.scope = WholeMesh() if scope is None else scope
        self.mesh, self.materials = mesh, problem.materials
        # (a remap in place sweeps nothing: no reconstruction in the donors to pay for)
        self.motion, self.order = motion, (1 if motion == "lagrangian" else order)
        self.heat = problem.scene.numerics.remap_energy == "total"
        self.trace = problem.scene.numerics.trace_fraction  # (see "Traces" above)
        self.initial = mesh.node_position.copy()
        self.a, self.b, self.plus, self.minus = mesh_edges(mesh.cell_nodes)
        interior = self.minus >= 0
        self.boundary_node = np.zeros(mesh.n_nodes, dtype=bool)
        self.boundary_node[self.a[~interior]] = True
        self.boundary_node[self.b[~interior]] = True
        self.neighbours = np.bincount(self.a, minlength=mesh.n_nodes) + np.bincount(self.b, minlength=mesh.n_nodes)
        interface = problem.scene.interface
        self.solver_options = dict(
            tolerance=problem.scene.numerics.interface_tolerance,
            max_iterations=problem.scene.numerics.interface_max_iterations,
            nonlinear=interface is None or interface.solver == "nonlinear",
            model="single_velocity" if interface is None else interface.model,
            relaxation=interface is None or interface.relaxation)
        self.normal = "youngs" if interface is None else interface.normal  # PLIC's in the mixed donors
        # 2D enriched mixed cells: (position, volume, mass, mixed cells) → (each material's
        # corner and nodal masses, the material each node lies in, which nodes carry each
        # material's mass) — the masses of the Lagrange step's momentum rows
        # (ale_xfem.mixed.cut_cells_2d.material_geometry; set by the time loop)
        self.material_geometry = None
        self.general_remaps = 0  # (the 1D remapper's counter; every 2D step is swept)
        self.energy_limited = 0  # (the 1D remapper's counter: the 2D deposit is always of losses only)
        # walls and pistons hold the remapped velocities inside the remap, so that the kinetic
        # energy they remove is heat like the rest; their impulse is reported here
        self.constraints = [boundary for boundary in (problem.boundaries if boundaries is None else boundaries)
                            if boundary.kind != "free"]
        self.wall_impulse, self.wall_work = np.zeros(2), 0.0
        self._fixed_target = None  # an Eulerian target's edge ends and cell areas (they never change)
        self.node_neighbours = node_neighbour_cells(mesh.cell_nodes, mesh.n_nodes)  # where traces go
        self.lone_traces = 0  # traces with no neighbour holding their material (merged in place)

    def _target_geometry(self, X):
        """The target mesh's edge ends (2, n_edges) each and cell areas."""
        if self._fixed_target is not None:
            return self._fixed_target
        geometry = (X.take(self.a, axis=1), X.take(self.b, axis=1), self.mesh.cell_volumes(X))
        if self.motion == "eulerian":
            self._fixed_target = geometry
        return geometry

    def target(self, position):
        """The regularised mesh (see the module docstring)."""
        if self.motion == "eulerian":
            return self.initial.copy()  # the new state's own array
        if self.motion == "lagrangian":  # in place: only what crossed the edges at Γ moves
            return position.copy()
        return self._smoothed(position)

    def _smoothed(self, position):
        """Interior nodes half-way to the mean of their edge neighbours; boundary nodes
        half-way to the mean of their two boundary neighbours, along the boundary (a node
        where the boundary turns stays)."""
        n = position.shape[1]
        mean = np.stack([np.bincount(self.a, position[d].take(self.b), n)
                         + np.bincount(self.b, position[d].take(self.a), n) for d in range(2)])
        mean /= np.maximum(self.neighbours, 1)
        target = position + 0.5 * (mean - position)
        a, b = self.a[self.minus < 0], self.b[self.minus < 0]  # boundary edges
        ends = np.stack([np.bincount(a, position[d, b], n) + np.bincount(b, position[d, a], n) for d in range(2)])
        count = np.bincount(a, minlength=n) + np.bincount(b, minlength=n)
        nodes = np.flatnonzero(self.boundary_node)
        # the two boundary edges at a node: straight if (p − prev) × (next − p) = 0
        previous = np.full(n, -1)
        following = np.full(n, -1)
        previous[b], following[a] = a, b
        straight = np.zeros(n, dtype=bool)
        valid = nodes[(previous[nodes] >= 0) & (following[nodes] >= 0) & (count[nodes] == 2)]
        e1 = position[:, valid] - position[:, previous[valid]]
        e2 = position[:, following[valid]] - position[:, valid]
        cross = e1[0] * e2[1] - e1[1] * e2[0]
        straight[valid] = np.abs(cross) <= 1e-9 * np.hypot(*e1) * np.hypot(*e2)
        target[:, nodes] = position[:, nodes]
        slide = nodes[straight[nodes]]
        if slide.size:
            tangent = position[:, following[slide]] - position[:, previous[slide]]
            tangent /= np.hypot(*tangent)
            move = 0.5 * (ends[:, slide] / 2 - position[:, slide])
            target[:, slide] += tangent * np.sum(move * tangent, axis=0)
        return target

    # -- the remap -----------------------------------------------------------------------

    def apply(self, state, layout, mixed):
        mesh = self.mesh
        n_materials, n_cells = len(self.materials), mesh.n_cells
        x, X = state.node_position, self.target(state.node_position)
        if self.motion != "eulerian":  # a smoothed node needs its neighbours: the ghost nodes' from their owners
            self.scope.nodes(X)
        # per material dense arrays (n_materials, n_cells): volume, mass, internal energy
        volume, mass, energy = swept_kernels_2d.by_material(layout.cell_material, state.material_volume,
                                                            state.material_mass, state.material_energy, n_materials)
        if state.material_crossing is not None:  # what the materials carried across the Lagrangian edges
            mass += state.material_crossing[0]
            energy += state.material_crossing[1]
        old_cell_mass = mass.sum(axis=0)
        # materials already below the trace fraction of their cell (the set-up's geometry made them, or an
        # earlier remap kept them): they stay while the remap leaves them as they are (to
        # round-off), so that a state remapped onto an unmoved mesh is left as it is
        Xa, Xb, area = self._target_geometry(X)  # the target's edge ends and cell areas
        standing, standing_where, standing_volume = swept_kernels_2d.standing_traces(volume, area, self.trace)

        # -- the swept regions (compiled: ale_xfem.remap.swept_kernels_2d) --------------------
        is_mixed = np.zeros(n_cells, dtype=bool)
        if mixed is not None:
            is_mixed[mixed.cells] = True
        # each moving edge's donor, receiver, |S|, quadrilateral (x_a, X_a, X_b, x_b) and the
        # volume of each material in it from pure donors
        donor, receiver, size, swept, flux_volume = swept_kernels_2d.swept_edges(
            x, Xa, Xb, self.a, self.b, self.plus, self.minus, is_mixed, layout.cell_material[0], n_materials)
        pure = ~is_mixed[donor]
        if np.any(~pure):  # mixed donors: exact clipping with their PLIC polygons
            self._mixed_donor_volumes(state, layout, mixed, swept, donor, size, flux_volume)
            # swept regions of two edges overlap near a moving node: a small material could be
            # taken more than once (its other material then fills the region)
            swept_kernels_2d.cap_outflow(volume, donor, flux_volume)
        # densities and energy densities of the donors, per material, and what the regions carry
        rho, eps, flux_mass, flux_energy = swept_kernels_2d.donor_fluxes(flux_volume, volume, mass, energy, donor)
        if self.order == 2:
            self._second_order(x, layout, is_mixed, rho, eps, swept, donor, flux_volume, flux_mass, flux_energy)
        for quantity, flux in ((volume, flux_volume), (mass, flux_mass), (energy, flux_energy)):
            swept_kernels_2d.exchange(quantity, flux, donor, receiver)
        self.scope.cells(volume, mass, energy)  # (on several ranks: the ghost cells' from their owners)
        # a trace the fluxes changed is a trace this remap made: it moves (kept, traces of a
        # shock's path took energy below zero on the shock on a disk)
        swept_kernels_2d.untouched_traces(standing, standing_where, standing_volume, volume)
        if state.material_node_velocity is not None and mixed is None:
            # no mixed cell this step: every material moved with the mesh, with the equal
            # corner shares of its cells as masses
            state = self._moved_with_the_mesh(state, layout)
        if state.material_node_velocity is not None:  # one velocity field per material
            momentum, kinetic_in, deviation = self._material_momentum_fluxes(state, flux_mass, donor, receiver)
            self._move_traces(volume, mass, energy, area, standing, carried=momentum)
            velocity, node_mass, kinetic_change, material_fields = self._material_velocities(
                state, X, volume, mass, energy, area, standing, momentum, kinetic_in, deviation)
            return self._new_state(state, layout, mixed, X, volume, mass, energy, area, standing, velocity,
                                   node_mass, kinetic_change, material_fields)
        self._move_traces(volume, mass, energy, area, standing)

        # -- nodal momentum through the cells (compiled) -------------------------------------
        u = state.node_velocity
        velocity, node_mass, kinetic_before, loss = swept_kernels_2d.cell_momentum(
            u, mesh.compiled_cell_nodes, *mesh.node_corners, old_cell_mass, mass.sum(axis=0), flux_mass, donor,
            receiver)
        owned_mass = node_mass if self.scope.owned_nodes is None else node_mass[self.scope.owned_nodes]
        self.scope.verdict(RemapFailure("a node lost all its mass in the remap") if np.any(owned_mass <= 0) else None)
        # walls take the normal velocity (that kinetic energy is heat too); pistons impose
        # theirs (the energy that costs is work of the boundary, like in the Lagrange step)
        self.wall_impulse, self.wall_work = np.zeros(velocity.shape[0]), 0.0
        for boundary in self.constraints:
            free = velocity[:, boundary.nodes].copy()
            boundary.apply(velocity)
            held = velocity[:, boundary.nodes]
            self.wall_impulse += np.sum(node_mass[boundary.nodes] * (held - free), axis=1)
            change_k = 0.5 * node_mass[boundary.nodes] * np.sum(held * held - free * free, axis=0)
            if boundary.kind == "wall":
                np.subtract.at(loss, boundary.nodes, change_k)
            else:
                self.wall_work += float(change_k.sum())
        self.wall_impulse, self.wall_work = self.scope.summed(self.wall_impulse), self.scope.summed(self.wall_work)
        self.scope.nodes(velocity, node_mass, loss)
        kinetic_after = 0.5 * node_mass * np.sum(velocity * velocity, axis=0)
        after, before = self.scope.totals((kinetic_after, kinetic_before), "nodes")
        kinetic_change = after - before - self.wall_work
        self._deposit(loss, node_mass, mass, energy)
        self.scope.cells(energy)

        return self._new_state(state, layout, mixed, X, volume, mass, energy, area, standing, velocity,
                               node_mass, kinetic_change)

    def _new_state(self, state, layout, mixed, X, volume, mass, energy, area, standing, velocity, node_mass,
                   kinetic_change, material_fields=None):
        """The remapped state from each material's (n_materials, n_cells) volume, mass and
        internal energy, back in slots; returns what :meth:`apply` returns."""
        count, cell_material, slot_mass, slot_volume, slot_energy = swept_kernels_2d.material_slots(
            volume, mass, energy, area, standing, self.trace)
        scope = self.scope
        if scope.anywhere(cell_material.shape[0] == 2) and cell_material.shape[0] == 1:
            # on several ranks: a rank whose cells all hold one material takes a second slot,
            # empty, as the serial remap leaves its pure cells when another cell is mixed
            cell_material = np.vstack([cell_material, np.full_like(cell_material, -1)])
            slot_mass, slot_volume, slot_energy = (np.vstack([a, np.zeros_like(a)])
                                                   for a in (slot_mass, slot_volume, slot_energy))
        for bad, what in ((count > 2, "three materials meet in one cell; refine the mesh"),
                          (count == 0, "no material left after the remap")):
            c = first_cell(bad)
            number = scope.cell_number(c) if c >= 0 else -1
            scope.verdict(RemapFailure(f"cell {number}: {what}") if c >= 0 else None, order=number)
        mixed_cells = np.flatnonzero(count == 2)
        scope.verdict(RemapFailure("a material's mass became ≤ 0 in the remap (a node moved too far)")
                      if np.any(slot_mass[cell_material >= 0] <= 0) else None)
        new_layout = layout.updated(cell_material)
        density = density_of(slot_mass, slot_volume)
        pressure, sound_speed = thermodynamics(self.materials, new_layout, density, slot_energy)
        new_mixed, interface_pressure, interface_velocity = None, None, None
        if mixed_cells.size:
            c = mixed_cells
            new_mixed = MixedCells(c, None, None, cell_material[0, c], cell_material[1, c], self.materials,
                                   **self.solver_options)
            if mixed is not None:
                new_mixed.stats = mixed.stats
            v = slot_volume[:, c]
            interface_pressure = (pressure[:, c] * v).sum(axis=0) / v.sum(axis=0)
            interface_velocity = np.zeros(c.size)
        new_mixed = scope.solved_mixed(new_mixed, self.solver_options)
        if new_mixed is not None and interface_pressure is None:  # (on several ranks: mixed cells, none here)
            interface_pressure, interface_velocity = np.zeros(0), np.zeros(0)
        new_state = state.evolved(
            node_position=X, node_velocity=velocity, material_mass=slot_mass, material_energy=slot_energy,
            material_volume=slot_volume, material_density=density, material_pressure=pressure,
            material_sound_speed=sound_speed, interface_pressure=interface_pressure,
            interface_velocity=interface_velocity, material_crossing=None, **(material_fields or {}))
        return new_state, new_layout, new_mixed, node_mass, kinetic_change

    def _deposit(self, loss, node_mass, mass, energy, corner_mass=None):
        """The kinetic energy the remap lost at each node (n_nodes,) into the materials'
        internal energies (n_materials, n_cells), in place (``numerics.remap_energy =
        "total"``; otherwise nothing).  ``corner_mass`` (2, k, n_cells): each material's own
        corner masses (2D enriched cells, condensed), which ``node_mass`` sums; by default
        each cell's equal corner shares, split by material mass."""
        total_loss, gains_left_out = self.scope.totals((loss, np.maximum(loss, 0.0)), "nodes")
        if self.heat and total_loss > 0:
            # Deposited where it is lost, by corner mass then by material mass.  A node may
            # gain a little where its neighbours lose (the cells' momentum is shared by
            # corners): only the losses are deposited, scaled to their sum — cold gas must
            # not be cooled below zero by a neighbour's gain.
            loss = losses_only(loss, (total_loss, gains_left_out))
            per_mass = loss / node_mass
            if corner_mass is not None:  # Σ_m Σ_K Σ_k (loss_i / M_i) c_m,K,k is the whole loss
                swept_kernels_2d.deposit_corner_heat(self.mesh.compiled_cell_nodes, per_mass, corner_mass, energy)
                return
            swept_kernels_2d.deposit_heat(self.mesh.cell_nodes, per_mass, mass, energy)
        elif self.heat and total_loss < 0:
            # The momentum remap through the cells is not dissipative node by node, and now and
            # then not overall either: the kinetic energy it made is taken from the internal
            # energies in proportion (each scaled by the same factor, so none goes below 0).
            energy *= made_kinetic_energy_factor(total_loss, self.scope.totals((energy,), "cells")[0])

    def _moved_with_the_mesh(self, state, layout):
        """The per-material fields of a state whose step had no mixed cell (all materials
        moved with the nodes): each material's velocity the node's, its corner masses the
        equal shares of its cells."""
        mass = np.stack([np.where(layout.cell_material[0] == m, state.material_mass[0], 0.0) for m in range(2)])
        corner_mass, node_mass, _, internal = self.material_geometry(state.node_position, None, mass,
                                                                     np.zeros(0, dtype=np.int64))
        return state.evolved(material_node_velocity=np.stack([state.node_velocity[:2]] * 2),
                             material_corner_mass=corner_mass, material_node_mass=node_mass,
                             material_node_internal=internal)

    def _material_momentum_fluxes(self, state, flux_mass, donor, receiver):
        """Each material's momentum per cell after the fluxes ((2 components, 2 materials, n_cells)):
        the cell holds Σ_i c_mi u_mi over its corners (c: the material's corner masses,
        condensed in mixed cells), and an edge carries each material's mass flux at the
        donor's mean velocity *of that material* — no tangential momentum crosses Γ inside
        a mixed donor.  Also the kinetic energy the fluxes bring each cell, per material
        ((2, n_cells)), and each corner's velocity less its cell's mean, per material
        ((2, 2, k, n_cells): what :meth:`_material_velocities` puts back) — at the
        material's internal nodes only: at its external nodes (nearly massless) its velocity
        is weakly determined by the interface solve (it grew to 4 times the flow's speed in
        a few steps of the spinning disk) and is re-extended from its cells' means."""
        return swept_kernels_2d.material_momentum_fluxes(
            self.mesh.cell_nodes, state.material_corner_mass, state.material_node_velocity,
            state.material_node_internal, flux_mass, donor, receiver, *self._crossed(state))

    def _crossed(self, state):
        """What the materials' crossings of the Lagrangian edges (the state's
        ``material_crossing``) brought each cell: mass (2, n_cells), momentum (2 components,
        2 materials, n_cells) and kinetic energy (2, n_cells) — added before the swept
        regions' fluxes, so that a cell's momentum goes with its mass (a cell the fluxes
        empty leaves none behind)."""
        if state.material_crossing is None:
            n_cells = self.mesh.n_cells
            return np.zeros((2, n_cells)), np.zeros((2, 2, n_cells)), np.zeros((2, n_cells))
        mass, _, momentum, kinetic = state.material_crossing
        return mass, momentum, kinetic

    def _material_velocities(self, state, X, volume, mass, energy, area, standing, momentum, kinetic_in,
                             deviation):
        """Each material's nodal velocities on the remapped mesh.  Each corner of a cell
        takes the cell's new mean velocity of the material plus the corner's old
        ``deviation`` from the old mean, less the new-mass-weighted mean of the deviations
        (so the cell's momentum is exact), weighted at the nodes by the material's new
        corner masses (condensed where the new mixed cells are).  A remap that moves
        nothing changes nothing: spreading the cells' mean velocities alone would damp every
        velocity gradient by the cells' own moment of inertia, a rigid rotation by about
        h²/R² a step (a spinning disk lost 4 % of its angular momentum a remap at R = 5h).
        Then walls held material by material, and the kinetic energy lost deposited as heat.
        Returns (the mesh's velocity: each node's own material's, the total nodal masses,
        the kinetic energy change, the state's material fields)."""
        mesh = self.mesh
        present = (volume > self.trace * area) | (standing & (mass != 0.0))
        cells = np.flatnonzero(present.sum(axis=0) == 2)
        kept_volume, kept_mass = np.where(present, volume, 0.0), np.where(present, mass, 0.0)
        corner_mass, node_mass, owner, internal = self.material_geometry(X, kept_volume, kept_mass, cells)
        # the fluxes' kinetic energy goes to the nodes by corner shares: the new ones, or, in a
        # cell the material has left (its outflow counted there, or a trace of it moved away),
        # the old ones — every cell's share reaches the nodes, so the losses sum to the kinetic
        # energy the remap changed (by the new shares alone, what left a cell was lost: total
        # energy drifted by 10⁻⁶ a remap on the sheared tube); and the mass the new shares
        # move between a cell's corners takes its kinetic energy along, so that a uniform
        # velocity loses none (tests/test_enriched_2d_run.py, the disk in a uniform flow)
        velocity, mesh_velocity, kinetic_before, loss = swept_kernels_2d.material_node_velocities(
            mesh.cell_nodes, corner_mass, node_mass, owner, momentum, deviation, state.material_node_mass,
            state.material_node_velocity, state.material_corner_mass, kinetic_in)
        self._merge_outside_mixed_cells(velocity, mesh_velocity, node_mass, loss, cells)
        self.wall_impulse, self.wall_work = np.zeros(2), 0.0
        for boundary in self.constraints:
            nodes = boundary.nodes
            for m in range(2):
                free = velocity[m][:, nodes].copy()
                boundary.apply(velocity[m])
                held = velocity[m][:, nodes]
                self.wall_impulse += np.sum(node_mass[m, nodes] * (held - free), axis=1)
                change = 0.5 * node_mass[m, nodes] * np.sum(held * held - free * free, axis=0)
                if boundary.kind == "wall":
                    np.subtract.at(loss, nodes, change)
                else:
                    self.wall_work += float(change.sum())
            boundary.apply(mesh_velocity)
        scope = self.scope
        self.wall_impulse, self.wall_work = scope.summed(self.wall_impulse), scope.summed(self.wall_work)
        n_nodes = node_mass.shape[1]
        # (on several ranks: the ghost nodes' and cells' from their owners)
        scope.nodes(velocity.reshape(-1, n_nodes), mesh_velocity, node_mass, loss, internal)
        scope.cells(corner_mass.reshape(-1, corner_mass.shape[-1]))
        kinetic_after, kinetic_before = scope.totals(((node_mass[:, None] * velocity**2).reshape(-1, n_nodes),
                                                      kinetic_before), "nodes")
        kinetic_change = float(0.5 * kinetic_after - kinetic_before) - self.wall_work
        total_node_mass = node_mass.sum(axis=0)
        self._deposit(loss, total_node_mass, mass, energy, corner_mass)
        scope.cells(energy)
        fields = dict(material_node_velocity=velocity, material_node_mass=node_mass,
                      material_corner_mass=corner_mass, material_node_internal=internal)
        return mesh_velocity, total_node_mass, kinetic_change, fields

    def _merge_outside_mixed_cells(self, velocity, mesh_velocity, node_mass, loss, cells) -> None:
        """A node that carries both materials' masses but is no node of a mixed cell (pure
        cells of both materials around it: Γ along mesh edges there) is outside the next
        step's interface system, which moves it with one velocity: its two velocities
        ``velocity`` (2, 2, n_nodes) become their mass-weighted mean, the mesh's too (in
        place), momentum kept, the kinetic energy that loses added to ``loss`` (n_nodes,),
        as heat.  (Left to the step, which moves such a node with its own material's
        velocity, the other material's momentum there changed: the sliver column of the
        stability suite drifted by 2 × 10⁻⁷ of M V in one step, once its slivers had left.)"""
        in_mixed = np.zeros(node_mass.shape[1], dtype=bool)
        in_mixed[self.mesh.cell_nodes[cells].ravel()] = True
        both = np.flatnonzero((node_mass[0] > 0.0) & (node_mass[1] > 0.0) & ~in_mixed)
        if both.size == 0:
            return
        mass = node_mass[:, both]  # (2, n)
        merged = np.einsum("mn,mdn->dn", mass, velocity[:, :, both]) / mass.sum(axis=0)
        loss[both] += 0.5 * np.einsum("mn,mdn->n", mass, (velocity[:, :, both] - merged) ** 2)
        velocity[:, :, both] = merged
        mesh_velocity[:, both] = merged

    def _move_traces(self, volume, mass, energy, area, standing, carried=()):
        """A material left below ``self.trace`` of a cell's area leaves the cell — unless it was
        there below that before this remap (``standing``): its mass and
        internal energy go to the cell around it (sharing a node) that holds the most of that
        material, if more than the trace, its volume to the cell's largest material — each
        material's mass and energy conserved; if none holds more, the cells around those
        (:meth:`_second_ring`).  A trace moved onto another trace moves on in the next pass;
        a fleck with no larger cell within those goes to its own cell's largest material
        instead (counted in ``lone_traces``: each material's mass is then exact within
        such flecks).  ``carried``: more (n_materials, n_cells) quantities that go
        with the mass (each material's momentum, per component)."""
        scope = self.scope  # (on several ranks every rank takes each pass, the ghost cells refreshed after it)
        for _ in range(MAX_TRACE_PASSES):
            material, cells = swept_kernels_2d.traces(volume, mass, area, standing, self.trace)
            if not scope.anywhere(cells.size > 0):
                return
            present = swept_kernels_2d.present_materials(volume[:, cells], area[cells], standing[:, cells], self.trace)
            keeper = np.argmax(np.where(present, volume[:, cells], -np.inf), axis=0)
            candidates = self.node_neighbours[cells]
            held = np.where(candidates >= 0, volume[material[:, None], candidates], -np.inf)
            best = _holding_most(held)
            rows = np.arange(cells.size)
            larger = held[rows, best] > volume[material, cells]
            if not np.all(larger):  # none around it holds more: the cells around those
                candidates, held, best = self._second_ring(volume, material, cells, ~larger, candidates)
                larger = held[rows, best] > volume[material, cells]
            if not scope.anywhere(np.any(larger)):
                break
            material, cells, keeper = material[larger], cells[larger], keeper[larger]
            receiver = candidates[rows[larger], best[larger]]
            for quantity in (mass, energy, *carried):
                _hand_over(quantity, (material, cells), (material, receiver))
            _hand_over(volume, (material, cells), (keeper, cells))
            scope.cells(mass, energy, *carried, volume)
        material, cells = swept_kernels_2d.traces(volume, mass, area, standing, self.trace)
        if cells.size:  # flecks: merged into their own cell's largest material
            present = swept_kernels_2d.present_materials(volume[:, cells], area[cells], standing[:, cells], self.trace)
            keeper = np.argmax(np.where(present, volume[:, cells], -np.inf), axis=0)
            for quantity in (mass, energy, volume, *carried):
                _hand_over(quantity, (material, cells), (keeper, cells))
            self.lone_traces += cells.size

    def _second_ring(self, volume, material, cells, lone, candidates):
        """For the traces ``lone`` (of ``material`` in ``cells``) that no cell around them
        holds more of: the cells around those cells instead (a trace can be all a donor
        had of a material, the donor emptied by the same remap — a region of a twisted edge
        taking it one way, the rest another); the others keep their ``candidates`` (the
        cells around them).  Returns (candidates (n, width²), the volume of the trace's
        material each holds, the place of the one holding most)."""
        around = self.node_neighbours
        width = around.shape[1]
        wide = np.full((cells.size, width * width), -1, dtype=around.dtype)
        wide[:, :width] = candidates
        first = candidates[lone]
        ring = np.where(first[:, :, None] >= 0, around[np.maximum(first, 0)], -1).reshape(first.shape[0], -1)
        wide[lone] = ring
        wide_held = np.where(wide >= 0, volume[material[:, None], wide], -np.inf)
        return wide, wide_held, _holding_most(wide_held)

    def _mixed_donor_volumes(self, state, layout, mixed, swept, donor, size, flux_volume):
        """Of each swept region whose donor is a mixed cell, the part inside the donor's α
        polygon (PLIC) is α, the rest of its part inside the donor β (exact clipping), and
        the part outside the donor is split by the donor's PLIC line, extended."""
        from ale_xfem.model.plic import interface_lines

        # the Lagrangian state's interface: α = {x·n ≤ s} in each mixed cell
        mixed_cells, normal, offset = interface_lines(self, state, layout, mixed, self.normal)
        where = np.full(self.mesh.n_cells, -1, dtype=np.int64)
        where[mixed_cells] = np.arange(mixed_cells.size)
        edges = np.flatnonzero(where[donor] >= 0)
        if edges.size == 0:
            return
        # the swept quadrilateral, counter-clockwise, clipped by its donor cell; then its α
        # part, {x·n ≤ s} of that (α's PLIC polygon is the cell's part there), by area only
        inside, alpha, alpha_whole = swept_kernels_2d.mixed_donor_parts(
            swept, edges, state.node_position, self.mesh.cell_nodes, donor, size, normal, offset, where[donor[edges]])
        # Near a node the region may reach out of its donor (the swept regions of the
        # node's edges overlap there): that part is neither of the donor's polygons, and
        # the donor's interface line, extended, splits it.  (Counted as β, it carried a
        # trace of β out of its cell every step — one cell a step, faster than the flow —
        # and left the rotated tube's shocked gas full of β debris: 1 479 mixed cells
        # instead of 212 at 100², Eulerian.  Shared by the donor's volume fractions, 212;
        # split by the line, 153.  By the fractions, the spinning disk's first step put
        # flecks of the fluid, 10⁻⁴ to 10⁻³ of a cell, into 52 cells inside the disk on 80²,
        # none by the line; they roughened the rim, and the disk lost more of its angular
        # momentum to the fluid the finer the mesh: docs/design.md §4.)
        outside = size[edges] - inside
        outside_alpha = np.clip(alpha_whole - alpha, 0.0, outside)
        beta = inside - alpha + (outside - outside_alpha)
        alpha += outside_alpha
        first, second = layout.cell_material[0, donor[edges]], layout.cell_material[1, donor[edges]]
        flux_volume[:, edges] = 0.0
        flux_volume[first, edges] = alpha
        flux_volume[second, edges] = beta

    def _second_order(self, x, layout, is_mixed, rho, eps, swept, donor, flux_volume, flux_mass, flux_energy):
        """Limited linear density and energy density in pure donors, at the centroid of the
        swept region (module docstring; compiled: swept_kernels_2d.second_order)."""
        mesh = self.mesh
        material = layout.cell_material[0]
        value = swept_kernels_2d.slot_values(rho, eps, material)
        swept_kernels_2d.second_order(CELL_TYPE_CODES[mesh.cell_type.name], x, mesh.compiled_cell_nodes,
                                      *mesh.node_corners, material, is_mixed, value, swept, donor, flux_volume,
                                      flux_mass, flux_energy)
