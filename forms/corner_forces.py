"""The weak pressure force of the momentum equation (paper, weak form of eq. 2):

    F_i = −∫_D σ : ∇ψ_i dx = ∫_D P ∇·ψ_i dx,   σ = −P I,  P = p + q ∈ DG0,

for every vector P1 test function ψ_i.  On a cell of constant P this is P ∂V_K/∂x_i, the
corner force of the explicit loop (``ale_xfem.lagrange``).
"""

from __future__ import annotations

import dolfinx_solver  # noqa: F401  (before dolfinx: it loads MPI and PETSc)
import dolfinx
import numpy as np
import ufl


class CornerForceForm:
    """The compiled form, its coefficient P (a DG0 Function), and the map from DOLFINx
    velocity dofs to mesh geometry nodes."""

    def __init__(self, mesh):
        gdim = mesh.geometry.dim
        self.velocity_space = dolfinx.fem.functionspace(mesh, ("Lagrange", 1, (gdim,)))
        stress_space = dolfinx.fem.functionspace(mesh, ("DG", 0))
        self.stress = dolfinx.fem.Function(stress_space)
        self.dof_of_cell = stress_space.dofmap.list[:, 0].copy()
        test = ufl.TestFunction(self.velocity_space)
        self.form = dolfinx.fem.form(self.stress * ufl.div(test) * ufl.dx)
        # geometry node → velocity dof: both dofmaps list a cell's nodes in the same order.
        node_of_dof = np.empty(self.velocity_space.dofmap.index_map.size_local, dtype=np.int64)
        node_of_dof[self.velocity_space.dofmap.list] = mesh.geometry.dofmaps[0]
        self.node_of_dof = node_of_dof
        self.gdim = gdim

    def nodal_forces(self, cell_stress: np.ndarray, n_nodes: int) -> np.ndarray:
        """Assemble F for a per-cell P (n_cells,) → (gdim, n_nodes), geometry node order."""
        self.stress.x.array[self.dof_of_cell] = cell_stress
        vector = dolfinx.fem.assemble_vector(self.form)
        by_dof = vector.array.reshape(-1, self.gdim)
        forces = np.zeros((self.gdim, n_nodes))
        forces[:, self.node_of_dof] = by_dof[: self.node_of_dof.size].T
        return forces
