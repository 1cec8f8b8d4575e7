"""The implicit system of enriched mixed cells as UFL forms (the paper's §2 and §3.2;
docs/design.md §4), compiled once per run and bound to the current mixed cells without
compiling; triangles and quadrilaterals, and intervals: the 1D mixed cell is this
system's 1D case (unstabilised: in 1D the natural pair is stable), assembled and iterated
as the 2D cells' are for the 1D closure's assembled step (``mixed/assembled_predictor.py``).

Unknowns on the submesh of the mixed cells, for each material m of a cell (α: slot 0, β:
slot 1): its mean velocity over the step ū_m (vector P1 at every node of every mixed cell:
the doubled velocities, internal and external nodes), its pressure at the end of the step
P_m (DG0) and, by stabilisation,

- ``"none"``:   the interface pressure p_Γ (DG0): the natural P1–P0 pair, not inf-sup stable;
- ``"bubble"``: p_Γ and one massless bubble per material per cell along the normal, b n (a
  bubble along Γ would have no equation under free slip — a fluid carries no shear — and
  under stick would meet the tangential condition by itself, inside the cell); zero on ∂K,
  a bubble touches no neighbour;
- ``"nitsche"``: no multiplier: the interface pressure is the weighted average of the two
  materials' pressures plus a penalty on the normal velocity jump,
  p̂ = w_α P_α + w_β P_β + γ [ū·n],
  w_m = (V_m/κ_m) / Σ_k (V_k/κ_k), γ = 2 a |Γ_K| / Σ_k (V_k/κ_k), κ_m = ρ_m c_m² dt
  (Annavarapu, Hautefeuille & Dolbow 2012: the larger part dominates, the penalty stays
  bounded on slivers), a the factor ``interface.nitsche_penalty``; symmetric.

``slip = "stick"`` constrains the whole velocity jump (vector multiplier; Nitsche: the
tangential jump penalised too, a fluid having no shear stress to average).

Rows, for material m with test functions v (v₁ its P1 part), r (its pressure):

    (4M_m/dt)(ū₁_m − u_m^n)·v₁ − ∫_{K_m} P_m ∇·v + (interface) = 2F̄ + f^n     (velocity)
    −∫_{K_m} r ∇·ū_m − ∫_{K_m} g_m (P_m − c_m) r = 0                          (pressure)

with g_m = −1/(D_m dt V_m) > 0, D_m = dp/dV along the material's adiabat, c_m its
linearisation offset: P_m = c_m + D_m dt ∫_{K_m} ∇·ū_m, the volume of m's part changing by
dt ∫_{K_m} ∇·ū_m on the geometry the forms are bound to (the part moves with its own
velocity: bound to the mid-step positions this is the exact change of a triangle's part
under a linear velocity; bound to the start, it is first order in dt).  The velocity row is
the trapezoidal momentum of an internal node, doubled so that its n+1 force has weight one
(M_m its condensed mass, the right side the pure cells' time-centred forces and the mixed
cells' forces at n), and the static equilibrium at n+1 of an external node (nothing
explicit on the right; its small inertia, ``EXTERNAL_SHARE`` of
``ale_xfem/mixed/cut_cells_2d.py``, keeps the system regular) — the paper's §2.2.1.

**The interface functional.**  ∫_Γ v·n_m enters every multiplier term.  It is written

    I_m(v) = ∫_{K_m} ∇·v − Σ_edges ∫_{e ∩ m} v₁·n_e

(the divergence theorem on m's part; a bubble vanishes on the edges), with the part of
each edge inside m shared by the two cells of the edge: a pure neighbour's edge is whole,
and between two mixed cells the edge is cut where a nodal level set (the mean of the
neighbouring PLIC lines' signed distances) changes sign.  The force of a uniform pressure
on any node then sums to zero around it whatever the reconstruction (PLIC cuts do not meet
across edges): a state at rest stays at rest.  The edge term enters the forms as a
DG1 vector E_m with the vertex rule, ∫_K E_m·v₁ = Σ_i G_mi·v_i, G_mi = Σ_e ∫_{e∩m} ψ_i n_e.

Cut-cell integrals use the moment-fitted measures of :mod:`forms.cut_quadrature` (exact
for the quadratic ∇·(b n) of a bubble and for the P1 products of the Nitsche penalty on Γ).
"""

from __future__ import annotations

import basix
import basix.ufl
import dolfinx_solver  # noqa: F401  (before dolfinx: it loads MPI and PETSc)
import dolfinx
import numpy as np
import ufl

from forms.bound_system import BoundSystem, FormBinder, every_rank
from forms.cut_quadrature import RULES, CutQuadrature, bilinear_map

STABILISATIONS = ("none", "bubble", "nitsche")
SLIPS = ("free", "stick")
# the bubble of each cell type: the cubic λ₁λ₂λ₃ of a triangle, the Q2 ξ(1−ξ)η(1−η) of a
# quadrilateral (its ∇·(b n) |det J| is of degree ≤ 3 in each of ξ, η: the cut rules are exact)
BUBBLE_DEGREE = {"interval": 2, "triangle": 3, "quadrilateral": 2}

# the subdomain id of the forms' integrals: the cells of the bound submesh that are mixed now
ACTIVE = 1
_MATERIAL_COEFFICIENTS = ("mass", "part", "edge_flux", "compliance", "offset", "ghost")
_CELL_COEFFICIENTS = ("normal", "interface", "weight", "penalty")


def unit_mean_normals(cell_nodes, normal, n_nodes: int) -> np.ndarray:
    """(n_nodes, gdim): at each node the unit mean of the ``normal`` (n, gdim) of the cells
    around it among the cells whose nodes are ``cell_nodes`` (n, k); zero where they cancel
    or no cell is."""
    # (summed over the cells' own nodes, in the cells' order, then placed: the mesh's other
    # nodes are most of them)
    nodes, local = np.unique(np.asarray(cell_nodes).ravel(), return_inverse=True)
    total = np.zeros((nodes.size, normal.shape[1]))
    np.add.at(total, local.ravel(), np.repeat(normal, np.shape(cell_nodes)[1], axis=0))
    size = np.linalg.norm(total, axis=1)[:, None]
    out = np.zeros((n_nodes, normal.shape[1]))
    out[nodes] = np.divide(total, size, out=np.zeros_like(total), where=size > 0)
    return out


def nitsche_weights(volume, stiffness, interface_length, penalty_factor: float):
    """(w_α (n,), γ (n,)) of the weighted Nitsche terms (module docstring): volume (2, n) the
    parts' areas V_m, stiffness (2, n) κ_m = ρ_m c_m² dt; w_α = (V_α/κ_α) / Σ_k (V_k/κ_k),
    γ = 2 a |Γ_K| / Σ_k (V_k/κ_k)."""
    softness = volume / stiffness
    total = softness.sum(axis=0)
    return softness[0] / total, 2.0 * penalty_factor * interface_length / total


class InterfaceForms:
    """The bilinear and linear forms of the system (module docstring), written on an
    abstract mesh of intervals, triangles or quadrilaterals and compiled once; :class:`InterfaceSystem`
    binds them."""

    def __init__(self, comm, stabilisation: str = "bubble", slip: str = "free", cell_name: str = "triangle"):
        if stabilisation not in STABILISATIONS:
            raise ValueError(f"stabilisation {stabilisation!r}: one of {', '.join(STABILISATIONS)}")
        if slip not in SLIPS:
            raise ValueError(f"slip {slip!r}: one of {', '.join(SLIPS)}")
        if cell_name not in RULES:
            raise ValueError(f"cell {cell_name!r}: one of {', '.join(RULES)}")
        if cell_name == "interval" and slip == "stick":
            raise ValueError("slip 'stick' on intervals: in 1D the interface has no tangent")
        self.stabilisation, self.slip, self.cell_name = stabilisation, slip, cell_name
        cell = basix.CellType[cell_name]
        rule_degree = RULES[cell_name][0]
        gdim = self.gdim = 1 if cell_name == "interval" else 2
        domain = ufl.Mesh(basix.ufl.element("Lagrange", cell, 1, shape=(gdim,)))
        velocity = basix.ufl.element("Lagrange", cell, 1, shape=(gdim,))
        scalar0 = basix.ufl.element("DG", cell, 0)
        stick = slip == "stick"
        blocks = [velocity, velocity]  # ū₁_α, ū₁_β
        self.bubbles = stabilisation == "bubble"
        if self.bubbles:
            # a normal bubble per material, for stick too: a tangential bubble would meet the
            # tangential condition by itself, inside the cell, and leave the nodes sliding
            normal_bubble = basix.ufl.element("Bubble", cell, BUBBLE_DEGREE[cell_name])
            blocks += [normal_bubble, normal_bubble]
        blocks += [scalar0, scalar0]  # P_α, P_β
        self.multiplier = stabilisation != "nitsche"
        if self.multiplier:
            blocks.append(basix.ufl.element("DG", cell, 0, shape=(2,)) if stick else scalar0)
        self.blocks = blocks
        self.mixed_element = basix.ufl.mixed_element(blocks)
        space = ufl.FunctionSpace(domain, self.mixed_element)

        def function_space(family, degree, shape=()):
            return ufl.FunctionSpace(domain, basix.ufl.element(family, cell, degree, shape=shape))

        quadrature = ufl.FunctionSpace(domain, basix.ufl.quadrature_element(
            cell_name, value_shape=(), scheme="default", degree=rule_degree))
        kinds = {"mass": function_space("Lagrange", 1, (gdim,)), "part": quadrature,
                 "edge_flux": function_space("DG", 1, (gdim,)), "compliance": function_space("DG", 0), "ghost": function_space("DG", 0),
                 "offset": function_space("DG", 0), "normal": function_space("DG", 0, (gdim,)),
                 "interface": quadrature, "weight": function_space("DG", 0), "penalty": function_space("DG", 0)}
        self.coefficients = {}
        for name in _MATERIAL_COEFFICIENTS:
            for side in "ab":
                self.coefficients[f"{name}_{side}"] = ufl.Coefficient(kinds[name])
        # free slip in 2D ties only the normal part of a sliding tied node's velocities
        # (InterfaceSystem._constraint)
        self.tie_normal = gdim == 2 and not stick
        for name in _CELL_COEFFICIENTS:
            self.coefficients[name] = ufl.Coefficient(kinds[name])
        c = self.coefficients

        trial, test = ufl.TrialFunctions(space), ufl.TestFunctions(space)
        n = c["normal"]
        # every integral is over the cells made active (InterfaceSystem.activate)
        lumped = ufl.dx(ACTIVE, scheme="vertex", degree=1)
        cut = ufl.dx(ACTIVE, metadata={"quadrature_degree": rule_degree, "quadrature_scheme": "default"})

        def unpack(functions):
            u1 = list(functions[:2])
            k = 2
            total = list(u1)
            if self.bubbles:
                for m in range(2):
                    total[m] = u1[m] + functions[k + m] * n
                k += 2
            pressures = list(functions[k:k + 2])
            multiplier = functions[k + 2] if self.multiplier else None
            return u1, total, pressures, multiplier

        u1, u, P, lam = unpack(trial)
        v1, v, R, mu = unpack(test)
        sides = ("a", "b")

        def interface_functional(factor, m, whole, linear):
            """factor · I_m(w), I_m(w) = ∫_Γ w·n_m (module docstring), factor constant in K."""
            return (factor * c[f"part_{sides[m]}"] * ufl.div(whole) * cut
                    - factor * ufl.dot(c[f"edge_flux_{sides[m]}"], linear) * lumped)

        def turned(w):
            """J w with (J w)·n = w·t, t = (−n_y, n_x): ∫_Γ w·t_m = I_m(J w)."""
            return ufl.as_vector([w[1], -w[0]])

        bilinear = 0
        linear = 0
        for m, side in enumerate(sides):
            part = c[f"part_{side}"]
            bilinear += ufl.inner(ufl.elem_mult(c[f"mass_{side}"], u1[m]), v1[m]) * lumped
            # ghost viscosity: the strain rate of m's velocity over the *other* material's part
            # of the cell (where m's field is only its extension), weighted by ghost_m
            other = c[f"part_{sides[1 - m]}"]
            bilinear += (c[f"ghost_{side}"] * other * ufl.inner(ufl.sym(ufl.grad(u1[m])), ufl.sym(ufl.grad(v1[m])))
                         * cut)
            bilinear -= part * P[m] * ufl.div(v[m]) * cut
            bilinear -= part * R[m] * ufl.div(u[m]) * cut
            bilinear -= part * c[f"compliance_{side}"] * P[m] * R[m] * cut
            linear -= part * c[f"compliance_{side}"] * c[f"offset_{side}"] * R[m] * cut
        if self.multiplier:
            for m in range(2):
                if stick:  # λ = (λ_n, λ_t): ∫_Γ λ_n [v·n] + λ_t [v·t]
                    bilinear += interface_functional(lam[0], m, v[m], v1[m])
                    bilinear += interface_functional(mu[0], m, u[m], u1[m])
                    bilinear += interface_functional(lam[1], m, turned(v[m]), turned(v1[m]))
                    bilinear += interface_functional(mu[1], m, turned(u[m]), turned(u1[m]))
                else:
                    bilinear += interface_functional(lam, m, v[m], v1[m])
                    bilinear += interface_functional(mu, m, u[m], u1[m])
        else:
            # Nitsche: ∫_Γ p̂ [v·n] with p̂ = Σ_m w_m P_m + γ [ū·n] (symmetric: its adjoint in
            # the pressure rows)
            weights = (c["weight"], 1.0 - c["weight"])
            for m in range(2):
                for k in range(2):
                    bilinear += interface_functional(weights[m] * P[m], k, v[k], v1[k])
                    bilinear += interface_functional(weights[m] * R[m], k, u[k], u1[k])
            jump_u, jump_v = u[0] - u[1], v[0] - v[1]
            gamma, on_gamma = c["penalty"], c["interface"]
            bilinear += gamma * ufl.dot(jump_u, n) * ufl.dot(jump_v, n) * on_gamma * cut
            if stick:
                tangent = ufl.as_vector([-n[1], n[0]])
                bilinear += gamma * ufl.dot(jump_u, tangent) * ufl.dot(jump_v, tangent) * on_gamma * cut
        self.bilinear = dolfinx.fem.compile_form(comm, bilinear)
        self.linear = dolfinx.fem.compile_form(comm, linear)

        # What the dissipative terms take from a velocity ū per cell (a DG0 vector): each
        # material's ghost viscosity g_m ∫_{K∖K_m} ε(ū_m):ε(ū_m), and Nitsche's penalty
        # γ ∫_Γ [ū·n]² (stick: the whole jump); the step gives it back as heat.
        cell_test = ufl.TestFunction(ufl.FunctionSpace(domain, scalar0))
        self.work_coefficients = {f"ubar_{side}": ufl.Coefficient(ufl.FunctionSpace(domain, velocity))
                                  for side in sides}
        ubar = [self.work_coefficients[f"ubar_{side}"] for side in sides]
        works = []
        for m, side in enumerate(sides):
            strain = ufl.sym(ufl.grad(ubar[m]))
            works.append(cell_test * c[f"ghost_{side}"] * c[f"part_{sides[1 - m]}"] * ufl.inner(strain, strain) * cut)
        if not self.multiplier:
            jump = ubar[0] - ubar[1]
            normal_jump = ufl.dot(jump, n)
            penalty_work = normal_jump * normal_jump
            if stick:
                tangential_jump = ufl.dot(jump, ufl.as_vector([-n[1], n[0]]))
                penalty_work = penalty_work + tangential_jump * tangential_jump
            works.append(cell_test * c["penalty"] * penalty_work * c["interface"] * cut)
        self.work = [dolfinx.fem.compile_form(comm, form) for form in works]


class InterfaceSystem:
    """The forms of :class:`InterfaceForms` bound to the cells ``cells`` of a mesh of their
    cell type (their submesh: a band around the interface), assembled and solved with PETSc
    over the band's cells made *active* (:meth:`activate`; at construction all of them);
    matrix and vectors are created here once and refilled at every solve, the forms are
    re-created (not compiled) at each activation, the KSP for each new set of unknowns.  Per-cell inputs and outputs are over
    the active cells in the order given to :meth:`activate`.  ``petsc_options``: the KSP and
    PC settings (default: a direct LDLᵀ solve by MUMPS, the forms being symmetric).

    ``numbering``: (the number of each of ``mesh``'s geometry nodes, of each of its cells)
    in the callers' numbering, the "parent" nodes and cells of every input and output
    (default: the mesh's own).  On a mesh shared out over MPI ranks (each rank its own
    cells, no ghost cells) each rank binds its cells, the system is assembled and solved by
    PETSc over all of them, a node's rows are the rank's that owns it, and the outputs are
    the rank's: its active cells' values and its own nodes' velocities."""

    def __init__(self, mesh, cells, forms: InterfaceForms, petsc_options: dict | None = None, numbering=None):
        self.forms = forms
        tdim = mesh.topology.dim
        gdim = self.gdim = forms.gdim
        mesh.topology.create_connectivity(tdim, 0)
        cells = np.asarray(cells, dtype=np.int32)
        self.submesh, entity_map, _, geometry_map = dolfinx.mesh.create_submesh(mesh, tdim, cells)
        sub = self.submesh
        n_sub = sub.topology.index_map(tdim).size_local
        node_number, cell_number = (None, None) if numbering is None else numbering
        # the parent cell of each submesh cell
        self.parent_cell = np.asarray(entity_map.sub_topology_to_topology(np.arange(n_sub, dtype=np.int32),
                                                                          inverse=False), dtype=np.int64)
        if cell_number is not None:
            self.parent_cell = np.asarray(cell_number, dtype=np.int64)[self.parent_cell]
        self._sub_order = np.argsort(self.parent_cell)
        self.geometry_map = np.asarray(geometry_map)
        if node_number is not None:
            self.geometry_map = np.asarray(node_number, dtype=np.int64)[self.geometry_map]
        self.sub_nodes = np.asarray(sub.geometry.dofmaps[0])  # (n_sub, k) submesh geometry nodes
        self.parent_nodes = self.geometry_map[self.sub_nodes]  # (n_sub, k) parent node of each vertex
        self._vertex_weights_at = None  # (the submesh's vertices, their weights) of the last call
        self.space = dolfinx.fem.functionspace(sub, forms.mixed_element)
        collapsed = [self.space.sub(i).collapse() for i in range(len(forms.blocks))]
        self.maps = [np.asarray(m).ravel() for _, m in collapsed]
        V1 = dolfinx.fem.functionspace(sub, ("Lagrange", 1, (gdim,)))
        DG0 = dolfinx.fem.functionspace(sub, ("DG", 0))
        DG1v = dolfinx.fem.functionspace(sub, ("DG", 1, (gdim,)))
        DG0v = dolfinx.fem.functionspace(sub, ("DG", 0, (gdim,)))
        self.parts = [CutQuadrature(sub) for _ in range(2)]
        self.interface = CutQuadrature(sub)
        functions = {}
        for m, side in enumerate("ab"):
            functions[f"mass_{side}"] = dolfinx.fem.Function(V1)
            functions[f"part_{side}"] = self.parts[m].ratio
            functions[f"edge_flux_{side}"] = dolfinx.fem.Function(DG1v)
            functions[f"compliance_{side}"] = dolfinx.fem.Function(DG0)
            functions[f"offset_{side}"] = dolfinx.fem.Function(DG0)
            functions[f"ghost_{side}"] = dolfinx.fem.Function(DG0)
        functions["normal"] = dolfinx.fem.Function(DG0v)
        functions["interface"] = self.interface.ratio
        functions["weight"] = dolfinx.fem.Function(DG0)
        functions["penalty"] = dolfinx.fem.Function(DG0)
        self.functions = functions
        coefficient_map = {forms.coefficients[name]: functions[name] for name in forms.coefficients}
        # the dissipated work's forms, on the velocities ū put in ``ubar`` (created at activation)
        self.ubar = [dolfinx.fem.Function(V1) for _ in range(2)]
        work_map = dict(coefficient_map)
        work_map.update({forms.work_coefficients[f"ubar_{side}"]: self.ubar[m] for m, side in enumerate("ab")})
        self._work_binders = [FormBinder(compiled, [DG0], self.submesh, work_map) for compiled in forms.work]
        self.work_forms = []
        # MUMPS: it pivots where the multiplier rows have no diagonal (PETSc's own LU does not);
        # the forms are symmetric (tests/test_enriched_2d.py checks it), so LDLᵀ; the matrix's
        # pattern is the whole band's
        self.system = BoundSystem(forms.bilinear, forms.linear, self.space, sub, coefficient_map,
                                  factor_solver="mumps", petsc_options=petsc_options,
                                  subdomains=self._subdomains(np.arange(n_sub)), symmetric=True)
        # the parent node of each velocity block (submesh vertex) of the collapsed P1 spaces,
        # and the cell dofs of the DG spaces, in submesh cell order
        V1_cells = np.asarray(V1.dofmap.list)
        self._V1 = V1
        self.velocity_parent = np.empty(V1.dofmap.index_map.size_local + V1.dofmap.index_map.num_ghosts,
                                        dtype=np.int64)
        self.velocity_parent[V1_cells] = self.parent_nodes
        # the unknowns this rank owns (the first ones of its local numbering: PETSc's rows)
        self.owned = self.space.dofmap.index_map.size_local * self.space.dofmap.index_map_bs
        # each material's velocity rows (block, component) and the parent node of each block
        # (the collapsed subspaces number their blocks their own way)
        self.velocity_block, self.block_parent = [], []
        for m in range(2):
            self.velocity_block.append(self.maps[m].reshape(-1, gdim))
            parent = np.empty(self.velocity_block[m].shape[0], dtype=np.int64)
            parent[np.asarray(collapsed[m][0].dofmap.list)] = self.parent_nodes
            self.block_parent.append(parent)
        self._velocity_cells = V1_cells
        self._dg0 = np.asarray(DG0.dofmap.list)[:, 0]
        self._dg0v = np.asarray(DG0v.dofmap.list)[:, 0]
        self._dg1v = np.asarray(DG1v.dofmap.list)  # (n_sub, 3) blocks of each cell's vertices
        k = 4 if forms.bubbles else 2
        self.pressure_dofs = [self.maps[k][self._dg0], self.maps[k + 1][self._dg0]]  # per submesh cell
        self.bubble_dofs = None
        if forms.bubbles:  # each material's bubble dof of each submesh cell
            self.bubble_dofs = [self.maps[2 + m][np.asarray(collapsed[2 + m][0].dofmap.list)[:, 0]]
                                for m in range(2)]
        self.multiplier_dofs = None
        if forms.multiplier:
            block = self.maps[k + 2]
            self.multiplier_dofs = block.reshape(-1, 2)[self._dg0v] if forms.slip == "stick" else block[self._dg0]
        self.vertex_area = None
        self._vertex_permutation = None
        self._last_constraint = None  # C of the last solve, kept across steps (_kept_constraint)
        self.activate(cells if cell_number is None else np.asarray(cell_number, dtype=np.int64)[cells])

    def _subdomains(self, active):
        return {dolfinx.fem.IntegralType.cell: [(ACTIVE, np.sort(np.asarray(active, dtype=np.int32)))]}

    def activate(self, cells) -> None:
        """Integrate over ``cells`` (parent cells, all in the band) only: the forms are
        re-created over them (nothing compiles), and every per-cell input and output is over
        them in this order from now on.  Call :meth:`vertex_order` after it."""
        cells = np.asarray(cells, dtype=np.int64)
        where = np.searchsorted(self.parent_cell, cells, sorter=self._sub_order)
        sub = self._sub_order[np.minimum(where, self.parent_cell.size - 1)]
        found = (where < self.parent_cell.size) & (self.parent_cell[sub] == cells)
        if not np.all(found):
            raise ValueError(f"InterfaceSystem.activate: cells {cells[~found][:5].tolist()} are not in the "
                             "bound band")
        order = np.argsort(sub)
        # the active submesh cells in submesh order, and the input index of each
        self.active, self.input_index = sub[order], order
        subdomains = self._subdomains(self.active)
        self.system.integrate_over(subdomains)
        self.work_forms = [binder.over(subdomains) for binder in self._work_binders]
        self._active_parent = self.velocity_parent[np.unique(self._velocity_cells[self.active])]
        self._vertex_permutation = None
        self._unknowns = None
        self._assembled = None  # (what resolve needs of the last solve)

    @property
    def nodes(self) -> np.ndarray:
        """The parent nodes of the active cells (each once)."""
        return self._active_parent

    def set_geometry(self, parts, start, end, edge_flux, normal) -> None:
        """Bind the cut geometry, each array over the active cells in the order given to
        :meth:`activate`: parts (2, n, m, 2) each material's polygon in the cell; start, end
        (n, 2) the interface segment; edge_flux (2, n, k, 2) G_mi = Σ_e ∫_{e∩m} ψ_i n_e for
        the vertices of each cell in the order given to :meth:`vertex_order`; normal (n, 2)
        n_α, out of α."""
        if self._vertex_permutation is None:
            raise RuntimeError("InterfaceSystem.set_geometry: call vertex_order first (the order of the "
                               "vertices of edge_flux)")
        n = self.input_index.size
        take, active = self.input_index, self.active
        if self.gdim == 2:  # the two parts tile each cell: one fan integrated, the other the rest
            self.parts[0].set_partition(self.parts[1], active, [parts[m][take] for m in range(2)])
        else:
            for m in range(2):
                self.parts[m].set_part_polygons(np.zeros(0, dtype=np.int64), active, parts[m][take])
        self.interface.set_interface_segments(active, start[take], end[take])
        gdim = self.gdim
        weights = self._vertex_weights()[active]  # the vertex rule's weight of each vertex
        for m, side in enumerate("ab"):
            values = self.functions[f"edge_flux_{side}"].x.array.reshape(-1, gdim)
            flux = edge_flux[m][take][np.arange(n)[:, None], self._vertex_permutation]  # (n, k, gdim)
            # the DG1 dofs of a cell follow its geometry nodes' order (P1 / Q1 alike)
            values[self._dg1v[active].ravel()] = (flux / weights[..., None]).reshape(-1, gdim)
        self.functions["normal"].x.array.reshape(-1, gdim)[self._dg0v[active]] = normal[take]
        self._unknowns = None  # (a sliding tie follows the normals)
        self._assembled = None

    def vertex_order(self, parent_cell_nodes) -> None:
        """The parent nodes of each mixed cell (n, k) in the order per-vertex inputs use;
        records how the submesh's vertices permute them."""
        given = np.asarray(parent_cell_nodes)[self.input_index]  # (n, k), active cells in submesh order
        self._vertex_permutation = np.argmax(self.parent_nodes[self.active][:, :, None] == given[:, None, :], axis=2)

    def set_ghost(self, ghost) -> None:
        """Per active cell (the order given to :meth:`activate`): ghost (2, n), the weight of each material's
        strain-rate penalty over the other material's part (0: none, the default)."""
        for m, side in enumerate("ab"):
            self.functions[f"ghost_{side}"].x.array[self._dg0[self.active]] = ghost[m][self.input_index]

    def set_materials(self, compliance, offset, weight=None, penalty=None) -> None:
        """Per active cell (the order given to :meth:`activate`): compliance (2, n) g_m = −1/(D_m dt V_m),
        offset (2, n) c_m; Nitsche: weight (n,) w_α and penalty (n,) γ."""
        if self.forms.stabilisation == "nitsche" and (weight is None or penalty is None):
            raise ValueError("set_materials: the Nitsche system needs its weight and penalty (nitsche_weights)")
        self._set_compliances(compliance, offset)
        take, dofs = self.input_index, self._dg0[self.active]
        if weight is not None:
            self.functions["weight"].x.array[dofs] = weight[take]
            self.functions["penalty"].x.array[dofs] = penalty[take]

    def _set_compliances(self, compliance, offset) -> None:
        """The pressure rows' coefficients of :meth:`set_materials`."""
        take, dofs = self.input_index, self._dg0[self.active]
        for m, side in enumerate("ab"):
            self.functions[f"compliance_{side}"].x.array[dofs] = compliance[m][take]
            self.functions[f"offset_{side}"].x.array[dofs] = offset[m][take]

    def solve(self, mass, rhs, tied=None, sliding=None, tie_normal=None):
        """Assemble and solve.  mass[m], rhs[m]: (2, n_parent_nodes) per material — 4M/dt per
        component (very large on held components) and the explicit right side
        4M u^n/dt + 2F̄ + f^n; ``tied`` (n_parent_nodes,) bool: nodes whose two velocities
        are one (pure cells of both materials around them); ``sliding`` (n_parent_nodes,)
        bool: the tied nodes whose normal parts only are one (free slip in 2D; default
        none), along ``tie_normal`` (2, n_parent_nodes) (default: the mean of the mixed
        cells' normals around each node).  Returns a dict: ``velocity``
        [m] (2, n_parent_nodes) ū_m at the mixed cells' nodes (other entries 0), ``pressure``
        (2, n) P_m per mixed cell, and, by stabilisation, ``interface_pressure`` (n,) p_Γ
        (free slip; stick: its normal part) and ``bubble`` [m]."""
        self._set_mass(mass)
        array = self.system.assemble()
        for m in range(2):
            blocks, parents = self._owned_blocks(m)
            for d in range(self.gdim):
                array[blocks[:, d]] += rhs[m][d][parents]
        # Massless bubbles and nearly massless external nodes weigh their rows by the parts'
        # small stiffness against masses of order 4M/dt: BoundSystem.solve refines
        # the same unknowns over a step's iterations (the same matrix C: the factorisation's
        # analysis is reused); new ones after set_geometry or activate
        key = (None if tied is None else tied.tobytes(), None if sliding is None else sliding.tobytes(),
               None if tie_normal is None else tie_normal.tobytes())
        if self._unknowns is None or self._unknowns[0] != key:
            self._unknowns = (key, self._kept_constraint(self._constraint(tied, sliding, tie_normal)))
        # what :meth:`resolve` changes: the pressure rows' diagonal −∫_{K_m} g_m and right
        # side −∫_{K_m} g_m c_m, both proportional to the compliance g_m (a DG0 pressure's
        # row is one cell's)
        self._assembled = (array.copy(), self.system.matrix.getDiagonal().array[self._active_pressure_dofs()],
                           self._active_compliance(), np.shape(rhs[0]))
        return self._unpacked(self.system.solve(array, "interface system", self._unknowns[1]), np.shape(rhs[0]))

    def resolve(self, compliance, offset):
        """:meth:`solve` again after :meth:`solve`, with new compliances and offsets (as
        :meth:`set_materials`; Nitsche's weight and penalty kept as they were set): the only
        entries that change are the pressure rows' diagonal and right side, each
        proportional to its compliance, set here without assembling the matrix or reducing
        it again (the factorisation redone, or refined on when the change is small:
        :meth:`forms.bound_system.BoundSystem.solve_with_diagonal`)."""
        if self._assembled is None:
            raise RuntimeError("resolve: solve first, on this geometry and these cells")
        right, diagonal, assembled_compliance, velocity_shape = self._assembled
        self._set_compliances(compliance, offset)
        dofs = self._active_pressure_dofs()
        new_diagonal = diagonal * (self._active_compliance() / assembled_compliance)
        right = right.copy()
        right[dofs] = new_diagonal * np.concatenate([self.functions[f"offset_{side}"].x.array[self._dg0[self.active]]
                                                     for side in "ab"])
        values = self.system.solve_with_diagonal(right, "interface system", self._unknowns[1], dofs, new_diagonal)
        return self._unpacked(values, velocity_shape)

    def destroy(self) -> None:
        """Free the system's PETSc objects now (:meth:`forms.bound_system.BoundSystem.destroy`;
        on a mesh shared out over ranks, every rank together)."""
        self.system.destroy()
        if self._last_constraint is not None:
            self._last_constraint.destroy()
            self._last_constraint = None

    def _owned_blocks(self, m):
        """Material m's velocity blocks whose rows this rank owns (all of them on one rank),
        and their parent nodes."""
        blocks, parents = self.velocity_block[m], self.block_parent[m]
        owned = blocks[:, 0] < self.owned
        return blocks[owned], parents[owned]

    @property
    def owned_nodes(self) -> np.ndarray:
        """The parent nodes whose velocities this rank solves for (its rows)."""
        return self._owned_blocks(0)[1]

    def _active_pressure_dofs(self):
        return np.concatenate([self.pressure_dofs[m][self.active] for m in range(2)])

    def _active_compliance(self):
        return np.concatenate([self.functions[f"compliance_{side}"].x.array[self._dg0[self.active]]
                               for side in "ab"])

    def _unpacked(self, values, velocity_shape):
        """The solution's arrays (:meth:`solve`'s dict) from the system's values."""
        n = self.input_index.size
        out = {"velocity": [], "pressure": np.empty((2, n))}
        for m in range(2):
            velocity = np.zeros(velocity_shape)
            blocks, parents = self._owned_blocks(m)
            velocity[:, parents] = values[blocks].T
            out["velocity"].append(velocity)
            out["pressure"][m, self.input_index] = values[self.pressure_dofs[m][self.active]]
        if self.multiplier_dofs is not None:
            interface = np.empty(n)
            dofs = self.multiplier_dofs[:, 0] if self.multiplier_dofs.ndim == 2 else self.multiplier_dofs
            interface[self.input_index] = values[dofs[self.active]]
            out["interface_pressure"] = interface
        if self.bubble_dofs is not None:
            out["bubble"] = []
            for dofs in self.bubble_dofs:
                bubble = np.empty(n)
                bubble[self.input_index] = values[dofs[self.active]]
                out["bubble"].append(bubble)
        return out

    def dissipated_work(self, velocity) -> np.ndarray:
        """(k, n) per active cell (the order given to :meth:`activate`): what the dissipative terms take from
        ``velocity`` [m] (2, n_parent_nodes), as rates — each material's ghost viscosity
        (rows 0, 1) and Nitsche's penalty (row 2, Nitsche only)."""
        for m in range(2):
            self.ubar[m].x.array.reshape(-1, self.gdim)[:] = velocity[m][:, self.velocity_parent].T
        n = self.input_index.size
        out = np.empty((len(self.work_forms), n))
        for row, form in enumerate(self.work_forms):
            vector = dolfinx.fem.assemble_vector(form)
            out[row, self.input_index] = vector.array[self._dg0[self.active]]
        return out

    def _set_mass(self, mass):
        """The vertex rule gives Σ_{K ∋ i} (|K|/3) m(x_i) u_i·v_i: the P1 density that lumps
        M_i on node i is M_i / Σ_{K ∋ i} |K|/3 (K over the mixed cells)."""
        if self.vertex_area is None or self.vertex_area.size != self.velocity_parent.size:
            self.vertex_area = np.zeros(self.velocity_parent.size)
        self.vertex_area[:] = 0.0
        np.add.at(self.vertex_area, self._velocity_cells[self.active].ravel(),
                  self._vertex_weights()[self.active].ravel())
        # (a node's cells on other ranks too: their sum, on each rank)
        self.vertex_area[:] = self._summed_over_ranks(self._V1.dofmap.index_map, 1, self.vertex_area)
        for m, side in enumerate("ab"):
            density = np.divide(mass[m][:, self.velocity_parent], self.vertex_area,
                                out=np.zeros((self.gdim, self.velocity_parent.size)), where=self.vertex_area > 0)
            self.functions[f"mass_{side}"].x.array.reshape(-1, self.gdim)[:] = density.T

    @staticmethod
    def _summed_over_ranks(index_map, block_size, values):
        """``values`` (the local entries of an index map's blocks) summed over the ranks that
        hold each entry, on every one of them (themselves on one rank)."""
        if index_map.comm.size == 1:
            return values
        vector = dolfinx.la.vector(index_map, bs=block_size)
        vector.array[:] = values
        vector.scatter_reverse(dolfinx.la.InsertMode.add)
        vector.scatter_forward()
        return vector.array.copy()

    def _constraint(self, tied, sliding=None, tie_normal=None):
        """The unknowns solved for, as a PETSc matrix C whose columns span them
        (:meth:`BoundSystem.solve`; None: all of them): those of the active cells — the
        inactive cells of the band carry no equation — with the tied nodes' velocities
        joined.  The tied nodes (pure cells of both materials around them: no mixed cell
        carries an interface there) move as one: their two velocities are one unknown.
        Under free slip in 2D a *sliding* tied node (Γ passes through it between mixed
        cells, along no mesh edge) shares only the normal part, along the
        node's normal to Γ (``tie_normal``, default the mean of its mixed cells' normals):
        the materials still slide past it (a spinning disk whose rim runs through nodes
        handed 11 % of its angular momentum to the fluid around it in one step when the
        whole velocity was tied there).  Where Γ follows a mesh edge into the node (a kink:
        two normals) the whole velocity is one (a normal-only tie let a kink at rest move by
        0.01).  Exact, not a stiff spring: a spring 10⁸ times the inertia left a residual at
        the round-off of its diagonal, a force that moved momentum by 10⁻¹⁰ of M V."""
        from petsc4py import PETSc

        gdim, blocks = self.gdim, self.velocity_block
        dofs = self.space.dofmap.index_map
        active_node = np.zeros(np.max(self.velocity_parent, initial=-1) + 1, dtype=bool)
        active_node[self._active_parent] = True
        kept = np.zeros((dofs.size_local + dofs.num_ghosts) * self.space.dofmap.index_map_bs, dtype=bool)
        for m in range(2):
            kept[blocks[m][active_node[self.block_parent[m]]].ravel()] = True
            kept[self.pressure_dofs[m][self.active]] = True
            if self.bubble_dofs is not None:
                kept[self.bubble_dofs[m][self.active]] = True
        if self.multiplier_dofs is not None:
            kept[self.multiplier_dofs[self.active].ravel()] = True
        # an unknown is kept when any rank's active cells reach it (on several ranks); a
        # rank's rows are its own unknowns, and the tied nodes among its own active nodes,
        # in the order of the velocity space's blocks
        kept = self._summed_over_ranks(dofs, self.space.dofmap.index_map_bs, kept.astype(float)) > 0.0
        material_block = np.full(np.max(self.block_parent[0], initial=-1) + 1, -1, dtype=np.int64)
        material_block[self.block_parent[0]] = np.arange(self.block_parent[0].size)
        own_parents = self.velocity_parent[:self._V1.dofmap.index_map.size_local]
        active_nodes = own_parents[kept[blocks[0][material_block[own_parents], 0]]]
        nodes = np.zeros(0, dtype=np.int64) if tied is None else active_nodes[tied[active_nodes]]
        comm = self.system.matrix.getComm().tompi4py()
        if every_rank(comm, nodes.size == 0 and self.active.size == self.parent_cell.size):
            return None
        kept = kept[:self.owned]
        block = []
        for m in range(2):  # each material's velocity block of each tied node
            where = np.full(np.max(self.block_parent[m], initial=-1) + 1, -1, dtype=np.int64)
            where[self.block_parent[m]] = np.arange(self.block_parent[m].size)
            block.append(where[nodes])
        slides = np.zeros(nodes.size, dtype=bool)
        if self.forms.tie_normal and sliding is not None:
            slides = sliding[nodes]
            normal = np.zeros((nodes.size, 2))
            if tie_normal is None:
                normal[slides] = self._mean_normals()[nodes[slides]]
            else:
                normal[slides] = tie_normal[:, nodes[slides]].T
            # a sliding node whose cells' normals cancel (a filament one cell thick) has no
            # direction to tie along: it stays untied (its columns would be zero)
            untied = slides & (np.linalg.norm(normal, axis=1) == 0.0)
            nodes, slides, normal = nodes[~untied], slides[~untied], normal[~untied]
            block = [b[~untied] for b in block]
        dof_a, dof_b = blocks[0][block[0]], blocks[1][block[1]]  # (n_tied, gdim)
        kept[dof_a.ravel()] = kept[dof_b.ravel()] = False  # joined below
        free = np.flatnonzero(kept)
        rows, columns, values = [free], [np.arange(free.size)], [np.ones(free.size)]
        column = free.size
        whole = ~slides
        # a whole tie: one unknown per component for both materials
        count = int(whole.sum()) * gdim
        shared = column + np.arange(count).reshape(-1, gdim)
        for dofs in (dof_a[whole], dof_b[whole]):
            rows.append(dofs.ravel())
            columns.append(shared.ravel())
            values.append(np.ones(count))
        column += count
        if slides.any():  # one normal unknown shared, each material its own tangential one
            normal = normal[slides]
            tangent = np.stack([-normal[:, 1], normal[:, 0]], axis=1)
            k = int(slides.sum())
            normal_column = column + np.arange(k)
            own = [column + k + np.arange(k), column + 2 * k + np.arange(k)]
            for m, dofs in enumerate((dof_a[slides], dof_b[slides])):
                for d in range(2):
                    rows += [dofs[:, d], dofs[:, d]]
                    columns += [normal_column, own[m]]
                    values += [normal[:, d], tangent[:, d]]
            column += 3 * k
        rows, columns, values = np.concatenate(rows), np.concatenate(columns), np.concatenate(values)
        order = np.lexsort((columns, rows))
        rows, columns, values = rows[order], columns[order], values[order]
        size = self.owned
        pointer = np.zeros(size + 1, dtype=PETSc.IntType)
        np.cumsum(np.bincount(rows, minlength=size), out=pointer[1:])
        # the columns numbered rank after rank (PETSc's rows are too)
        first = comm.exscan(column)  # (None on the first rank)
        return PETSc.Mat().createAIJ(size=((size, self.system.matrix.getSize()[0]), (column, comm.allreduce(column))),
                                     csr=(pointer, (columns + (first or 0)).astype(PETSc.IntType), values),
                                     comm=self.system.matrix.getComm())

    def _kept_constraint(self, constraint):
        """``constraint``, or the last one made if it has the same pattern (the same unknowns
        joined the same way: a steady interface, step after step), its values refreshed — the
        reduced matrix and its factorisation's analysis are then kept
        (:meth:`forms.bound_system.BoundSystem.solve`)."""
        last, self._last_constraint = self._last_constraint, constraint
        if last is None or constraint is None or last.getSize() != constraint.getSize():
            if last is not None:
                last.destroy()
            return constraint
        pointer, columns, values = constraint.getValuesCSR()
        last_pointer, last_columns, _ = last.getValuesCSR()
        same = np.array_equal(pointer, last_pointer) and np.array_equal(columns, last_columns)
        if not every_rank(constraint.getComm().tompi4py(), same):  # (every rank keeps it, or none)
            last.destroy()
            return constraint
        last.setValuesCSR(pointer, columns, values)
        last.assemble()
        constraint.destroy()
        self._last_constraint = last
        return last

    def _mean_normals(self):
        """(n_parent_nodes, 2): the unit mean of the normals of the active cells around each
        node (zero off them)."""
        normal = self.functions["normal"].x.array.reshape(-1, self.gdim)[self._dg0v[self.active]]  # (n, 2)
        return unit_mean_normals(self.parent_nodes[self.active], normal, self.parent_nodes.max() + 1)

    def move(self, node_position) -> None:
        """Follow the mesh: node_position (gdim, n_parent_nodes)."""
        self.submesh.geometry.x[:, :self.gdim] = node_position[:, self.geometry_map].T

    def _vertex_weights(self):
        """(n_sub, k): the vertex rule's weight at each vertex of each cell, in the order of
        its geometry nodes: |K|/2 on an interval, |K|/3 on a triangle, |det J(vertex)|/4 on a
        quadrilateral — kept while the submesh does not move (asked several times a step,
        for every cell of the band; an Eulerian mesh never moves)."""
        x = self.submesh.geometry.x[self.sub_nodes, :2]
        last = self._vertex_weights_at
        if last is None or not np.array_equal(last[0], x):
            weights = self._vertex_weights_of(x)
            weights.flags.writeable = False  # kept: callers read it
            self._vertex_weights_at = (x, weights)
        return self._vertex_weights_at[1]

    @staticmethod
    def _vertex_weights_of(x):
        if x.shape[1] == 2:
            return np.repeat(np.abs(x[:, 1, :1] - x[:, 0, :1]) / 2.0, 2, axis=1)
        if x.shape[1] == 3:
            e1, e2 = x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]
            area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
            return np.repeat(area[:, None] / 3.0, 3, axis=1)
        corners = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])  # tensor order
        jacobian = bilinear_map(x, np.broadcast_to(corners, (x.shape[0], 4, 2)))[1]
        return 0.25 * np.abs(np.linalg.det(jacobian))
