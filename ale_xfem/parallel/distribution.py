"""A run on several MPI ranks: the cells shared out, a ghost layer, and the exchanges a
Lagrange step needs, so that every rank's cells and nodes take the serial run's values to
the bit.

- **The partition.**  Every rank builds the whole problem (its set-up is serial and
  deterministic) and keeps its share: DOLFINx's graph partitioner cuts the cells' dual
  graph (cells joined across their facets) into as many parts as there are ranks
  (:func:`cell_partition`).  A node belongs to the lowest rank among its cells'.
- **The ghost layer.**  A rank steps its own cells and every cell around one of its nodes,
  so that each of its nodes sums the forces of all its cells, in the serial order (corner
  by corner: :func:`ale_xfem.lagrange.kernels.scatter_corners`); the other nodes of those
  cells are ghosts.  A ghost node's force, which misses cells the rank does not hold, is
  replaced by its owner's after each force evaluation (``scatter_forward`` of a DOLFINx
  vector on an ``IndexMap`` of the nodes): from then on every velocity, position, energy
  and force on the rank is the serial run's, the ghost cells' included, which therefore
  need no exchange of their own.
- **What is reduced.**  The time step (the least over the ranks: each rank's is the least
  over a subset of the cells, by the same monotone formula), a breakdown (each rank's
  verdict after the step, the first failing rank's diagnostic for all), the boundary
  reactions' work and impulse (each rank's own nodes; summed in rank order).
- **The result.**  Each rank's own cells and nodes, gathered into the serial state on every
  rank; conservation and errors are taken on it as in a serial run.

What runs distributed: Lagrangian meshes whose cells are all pure (no interface, no
remap), in 1D and 2D; other scenes are refused at the start with the key that needs one
rank.
"""

from __future__ import annotations

import numpy as np

from ale_xfem.lagrange.breakdown import Breakdown
from ale_xfem.lagrange.wilkins import ExplicitWilkins
from ale_xfem.model.boundaries import Boundary
from ale_xfem.model.mesh import MeshArrays
from ale_xfem.model.state import MaterialLayout, State
from ale_xfem.scene import SceneError


def launched_by_mpiexec() -> bool:
    """Whether an MPI launcher started this process among several (from its environment,
    without loading MPI: MPICH's Hydra and PMIx set PMI_SIZE / PMIX_RANK, Open MPI
    OMPI_COMM_WORLD_SIZE)."""
    import os

    size = os.environ.get("PMI_SIZE") or os.environ.get("OMPI_COMM_WORLD_SIZE")
    return (size is not None and size != "1") or "PMIX_RANK" in os.environ


def world():
    """The MPI world communicator (DOLFINx's MPI, loaded as DOLFINx wants it)."""
    import dolfinx_solver  # noqa: F401  (before mpi4py's users: it loads MPI and PETSc)
    from mpi4py import MPI

    return MPI.COMM_WORLD


def ranks() -> int:
    """The number of MPI ranks this process runs among (1 without mpiexec)."""
    return world().size


def rank() -> int:
    return world().rank


def check_distributable(problem) -> None:
    """Raise SceneError naming the key that keeps ``problem`` on one rank."""
    n = ranks()
    effects = problem.effects
    if problem.scene.mesh.motion != "lagrangian":
        raise SceneError("mesh.motion", problem.scene.mesh.motion,
                         f"'lagrangian' on {n} ranks (the remap runs on one rank in this version: run without mpiexec)")
    if problem.scene.interface is not None or problem.mixed is not None or problem.layout.slots != 1 or any(
            name.startswith("remap_") for name in effects):
        raise SceneError("interface", problem.scene.interface.model if problem.scene.interface else "(mixed cells)",
                         f"none on {n} ranks (mixed cells run on one rank in this version: run without mpiexec)")
    if problem.mesh.n_cells < n:
        raise SceneError("mesh.cells", problem.scene.mesh.cells, f"at least {n} cells on {n} ranks (one a rank)")


def facet_neighbours(cell_nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The cells' dual graph, cells joined across the facets they share (1D: a node; 2D:
    an edge between consecutive corners, which go round the cell): (neighbours, offsets) of
    an adjacency list, each cell's neighbours in increasing order."""
    n, k = cell_nodes.shape
    if k == 2:  # intervals: a facet is a node
        facets = cell_nodes.reshape(-1, 1)
    else:
        facets = np.sort(np.stack([cell_nodes, np.roll(cell_nodes, -1, axis=1)], axis=2).reshape(-1, 2), axis=1)
    owner = np.repeat(np.arange(n), facets.shape[0] // n)
    order = np.lexsort(facets.T[::-1])
    facets, owner = facets[order], owner[order]
    shared = np.flatnonzero(np.all(facets[1:] == facets[:-1], axis=1))
    pairs = np.concatenate([np.stack([owner[shared], owner[shared + 1]], axis=1),
                            np.stack([owner[shared + 1], owner[shared]], axis=1)])
    pairs = pairs[np.lexsort(pairs.T[::-1])]
    offsets = np.searchsorted(pairs[:, 0], np.arange(n + 1))
    return np.ascontiguousarray(pairs[:, 1], dtype=np.int64), offsets.astype(np.int32)


def cell_partition(cell_nodes: np.ndarray, parts: int, comm) -> np.ndarray:
    """Each cell's rank: DOLFINx's graph partitioner (dolfinx.graph.partitioner: SCOTCH,
    ParMETIS or KaHIP, as DOLFINx was built) on the cells' dual graph, run on rank 0 and
    sent to every rank (each then shares the cells out alike)."""
    owner = None
    if comm.rank == 0:
        import dolfinx
        from mpi4py import MPI

        neighbours, offsets = facet_neighbours(cell_nodes)
        graph = dolfinx.cpp.graph.AdjacencyList_int64(neighbours, offsets)
        owner = np.array(dolfinx.graph.partitioner()(MPI.COMM_SELF, parts, graph, False).array, dtype=np.int64)
    return comm.bcast(owner, root=0)


class Distribution:
    """This rank's share of a serial problem (module docstring): its cells (``cells``, global
    indices, sorted) and nodes (``nodes``), the local problem's mesh, and the exchange of
    nodal fields with the other ranks."""

    def __init__(self, problem, comm=None):
        self.comm = comm if comm is not None else world()
        self.problem = problem
        size, me = self.comm.size, self.comm.rank
        mesh = problem.mesh
        cell_nodes = mesh.cell_nodes
        owner = cell_partition(cell_nodes, size, self.comm)
        held = np.bincount(owner, minlength=size)
        if held.min() == 0:
            raise SceneError("mesh.cells", problem.scene.mesh.cells,
                             f"enough cells for every one of {size} ranks to hold some (rank "
                             f"{int(np.argmin(held))} got none)")
        node_owner = np.full(mesh.n_nodes, size, dtype=np.int64)
        for corner in range(cell_nodes.shape[1]):
            np.minimum.at(node_owner, cell_nodes[:, corner], owner)
        self.cell_owner, self.node_owner = owner, node_owner
        local = (owner == me) | np.any(node_owner[cell_nodes] == me, axis=1)
        self.cells = np.flatnonzero(local)
        self.nodes = np.unique(cell_nodes[self.cells])
        self.owned_cells = np.flatnonzero(owner[self.cells] == me)  # local indices
        self.owned_nodes = np.flatnonzero(node_owner[self.nodes] == me)
        self.ghost_nodes = np.flatnonzero(node_owner[self.nodes] != me)
        local_cell_nodes = np.searchsorted(self.nodes, cell_nodes[self.cells])
        self.mesh = MeshArrays(mesh.cell_type, np.ascontiguousarray(mesh.node_position[:, self.nodes]),
                               local_cell_nodes)
        # the nodes' numbers in the index map: each rank's own nodes in a block, in order
        counts = np.bincount(node_owner, minlength=size)
        offsets = np.concatenate([[0], np.cumsum(counts)])
        number = np.empty(mesh.n_nodes, dtype=np.int64)
        for r in range(size):
            mine = np.flatnonzero(node_owner == r)
            number[mine] = offsets[r] + np.arange(mine.size)
        ghosts = self.nodes[self.ghost_nodes]
        import dolfinx

        self.index_map = dolfinx.common.IndexMap(self.comm, int(self.owned_nodes.size), number[ghosts],
                                                 node_owner[ghosts].astype(np.int32), 1)
        self.vectors = {}

    # -- the local problem ----------------------------------------------------------------

    def local_boundaries(self):
        """The problem's boundaries on this rank's nodes (local numbers)."""
        local = []
        for boundary in self.problem.boundaries:
            here = np.flatnonzero(np.isin(self.nodes, boundary.nodes))
            local.append(Boundary(boundary.side, boundary.kind, here, boundary.normal, boundary.velocity))
        return local

    def local_state(self, state: State) -> State:
        cells, nodes = self.cells, self.nodes

        def cell_values(values):
            return None if values is None else np.ascontiguousarray(values[:, cells])
        return state.evolved(
            node_position=np.ascontiguousarray(state.node_position[:, nodes]),
            node_velocity=np.ascontiguousarray(state.node_velocity[:, nodes]),
            material_mass=cell_values(state.material_mass), material_energy=cell_values(state.material_energy),
            material_volume=cell_values(state.material_volume), material_density=cell_values(state.material_density),
            material_pressure=cell_values(state.material_pressure),
            material_sound_speed=cell_values(state.material_sound_speed))

    def stepper(self, make_stepper) -> "DistributedWilkins":
        """The Lagrange step of this rank's cells (``make_stepper``: ale_xfem.run's, given
        the local problem's parts)."""
        problem = self.problem
        layout = MaterialLayout(problem.layout.cell_material[:, self.cells], problem.layout.n_materials)
        stepper = make_stepper(self.mesh, layout, np.ascontiguousarray(problem.node_mass[self.nodes]),
                               self.local_boundaries(), stepper_class=DistributedWilkins)
        stepper.share(self)
        return stepper

    # -- exchanges ------------------------------------------------------------------------

    def forward(self, field: np.ndarray) -> None:
        """Replace the ghost nodes' values of a nodal field (components, local nodes) by
        their owners' (DOLFINx's scatter_forward)."""
        import dolfinx

        components = field.shape[0]
        vector = self.vectors.get(components)
        if vector is None:
            vector = self.vectors[components] = dolfinx.la.vector(self.index_map, bs=components)
        values = vector.array.reshape(-1, components)
        owned = self.owned_nodes.size
        values[:owned] = field[:, self.owned_nodes].T
        vector.scatter_forward()
        field[:, self.ghost_nodes] = values[owned:].T

    def observer(self, observe, observe_from, problem):
        """``observe`` (rank 0's, or None) called with the serial state, gathered from the
        ranks whenever rank 0 wants one (``observe_from``: from which time; None: every
        state); None when no rank observes."""
        wanted = self.comm.bcast(observe is not None, root=0)
        if not wanted:
            return None

        def observe_gathered(state, _problem):
            due = observe is not None and (observe_from is None or state.time >= observe_from())
            if self.comm.bcast(due, root=0):
                whole = self.gathered(state)
                if observe is not None:
                    observe(whole, problem)
        return observe_gathered

    def least(self, value: float) -> float:
        """The least of each rank's ``value`` (NaN if any is)."""
        values = self.comm.allgather(float(value))
        return float("nan") if any(v != v for v in values) else min(values)

    def summed(self, value):
        """Σ over the ranks of ``value`` (a number or an array), in rank order."""
        values = self.comm.allgather(value)
        total = values[0]
        for other in values[1:]:
            total = total + other
        return total

    def gathered(self, state: State) -> State:
        """The serial state from every rank's own cells and nodes (on every rank)."""
        cells, nodes = self.cells[self.owned_cells], self.nodes[self.owned_nodes]
        names = ("material_mass", "material_energy", "material_volume", "material_density", "material_pressure",
                 "material_sound_speed")
        mine = {"cells": cells, "nodes": nodes, "node_position": state.node_position[:, self.owned_nodes],
                "node_velocity": state.node_velocity[:, self.owned_nodes]}
        for name in names:
            values = getattr(state, name)
            mine[name] = None if values is None else values[:, self.owned_cells]
        pieces = self.comm.allgather(mine)
        whole = self.problem.state
        changes = {}
        for name, shape_of in (("node_position", whole.node_position), ("node_velocity", whole.node_velocity)):
            values = np.empty_like(shape_of)
            for piece in pieces:
                values[:, piece["nodes"]] = piece[name]
            changes[name] = values
        for name in names:
            if pieces[0][name] is None:
                changes[name] = None
                continue
            values = np.empty((pieces[0][name].shape[0], whole.material_mass.shape[1]))
            for piece in pieces:
                values[:, piece["cells"]] = piece[name]
            changes[name] = values
        return state.evolved(**changes)


class DistributedWilkins(ExplicitWilkins):
    """ExplicitWilkins on one rank's cells (a Distribution's local problem): the ghost
    nodes' forces exchanged after each evaluation, the time step the least over the ranks,
    a breakdown on any rank a breakdown on all, the boundary reactions summed over the
    ranks' own nodes.  Steps are taken one by one (no compiled chunks: an exchange sits
    inside each)."""

    distribution: Distribution

    def share(self, distribution: Distribution) -> None:
        """Step ``distribution``'s cells (this stepper is built on its local problem)."""
        self.distribution = distribution
        self.exchange = distribution.forward
        self.node_numbers = distribution.nodes
        # the boundary reactions of this rank's own held nodes only (each node counted once)
        self.held_nodes = self.held_nodes[np.isin(self.held_nodes, distribution.owned_nodes)]
        self.constrained_nodes = self.constrained_nodes[np.isin(self.constrained_nodes, distribution.owned_nodes)]

    def compiles_steps(self) -> bool:
        return False

    def stable_time_step(self, evaluation) -> float:
        return self.distribution.least(super().stable_time_step(evaluation))

    def limiting_cell(self, evaluation, position) -> str:
        """The cell that sets the time step over all ranks (the least limit, of equal ones
        the lowest serial number, as one rank's argmin takes it), in the serial numbering."""
        times = self._cell_time_limits(evaluation)
        local = int(np.argmin(times))
        number = int(self.distribution.cells[local])
        text = super().limiting_cell(evaluation, position).replace(f"cell {local} ", f"cell {number} ", 1)
        return min(self.distribution.comm.allgather((float(times[local]), number, text)))[2]

    def step(self, state, dt, start=None, remapped_next=False):
        failure = None
        try:
            new_state, evaluation, work, impulse = super().step(state, dt, start, remapped_next)
        except Breakdown as error:
            failure = error
        distribution = self.distribution
        failures = distribution.comm.allgather(None if failure is None else self._global(failure))
        first = next((f for f in failures if f is not None), None)
        if first is not None:
            raise Breakdown(*first[:4], **first[4])
        return new_state, evaluation, distribution.summed(work), distribution.summed(impulse)

    def _global(self, failure: Breakdown):
        """A breakdown's arguments with the rank's cell number made the serial one."""
        cell = int(self.distribution.cells[failure.cell]) if failure.cell >= 0 else failure.cell
        return failure.quantity, cell, failure.value, failure.position, dict(
            allowed=failure.allowed, materials=failure.materials, detail=failure.detail)
