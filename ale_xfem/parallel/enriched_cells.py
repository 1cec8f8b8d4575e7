"""2D enriched mixed cells on several MPI ranks: every rank solves all the ranks' mixed
cells as one set, on the serial mesh, from the serial arrays gathered from the ranks.

The closure of 2D enriched cells (:class:`ale_xfem.mixed.enriched_2d.EnrichedClosure2D`)
works on whole-mesh arrays in the serial numbering: its interface system is bound to a band
of the serial DOLFINx mesh, and its cut geometry, the pure cells' forces on the mixed cells'
nodes and the momentum balance of those nodes are taken over the mesh.  On several ranks
each rank keeps one such closure over the serial mesh and all the ranks' mixed cells
(:class:`EnrichedCellsOnRanks`), and hands it, at each step, the serial arrays gathered
from the ranks' own cells and nodes (:meth:`Distribution.whole_arrays`): every rank then
solves the serial run's system, to the bit, and keeps what falls on its own cells and
nodes — the mean forces of the mixed cells' nodes, the heat of the pure cells beside them,
each material's velocity.  The step's per-cell hooks (the viscosity's medium, the predicted
view, the start's relaxation) act on the rank's own mixed cells as for the other closures
(``MixedCells.across_ranks``).

The gathers take only what the serial closure reads (:class:`ale_xfem.parallel.distribution.Reach`):
the band of cells its interface system is bound to and ``REACH_RINGS`` rings of cells
around the mixed cells, a strip along the interface; the serial arrays' other entries are
zero, and the closure's results there are neither read nor kept.

What it costs: a gather of the strip's fields a step, and the closure's work (its solve,
and its passes over the serial mesh's arrays) on every rank — the mixed cells' part of a
step does not shrink with the ranks.  With ``interface_solve = "distributed"``
(``Distribution.interface_solve``, the run's ``--interface-solve``) the closure's interface
system is one system shared out over the ranks instead
(:class:`ale_xfem.parallel.interface_system.DistributedInterfaceSystem`): each rank
assembles its own cells' terms and MUMPS factorises over the ranks — the serial run to
round-off, not to the bit.
"""

from __future__ import annotations

from functools import partial
from types import SimpleNamespace

import numpy as np

from ale_xfem.lagrange.breakdown import Breakdown
from ale_xfem.mixed.closures import Closures
from ale_xfem.mixed.common import SharedClosure
from ale_xfem.mixed.enriched_2d import EnrichedClosure2D
from ale_xfem.model.mesh import cells_around
from ale_xfem.parallel.interface_system import DistributedInterfaceSystem

# the rings of cells around the mixed cells whose fields the serial closure reads (besides
# its band): a mixed cell's nodes take the forces, materials and masses of the cells around
# them (one ring), and the pure cells next to those nodes work on each material's velocity
# (the same ring); one ring more is kept in hand
REACH_RINGS = 2


class EnrichedCellsOnRanks(SharedClosure):
    """One rank's 2D enriched mixed cells (module docstring): ``mixed`` the rank's (local
    numbers, ``across_ranks`` set), ``distribution`` its share of the problem; ``options``:
    EnrichedClosure2D's stabilisation, slip, Nitsche factor and PETSc options."""

    implicit = True

    def __init__(self, distribution, mesh, materials, mixed, **options):
        self.distribution = distribution
        problem = distribution.problem
        # the serial closure (its forms compiled here, once per run)
        self.whole = EnrichedClosure2D(problem.mesh, materials, distribution.whole_mixed,
                                       system=interface_system(distribution), **options)
        # what the serial closure reads of a step: the serial mesh's corners, the walls and
        # pistons in serial node numbers, and the layout (gathered at each solve)
        self.whole_step = SimpleNamespace(corners=problem.mesh.corners, layout=None,
                                          constraints=[b for b in problem.boundaries if b.kind != "free"])
        self.whole_state = None
        super().__init__(mesh, materials, mixed)

    def bind(self, mixed) -> None:
        super().bind(mixed)
        whole = self.distribution.whole_mixed
        self.whole.bind(whole)
        # what the serial closure reads of the serial arrays: the band its system is bound
        # to, and REACH_RINGS rings of cells around the mixed cells
        reached = whole.cells
        for _ in range(REACH_RINGS):
            reached = cells_around(self.distribution.problem.mesh, reached)
        cells = self.whole.band.copy()
        cells[reached] = True
        self.reach = self.distribution.reach(cells)

    def _local_nodes(self, serial):
        """(places among ``serial`` (serial node numbers) of the nodes this rank holds,
        their local numbers)."""
        nodes = self.distribution.nodes
        where = np.minimum(np.searchsorted(nodes, serial), nodes.size - 1)
        held = np.flatnonzero(nodes[where] == serial)
        return held, where[held]

    def _local_breakdown(self, failure: Breakdown) -> Breakdown:
        """The serial closure's breakdown, its cell this rank's number (-1: another rank's)."""
        cells = self.distribution.cells
        where = int(np.searchsorted(cells, failure.cell))
        held = failure.cell >= 0 and where < cells.size and cells[where] == failure.cell
        return Breakdown(failure.quantity, where if held else -1, failure.value, failure.position,
                         allowed=failure.allowed, materials=failure.materials, detail=failure.detail)

    def hold_predictor(self, u0, u_pred) -> None:
        """As EnrichedClosure2D's, on the nodes this rank holds of every rank's mixed cells."""
        whole = self.distribution.whole_mixed.cells
        _, local = self._local_nodes(np.unique(self.distribution.problem.mesh.cell_nodes[whole]))
        u_pred[:, local] = u0[:, local]

    def implicit_solve(self, step, state, first, predicted, mean_force, dt, dt_over_node_mass):
        distribution, ranks = self.distribution, self.mixed.across_ranks
        whole_state = self.whole_state = distribution.gathered(state, self.reach)
        (dt_over_mass,), (cell_material, first_force, predicted_force) = distribution.whole_arrays(
            (dt_over_node_mass,), (step.layout.cell_material, first.corner_force, predicted.corner_force), self.reach)
        self.whole_step.layout = SimpleNamespace(cell_material=cell_material)
        self.whole_step.viscosity_law = step.viscosity_law
        # what the mixed cells' viscosity reads of the two evaluations, in the serial numbering
        cells, whole_cells = self.mixed.cells, distribution.whole_mixed.cells
        evaluations = []
        for evaluation, force in ((first, first_force), (predicted, predicted_force)):
            sound_speed, *rest = ranks.whole((evaluation.mixed_sound_speed, evaluation.velocity_jump[cells],
                                              evaluation.volume[cells]))
            jump, volume = np.zeros(distribution.problem.mesh.n_cells), np.ones(distribution.problem.mesh.n_cells)
            jump[whole_cells], volume[whole_cells] = rest
            evaluations.append(SimpleNamespace(corner_force=force, mixed_sound_speed=sound_speed,
                                               velocity_jump=jump, volume=volume))
        whole_force = np.zeros((mean_force.shape[0], dt_over_mass.size))
        try:
            out = self.whole.implicit_solve(self.whole_step, whole_state, *evaluations, whole_force, dt, dt_over_mass)
        except Breakdown as failure:
            raise self._local_breakdown(failure) from None
        # the mixed cells' nodes take the serial closure's mean forces (it sets them all)
        sub = self.whole.last_step["sub"]
        held, local = self._local_nodes(sub)
        mean_force[:, local] = whole_force[:, sub[held]]
        return out

    def end_of_step(self, state, first, predicted, x_new, e_new, solution):
        """The serial closure's end of step on the gathered positions and energies; this
        rank's mixed cells' volumes and details, and its cells' energies (the pure cells
        beside the mixed ones take the work of their forces on each material's velocity)."""
        distribution = self.distribution
        (whole_x,), (whole_e,) = distribution.whole_arrays((x_new,), (e_new[:1],), self.reach)
        try:
            va, vb, details = self.whole.end_of_step(self.whole_state, first, predicted, whole_x, whole_e, solution)
        except Breakdown as failure:
            raise self._local_breakdown(failure) from None
        reached = self.reach.cells
        e_new[0, reached] = whole_e[0, distribution.cells[reached]]
        va, vb, *details = self.mixed.across_ranks.mine((va, vb, *details))
        return va, vb, tuple(details)

    def state_for_remap(self, step, state, solution, x_new, u_new, cell_volume, e_new, dt):
        """As EnrichedClosure2D's, on this rank's cells and nodes: the mixed cells' volumes,
        energies and interface pressure, what the materials' crossings of the mesh's
        edges brought its cells, each material's velocity (the serial solve's on the
        mixed cells' nodes, the mesh's elsewhere) and the start's masses."""
        cells = self.mixed.cells
        volumes = self.remapped_slots(step, solution, cell_volume, e_new, solution[1])
        last = self.whole.last_step
        (interface_pressure,) = self.mixed.across_ranks.mine((last["interface_pressure"],))
        velocity = np.stack([u_new[:2]] * 2)
        held, local = self._local_nodes(last["sub"])
        velocity[:, :, local] = last["velocity"][:, :, last["sub"][held]]
        crossing = tuple(gained[..., self.distribution.cells] for gained in last["crossing"])
        fields = dict(interface_pressure=interface_pressure, interface_velocity=np.zeros(cells.size),
                      material_crossing=crossing, material_node_velocity=velocity,
                      material_node_mass=state.material_node_mass,
                      material_corner_mass=state.material_corner_mass,
                      material_node_internal=state.material_node_internal)
        return volumes, fields

    def finish(self, step, state, solution, x_new, u_new, e_new, dt):
        raise RuntimeError("2D enriched mixed cells need a remap after every step (remap_lagrangian on a "
                           "Lagrangian mesh)")


def interface_system(distribution):
    """What binds enriched cells' assembled interface system to its cells on this run's
    ranks: one system shared out over them (``interface_solve = "distributed"``), or None
    (every rank its own whole system)."""
    if distribution.interface_solve == "distributed":
        return partial(DistributedInterfaceSystem, distribution)
    return None


class ClosuresOnRanks(Closures):
    """The closures of one rank's mixed cells: Closures', with the 2D enriched cells solved
    over all the ranks' (:class:`EnrichedCellsOnRanks`), and the enriched cells' assembled
    systems shared out over the ranks if the run asks (:func:`interface_system`)."""

    def __init__(self, distribution, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.distribution = distribution
        self.interface_system = interface_system(distribution)

    def enriched_2d(self, mixed):
        return EnrichedCellsOnRanks(self.distribution, self.mesh, self.materials, mixed,
                                    petsc_options=self.petsc_options, **self.enriched_2d_options)
