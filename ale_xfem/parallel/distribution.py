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
  rank (with the layout, nodal masses and mixed cells a remap left); conservation and
  errors are taken on it as in a serial run.
- **Mixed cells.**  A rank holds the mixed cells among its cells (:meth:`Distribution.local_mixed`);
  their closure works cell by cell, but the interface solve and the relaxation iterate all
  the mixed cells together until every one is done, and relax all or none: so every rank
  solves the whole set, each cell's inputs gathered from its owner
  (:class:`MixedCellsOnRanks`, ``MixedCells.across_ranks``), and keeps its own cells'
  results — the serial run's iterations, and a failure seen by every rank at once.  The
  1D enriched cells' interface pressure acts on their nodes after the forces' exchange:
  the mean force is exchanged again after the solve.  A predicted state's breakdown waits
  for the step's end (:meth:`DistributedWilkins.check`), so that no rank leaves an exchange
  the others are in.
- **The 2D remap.**  A remapped mesh takes a ghost layer of :data:`REMAP_GHOST_RINGS` rings
  of cells; each rank remaps its local mesh, whose outer ghost cells miss neighbours and
  come out wrong, and :class:`RankScope` refreshes the ghost cells and nodes from their
  owners (an ``IndexMap`` of the cells besides the nodes') after the fluxes, after each
  pass of the traces' moves and at the end, takes the sums over the mesh in the serial
  order (:meth:`Distribution.serial_totals`) and agrees on failures; the new mixed cells are
  then solved as one set again (:meth:`Distribution.adopt_mixed`, which the remap calls
  through its scope: ``RankScope.solved_mixed``).
- **The 1D remap.**  Every rank remaps the whole line from the serial state gathered from
  the ranks' own cells and nodes, with the serial remapper, and keeps its share
  (:class:`RemapOnEveryRank`): a 1D mesh of a few thousand cells remaps in the time of a
  few of its Lagrange steps, and its interface-following windows and fall-back to the
  general intersection need nothing of their own.
- **The assembled 1D step** (predictor and corrector) is assembled and solved by every rank over all the
  ranks' mixed cells, on the serial mesh (:class:`ale_xfem.mixed.assembled_predictor.AssembledPredictor`),
  as the closed-form solve is; or, with ``interface_solve = "distributed"``, shared out
  over the ranks (:mod:`ale_xfem.parallel.interface_system`).

- **2D enriched cells.**  Every rank solves all the ranks' mixed cells with the serial
  closure on the serial mesh, from the serial arrays gathered from the ranks within the
  strip along the interface that the closure reads (:meth:`Distribution.reach`,
  :mod:`ale_xfem.parallel.enriched_cells`; or, with ``interface_solve = "distributed"``,
  their interface system shared out over the ranks: :mod:`ale_xfem.parallel.interface_system`); the remap moves each material's velocity and
  masses on the rank's share, their ghost entries refreshed from their owners.

Every scene runs distributed; a mesh with fewer cells than ranks is refused at the start.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from functools import partial

import numpy as np

from ale_xfem.lagrange.breakdown import Breakdown
from ale_xfem.lagrange.wilkins import ExplicitWilkins
from ale_xfem.model.boundaries import Boundary
from ale_xfem.model.mesh import MeshArrays
from ale_xfem.model.mixed_cells import MixedCells
from ale_xfem.model.state import MaterialLayout, State
from ale_xfem.remap.failure import RemapFailure
from ale_xfem.remap.scope import WholeMesh
from ale_xfem.scene import SceneError

# The ghost layer of a remapped mesh, in rings of cells around each rank's own: a cell's
# new state needs its donors' reconstructions (their neighbours: 2 rings), a node's its
# cells' fluxes and their donors' velocities and reconstructions (3 rings); the ghost
# cells are refreshed from their owners after the fluxes and after each pass of the
# traces' moves (RankScope), so those passes need no more.  The tests' runs were the serial
# ones with 3 rings and not with 2; one ring more is kept in hand.
REMAP_GHOST_RINGS = 4


# How the interface system of enriched mixed cells (2D, or the 1D assembled predictor) is solved on several ranks: every
# rank the whole system (the serial run to the bit), or one system shared out over the
# ranks, assembled and factorised by PETSc over them (parallel/interface_system.py: the
# serial run to round-off)
INTERFACE_SOLVES = ("replicated", "distributed")


def has_interface_system(problem) -> bool:
    """Whether ``problem``'s mixed cells solve an assembled interface system (what
    ``interface_solve`` chooses how to solve): 2D enriched cells, or 1D enriched cells whose
    predictor is assembled."""
    interface = problem.scene.interface
    if interface is None or interface.model != "enriched":
        return False
    return problem.mesh.dimension == 2 or interface.predictor == "assembled"


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
    """Raise SceneError when ``problem`` cannot share its cells out over the ranks (fewer
    cells than ranks)."""
    n = ranks()
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


def node_owners(cell_nodes: np.ndarray, owner: np.ndarray, n_nodes: int) -> np.ndarray:
    """Each node's rank: the lowest among its cells' (``owner``: each cell's)."""
    node_owner = np.full(n_nodes, owner.max() + 1, dtype=np.int64)
    for corner in range(cell_nodes.shape[1]):
        np.minimum.at(node_owner, cell_nodes[:, corner], owner)
    return node_owner


def local_cells(cell_nodes: np.ndarray, owner: np.ndarray, node_owner: np.ndarray, rank: int,
                rings: int) -> np.ndarray:
    """The cells ``rank`` holds (serial numbers, ascending): its own, every cell around one of
    its nodes, and ``rings`` − 1 more rings of cells around those."""
    local = (owner == rank) | np.any(node_owner[cell_nodes] == rank, axis=1)
    for _ in range(rings - 1):  # one more ring: every cell around a node of the local cells
        reached = np.zeros(node_owner.size, dtype=bool)
        reached[cell_nodes[local]] = True
        local |= np.any(reached[cell_nodes], axis=1)
    return np.flatnonzero(local)


def ghost_index_map(comm, owner: np.ndarray, held: np.ndarray, tag: int):
    """A DOLFINx IndexMap of the entries ``held`` (serial numbers, ascending) of this rank,
    ``owner`` each entry's rank (all of them): the entries numbered rank by rank, each
    rank's own in a block in the serial order.  Returns (the map, the places among ``held``
    of its ghosts, in the map's order)."""
    import dolfinx

    number = np.empty(owner.size, dtype=np.int64)
    number[np.argsort(owner, kind="stable")] = np.arange(owner.size)
    ghost_places = np.flatnonzero(owner[held] != comm.rank)
    ghosts = held[ghost_places]
    owned = held.size - ghost_places.size
    return dolfinx.common.IndexMap(comm, owned, number[ghosts], owner[ghosts].astype(np.int32), tag), ghost_places


class Distribution:
    """This rank's share of a serial problem (module docstring): its cells (``cells``, global
    indices, sorted) and nodes (``nodes``), the local problem's mesh, and the exchange of
    nodal fields with the other ranks."""

    def __init__(self, problem, comm=None, rings: int = 1, interface_solve: str = "replicated"):
        """``rings``: the ghost layer's depth in rings of cells around the rank's own (1: the
        cells around its nodes, what a Lagrange step and the 1D remap need; a 2D remap needs
        REMAP_GHOST_RINGS).  ``interface_solve``: how enriched cells' assembled interface system is
        solved (:data:`INTERFACE_SOLVES`)."""
        self.comm = comm if comm is not None else world()
        self.interface_solve = interface_solve
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
        node_owner = node_owners(cell_nodes, owner, mesh.n_nodes)
        self.cell_owner, self.node_owner = owner, node_owner
        self.cells = local_cells(cell_nodes, owner, node_owner, me, rings)
        self.nodes = np.unique(cell_nodes[self.cells])
        self.owned_cells = np.flatnonzero(owner[self.cells] == me)  # local indices
        self.owned_nodes = np.flatnonzero(node_owner[self.nodes] == me)
        local_cell_nodes = np.searchsorted(self.nodes, cell_nodes[self.cells])
        self.mesh = MeshArrays(mesh.cell_type, np.ascontiguousarray(mesh.node_position[:, self.nodes]),
                               local_cell_nodes)
        # the index maps of the nodes and of the cells (refreshing ghost cells after a remap)
        self.index_map, self.ghost_nodes = ghost_index_map(self.comm, node_owner, self.nodes, 1)
        self.cell_map, self.ghost_cells = ghost_index_map(self.comm, owner, self.cells, 2)
        # each rank's own nodes and cells in the serial numbering, ascending (rank 0 gathers
        # fields into the serial order with them: serial_totals)
        self.owned_by_rank = {"nodes": [np.flatnonzero(node_owner == r) for r in range(size)] if me == 0 else None,
                              "cells": [np.flatnonzero(owner == r) for r in range(size)] if me == 0 else None}
        # the owned entries another rank holds as ghosts: the only ones an exchange reads
        # (copying every owned entry into the vector took 2–3 ms an exchange at 10⁵ cells a rank)
        self.shared_node_places, self.shared_cell_places = (
            np.flatnonzero(np.diff(index_map.index_to_dest_ranks(tag).offsets)[:index_map.size_local] > 0)
            for index_map, tag in ((self.index_map, 3), (self.cell_map, 4)))
        self.vectors, self.cell_vectors = {}, {}
        self.stats = None  # the mixed cells' solver statistics (the whole run's)
        # seconds in the exchanges and reductions over the ranks (waiting for the others
        # included): the run's phase_seconds["communication"]
        self.seconds = 0.0
        self.whole_mixed = None  # all the ranks' mixed cells, serial numbers (local_mixed)
        self.mixed = self.local_mixed(problem.mixed)

    def local_mixed(self, whole: MixedCells | None) -> MixedCells | None:
        """The mixed cells this rank holds (local numbers, in the serial order), solved with
        all the ranks' (MixedCells.across_ranks: the serial run's iterations); None when the
        problem has none.  A rank that holds none still solves with the others."""
        self.whole_mixed = whole
        if whole is not None and getattr(self, "stats", None) is None:
            self.stats = whole.stats
        if whole is None:
            return None
        held = np.flatnonzero(np.isin(whole.cells, self.cells))
        owned = np.flatnonzero(self.cell_owner[whole.cells[held]] == self.comm.rank)
        self.mixed_held, self.mixed_owned = held, owned

        def local_nodes(nodes):
            return None if nodes is None else np.searchsorted(self.nodes, nodes[held])
        return replace(whole, cells=np.searchsorted(self.cells, whole.cells[held]),
                       node_left=local_nodes(whole.node_left), node_right=local_nodes(whole.node_right),
                       material_left=whole.material_left[held], material_right=whole.material_right[held],
                       stats=whole.stats, across_ranks=MixedCellsOnRanks(self, whole, held, owned))

    # -- the local problem ----------------------------------------------------------------

    def adopt_mixed(self, mixed: MixedCells | None, options: dict) -> MixedCells | None:
        """The mixed cells a remap left on this rank (local numbers, every local cell's
        state the serial one), solved with all the ranks' as one set: the whole set from each
        rank's own mixed cells, in the serial order (ascending cell numbers, as a serial
        remap lists them; ``options``: the solver settings a remap gives new mixed cells)."""
        mine = np.empty(0, dtype=np.int64) if mixed is None else mixed.cells
        sides = (np.empty(0, dtype=np.int64),) * 2 if mixed is None else (mixed.material_left, mixed.material_right)
        owned = self.cell_owner[self.cells[mine]] == self.comm.rank
        pieces = self.allgather((self.cells[mine][owned], sides[0][owned], sides[1][owned]))
        cells = np.concatenate([p[0] for p in pieces])
        if cells.size == 0:
            self.whole_mixed, self.mixed = None, None
            return None
        order = np.argsort(cells)
        left, right = (np.concatenate([p[k] for p in pieces])[order] for k in (1, 2))
        whole = MixedCells(cells[order], None, None, left, right, self.problem.materials, **options)
        if self.stats is not None:  # one record of the solves for the whole run
            whole.stats = self.stats
        self.stats = whole.stats
        self.mixed = self.local_mixed(whole)
        return self.mixed

    def local_boundaries(self, owned_only: bool = False):
        """The problem's boundaries on this rank's nodes (local numbers; ``owned_only``: on
        the nodes it owns)."""
        local = []
        for boundary in self.problem.boundaries:
            here = np.flatnonzero(np.isin(self.nodes, boundary.nodes))
            if owned_only:
                here = here[self.node_owner[self.nodes[here]] == self.comm.rank]
            local.append(Boundary(boundary.side, boundary.kind, here, boundary.normal, boundary.velocity))
        return local

    def local_state(self, state: State) -> State:
        cells, nodes = self.cells, self.nodes

        def cell_values(values):
            return None if values is None else np.ascontiguousarray(values[:, cells])
        mixed_values = {}
        if self.mixed is not None:
            mixed_values = {name: np.ascontiguousarray(getattr(state, name)[self.mixed_held])
                            for name in ("interface_pressure", "interface_velocity")}
        def node_values(values):
            return None if values is None else np.ascontiguousarray(values[..., nodes])
        material_fields = {}  # 2D enriched cells: each material's nodal velocities and masses
        if state.material_node_velocity is not None:
            material_fields = dict(material_node_velocity=node_values(state.material_node_velocity),
                                   material_node_mass=node_values(state.material_node_mass),
                                   material_node_internal=node_values(state.material_node_internal),
                                   material_corner_mass=np.ascontiguousarray(state.material_corner_mass[..., cells]))
        return state.evolved(**mixed_values, **material_fields,
            node_position=np.ascontiguousarray(state.node_position[:, nodes]),
            node_velocity=np.ascontiguousarray(state.node_velocity[:, nodes]),
            material_mass=cell_values(state.material_mass), material_energy=cell_values(state.material_energy),
            material_volume=cell_values(state.material_volume), material_density=cell_values(state.material_density),
            material_pressure=cell_values(state.material_pressure),
            material_sound_speed=cell_values(state.material_sound_speed))

    def remap_parts(self) -> dict:
        """What a remapper of this rank's share takes (Remapper2D's mesh, boundaries and
        scope): the local mesh, the boundaries of its own nodes (a ghost node takes its
        owner's remapped velocity), and the scope that reaches the other ranks."""
        return {"mesh": self.mesh, "boundaries": self.local_boundaries(owned_only=True), "scope": RankScope(self)}

    def stepper(self, make_stepper) -> "DistributedWilkins":
        """The Lagrange step of this rank's cells (``make_stepper``: ale_xfem.run's, given
        the local problem's parts)."""
        problem = self.problem
        layout = MaterialLayout(problem.layout.cell_material[:, self.cells], problem.layout.n_materials)
        from ale_xfem.parallel.enriched_cells import ClosuresOnRanks

        stepper = make_stepper(self.mesh, layout, np.ascontiguousarray(problem.node_mass[self.nodes]),
                               self.local_boundaries(), mixed=self.mixed, stepper_class=DistributedWilkins,
                               closures_class=partial(ClosuresOnRanks, self))
        stepper.share(self)
        self.step = stepper
        return stepper

    # -- exchanges ------------------------------------------------------------------------

    def forward(self, field: np.ndarray) -> None:
        """Replace the ghost nodes' values of a nodal field (components, local nodes) by
        their owners' (DOLFINx's scatter_forward)."""
        self._scatter(field, self.vectors, self.index_map, self.owned_nodes, self.shared_node_places,
                      self.ghost_nodes)

    def forward_cells(self, field: np.ndarray) -> None:
        """Replace the ghost cells' values of a cell field (rows, local cells) by their
        owners' (DOLFINx's scatter_forward on the cells' index map)."""
        self._scatter(field, self.cell_vectors, self.cell_map, self.owned_cells, self.shared_cell_places,
                      self.ghost_cells)

    def _scatter(self, field, vectors, index_map, owned, shared, ghosts) -> None:
        """``field`` (rows, local entries): its ``ghosts`` take their owners' values, through
        a DOLFINx vector of ``rows`` per entry on ``index_map`` (made once, kept in
        ``vectors``) whose owned part holds ``owned``'s values where another rank reads
        them (``shared``: their places among ``owned``)."""
        import dolfinx

        clock = time.perf_counter()
        rows = field.shape[0]
        vector = vectors.get(rows)
        if vector is None:
            vector = vectors[rows] = dolfinx.la.vector(index_map, bs=rows)
        values = vector.array.reshape(-1, rows)
        values[shared] = field[:, owned[shared]].T
        vector.scatter_forward()
        field[:, ghosts] = values[owned.size:].T
        self.seconds += time.perf_counter() - clock

    def serial_totals(self, fields, over: str) -> list[float]:
        """Σ of each field over the whole mesh in the serial order: each rank's own entries
        gathered on rank 0 (MPI Gatherv) into the serial array, summed there as one rank sums
        it, the sums sent to every rank (``over``: "nodes", each (n_nodes,) or (rows,
        n_nodes), or "cells", (rows, n_cells))."""
        clock = time.perf_counter()
        nodes = over == "nodes"
        owned = self.owned_nodes if nodes else self.owned_cells
        fields = [values[None, :] if values.ndim == 1 else values for values in fields]
        rows = [values.shape[0] for values in fields]
        mine = np.concatenate([values[:, owned].ravel() for values in fields])
        by_rank = self.owned_by_rank[over]
        totals = None
        if self.comm.rank == 0:
            counts = [sum(rows) * numbers.size for numbers in by_rank]
            received = np.empty(sum(counts))
            self.comm.Gatherv(mine, (received, counts), root=0)
            n = self.problem.mesh.n_nodes if nodes else self.problem.mesh.n_cells
            wholes = [np.empty((r, n)) for r in rows]
            start = 0
            for numbers in by_rank:
                for whole, r in zip(wholes, rows):
                    whole[:, numbers] = received[start:start + r * numbers.size].reshape(r, numbers.size)
                    start += r * numbers.size
            totals = [float((whole[0] if nodes and whole.shape[0] == 1 else whole).sum()) for whole in wholes]
        else:
            self.comm.Gatherv(mine, None, root=0)
        totals = self.comm.bcast(totals, root=0)
        self.seconds += time.perf_counter() - clock
        return totals

    def allgather(self, value) -> list:
        """Every rank's ``value``, in rank order (timed as communication)."""
        clock = time.perf_counter()
        values = self.comm.allgather(value)
        self.seconds += time.perf_counter() - clock
        return values

    def gather_problem(self) -> None:
        """The problem's material layout, nodal masses and mixed cells made the whole run's
        from the ranks' own (a remap changes them as the run goes)."""
        step = self.step
        layout = step.layout
        (node_mass,), (material,) = self.whole_arrays((step.node_mass,), (layout.cell_material,))
        problem = self.problem
        problem.layout = MaterialLayout(material, layout.n_materials)
        problem.node_mass = node_mass
        problem.mixed = None if self.whole_mixed is None else replace(self.whole_mixed, across_ranks=None)

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
                self.gather_problem()
                if observe is not None:
                    observe(whole, problem)
        return observe_gathered

    def least(self, value: float) -> float:
        """The least of each rank's ``value`` (NaN if any is)."""
        values = self.allgather(float(value))
        return float("nan") if any(v != v for v in values) else min(values)

    def summed(self, value):
        """Σ over the ranks of ``value`` (a number or an array), in rank order."""
        values = self.allgather(value)
        total = values[0]
        for other in values[1:]:
            total = total + other
        return total

    def gathered(self, state: State, reach: "Reach | None" = None) -> State:
        """The serial state from every rank's own cells and nodes (on every rank); within
        ``reach`` only (:meth:`reach`; the other entries zero) if given."""
        node_names = ["node_position", "node_velocity"]
        cell_names = ["material_mass", "material_energy", "material_volume", "material_density",
                      "material_pressure", "material_sound_speed"]
        if state.material_node_velocity is not None:  # 2D enriched cells' per-material fields
            node_names += ["material_node_velocity", "material_node_mass", "material_node_internal"]
            cell_names += ["material_corner_mass"]
        present = [name for name in cell_names if getattr(state, name) is not None]
        changes = dict.fromkeys(cell_names)
        node_values, cell_values = self.whole_arrays([getattr(state, name) for name in node_names],
                                                     [getattr(state, name) for name in present], reach)
        changes.update(zip(node_names, node_values))
        changes.update(zip(present, cell_values))
        if self.mixed is not None:  # each mixed cell's from its owner
            changes["interface_pressure"], changes["interface_velocity"] = self.mixed.across_ranks.whole(
                (state.interface_pressure, state.interface_velocity))
        return state.evolved(**changes)

    def whole_arrays(self, node_fields=(), cell_fields=(), reach: "Reach | None" = None) -> tuple[list, list]:
        """Arrays (..., local entries) of the rank's nodes and of its cells → the same over the
        serial mesh's, each entry from the rank that owns it, in one exchange (every rank gets
        them all): (the node fields', the cell fields').  ``reach`` (:meth:`reach`): only its
        cells' and nodes' entries are exchanged, the others are zero."""
        nodes, cells, fill = self.owned_nodes, self.owned_cells, np.empty
        if reach is not None:
            nodes, cells, fill = reach.owned_nodes, reach.owned_cells, np.zeros
        pieces = self.allgather((self.nodes[nodes], [values[..., nodes] for values in node_fields],
                                 self.cells[cells], [values[..., cells] for values in cell_fields]))
        mesh = self.problem.mesh
        wholes = ([fill(values.shape[:-1] + (mesh.n_nodes,), dtype=values.dtype) for values in node_fields],
                  [fill(values.shape[:-1] + (mesh.n_cells,), dtype=values.dtype) for values in cell_fields])
        for piece in pieces:
            for kind in (0, 1):
                numbers, values = piece[2 * kind], piece[2 * kind + 1]
                for whole, part in zip(wholes[kind], values):
                    whole[..., numbers] = part
        return wholes

    def reach(self, cells: np.ndarray) -> "Reach":
        """A gather restricted to the serial ``cells`` ((n_cells,) bool) and their nodes, on
        this rank (:class:`Reach`)."""
        nodes = np.zeros(self.problem.mesh.n_nodes, dtype=bool)
        nodes[self.problem.mesh.cell_nodes[cells]] = True
        return Reach(cells=np.flatnonzero(cells[self.cells]),
                     owned_cells=self.owned_cells[cells[self.cells[self.owned_cells]]],
                     owned_nodes=self.owned_nodes[nodes[self.nodes[self.owned_nodes]]])


@dataclass(frozen=True)
class Reach:
    """The part of the mesh a gather is restricted to, as this rank holds it (local
    numbers): its cells on the rank (``cells``), and those the rank owns of its cells and
    nodes (``owned_cells``, ``owned_nodes``: what the rank sends)."""

    cells: np.ndarray
    owned_cells: np.ndarray
    owned_nodes: np.ndarray


class RemapOnEveryRank:
    """A 1D remap on several ranks: every rank remaps the whole mesh with the serial
    remapper (``remapper``, built on the serial problem), from the serial state gathered
    from the ranks' own cells and nodes, and keeps its share.  A 1D mesh is a line of a few
    thousand cells, whose remap costs a few Lagrange steps of it; its interface-following
    windows and its fall-back to the general intersection then need nothing of their own on
    ranks.  An interface-following mesh gathers nothing on the steps where no rank's own
    mixed cell has its interface near a node (most steps: nothing is remapped then).  (The
    2D remap is shared out: :class:`RankScope`.)  Everything else is the serial remapper's
    (its settings and counters, the same on every rank)."""

    def __init__(self, distribution: Distribution, remapper):
        self.distribution, self.remapper = distribution, remapper

    def __getattr__(self, name):
        return getattr(self.remapper, name)

    def apply(self, state, layout, mixed):
        """Remapper.apply on the serial state; returns this rank's share of its results (the
        new mixed cells already solved as one set over the ranks)."""
        distribution = self.distribution
        if self.remapper.motion == "interface":  # nothing to remap unless an interface nears a node
            if mixed is None:  # (then on every rank)
                return state, layout, mixed, None, 0.0
            _, near = self.remapper.near_a_node(state, mixed)
            if not any(distribution.allgather(bool(np.isin(near, mixed.across_ranks.owned).any()))):
                return state, layout, mixed, None, 0.0
        whole = distribution.gathered(state)
        distribution.gather_problem()  # the serial layout and mixed cells, from the ranks' own
        problem = distribution.problem
        new, new_layout, new_mixed, node_mass, kinetic_change = self.remapper.apply(whole, problem.layout,
                                                                                     problem.mixed)
        if node_mass is None:  # nothing was remapped this step
            return state, layout, mixed, None, 0.0
        local_mixed = distribution.mixed = distribution.local_mixed(new_mixed)
        cells = distribution.cells
        return (distribution.local_state(new),
                MaterialLayout(np.ascontiguousarray(new_layout.cell_material[:, cells]), new_layout.n_materials),
                local_mixed, np.ascontiguousarray(node_mass[distribution.nodes]), kinetic_change)


class RankScope(WholeMesh):
    """What one rank's remap reaches beyond its cells (ale_xfem.remap.scope): the ghost cells
    and nodes refreshed from their owners, sums over the ranks' own entries in the serial
    order, failures agreed over the ranks (the serial run's: of one check, the lowest
    serial cell number)."""

    def __init__(self, distribution: Distribution):
        self.distribution = distribution
        self.owned_nodes = distribution.owned_nodes

    def cells(self, *fields) -> None:
        for field in fields:
            self.distribution.forward_cells(field)

    def nodes(self, *fields) -> None:
        for field in fields:
            self.distribution.forward(field if field.ndim == 2 else field[None, :])

    def totals(self, fields, over: str) -> list[float]:
        return self.distribution.serial_totals(fields, over)

    def summed(self, value):
        return self.distribution.summed(value)

    def anywhere(self, flag: bool) -> bool:
        return any(self.distribution.allgather(bool(flag)))

    def solved_mixed(self, mixed, options: dict):
        return self.distribution.adopt_mixed(mixed, options)

    def cell_number(self, cell: int) -> int:
        return int(self.distribution.cells[cell])

    def verdict(self, failure: RemapFailure | None, order: int = 0) -> None:
        found = [f for f in self.distribution.allgather(None if failure is None else (order, str(failure)))
                 if f is not None]
        if found:
            raise RemapFailure(min(found)[1])


class MixedCellsOnRanks:
    """All the ranks' mixed cells as one set, in the serial order (``MixedCells.across_ranks``):
    the per-cell inputs of a solve gathered from the ranks that own the cells
    (:meth:`whole`), this rank's entries of its results (:meth:`mine`)."""

    def __init__(self, distribution: Distribution, whole: MixedCells, held, owned):
        """``whole``: the problem's mixed cells; ``held``: the places among them of this
        rank's, ``owned`` (among ``held``) those it owns."""
        self.distribution, self.count = distribution, whole.count
        # the whole set's cells and (1D) internal nodes in the serial numbering, on the serial mesh
        self.cells, self.node_left, self.node_right = whole.cells, whole.node_left, whole.node_right
        self.mesh = distribution.problem.mesh
        self.held, self.owned_places = held, held[owned]
        self.owned = owned
        self.place = np.full(whole.count, -1, dtype=np.int64)
        self.place[held] = np.arange(held.size)
        # the settings the compiled solves take of every cell
        self.sides = tuple(np.ascontiguousarray(ids, dtype=np.int64) for ids in (whole.material_left,
                                                                                 whole.material_right))
        self.density_limits = (whole.max_density_left, whole.max_density_right)

    def whole(self, arrays):
        """Per-cell arrays of this rank's mixed cells → the same of all the ranks' (each cell
        from its owner)."""
        pieces = self.distribution.allgather((self.owned_places, np.stack(arrays)[:, self.owned]))
        out = np.empty((len(arrays), self.count))
        for places, values in pieces:
            out[:, places] = values
        return tuple(out)

    def mine(self, arrays):
        """Arrays over all the ranks' mixed cells (last axis) → this rank's entries."""
        return tuple(np.asarray(values)[..., self.held] for values in arrays)

    def local(self, index: int) -> int:
        """The place among this rank's mixed cells of the whole set's ``index`` (-1: none)."""
        return int(self.place[index]) if 0 <= index < self.count else -1


class DistributedWilkins(ExplicitWilkins):
    """ExplicitWilkins on one rank's cells (a Distribution's local problem): the ghost
    nodes' forces exchanged after each evaluation, the time step the least over the ranks,
    a breakdown on any rank a breakdown on all, the boundary reactions summed over the
    ranks' own nodes.  Steps are taken one by one (no compiled chunks: an exchange sits
    inside each)."""

    distribution: Distribution
    predicted_failure: Breakdown | None = None

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
        return min(self.distribution.allgather((float(times[local]), number, text)))[2]

    def check_predicted(self, evaluation, position, energy) -> None:
        """A predicted state's breakdown is kept until the step ends, when the ranks agree
        on it, before any later one (the other ranks still exchange forces and solve the
        mixed cells with this one; the serial run reports it first); the step's other checks
        come after its last exchange and raise at once."""
        try:
            super().check_predicted(evaluation, position, energy)
        except Breakdown as failure:
            if self.predicted_failure is None:
                self.predicted_failure = failure

    def check_remapped(self, evaluation, position, energy) -> None:
        """After the remap, outside a step: the ranks agree at once (the first rank's)."""
        failure = None
        try:
            super().check_remapped(evaluation, position, energy)
        except Breakdown as error:
            failure = self._global(error)
        failures = [f for f in self.distribution.allgather(failure) if f is not None]
        if failures:
            first = failures[0]
            raise Breakdown(*first[:4], **first[4])

    def breaks_mixed_cell(self, failure: Breakdown) -> bool:
        """As ExplicitWilkins's, of the serial cell numbers (every rank decides alike): the
        mixed cells of all the ranks as the last remap left them."""
        whole = self.distribution.whole_mixed
        return whole is not None and failure.cell in whole.cells

    def step(self, state, dt, start=None, remapped_next=False):
        failure, self.predicted_failure = None, None
        try:
            new_state, evaluation, work, impulse = super().step(state, dt, start, remapped_next)
        except Breakdown as error:
            failure = error
        # a predicted state's breakdown comes first, as it would in the serial run
        stage = 1 if failure is not None else 2
        if self.predicted_failure is not None:
            stage, failure = 0, self.predicted_failure
        distribution = self.distribution
        failures = distribution.allgather(None if failure is None else (stage, *self._global(failure)))
        # the first of the earliest stage, its cell named by a rank that holds it (a mixed
        # cell's failure reaches every rank: those that hold the cell name it)
        failures = [f for f in failures if f is not None]
        if failures:
            stage, *first = min(failures, key=lambda f: (f[0], f[2] < 0))
            raise Breakdown(*first[:4], **first[4])
        return new_state, evaluation, distribution.summed(work), distribution.summed(impulse)

    def _global(self, failure: Breakdown):
        """A breakdown's arguments with the rank's cell number made the serial one."""
        cell = int(self.distribution.cells[failure.cell]) if failure.cell >= 0 else failure.cell
        return failure.quantity, cell, failure.value, failure.position, dict(
            allowed=failure.allowed, materials=failure.materials, detail=failure.detail)
