"""The interface system of enriched mixed cells (2D, and the 1D assembled predictor)
assembled and solved by PETSc over the MPI ranks, on a band of cells shared out as the
run's cells are.

On several ranks every rank runs the serial closure of the enriched cells
(:mod:`ale_xfem.parallel.enriched_cells`; in 1D the assembled predictor over every rank's
mixed cells), whose interface system
(:class:`forms.enriched_interface.InterfaceSystem`) would then be assembled and factorised
whole on every rank.  :class:`DistributedInterfaceSystem` takes its place: it speaks the
serial system's interface — inputs and outputs over all the active cells and over the
serial mesh's nodes — but binds the forms to a DOLFINx mesh of the band whose cells stay on
the ranks that own them in the run (:func:`band_mesh`), so that each rank assembles its own
cells' terms, PETSc holds each unknown on the rank that owns its node or cell, and MUMPS
factorises the system over the ranks; each rank hands its share of the solution to the
others (one exchange a solve), and every rank's closure goes on with the whole of it.

The solves are the serial ones up to the order of their sums (the assembly's at the
partition, MUMPS's pivots): the fields agree with a serial run to round-off, not to the bit.
"""

from __future__ import annotations

import numpy as np

import dolfinx_solver  # noqa: F401  (before dolfinx: it loads MPI and PETSc)
from ale_xfem.model.mesh import distributed_mesh
from forms.enriched_interface import InterfaceSystem, unit_mean_normals


def band_mesh(comm, mesh, cells, owner):
    """A DOLFINx mesh of the serial mesh ``mesh``'s ``cells`` (its cell numbers), each kept
    by the rank ``owner`` gives it (``owner``: each of ``mesh``'s cells' rank), without
    ghost cells: (the mesh, the serial number of each of its geometry nodes, of each of its
    cells)."""
    mine = cells[owner[cells] == comm.rank]
    return distributed_mesh(comm, mine, np.asarray(mesh.geometry.dofmaps[0])[mine],
                            mesh.geometry.x[:, :mesh.geometry.dim], mesh.ufl_domain(), keep=True)


class DistributedInterfaceSystem:
    """:class:`forms.enriched_interface.InterfaceSystem`'s interface (the serial mesh's cell
    and node numbers, every active cell's inputs and outputs) over a system shared out over
    the ranks (module docstring).  ``distribution``: the run's
    :class:`ale_xfem.parallel.distribution.Distribution`; ``mesh``, ``cells``, ``forms``,
    ``petsc_options``: InterfaceSystem's (the serial DOLFINx mesh, the band's cells)."""

    def __init__(self, distribution, mesh, cells, forms, petsc_options: dict | None = None):
        self.comm = distribution.comm
        self.allgather = distribution.allgather  # (timed as the run's communication)
        serial = distribution.problem.mesh
        # each DOLFINx cell's rank (the run's partition is in the mesh arrays' numbering)
        self.owner = np.empty_like(distribution.cell_owner)
        self.owner[np.arange(serial.n_cells) if serial.dolfinx_cell is None else serial.dolfinx_cell] = \
            distribution.cell_owner
        band, node_number, cell_number = band_mesh(self.comm, mesh, np.asarray(cells, dtype=np.int64), self.owner)
        self.local = InterfaceSystem(band, np.arange(cell_number.size, dtype=np.int32), forms, petsc_options,
                                     numbering=(node_number, cell_number))
        self.forms = forms
        self.cell_nodes = np.asarray(mesh.geometry.dofmaps[0], dtype=np.int64)
        self.n_nodes = mesh.geometry.x.shape[0]
        self.own, self.count, self._cells, self._nodes, self._normal = None, 0, None, None, None
        self.activate(cells)  # (as InterfaceSystem: all the band's cells, until told otherwise)

    # -- the active cells ----------------------------------------------------------------

    def activate(self, cells) -> None:
        """All the active cells (serial numbers); this rank binds its own."""
        cells = np.asarray(cells, dtype=np.int64)
        self.own = np.flatnonzero(self.owner[cells] == self.comm.rank)
        self.count, self._cells = cells.size, cells
        self._nodes = np.unique(self.cell_nodes[cells])
        self.local.activate(cells[self.own])

    @property
    def nodes(self) -> np.ndarray:
        """The nodes of all the active cells (serial numbers, each once, ascending)."""
        return self._nodes

    def vertex_order(self, parent_cell_nodes) -> None:
        self.local.vertex_order(np.asarray(parent_cell_nodes)[self.own])

    def set_geometry(self, parts, start, end, edge_flux, normal) -> None:
        own = self.own
        self._normal = np.asarray(normal)
        self.local.set_geometry([np.asarray(p)[own] for p in parts], np.asarray(start)[own], np.asarray(end)[own],
                                [np.asarray(e)[own] for e in edge_flux], self._normal[own])

    def set_ghost(self, ghost) -> None:
        self.local.set_ghost(np.asarray(ghost)[:, self.own])

    def set_materials(self, compliance, offset, weight=None, penalty=None) -> None:
        own = self.own
        self.local.set_materials(np.asarray(compliance)[:, own], np.asarray(offset)[:, own],
                                 None if weight is None else np.asarray(weight)[own],
                                 None if penalty is None else np.asarray(penalty)[own])

    def move(self, node_position) -> None:
        self.local.move(node_position)

    def destroy(self) -> None:
        """Free the system's PETSc objects now (every rank together)."""
        self.local.destroy()

    # -- the solves ----------------------------------------------------------------------

    def solve(self, mass, rhs, tied=None, sliding=None, tie_normal=None):
        """InterfaceSystem.solve's, over all the ranks; a sliding node's tie along the mean
        of all its active cells' normals (the ranks' own would each see some of them)."""
        if sliding is not None and tie_normal is None:
            tie_normal = self._mean_normals()
        return self._whole(self.local.solve(mass, rhs, tied, sliding, tie_normal))

    def resolve(self, compliance, offset):
        return self._whole(self.local.resolve(np.asarray(compliance)[:, self.own], np.asarray(offset)[:, self.own]))

    def dissipated_work(self, velocity) -> np.ndarray:
        (rows,) = self._gathered_cells([self.local.dissipated_work(velocity)])
        return rows

    def _mean_normals(self) -> np.ndarray:
        """(2, n_nodes): the unit mean of the normals of the active cells around each node."""
        return unit_mean_normals(self.cell_nodes[self._cells], self._normal, self.n_nodes).T

    def _gathered_cells(self, arrays):
        """Arrays (..., this rank's active cells) → (..., all the active cells), from every
        rank (one exchange)."""
        pieces = self.allgather((self.own, arrays))
        wholes = [np.empty(np.shape(a)[:-1] + (self.count,)) for a in arrays]
        for own, values in pieces:
            for whole, part in zip(wholes, values):
                whole[..., own] = part
        return wholes

    def _whole(self, out: dict) -> dict:
        """A solve's outputs from this rank (its own nodes' velocities, its cells' values) →
        the whole system's, on every rank (one exchange)."""
        nodes = self.local.owned_nodes
        cell_keys = [key for key in ("pressure", "interface_pressure") if key in out]
        bubbles = len(out.get("bubble", ()))
        local = ([v[:, nodes] for v in out["velocity"]], [out[key] for key in cell_keys] + list(out.get("bubble", ())))
        pieces = self.allgather((nodes, self.own, local))
        shape = np.shape(out["velocity"][0])
        velocity = [np.zeros(shape) for _ in out["velocity"]]
        cells = [np.empty(np.shape(a)[:-1] + (self.count,)) for a in local[1]]
        for node_numbers, own, (velocities, values) in pieces:
            for whole, part in zip(velocity, velocities):
                whole[:, node_numbers] = part
            for whole, part in zip(cells, values):
                whole[..., own] = part
        whole = dict(velocity=velocity, **dict(zip(cell_keys, cells)))
        if bubbles:
            whole["bubble"] = cells[len(cell_keys):]
        return whole
