"""The predictor of the mixed-cell solve as UFL forms, assembled with DOLFINx on the
mixed cells and solved with PETSc (the paper's §2.2.1 and §3, DESIGN.md §1 and §5).

Unknowns on the submesh of the mixed cells: each material's *mean* velocity over the step
ū_α, ū_β (vector P1: internal and external nodes, the doubled velocities) and the interface
pressure p_Γ (DG0).  With the constitutive law linearised about the current iterate,
P_α^{n+1} = c_α + D_α dt |K_α| ∇·ū_α (c_α: the iterate's pressure, its offset to the
start of the step and the viscosity q*; D_α = dp/dV along the material's adiabat; the
volume of α's part changes by dt ∫_{K∩α} ∇·ū_α = dt f_α |K| ∇·ū_α for P1 velocities),
the rows are, for α's test functions ψ (β alike, with n_β = −n_α):

    (4M_α/dt)(ū_α − u_α^n)·ψ − [∫_K f_α P_α^{n+1} ∇·ψ − ∫_Γ p_Γ n_α·ψ] = 2F̄ + F^n

— the trapezoidal momentum of an internal node (lumped, condensed mass M_α: the row is
doubled, so its n+1 mixed force has weight one), and the static equilibrium of an external
node (M_α = 0, no explicit force) — plus the continuity of the normal velocity,
∫_Γ (ū_α − ū_β)·n_α q = 0.  Interface integrals use ∫_Γ g = (|Γ|/|K|) ∫_K [g + (x_Γ − x)·∇g]
(exact for the linear integrands here; a point interface in 1D has |Γ| = 1).

The forms are compiled once per run (:class:`MixedCellForms`, on an abstract mesh); a
remap that moves an interface to another cell binds them to new spaces on the new
submesh without compiling.  Matrix, vectors and the KSP are created once per set of mixed
cells and refilled every iteration.
"""

from __future__ import annotations

import basix.ufl
import dolfinx_solver  # noqa: F401  (before dolfinx: it loads MPI and PETSc)
import dolfinx
import numpy as np
import ufl

from forms.bound_system import BoundSystem


_COEFFICIENTS = ("mass_a", "mass_b", "fraction_a", "fraction_b", "stiffness_a", "stiffness_b",
                 "offset_a", "offset_b", "normal", "interface", "interface_measure")


class MixedCellForms:
    """The predictor's bilinear and linear forms, written on an abstract mesh of one cell
    type and compiled once per run; :class:`MixedCellPredictor` binds them to the current
    mixed cells (a remap that moves an interface to another cell binds them anew, without
    compiling)."""

    def __init__(self, comm, cell_name: str, gdim: int):
        cell = basix.CellType[cell_name]
        domain = ufl.Mesh(basix.ufl.element("Lagrange", cell, 1, shape=(gdim,)))
        velocity = basix.ufl.element("Lagrange", cell, 1, shape=(gdim,))
        pressure = basix.ufl.element("DG", cell, 0)
        self.mixed_element = basix.ufl.mixed_element([velocity, velocity, pressure])
        space = ufl.FunctionSpace(domain, self.mixed_element)
        P1 = ufl.FunctionSpace(domain, basix.ufl.element("Lagrange", cell, 1))
        DG0 = ufl.FunctionSpace(domain, basix.ufl.element("DG", cell, 0))
        DG0v = ufl.FunctionSpace(domain, basix.ufl.element("DG", cell, 0, shape=(gdim,)))
        kinds = {"mass": P1, "fraction": DG0, "stiffness": DG0, "offset": DG0, "normal": DG0v,
                 "interface": DG0v, "interface_measure": DG0}
        self.coefficients = {name: ufl.Coefficient(kinds[name.rsplit("_", 1)[0]
                                                        if name.endswith(("_a", "_b")) else name])
                             for name in _COEFFICIENTS}
        c = self.coefficients
        (u_a, u_b, p) = ufl.TrialFunctions(space)
        (v_a, v_b, q) = ufl.TestFunctions(space)
        x = ufl.SpatialCoordinate(domain)
        volume = ufl.CellVolume(domain)
        lumped = ufl.dx(scheme="vertex", degree=1)
        n, xg, area = c["normal"], c["interface"], c["interface_measure"]

        def on_interface(g):
            return area / volume * (g + ufl.dot(xg - x, ufl.grad(g))) * ufl.dx

        bilinear = 0
        linear = 0
        for u, v, side, sign in ((u_a, v_a, "a", 1.0), (u_b, v_b, "b", -1.0)):
            m, f = c[f"mass_{side}"], c[f"fraction_{side}"]
            k, offset = c[f"stiffness_{side}"], c[f"offset_{side}"]
            bilinear += m * ufl.inner(u, v) * lumped
            bilinear -= f * k * f * volume * ufl.div(u) * ufl.div(v) * ufl.dx
            bilinear += on_interface(sign * p * ufl.dot(n, v))
            linear += f * offset * ufl.div(v) * ufl.dx
        bilinear += on_interface(ufl.dot(u_a - u_b, n) * q)
        self.bilinear = dolfinx.fem.compile_form(comm, bilinear)
        self.linear = dolfinx.fem.compile_form(comm, linear)


class MixedCellPredictor:
    """Assemble and solve the linearised interface system of all mixed cells at once."""

    def __init__(self, mesh, mixed_cells: np.ndarray, forms: MixedCellForms):
        self.parent = mesh
        mesh.topology.create_connectivity(mesh.topology.dim, 0)
        self.submesh, entity_map, _, self.geometry_map = dolfinx.mesh.create_submesh(
            mesh, mesh.topology.dim, np.asarray(mixed_cells, dtype=np.int32))
        sub = self.submesh
        # submesh cell i is parent cell parent[i], the input_index[i]-th of mixed_cells
        n_sub = sub.topology.index_map(sub.topology.dim).size_local
        parent = entity_map.sub_topology_to_topology(np.arange(n_sub, dtype=np.int32), inverse=False)
        position = {int(c): i for i, c in enumerate(mixed_cells)}
        self.input_index = np.array([position[int(c)] for c in parent], dtype=np.int64)
        gdim = sub.geometry.dim
        self.space = dolfinx.fem.functionspace(sub, forms.mixed_element)
        collapsed = [self.space.sub(i).collapse() for i in range(3)]
        self.maps = [np.asarray(m).ravel() for _, m in collapsed]
        P1 = dolfinx.fem.functionspace(sub, ("Lagrange", 1))
        DG0 = dolfinx.fem.functionspace(sub, ("DG", 0))
        DG0v = dolfinx.fem.functionspace(sub, ("DG", 0, (gdim,)))
        self.scalar_nodes = P1
        self.mass = [dolfinx.fem.Function(P1) for _ in range(2)]  # 4M/dt as a vertex-rule density
        self.fraction = [dolfinx.fem.Function(DG0) for _ in range(2)]
        self.stiffness = [dolfinx.fem.Function(DG0) for _ in range(2)]  # D_α dt
        self.offset = [dolfinx.fem.Function(DG0) for _ in range(2)]  # c_α
        self.normal = dolfinx.fem.Function(DG0v)  # n_α, outward from α
        self.interface = dolfinx.fem.Function(DG0v)  # x_Γ
        self.interface_measure = dolfinx.fem.Function(DG0)  # |Γ_K|
        functions = {"mass_a": self.mass[0], "mass_b": self.mass[1],
                     "fraction_a": self.fraction[0], "fraction_b": self.fraction[1],
                     "stiffness_a": self.stiffness[0], "stiffness_b": self.stiffness[1],
                     "offset_a": self.offset[0], "offset_b": self.offset[1], "normal": self.normal,
                     "interface": self.interface, "interface_measure": self.interface_measure}
        coefficient_map = {forms.coefficients[name]: functions[name] for name in _COEFFICIENTS}
        self.system = BoundSystem(forms.bilinear, forms.linear, self.space, sub, coefficient_map)
        # submesh vertex dofs ↔ parent geometry nodes, and DG0 dofs ↔ mixed cells
        self.parent_node_of_p1 = np.empty(P1.dofmap.index_map.size_local, dtype=np.int64)
        self.parent_node_of_p1[P1.dofmap.list] = self.geometry_map[sub.geometry.dofmaps[0]]
        self.dg0_of_cell = DG0.dofmap.list[:, 0]
        self.pressure_of_cell = self.maps[2][collapsed[2][0].dofmap.list[:, 0]]
        # parent node of each block of the collapsed velocity spaces
        self.velocity_parent = []
        for k in range(2):
            space = collapsed[k][0]
            parent = np.empty(space.dofmap.index_map.size_local, dtype=np.int64)
            parent[space.dofmap.list] = self.geometry_map[sub.geometry.dofmaps[0]]
            self.velocity_parent.append(parent)

    def move(self, node_position: np.ndarray) -> None:
        """Follow the Lagrangian mesh: node_position (gdim, n_parent_nodes)."""
        gdim = self.submesh.geometry.dim
        self.submesh.geometry.x[:, :gdim] = node_position[:, self.geometry_map].T

    def solve(self, nodal_mass, nodal_rhs, fractions, stiffness, offsets, normal, interface,
              interface_measure):
        """nodal_mass / nodal_rhs: per material, arrays over parent nodes (4M/dt at internal
        nodes, 0 at external ones; and 4M u^n/dt + 2F̄ + F^n); per mixed cell (in the
        order given at construction): fractions, stiffness (D dt), offsets c, normal n_α
        (gdim,), interface point, |Γ_K|.  Returns (p_Γ per mixed cell, ū_α and ū_β at the
        parent nodes of the mixed cells)."""
        sub = self.submesh
        cell_volume = self._cell_volumes()
        for k in range(2):
            # vertex rule: ∫ m u v ≈ Σ_vertices |K|/(nv) m_i u_i v_i → density = M nv / |K|
            per_vertex = np.zeros(self.parent_node_of_p1.size)
            vertices_per_cell = sub.geometry.dofmaps[0].shape[1]
            dofs = self.scalar_nodes.dofmap.list
            density = nodal_mass[k][self.parent_node_of_p1[dofs]] * vertices_per_cell / cell_volume[:, None]
            per_vertex[dofs.ravel()] = density.ravel()  # mixed cells share no node
            self.mass[k].x.array[:] = per_vertex
            self.fraction[k].x.array[self.dg0_of_cell] = fractions[k][self.input_index]
            self.stiffness[k].x.array[self.dg0_of_cell] = stiffness[k][self.input_index]
            self.offset[k].x.array[self.dg0_of_cell] = offsets[k][self.input_index]
        gdim = sub.geometry.dim
        blocks = (self.dg0_of_cell[:, None] * gdim + np.arange(gdim)).ravel()
        self.normal.x.array[blocks] = np.asarray(normal).reshape(-1, gdim)[self.input_index].ravel()
        self.interface.x.array[blocks] = np.asarray(interface).reshape(-1, gdim)[self.input_index].ravel()
        self.interface_measure.x.array[self.dg0_of_cell] = interface_measure[self.input_index]
        array = self.system.assemble()
        # explicit nodal terms: added to the velocity rows of each material
        for k in range(2):
            rows = self.maps[k].reshape(-1, gdim)  # (block, component) → W dof
            for d in range(gdim):
                array[rows[:, d]] += nodal_rhs[k][d][self.velocity_parent[k]]
        # The external nodes' rows weigh the velocity by the small stiffness D dt f²|K|
        # against masses of order 4M/dt: the iterative refinement of BoundSystem.solve
        # recovers the digits the factorisation loses to that conditioning.
        values = self.system.solve(array, "mixed-cell predictor")
        pressure = np.empty(self.input_index.size)
        pressure[self.input_index] = values[self.pressure_of_cell]
        velocities = [(self.velocity_parent[k], values[self.maps[k].reshape(-1, gdim)].T) for k in range(2)]
        return pressure, velocities

    def _cell_volumes(self):
        x = self.submesh.geometry.x
        cells = self.submesh.geometry.dofmaps[0]
        if cells.shape[1] == 2:
            return np.abs(x[cells[:, 1], 0] - x[cells[:, 0], 0])
        raise NotImplementedError("the assembled predictor is written for intervals so far")
