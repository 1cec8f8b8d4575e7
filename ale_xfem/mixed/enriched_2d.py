"""The enriched closure of 2D mixed cells (the paper's §3.2): one velocity field per
material on the nodes of the mixed cells, mass condensation, the interface system of
``forms/enriched_interface.py`` (bubble or Nitsche stabilisation, free slip or stick)
solved implicitly inside the Wilkins step, with the predictor/corrector of
:mod:`ale_xfem.mixed.implicit_step`.

**Within the step.**  The explicit step evaluates every cell's corner forces at n and at the
predicted state.  The closure keeps, for each material, the time-centred forces F̄ of its
*pure* cells at the nodes of the mixed cells, and solves for each material's mean velocity
ū_m over the step at those nodes (internal rows: 4M_m(ū_m − u_m^n)/dt = 2F̄_m + f_m^n +
f_m^{n+1}; external rows: the interface's equilibrium at n+1, their share of f_m^n moved
onto the internal nodes).  f_m: the mixed cell's stress on its material's nodes, (P_m + q̄)
on its part and (p_Γ + q̄) on Γ, q̄ = ½(q^n + q*) the mixed cell's artificial viscosity (a
stress on both materials alike).  Each material's nodal velocity is then u_m^{n+1} = 2ū_m
− u_m^n; a node moves with the material it lies in (``EnrichedGeometry.owner``), and the
step's own update of those nodes is replaced by that; walls hold their components in
every material's rows and their reaction enters the step's bookkeeping.  A ghost
viscosity (``interface.ghost_viscosity``, by default ``GHOST_VISCOSITY`` of the mesh's
cell type) steadies each material's velocity beyond its part; what it and Nitsche's
penalty dissipate, and what the moved share of f^n gains or loses, is heat, shared by the
cell's materials by mass.

**Material numbering.**  The system's α is material 0 of the scene in every mixed cell (a
node's velocities must mean the same material in all its cells): 2D enriched scenes have
two materials.  The state's slots (0: the larger material of a cell) are mapped to it.

**Volumes.**  Each material's part changes by ΔV_m = dt ∫_{K_m} ∇·ū_m (the forms bound to
the start of the step): it moves with its own velocity.  The cell moves with its nodes,
each node with the material it lies in, so where the materials slide an edge between
nodes of the two materials moves with neither, and each material crosses it (the
*crossings*, :meth:`EnrichedClosure2D._crossings`): the part in the Lagrangian cell is
V_m + ΔV_m + R_m, R_m what m brought across the cell's edges.  Under normal continuity
the two then fill the Lagrangian cell to first order in dt; the rest (O(dt²)) is scaled
away, and the largest relative mismatch of a step is recorded
(``MixedCells.stats["volume_mismatch"]``).  The mass, internal energy, momentum and
kinetic energy that crossed are handed to the remap (the state's ``material_crossing``),
which moves them before its own fluxes.  The mixed cells' artificial viscosity is taken on
their compression less the part the sliding makes (:meth:`EnrichedClosure2D._own_viscosity`).
This needs a remap after every step: on a Lagrangian mesh it is made in place
(``remap_lagrangian``: nothing swept, only what crossed moves).

**State.**  Each material's nodal velocities and masses (the condensed ones, the same in
the step and in the remap: momentum passes between them exactly) are in the state
(``material_node_velocity``, ``material_node_mass``, ``material_corner_mass``,
``material_node_internal``); the state's ``node_velocity`` is the mesh's: each node's own
material's.  docs/design.md §4 gives the measurements behind each choice.
"""

from __future__ import annotations

import numpy as np

import dolfinx_solver  # noqa: F401  (before dolfinx: it loads MPI and PETSc)
from ale_xfem.lagrange.breakdown import Breakdown
from ale_xfem.mixed.closure_kernels import add_viscosity, pure_cell_forces
from ale_xfem.mixed.common import SharedClosure
from ale_xfem.mixed.cut_cells_2d import (by_material, crossed_volume, edge_weights, edges_of, interface_geometry,
                                         node_edges)
from ale_xfem.mixed.implicit_step import ImplicitStep, MaterialStart
from ale_xfem.mixed.equilibrium import MixedCellFailure
from ale_xfem.model.mesh import cells_around, cells_at_nodes, csr_rows
from ale_xfem.model.mixed_cells import MixedCells
from forms.enriched_interface import InterfaceForms, InterfaceSystem

# the inertia 4M/dt of a held velocity component: the wall's or the piston's value wins
HELD_INERTIA = 1e20
# rings of cells around the mixed cells in the band the interface system is bound to: Γ can
# move this many cells before the system is bound again
BAND_RINGS = 2
# the weight of the strain rate of a material's velocity over the other material's part of
# a cut cell, relative to the inertia 4ρ_m|K|/dt of the cell's area at the material's own
# density: the default of the scene key interface.ghost_viscosity (scene.schema's
# TWO_D_DEFAULTS, which a test holds equal to it).  Both materials at 0.1 on the cell's whole
# mass instead took the water-air case of the stability suite (air drawn to near vacuum
# where Γ meets the wall) from 108 steps to a breakdown after 1132.  At 0.2 and 0.1 other
# cases lose accuracy or robustness; on quadrilaterals at 1.0 the sheared tube's errors
# converge faster and the spinning disk's rim keeps more, but a sliding block is dragged
# more and a slip line on a Lagrangian mesh loses (docs/design.md §4, "The extension of
# each material's velocity").
# On crossed triangles the extension's noise along Γ is stronger: at 1.0 there the sheared
# tube's errors converge faster and the spinning disk hands its fluid less, and a block
# still slides more freely than with one velocity field, which at 2.0 it does not; so the
# default is by the mesh's cell type.
GHOST_VISCOSITY = {"quadrilateral": 0.3, "triangle": 1.0}
# the largest share of what a cell holds of a material that may cross its edges in a step
# (EnrichedClosure2D._crossings: a sliver cannot give more than it has)
CROSSING_SHARE = 0.5


def held_components(boundary) -> list[int]:
    """The velocity components a boundary constraint holds: a wall its normal one, a piston
    both."""
    return [int(np.argmax(np.abs(boundary.normal)))] if boundary.kind == "wall" else [0, 1]


def held_nodes(step, nodes, d: int) -> np.ndarray:
    """The ``nodes`` whose component ``d`` a wall or a piston of the step holds."""
    held = [b.nodes for b in step.constraints if b.kind == "velocity" or abs(b.normal[d]) > 0.5]
    return np.intersect1d(np.concatenate(held), nodes) if held else np.zeros(0, dtype=np.int64)


class EnrichedClosure2D(SharedClosure):
    """2D mixed cells with doubled velocities (module docstring).  ``stabilisation``:
    bubble | nitsche | none; ``slip``: free | stick; ``nitsche_penalty``: Nitsche's
    dimensionless factor; ``petsc_options``: the interface system's KSP (default MUMPS);
    ``ghost_viscosity``: the weight of the ghost viscosity (scene key
    ``interface.ghost_viscosity``; None: ``GHOST_VISCOSITY`` of the mesh's cell type);
    ``system``: what binds the interface system to a band of cells (InterfaceSystem's
    arguments; None: InterfaceSystem; on several MPI ranks, one shared out over them)."""

    implicit = True

    def __init__(self, mesh, materials, mixed: MixedCells, stabilisation: str = "bubble",
                 slip: str = "free", nitsche_penalty: float = 1.0, petsc_options: dict | None = None,
                 system=None, normal: str = "youngs", ghost_viscosity: float | None = None):
        if len(materials) != 2:
            raise ValueError("2D enriched mixed cells need exactly two materials")
        self.forms = InterfaceForms(mesh.dolfinx_mesh.comm, stabilisation, slip, mesh.cell_type.name)
        self.nitsche_penalty, self.petsc_options = nitsche_penalty, petsc_options
        self.normal = normal  # PLIC's normals in the cut cells: "youngs" | "lvira" (ale_xfem.model.plic)
        # the ghost viscosity's weight (GHOST_VISCOSITY of the cell type by default)
        self.ghost_viscosity = GHOST_VISCOSITY[mesh.cell_type.name] if ghost_viscosity is None else ghost_viscosity
        self.bound_system = InterfaceSystem if system is None else system
        self.system, self._system_cells, self._in_band, self._band_nodes = None, None, None, None
        self._last = None
        # the interface system speaks DOLFINx's numbering of nodes and cells (a structured
        # rectangle of quadrilaterals numbers its own row by row)
        identity = np.arange(mesh.n_nodes)
        self.dolfinx_node = identity if mesh.dolfinx_node is None else mesh.dolfinx_node
        self.node_of_dolfinx = np.empty_like(self.dolfinx_node)
        self.node_of_dolfinx[self.dolfinx_node] = identity
        super().__init__(mesh, materials, mixed)

    @property
    def last_step(self) -> dict:
        """What the last interface solve left for the step's end: its mixed cells' nodes
        (``sub``), each material's new velocities (``velocity``), the interface pressure
        (``interface_pressure``, once :meth:`end_of_step` has run), ..."""
        return self._last

    @property
    def band(self) -> np.ndarray:
        """(n_cells,) bool: the cells the interface system is bound to (:meth:`bind`)."""
        return self._in_band

    def _to_dolfinx(self, node_values):
        """A node field (..., n_nodes) in DOLFINx's node order."""
        return np.take(node_values, self.node_of_dolfinx, axis=-1)

    def bind(self, mixed: MixedCells) -> None:
        """The interface system over the mixed cells: bound to a band of cells around them
        (BAND_RINGS rings of neighbours), made active on the mixed cells only; a new band
        only when a mixed cell leaves it (binding a submesh costs more than a step's solves)."""
        super().bind(mixed)
        mixed.stats.setdefault("volume_mismatch", 0.0)
        mixed.stats.setdefault("bands", 0)
        if self._system_cells is None or not np.array_equal(self._system_cells, mixed.cells):
            mesh = self.mesh
            dolfinx_cell = (lambda c: c) if mesh.dolfinx_cell is None else (lambda c: mesh.dolfinx_cell[c])
            if self.system is None or not np.all(self._in_band[mixed.cells]):
                self._in_band = self._band(mixed.cells)
                self._band_nodes = np.unique(mesh.cell_nodes[self._in_band])
                band = np.flatnonzero(self._in_band)
                if self.system is not None:  # (its PETSc objects freed now, not parked: InterfaceSystem.destroy)
                    self.system.destroy()
                self.system = self.bound_system(mesh.dolfinx_mesh, dolfinx_cell(band), self.forms, self.petsc_options)
                mixed.stats["bands"] += 1
            self.system.activate(dolfinx_cell(mixed.cells))
            self.system.vertex_order(self.dolfinx_node[mesh.cell_nodes[mixed.cells]])
            self._system_cells = mixed.cells.copy()

    def _band(self, cells) -> np.ndarray:
        """(n_cells,) bool: ``cells`` and BAND_RINGS rings of cells around them (sharing a node)."""
        for _ in range(BAND_RINGS):
            cells = cells_around(self.mesh, cells)
        band = np.zeros(self.mesh.n_cells, dtype=bool)
        band[cells] = True
        return band

    # -- the implicit solve ---------------------------------------------------------------

    def _pure_forces(self, first, predicted, cell_material):
        """(2, 2, n_nodes): each material's time-centred force F̄ of its pure cells at the
        band's nodes, the only ones the interface system reads (zero elsewhere)."""
        out = np.zeros((2, 2, self.mesh.n_nodes))
        pure_cell_forces(self._band_nodes, *self.mesh.node_corners, cell_material, first.corner_force,
                         predicted.corner_force, out)
        return out

    def hold_predictor(self, u0, u_pred) -> None:
        """The mixed cells' nodes keep their start velocities in the explicit predictor
        (x* = x^n + dt u^n there, still second order in time): the interface solve moves
        them, with the materials' own masses and the interface's forces, where the predictor
        would accelerate them by the mesh's forces over the mesh's masses.  That guess
        squeezed a pure cell of a disk 100 times lighter than the fluid around it by 6 % in
        its predicted state (its predicted viscosity 30 times its pressure), whose work on
        the step's velocities took 0.17 of its specific energy a step until the EOS left its
        domain (100² crossed triangles, a ghost viscosity of 0.1)."""
        nodes = self.mesh.cell_nodes[self.mixed.cells].ravel()
        u_pred[:, nodes] = u0[:, nodes]

    def implicit_solve(self, step, state, first, predicted, mean_force, dt, dt_over_node_mass):
        mixed, mesh = self.mixed, self.mesh
        cells = mixed.cells
        layout = step.layout.cell_material
        x0 = state.node_position
        volume = by_material(state.material_volume, layout)
        mass = by_material(state.material_mass, layout)
        energy = by_material(state.material_energy, layout)
        pressure = by_material(state.material_pressure, layout)
        try:
            geometry = interface_geometry(mesh, x0, volume, mass, cells, self.normal)
        except ValueError as failure:
            raise Breakdown("interface reconstruction", int(cells[0]), float("nan"),
                            mesh.cell_centroids(x0)[cells[0]], detail=str(failure)) from None
        # the masses the state's velocities go with (the set-up's or the remap's; the
        # start-of-step pressure relaxation may have moved Γ a little since): momentum
        # passes on exactly
        node_mass, corner_mass = state.material_node_mass, state.material_corner_mass
        internal = state.material_node_internal
        cut, system = geometry.cut, self.system
        reconstruction = cut.reconstruction
        system.move(self._to_dolfinx(x0))
        system.set_geometry((reconstruction.alpha, reconstruction.beta), reconstruction.start,
                            reconstruction.end, cut.edge_flux, cut.normal)
        cell_material = np.where(mass[1] > 0.0, 1, 0)
        cell_material[cells] = -1
        pure = self._pure_forces(first, predicted, cell_material)
        nodes = mesh.cell_nodes[cells]
        velocity = state.material_node_velocity
        inertia, right, internal_force, transfers = [], [], np.zeros(2), []
        gradient = cut.part_integrals()[1]  # (2, n, k, 2) ∫_{K_m} ∇ψ_i
        slip = self._slip_rate(cut, state.node_velocity[:2], velocity, nodes)
        evaluations = [(e.velocity_jump[cells], e.volume[cells], e.mixed_sound_speed) for e in (first, predicted)]
        viscosity = self._own_viscosity(step.viscosity_law, evaluations, slip, volume[:, cells], mass[:, cells])
        system_nodes = self.node_of_dolfinx[system.nodes]
        interface = state.interface_pressure + viscosity
        for m in range(2):
            # f_m^n = (P_m^n + q̄) ∫_{K_m} ∇ψ_i − (p_Γ^n + q̄) ∫_Γ ψ_i n_m, ∫_Γ ψ_i n_m = ∫_{K_m} ∇ψ_i − G_mi:
            # summed over the materials and nodes it vanishes (momentum), and its work is
            # Σ_m (P_m^n + q̄) ∫_{K_m} ∇·ū_m once the normal jump vanishes (energy)
            stress = pressure[m, cells] + viscosity
            force = (stress - interface)[:, None, None] * gradient[m] + interface[:, None, None] * cut.edge_flux[m]
            explicit = np.stack([np.bincount(nodes.ravel(), force[..., d].ravel(), mesh.n_nodes) for d in range(2)])
            walls = self._leave_to_the_walls(step, explicit, internal[m])
            explicit, transfer = self._onto_internal_nodes(explicit, nodes, internal[m],
                                                           corner_mass[m][:, cells].T)
            transfers.append(transfer)
            held_inertia = np.repeat(4.0 * node_mass[m][None] / dt, 2, axis=0)
            rhs = held_inertia * velocity[m] + np.where(internal[m], 2.0 * pure[m] + explicit, 0.0)
            # the explicit forces on the mixed cells' nodes (for the walls' reaction)
            internal_force += np.where(internal[m], pure[m] + 0.5 * explicit, 0.0)[:, system_nodes].sum(axis=1)
            internal_force += 0.5 * walls[:, system_nodes].sum(axis=1)  # (the walls' to cancel)
            for boundary in step.constraints:
                held = np.zeros(2) if boundary.kind == "wall" else boundary.velocity[:2]
                for d in held_components(boundary):
                    held_inertia[d, boundary.nodes] = HELD_INERTIA
                    rhs[d, boundary.nodes] = HELD_INERTIA * held[d]
            inertia.append(held_inertia)
            right.append(rhs)
        # the ghost viscosity of each material's extension (forms/enriched_interface.py)
        cell_area = volume[:, cells].sum(axis=0)
        density = np.divide(mass[:, cells], volume[:, cells], out=np.zeros((2, cells.size)), where=volume[:, cells] > 0)
        system.set_ghost(self.ghost_viscosity * 4.0 * density * cell_area / dt)
        eos = [self.materials[k].eos.state for k in range(2)]
        solver = ImplicitStep(system, cells, eos, reconstruction.length, self.nitsche_penalty,
                              mixed.tolerance, mixed.max_iterations, nonlinear=mixed.nonlinear)
        start = MaterialStart(mass[:, cells], volume[:, cells], energy[:, cells], pressure[:, cells])
        inertia, right = [self._to_dolfinx(a) for a in inertia], [self._to_dolfinx(a) for a in right]
        # A tied node that a wall or piston holds is tied whole.  A sliding tie shares the
        # normal part and leaves each material its tangential one: at a held node both
        # unknowns mix the held component (inertia HELD_INERTIA, 10²⁰ the others), and the
        # round-off at that inertia swamped the one direction left free — on the sheared
        # tube (crossed triangles, 16², 20², 24², Γ reaching the wall between pure cells)
        # every mixed cell's volume change came out wrong and the time step collapsed.
        sliding = geometry.sliding.copy()
        for boundary in step.constraints:
            sliding[boundary.nodes] = False
        try:
            out = solver.solve(dt, start, inertia, right, self._to_dolfinx(geometry.tied), viscosity,
                               self._to_dolfinx(sliding))
        except MixedCellFailure as failure:
            raise self.breakdown("interface solve", failure, x0) from None
        except RuntimeError as failure:  # PETSc did not solve the system (BoundSystem's one line)
            raise Breakdown("interface solve", int(cells[0]), float("nan"), mesh.cell_centroids(x0)[cells[0]],
                            detail=str(failure)) from None
        # Heat: the work the ghost viscosity and Nitsche's penalty take from ū over the step
        # (a doubled row holds G(ū) at weight one: each takes ½ dt G(ū, ū)), and what the
        # external nodes' share of f^n loses by acting on the internal nodes (½ f^n·ū dt).
        # Shared by the cell's materials by mass, as the single-velocity closure shares its
        # heat: a sliver given its own ghost's work (done over the other, larger part) heated
        # up until the time step collapsed (the spinning disk on 20² triangles: 483 steps to
        # t = 1 instead of 171).
        heat = 0.5 * dt * system.dissipated_work(out["velocity"]).sum(axis=0)
        # ū_m in the mesh's numbering on the mixed cells' nodes (``sub``), zero elsewhere as the
        # solve leaves it
        sub = self.node_of_dolfinx[system.nodes]
        mean_velocity = np.zeros_like(velocity)
        for m in range(2):
            mean_velocity[m][:, sub] = out["velocity"][m][:, system.nodes]
            heat -= 0.5 * dt * self._moved_work(transfers[m], nodes, mean_velocity[m])
        cell_mass = mass[:, cells].sum(axis=0)
        heat = np.stack([heat * mass[m, cells] / cell_mass for m in range(2)])
        out["heat"] = heat
        mixed.record_solve(out["iterations"])
        # each material's velocity at n+1 on the mixed cells' nodes; the mesh follows the
        # material each node lies in
        new_velocity = velocity.copy()
        self._keep_momentum(step, mean_velocity, velocity, node_mass, sub, internal_force, dt)
        for m in range(2):
            new_velocity[m][:, sub] = 2.0 * mean_velocity[m][:, sub] - velocity[m][:, sub]
        # the time-centred corner forces of the cells around those nodes (_pure_cells_work)
        around = cells_at_nodes(mesh, sub)
        corner_force = (around, (first.corner_force[:, :, around] + predicted.corner_force[:, :, around]) * 0.5)
        target = new_velocity[geometry.owner[sub], :, sub].T  # (2, n_sub)
        u0 = state.node_velocity
        mean_force[:2, sub] = (target - u0[:2, sub]) / dt_over_node_mass[sub]
        self._wall_reactions(step, mean_force, sub, node_mass, velocity, new_velocity, internal_force, dt)
        self._last = dict(time=state.time, out=out, mass=mass[:, cells], node_mass=node_mass,
                          corner_mass=corner_mass, velocity=new_velocity, owner=geometry.owner, sub=sub,
                          internal=internal, viscosity=viscosity, mean_velocity=mean_velocity,
                          corner_force=corner_force, cell_material=cell_material, x0=x0, dt=dt, cut=cut,
                          nodes=nodes)
        return out

    @staticmethod
    def _own_viscosity(viscosity_law, evaluations, slip, volume, mass):
        """The mixed cells' artificial viscosity q̄ over the step (n,): the mean of q at n and
        at the predicted state (``evaluations``: their ``velocity_jump`` Δu = √|K| (d|K|/dt)/|K|,
        ``volume`` |K| and ``mixed_sound_speed`` c over the mixed cells), q = ρ (c2 Δu² + c1 c
        |Δu|) in compression, ρ the parts' harmonic mean 1/ρ = Σ_m f_m/ρ_m (``volume``,
        ``mass`` (2, n) the parts' at n; c the larger material sound speed, as
        SharedClosure.viscosity_medium).  The mesh's velocity, which a node takes from the
        material it lies in, jumps inside a cut cell where the materials slide: the cell's
        area rate then squeezes it where neither material is compressed (from a steady slip
        line, q reached 7 % of the pressure in the cut cells and pushed the two materials
        apart).  So the compression is the cell's less ``slip`` (n,), the part of its area
        rate the sliding makes (:meth:`_slip_rate`) — which may take compression away, never
        add it: read from each material's velocity beyond its part, which the interface
        system determines only weakly, an added compression fed back on it (on the sheared
        tube, 32² triangles, ghost viscosity 0.3, a solve shared out over 3 MPI ranks then
        ended 6 × 10⁻⁶ apart from the serial run, against 10⁻¹¹ when it only takes away).
        ``viscosity_law``:
        (c2, c1, on)."""
        q_quadratic, q_linear, artificial = viscosity_law
        if not artificial:
            return np.zeros(slip.size)
        density = volume.sum(axis=0) / np.sum(volume**2 / mass, axis=0)
        q = np.zeros(slip.size)
        for jump, cell_volume, sound_speed in evaluations:
            compression = np.minimum(jump, 0.0)
            compression = np.maximum(np.minimum(jump - slip / np.sqrt(cell_volume), 0.0), compression)
            add_viscosity(q_quadratic, q_linear, compression, density, sound_speed, 0.5, q)
        return q

    @staticmethod
    def _slip_rate(cut, mesh_velocity, velocity, nodes):
        """(n,): what the materials' velocities ``velocity`` [m] (2, n_nodes) sliding past each
        other add to a mixed cell's area rate under ``mesh_velocity`` (2, n_nodes), each node
        its own material's: Σ_m Σ_edges ∫_{e∩m} (u_mesh − u_m)·n_e, the rate of the
        materials' crossings of its edges (:meth:`CutCells.crossing_volumes`); the cell's
        rate less it is Σ_m ∫_{K_m} ∇·u_m, its materials' own compression, wherever the
        normal velocity is continuous across Γ.  (Crossings of the boundary are left out:
        walls and pistons hold the normal velocity of every material alike; at a free
        boundary the materials' normal velocities may differ, and what that leaves out is
        part of the remainder scaled away.)"""
        return cut.crossing_volumes(mesh_velocity, velocity, nodes, 1.0).sum(axis=(0, 2))

    @staticmethod
    def _leave_to_the_walls(step, force, internal):
        """Take out of a material's explicit force (2, n_nodes), in place, the components
        that a wall or a piston holds at its external nodes, and return them (2, n_nodes):
        the wall's reaction cancels them there, as it cancels a pure cell's, and they stay in
        the step's account of the forces.  Moved onto the internal nodes
        (:meth:`_onto_internal_nodes`), the pressure on a wall cell's wall edge pushed the row
        of nodes above it towards the wall where Γ meets it: a contact between two gases at
        rest, touching two walls, moved them by 10⁻³ of the sound speed in one step
        (tests/test_enriched_2d_run.py)."""
        taken = np.zeros_like(force)
        for boundary in step.constraints:
            external = boundary.nodes[~internal[boundary.nodes]]
            for d in held_components(boundary):
                taken[d, external] = force[d, external]
                force[d, external] = 0.0
        return taken

    @staticmethod
    def _onto_internal_nodes(force, nodes, internal, corner_mass):
        """A material's explicit force at n (2, n_nodes) with what its external nodes carry
        moved onto the internal ones.  An external row is the interface's equilibrium at
        n+1 and takes nothing at n: the node's total (zero under a uniform pressure, the
        edge parts being shared) is split among its mixed cells by the material's internal
        mass in each, and each part spread on that cell's internal nodes by their condensed
        masses (as its mass was).  All of f^n then acts on the nodes: momentum is kept.
        ``nodes`` (n, k) the mixed cells' nodes, ``internal`` (n_nodes,) the nodes carrying
        the material's mass, ``corner_mass`` (n, k) its condensed masses."""
        inside = internal[nodes]
        weight = np.where(inside, corner_mass, 0.0)  # (n, k)
        cell_weight = weight.sum(axis=1)  # the material's internal mass in each cell
        n_nodes = force.shape[1]
        external = ~internal
        # each external node's total, split by its cells' internal masses
        node_weight = np.bincount(nodes.ravel(), np.repeat(cell_weight, nodes.shape[1]), n_nodes)
        per_weight = np.divide(np.where(external, force, 0.0), node_weight, out=np.zeros_like(force),
                               where=node_weight > 0)
        received = (per_weight[:, nodes] * np.where(inside, 0.0, 1.0)).sum(axis=2) * cell_weight  # (2, n)
        share = np.divide(weight, cell_weight[:, None], out=np.zeros_like(weight), where=cell_weight[:, None] > 0)
        moved = np.stack([np.bincount(nodes.ravel(), (share * received[d][:, None]).ravel(), n_nodes)
                          for d in range(2)])
        kept = np.where(external & (node_weight > 0), 0.0, force)
        return kept + moved, (per_weight, cell_weight, share, received)

    @staticmethod
    def _moved_work(transfer, nodes, velocity):
        """(n,) per mixed cell: how much more the moved share of f^n (:meth:`_onto_internal_nodes`)
        works on the material's ``velocity`` (2, n_nodes) at the internal nodes than it would
        have at the external ones."""
        per_weight, cell_weight, share, received = transfer
        mean_inside = np.einsum("nk,dnk->dn", share, velocity[:, nodes])  # (2, n)
        inside = share > 0.0
        at_external = np.einsum("dnk,dnk->n", per_weight[:, nodes] * (~inside), velocity[:, nodes])
        return np.einsum("dn,dn->n", received, mean_inside) - cell_weight * at_external

    @staticmethod
    def _keep_momentum(step, mean_velocity, velocity, node_mass, sub, explicit_force, dt):
        """The interface system's n+1 forces sum to zero over the nodes, exactly in exact
        arithmetic (:meth:`_wall_reactions`); the solve's residual does not, and moved
        momentum: on the nearly singular systems of slivers (the shock through the heavy disk
        on 80 × 40 triangles) up to 10⁻⁷ of it a step, 9 × 10⁻⁶ over the run.  Along a
        component that no wall or piston holds on these nodes, that residual is taken out
        of ``mean_velocity`` (ū_m (2, 2, n_nodes), in place) by one shift of every
        material's ū on the nodes ``sub``, by mass (a uniform shift changes no volume, no
        normal jump, no strain); along a held one the walls' reaction takes it."""
        mass = node_mass[:, sub].sum()
        change = 2.0 * np.sum(node_mass[:, None, sub] * (mean_velocity[:, :, sub] - velocity[:, :, sub]),
                              axis=(0, 2)) / dt
        residual = change - explicit_force
        for d in range(2):
            if held_nodes(step, sub, d).size == 0 and mass > 0.0:
                mean_velocity[:, d, sub] -= residual[d] * dt / (2.0 * mass)

    @staticmethod
    def _wall_reactions(step, mean_force, sub, node_mass, velocity, new_velocity, explicit_force, dt):
        """The walls' and pistons' reaction on the mixed cells' nodes, in the step's
        bookkeeping (its reaction at a held node is M du/dt − F̄).  The interface system's
        n+1 forces sum to zero over the nodes (tested with a uniform velocity, each term
        vanishes: ∇·c = 0 and Σ_m ∫_Γ c·n_m = 0), so the held components' total reaction is
        the nodes' momentum change less the explicit forces; it is given to the held nodes
        in equal parts (a wall does no work whatever the split, and a piston moves its
        nodes alike)."""
        change = np.sum(node_mass[:, None, sub] * (new_velocity[:, :, sub] - velocity[:, :, sub]), axis=(0, 2)) / dt
        reaction = change - explicit_force
        for d in range(2):
            held = held_nodes(step, sub, d)
            if held.size:
                mean_force[d, held] -= reaction[d] / held.size

    # -- the step's end --------------------------------------------------------------------

    def end_of_step(self, state, first, predicted, x_new, e_new, solution):
        """The pure cells' work on their own materials' velocities (:meth:`_pure_cells_work`,
        into ``e_new``), the materials' crossings of the mesh's moving edges
        (:meth:`_crossings`), and the parts in the Lagrangian cell (module docstring);
        (V_α, V_β, details) in the state's slot order."""
        last = self._last
        if last is None or last["time"] != state.time:
            raise RuntimeError("end_of_step without the interface solve of its step")
        self._pure_cells_work(state, x_new, e_new)
        mixed = self.mixed
        out, mass = last["out"], last["mass"]
        own = out["volume"]  # each part moved with its own material
        energy = out["energy"] + out["heat"] / mass  # the dissipated work, as heat
        rho = mass / own
        crossing = self._crossings(state, x_new, e_new, own, rho, energy)
        area = self.mesh.cell_geometry(x_new, mixed.cells)[0]
        total = (own + crossing).sum(axis=0)
        mixed.stats["volume_mismatch"] = max(mixed.stats["volume_mismatch"], float(np.max(np.abs(total / area - 1.0))))
        volume = (own + crossing) * (area / total)
        values = [self.materials[k].eos.state(rho[k], energy[k]) for k in range(2)]
        pressure = np.stack([v[0] for v in values])
        c2 = np.stack([v[3] for v in values])
        # slot 0 of the state is material_left (the larger material of the cell)
        a = np.where(mixed.material_left == 0, 0, 1)
        b = 1 - a
        columns = np.arange(a.size)
        pick = lambda array, slot: array[slot, columns]  # noqa: E731
        details = (pick(energy, a), pick(energy, b), pick(pressure, a), pick(pressure, b),
                   pick(rho, a), pick(rho, b), pick(c2, a), pick(c2, b))
        # (the system's pressures are p + q̄: its interface pressure too)
        last["interface_pressure"] = (out["interface_pressure"] - last["viscosity"] if "interface_pressure" in out
                                      else 0.5 * (pressure[0] + pressure[1]))
        return pick(volume, a), pick(volume, b), details

    def _crossings(self, state, x_new, e_new, own, rho, energy) -> np.ndarray:
        """The materials' crossings of the Lagrangian mesh's edges: a node moves with the
        material it lies in, so an edge one of whose nodes lies in another material than m
        moves otherwise than m, and m crosses it, relative to the edge, by
        R_m = dt ∫_{e∩m} (ū_mesh − ū_m)·n_e (ū the step's mean velocities, on the geometry
        at its start).  Two kinds of edges: those of the mixed cells
        (:meth:`CutCells.crossing_volumes`), and those between two pure cells of m with an
        end on a mixed cell's node (:meth:`_pure_edge_crossings`), whose cells' forces work
        on ū_m there (:meth:`_pure_cells_work`) while their areas follow the mesh.  That
        volume of m changes cells, at its donor's density and specific energy (the donor's
        own, ``rho`` and ``energy`` (2, n), in a mixed cell; the pure cell's new state
        otherwise), at most CROSSING_SHARE of what the donor holds over all its edges, and
        with it the momentum and kinetic energy of m's new velocity on the edge (the mean of
        its two nodes'): the remap moves what each cell gains, the state's
        ``material_crossing`` (kept in ``last_step["crossing"]``), with its own fluxes.
        Returns the net volume (2, n) each mixed cell's part gains, by which the part in the
        Lagrangian cell differs from ``own`` (2, n), the part moved with its material's
        velocity.  Under normal continuity (Σ_m ∫_Γ ū·n_m = 0) Σ_m (ΔV_m + R_m) is the
        cell's own change of area to first order in dt: the parts and the cell then differ
        by O(dt²) only (without the crossings, by dt × the slip / h: up to 4 % a step in the
        slip line's error disk at 40²).  Without the pure cells' edges, such a cell's
        specific energy followed ū_m and its density the mesh: in the shock on the heavy
        disk (100 × 50 crossed triangles) two pure cells of the disk by a node of the air
        drifted apart, one to tension below −p∞, where the EOS has no sound speed."""
        last, mesh = self._last, self.mesh
        cut, nodes, dt, cells = last["cut"], last["nodes"], last["dt"], self.mixed.cells
        mean = last["mean_velocity"]
        owner = last["owner"]
        mesh_velocity = np.where(owner == 0, mean[0], mean[1])  # (2, n_nodes): each node's own material's
        crossing = cut.crossing_volumes(mesh_velocity, mean, nodes, dt)  # (2, n, k) into each cell
        neighbour = cut.edge_neighbour
        where = np.full(mesh.n_cells, -1, dtype=np.int64)
        where[cells] = np.arange(cells.size)
        # each edge once: from its mixed cell, or from the lower-numbered of two mixed cells
        row, side = np.nonzero((neighbour >= 0) & ((where[np.maximum(neighbour, 0)] < 0)
                                                   | (cells[:, None] < neighbour)))
        here, there = cells[row], neighbour[row, side]
        there_mixed = where[there] >= 0
        there_row = np.maximum(where[there], 0)
        cell_volume = mesh.cell_geometry(x_new, there)[0]
        pure_density = state.material_mass[0, there] / cell_volume
        ends = nodes[row, side], nodes[row, (side + 1) % nodes.shape[1]]  # the edge's nodes
        net = np.zeros((2, cells.size))
        gained_mass, gained_energy, gained_kinetic = (np.zeros((2, mesh.n_cells)) for _ in range(3))
        gained_momentum = np.zeros((2, 2, mesh.n_cells))
        for m in range(2):
            r = crossing[m, row, side]
            inward = r > 0.0  # m comes from ``there``
            # what each side holds of m, and at which density and specific energy
            held = np.where(inward, np.where(there_mixed, own[m, there_row], cell_volume), own[m, row])
            density = np.where(inward, np.where(there_mixed, rho[m, there_row], pure_density), rho[m, row])
            specific = np.where(inward, np.where(there_mixed, energy[m, there_row], e_new[0, there]),
                                energy[m, row])
            pure = self._pure_edge_crossings(m, state, x_new, e_new, mesh_velocity)
            # every donor gives at most CROSSING_SHARE of what it holds, over all its edges
            donor = np.concatenate([np.where(inward, there, here), pure["donor"]])
            crossed = np.abs(np.concatenate([r, pure["r"]]))
            given = np.bincount(donor, crossed, mesh.n_cells)[donor]
            held = np.concatenate([held, pure["held"]])
            share = np.minimum(1.0, CROSSING_SHARE * held / np.where(given > 0.0, given, 1.0))
            volume = np.where(inward, 1.0, -1.0) * np.abs(r) * share[:r.size]  # into ``here``
            np.add.at(net[m], row, volume)
            np.subtract.at(net[m], where[there[there_mixed]], volume[there_mixed])
            # (into the receiver, out of the donor)
            mass = np.concatenate([volume * density, crossed[r.size:] * share[r.size:] * pure["density"]])
            specific = np.concatenate([specific, pure["specific"]])
            receiver = np.concatenate([here, pure["receiver"]])
            giver = np.concatenate([there, pure["donor"]])
            # carried at m's new velocity on the edge, the mean of its two nodes' (one of them, at
            # least, an external node of m: the extension of its field, which the ghost viscosity
            # steadies).  The donor's mean velocity, by its condensed masses (its velocities where
            # it has mass), smeared more: two identical gases across a contact (16² Eulerian)
            # gave L1(u) 1.626e-2 against 1.600e-2 here, one material's being 1.458e-2
            first, second = np.concatenate([ends[0], pure["ends"][0]]), np.concatenate([ends[1], pure["ends"][1]])
            velocity = 0.5 * (last["velocity"][m][:, first] + last["velocity"][m][:, second])  # (2, n_edges)
            for total, amount in ((gained_mass[m], mass), (gained_energy[m], mass * specific),
                                  (gained_kinetic[m], 0.5 * mass * np.sum(velocity * velocity, axis=0)),
                                  (gained_momentum[0, m], mass * velocity[0]),
                                  (gained_momentum[1, m], mass * velocity[1])):
                np.add.at(total, receiver, amount)
                np.subtract.at(total, giver, amount)
        last["crossing"] = (gained_mass, gained_energy, gained_momentum, gained_kinetic)
        return net

    def _pure_edge_crossings(self, m: int, state, x_new, e_new, mesh_velocity) -> dict:
        """The crossings of material m through the edges between two pure cells of m with
        an end on a mixed cell's node, where m moves with ū_m and the mesh with ū_mesh
        (``mesh_velocity``, (2, n_nodes)): R = dt ∫_e (ū_mesh − ū_m)·n_e into the cell the
        edge goes counter-clockwise round, both velocities linear along the edge.  Returns
        each crossing's donor and receiver cells, its volume |R| (``r``), what the donor
        holds (its area), its density and specific energy (its new state's), and the
        edge's two nodes (``ends``)."""
        last, mesh = self._last, self.mesh
        material = last["cell_material"]  # −1 on the mixed cells
        relative = np.zeros((2, mesh.n_nodes))  # ū_mesh − ū_m, zero off the mixed cells' nodes
        sub = last["sub"]
        relative[:, sub] = mesh_velocity[:, sub] - last["mean_velocity"][m][:, sub]
        # the edges with an end where m slides past the mesh (an edge where m moves with the
        # mesh at both ends crosses nothing), in increasing order
        edge = csr_rows(*node_edges(mesh.cell_nodes), sub[np.any(relative[:, sub] != 0.0, axis=0)])
        a, b, plus, minus = (ends[edge] for ends in edges_of(mesh.cell_nodes))
        edge = np.flatnonzero((minus >= 0) & (material[plus] == m) & (material[np.maximum(minus, 0)] == m))
        a, b, plus, minus = a[edge], b[edge], plus[edge], minus[edge]
        x0 = last["x0"]
        outward = np.stack([x0[1, b] - x0[1, a], x0[0, a] - x0[0, b]], axis=-1)  # |e| n_e, out of ``plus``
        r = crossed_volume(relative[:, a].T, relative[:, b].T, outward, edge_weights(0.0, 1.0), last["dt"])  # into ``plus``
        into_plus = r > 0.0
        donor = np.where(into_plus, minus, plus)
        held = mesh.cell_geometry(x_new, donor)[0]
        return dict(donor=donor, receiver=np.where(into_plus, plus, minus), r=np.abs(r), held=held,
                    density=state.material_mass[0, donor] / held, specific=e_new[0, donor], ends=(a, b))

    def _material_fields(self, u_new):
        """The state's fields of the materials' velocities (u_new: the mesh's, for the nodes
        outside the mixed cells, where every material present moves with the node)."""
        last = self._last
        velocity = np.stack([u_new[:2]] * 2)
        sub = last["sub"]
        velocity[:, :, sub] = last["velocity"][:, :, sub]
        return dict(material_node_velocity=velocity, material_node_mass=last["node_mass"],
                    material_corner_mass=last["corner_mass"], material_node_internal=last["internal"])

    def state_for_remap(self, step, state, solution, x_new, u_new, cell_volume, e_new, dt):
        cells = self.mixed.cells
        volumes = self.remapped_slots(step, solution, cell_volume, e_new, solution[1])
        fields = dict(interface_pressure=self._last["interface_pressure"], interface_velocity=np.zeros(cells.size),
                      material_crossing=self._last["crossing"])
        fields.update(self._material_fields(u_new))
        return volumes, fields

    def _pure_cells_work(self, state, x_new, e_new):
        """The work of the pure cells next to the mixed cells, on the velocities their forces
        act on (``e_new``, slot 0, in place).  The step took it on the mesh's velocity ū;
        a pure cell's forces F̄ enter its own material's momentum rows, so at a node the
        other material owns (where one slid past it) they work on ū_m:
        m_K Δe_K −= Σ_i F̄_Ki·(ū_m,i − ū_i) dt.  Total energy is then kept by the Lagrange
        step to round-off (on the mesh's velocity the spinning disk on triangles lost 10⁻⁴
        of it a step).  Their areas stay the mesh's: what m moves past the mesh crosses
        their edges (:meth:`_crossings`)."""
        last = self._last
        sub, dt = last["sub"], last["dt"]
        mesh = self.mesh
        nodes = mesh.cell_nodes.T  # (k, n_cells)
        next_to_mixed, corner_force = last["corner_force"]  # (the mixed cells among them, of material −1)
        for m in range(2):
            which = last["cell_material"][next_to_mixed] == m
            cells = next_to_mixed[which]
            if cells.size == 0:
                continue
            slide = np.zeros((2, mesh.n_nodes))  # (ū_m − ū) dt, on the mixed cells' nodes
            slide[:, sub] = last["x0"][:2, sub] + dt * last["mean_velocity"][m][:, sub] - x_new[:2, sub]
            work = np.sum(corner_force[:, :, which] * slide[:, nodes[:, cells]], axis=(0, 1))
            e_new[0, cells] -= work / state.material_mass[0, cells]

    def finish(self, step, state, solution, x_new, u_new, e_new, dt):
        """A state no remap follows (not reached by scenes: every step of theirs is remapped,
        in place on a Lagrangian mesh)."""
        new_state, final = super().finish(step, state, solution, x_new, u_new, e_new, dt)
        return new_state.evolved(**self._material_fields(u_new)), final
