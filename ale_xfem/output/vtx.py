"""The 2D states as ADIOS2 VTX files (ParaView's ``ADIOS2VTXReader``), written by every MPI
rank in parallel: ``<name>-cells.bp``, the cell fields of the VTK series (``cells_2d.cell_fields``)
and each cell's number in the serial mesh (``cell``, as in ``cells.csv``'s order), and
``<name>-velocity.bp``, the nodal ``velocity`` and each node's number in the serial mesh
(``node``); both on the moving mesh, one step per written time.

The files are DOLFINx's ``VTXWriter`` of functions on a DOLFINx mesh of the problem's cells
that DOLFINx's partitioner shares out over the ranks (rank 0 hands it every cell; one rank
keeps them all): each rank writes its own cells (DG0: one value a cell) and the nodes of
its cells (P1), as one block of each step, from the serial state that the run gathers for
its frames.  A VTX file holds the cell values of DG0 or the point values of Lagrange
elements, not both: the cell fields and the nodal velocity are two files.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ale_xfem.model.mesh import distributed_mesh
from ale_xfem.output.cells_2d import cell_fields

ENGINE = "BP5"


class VTXFiles:
    """Writes a state's cell fields and velocity into ``<folder>/<name>-cells.bp`` and
    ``<name>-velocity.bp`` (module docstring); collective: every rank of the run makes it
    and calls :meth:`write` with the same (gathered, serial) states, then :meth:`close`."""

    def __init__(self, problem, folder: Path):
        import basix.ufl
        import dolfinx_solver  # noqa: F401  (before dolfinx and mpi4py's users: it loads MPI)
        import dolfinx
        import dolfinx.io
        import ufl
        from mpi4py import MPI

        comm = MPI.COMM_WORLD
        mesh = problem.mesh
        cell_nodes = mesh.cell_nodes
        if mesh.cell_type.name == "quadrilateral":
            cell_nodes = cell_nodes[:, [0, 1, 3, 2]]  # going round → DOLFINx's tensor-product order
        root = comm.rank == 0
        element = ufl.Mesh(basix.ufl.element("Lagrange", mesh.cell_type.name, 1, shape=(2,)))
        # rank 0 hands every cell in, DOLFINx's partitioner shares them out
        self.mesh, self.geometry_nodes, self.cells = distributed_mesh(
            comm, np.arange(mesh.n_cells) if root else np.zeros(0, dtype=np.int64),
            cell_nodes if root else np.empty((0, cell_nodes.shape[1]), dtype=np.int64), mesh.node_position.T,
            element, keep=False)
        owned = self.cells.size
        cells_space = dolfinx.fem.functionspace(self.mesh, ("DG", 0))
        velocity_space = dolfinx.fem.functionspace(self.mesh, ("Lagrange", 1, (2,)))
        # a P1 dof lies on a geometry node (a P1 mesh): the serial node of each dof
        local_dofs = velocity_space.dofmap.index_map.size_local + velocity_space.dofmap.index_map.num_ghosts
        self.dof_nodes = np.empty(local_dofs, dtype=np.int64)
        self.dof_nodes[np.asarray(velocity_space.dofmap.list)] = self.geometry_nodes[
            np.asarray(self.mesh.geometry.dofmaps[0])]
        names = ["cell", *cell_fields(problem, problem.state)]
        self.fields = {name: dolfinx.fem.Function(cells_space, name=name) for name in names}
        self.fields["cell"].x.array[:owned] = self.cells
        self.velocity = dolfinx.fem.Function(velocity_space, name="velocity")
        node = dolfinx.fem.Function(dolfinx.fem.functionspace(self.mesh, ("Lagrange", 1)), name="node")
        node.x.array[self._scalar_dofs(node.function_space)] = self.dof_nodes
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        name = problem.scene.name
        policy = dolfinx.io.VTXMeshPolicy.update  # the mesh moves
        self.paths = (folder / f"{name}-cells.bp", folder / f"{name}-velocity.bp")
        self.writers = (dolfinx.io.VTXWriter(comm, str(self.paths[0]), list(self.fields.values()), engine=ENGINE,
                                             mesh_policy=policy),
                        dolfinx.io.VTXWriter(comm, str(self.paths[1]), [self.velocity, node], engine=ENGINE,
                                             mesh_policy=policy))

    def _scalar_dofs(self, space) -> np.ndarray:
        """The dofs of the scalar P1 ``space`` in the order of the vector P1 space's blocks
        (both on the geometry's nodes, cell by cell)."""
        order = np.empty(self.dof_nodes.size, dtype=np.int64)
        order[np.asarray(self.velocity.function_space.dofmap.list)] = np.asarray(space.dofmap.list)
        return order

    def write(self, state, problem) -> None:
        """One step of both files: ``state`` the serial state (every rank the same)."""
        self.mesh.geometry.x[:, :2] = state.node_position[:, self.geometry_nodes].T
        for name, values in cell_fields(problem, state).items():
            self.fields[name].x.array[:self.cells.size] = values[self.cells]
        self.velocity.x.array.reshape(-1, 2)[:] = state.node_velocity[:2, self.dof_nodes].T
        for writer in self.writers:
            writer.write(float(state.time))

    def close(self) -> None:
        for writer in self.writers:
            writer.close()
