"""What the 2D enriched mixed cells need of their cut geometry (triangles and
quadrilaterals): each
material's part (volume, centroid, ∫ψ_i and ∫∇ψ_i), the interface segment, the edge flux
G_mi = Σ_e ∫_{e∩m} ψ_i n_e with each edge's parts shared by its two cells, which node
carries which material's mass (mass condensation, paper fig. 3) — the inputs of the forms
of ``forms/enriched_interface.py``.

**Edges shared by their two cells.**  The parts of an edge inside each material are read
the same way from both of its cells: an edge next to a pure cell belongs wholly to that
cell's material; an edge between two mixed cells (or on the boundary) is cut where a nodal
level set changes sign, φ_i the mean over the mixed cells around node i of its signed
distance to their PLIC lines (each cell's own line would cut a shared edge at two
different points).  A uniform pressure then pushes every node equally from all sides,
whatever the reconstruction.

**Mass condensation.**  A node *lies in* the material of the pure cells around it; a node
with none (every cell around it mixed) lies in the material holding the larger share of the
area around it.  In a mixed cell each material's mass goes to the cell's nodes that lie in
it, split in proportion to ∫_{K_m} ψ_i (the part's consistent row sums, which carries the
external nodes' shares onto the internal ones); the other nodes carry none of it: their
momentum equations are the interface's static equilibrium — but for a small inertia
(``EXTERNAL_SHARE`` of their consistent share, below).  **Slivers**: a material whose
part contains none of the cell's nodes (a trace of it, or an interface close to a node)
gives its whole mass to the cell's node nearest its part (the largest ∫_{K_m} ψ_i): that
node then carries both materials' masses, one velocity each.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import basix
import numba
import numpy as np

from ale_xfem.geometry.shapes import polygon_area, polygon_centroid
from ale_xfem.model.mesh import mesh_edges
from ale_xfem.model.plic import Reconstruction, reconstruct, refined_normals, youngs_normals
from forms.cut_quadrature import (NEWTON_STEPS, NEWTON_TOLERANCE, bilinear_jacobian, fan_point,
                                  reference_point, triangle_reference_point)

# the rule on the triangles of a part's fan (∫ ψ_i, ∫ ∇ψ_i), by the cell's vertex count:
# exact for the linear ψ of a triangle; through the inverse map of a quadrilateral, smooth
PART_RULE = {3: 1, 4: 10}

# The share of its consistent mass ∫_{K_m} ρ_m ψ_i an external node keeps (the rest goes to
# the internal nodes).  Massless external nodes leave the implicit system singular in 2D:
# their velocities enter only through the parts' volume changes and the normal jump (three
# conditions a cell), and a bubble per material adds two unknowns a cell that meet the same
# conditions — velocity modes that change no volume and no jump are free (massless, the
# bubble system on a disk on 6 × 6 triangles has singular values 1e-14 of its largest, and
# its solution at rest is 1e18).  A small inertia picks, among those modes, the one closest
# to the external node's previous velocity; total mass and momentum are exact (every node's
# mass is counted).
EXTERNAL_SHARE = 1e-3


@dataclass
class CutCells:
    """The cut geometry of the mixed cells (arrays over them; material slot m = 0: α, 1: β)."""

    cells: np.ndarray  # (n,)
    vertices: np.ndarray  # (n, k, 2) the cells' corners, counter-clockwise
    reconstruction: Reconstruction
    volume: np.ndarray  # (2, n) V_m, the parts' areas
    centroid: np.ndarray  # (2, n, 2)
    edge_flux: np.ndarray  # (2, n, k, 2) G_mi for the cell's vertices in cell_nodes order
    # each local edge j (vertices j → j+1): α's interval [t0, t1] of its parameter (n, k, 2),
    # the cell across it (n, k; −1 on the boundary) and |e| times its outward normal (n, k, 2)
    edge_alpha: np.ndarray | None = None
    edge_neighbour: np.ndarray | None = None
    edge_outward: np.ndarray | None = None
    _part_integrals: tuple | None = None

    @property
    def normal(self) -> np.ndarray:
        return self.reconstruction.normal

    def normal_flux(self, m: int, velocity, nodes) -> np.ndarray:
        """(n,): ∫_Γ u·n_m = ∫_{K_m} ∇·u − Σ_i G_mi·u_i for a P1/Q1 velocity (2, n_nodes) of
        material m; ``nodes`` (n, k) the cells' nodes."""
        u = np.moveaxis(velocity[:, nodes], 0, -1)  # (n, k, 2)
        gradient = self.part_integrals()[1][m]  # (n, k, 2): ∫_{K_m} ∇ψ_i
        return np.einsum("nkd,nkd->n", u, gradient) - np.einsum("nkd,nkd->n", self.edge_flux[m], u)

    def crossing_volumes(self, mesh_velocity, velocity, nodes, dt: float) -> np.ndarray:
        """(2, n, k): the volume of each material that crosses each edge of each cell into
        the cell over a step of ``dt``, relative to the edge, which moves with the mesh's
        ``mesh_velocity`` (2, n_nodes) while the material moves with its own ``velocity``
        [m] (2, n_nodes) (both linear along an edge): dt ∫_{e∩m} (ū_mesh − ū_m)·n_e on
        this geometry; zero on the boundary.  ``nodes`` (n, k) the cells' nodes."""
        t0, t1 = self.edge_alpha[..., 0], self.edge_alpha[..., 1]
        weights = edge_weights(t0, t1)  # α's interval, then β's (the rest of [0, 1])
        out = np.empty((2,) + t0.shape)
        for m in range(2):
            relative = np.moveaxis((mesh_velocity - velocity[m])[:, nodes], 0, -1)  # (n, k, 2) at the vertices
            out[m] = crossed_volume(relative, np.roll(relative, -1, axis=1), self.edge_outward,
                                    weights if m == 0 else (0.5 - weights[0], 0.5 - weights[1]), dt)
        out[:, self.edge_neighbour < 0] = 0.0
        return out

    def vertex_integrals(self) -> np.ndarray:
        """(2, n, k): ∫_{K_m} ψ_i."""
        return self.part_integrals()[0]

    def part_integrals(self):
        """(∫_{K_m} ψ_i (2, n, k), ∫_{K_m} ∇ψ_i (2, n, k, 2)) over each material's polygon,
        fanned into triangles, by a PART_RULE rule (exact on triangles; on
        quadrilaterals, through the inverse bilinear map, to round-off)."""
        if self._part_integrals is None:
            k = self.vertices.shape[1]
            points, weights = basix.make_quadrature(basix.CellType.triangle, PART_RULE[k])
            vertices = np.ascontiguousarray(self.vertices, dtype=float)
            values, gradients = [], []
            for polygon in (self.reconstruction.alpha, self.reconstruction.beta):
                value, gradient = _fan_shape_integrals(vertices, np.ascontiguousarray(polygon, dtype=float),
                                                       points, weights, NEWTON_STEPS, NEWTON_TOLERANCE)
                values.append(value)
                gradients.append(gradient)
            self._part_integrals = (np.stack(values), np.stack(gradients))
        return self._part_integrals


def edge_weights(t0, t1):
    """(∫ (1 − t) dt, ∫ t dt) over [t0, t1] ⊂ [0, 1], t an edge's parameter from its start
    to its end: the shares of a linear field's values at the edge's ends in its integral
    over that part of the edge."""
    second = 0.5 * (t1**2 - t0**2)
    return (t1 - t0) - second, second


def crossed_volume(relative_start, relative_end, outward, weights, dt: float):
    """The volume that crosses part of an edge into the cell it bounds over a step of
    ``dt``: dt ∫ w·n_e over that part, the velocity relative to the edge w linear from
    ``relative_start`` to ``relative_end`` (…, 2) at its ends, ``outward`` (…, 2) |e| n_e
    out of that cell, ``weights`` the part's :func:`edge_weights`.  The materials'
    crossings of the Lagrangian edges (:meth:`CutCells.crossing_volumes` on the mixed cells,
    ``EnrichedClosure2D._pure_edge_crossings`` between pure cells)."""
    at_start = np.einsum("...d,...d->...", relative_start, outward)
    at_end = np.einsum("...d,...d->...", relative_end, outward)
    return dt * (weights[0] * at_start + weights[1] * at_end)


def cut_cells(cell_nodes, node_position, cells, reconstruction: Reconstruction, cell_material,
              alpha_material) -> CutCells:
    """The cut geometry of the mixed cells ``cells`` of a mesh of triangles or
    quadrilaterals (corners going round in ``cell_nodes``).  ``cell_material``
    (n_cells,): each cell's material, −1 for mixed cells; ``alpha_material`` (n,): each mixed
    cell's α (slot 0) material.  α is {x·n ≤ s} in ``reconstruction``."""
    cells = np.asarray(cells)
    if cells.size == 0:
        raise ValueError("cut_cells: no mixed cells (the interface lies along mesh edges or outside the mesh)")
    nodes = cell_nodes[cells]  # (n, k)
    vertices = np.moveaxis(node_position[:, nodes], 0, -1)
    polygons = (reconstruction.alpha, reconstruction.beta)
    volume = np.stack([np.abs(polygon_area(p)) for p in polygons])
    centroid = np.stack([polygon_centroid(p) for p in polygons])
    # the nodal level set: out of α positive, in a common orientation for the mixed cells
    # around a node (the material of lower id inside); each cell's sign brings it back
    orientation = np.where(alpha_material <= np.min(alpha_material), 1.0, -1.0)
    distance = (np.einsum("nkd,nd->nk", vertices, reconstruction.normal) - reconstruction.offset[:, None])
    n_nodes = node_position.shape[1]
    total, count = np.zeros(n_nodes), np.zeros(n_nodes)
    np.add.at(total, nodes.ravel(), (distance * orientation[:, None]).ravel())
    np.add.at(count, nodes.ravel(), 1.0)
    level = total / np.maximum(count, 1.0)
    d = level[nodes] * orientation[:, None]  # (n, k) < 0 inside α
    # each local edge k: vertices k → k+1; α's interval [t0, t1] along it
    start, end = d, np.roll(d, -1, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        crossing = np.clip(start / (start - end), 0.0, 1.0)
    inside_start, inside_end = start < 0.0, end < 0.0
    t0 = np.where(inside_start, 0.0, np.where(inside_end, crossing, 1.0))
    t1 = np.where(inside_start, np.where(inside_end, 1.0, crossing), 1.0)
    # an edge next to a pure cell is that cell's material, wholly
    neighbour = _edge_neighbours(cell_nodes, cells)  # (n, k), −1 on the boundary
    neighbour_material = np.where(neighbour >= 0, cell_material[np.maximum(neighbour, 0)], -1)
    whole_alpha = neighbour_material == alpha_material[:, None]
    whole_beta = (neighbour_material >= 0) & ~whole_alpha
    t0 = np.where(whole_alpha, 0.0, np.where(whole_beta, 1.0, t0))
    t1 = np.where(whole_alpha | whole_beta, 1.0, t1)
    along = np.roll(vertices, -1, axis=1) - vertices  # (n, k, 2)
    outward = np.stack([along[..., 1], -along[..., 0]], axis=-1)  # |e| n_e for a counter-clockwise cell
    first = (t1 - t0) - 0.5 * (t1**2 - t0**2)  # ∫ (1 − t) dt over α's interval
    second = 0.5 * (t1**2 - t0**2)  # ∫ t dt
    alpha_flux = outward * first[..., None] + np.roll(outward * second[..., None], 1, axis=1)
    whole = outward * 0.5 + np.roll(outward * 0.5, 1, axis=1)
    edge_flux = np.stack([alpha_flux, whole - alpha_flux])
    return CutCells(cells, vertices, reconstruction, volume, centroid, edge_flux, np.stack([t0, t1], axis=-1),
                    neighbour, outward)


def _edge_neighbours(cell_nodes, cells):
    """(n, k): the cell across local edge j (vertices j → j+1) of each of ``cells``."""
    return _all_edge_neighbours(cell_nodes)[np.asarray(cells)]


class PerMesh:
    """A function of a mesh's cell_nodes array that every step asks for again, its value
    kept for the last MESHES meshes asked for (latest first): a serial run asks for one
    mesh; on several MPI ranks a rank's remap and the serial mesh's enriched cells take
    turns (with one kept, each step computed both again: 60 ms of a 90 ms step at 200²)."""

    MESHES = 2

    def __init__(self, compute):
        self.compute, self.kept = compute, []  # [(a weak reference to a cell_nodes array, its value)]

    def __call__(self, cell_nodes):
        for place, (reference, value) in enumerate(self.kept):
            if reference() is cell_nodes:
                self.kept.insert(0, self.kept.pop(place))
                return value
        value = self.compute(cell_nodes)
        self.kept.insert(0, (weakref.ref(cell_nodes), value))
        del self.kept[self.MESHES:]
        return value


def _every_cells_edge_neighbours(cell_nodes):
    """(n_cells, k): the cell across each local edge of every cell (−1 on the boundary)."""
    return _find_edge_neighbours(cell_nodes, np.arange(cell_nodes.shape[0]))


_all_edge_neighbours = PerMesh(_every_cells_edge_neighbours)


def _find_edge_neighbours(cell_nodes, cells):
    k = cell_nodes.shape[1]
    start, end = cell_nodes.ravel(), np.roll(cell_nodes, -1, axis=1).ravel()
    key = np.minimum(start, end) * (cell_nodes.max() + 1) + np.maximum(start, end)
    order = np.argsort(key, kind="stable")
    sorted_key = key[order]
    owner = np.repeat(np.arange(cell_nodes.shape[0]), k)
    ours = key.reshape(-1, k)[cells]  # (n, k)
    left = np.searchsorted(sorted_key, ours, side="left")
    right = np.searchsorted(sorted_key, ours, side="right")
    own = np.asarray(cells)[:, None]
    first = owner[order[left]]
    second = np.where(right - left == 2, owner[order[np.minimum(left + 1, key.size - 1)]], -1)
    return np.where(right - left == 2, np.where(first == own, second, first), -1)


def node_materials(cell_nodes, n_nodes, cell_material, material_volume, material_of_slot):
    """The material each node lies in (module docstring): (n_nodes,) material id, and a
    flag of the nodes with pure cells of two materials around them.  ``cell_material``:
    each cell's material (−1: mixed); ``material_volume`` (2, n_cells) and
    ``material_of_slot`` (2, n_cells) the materials' areas in each cell."""
    return _node_materials(cell_nodes, n_nodes, cell_material, material_volume, material_of_slot,
                           int(material_of_slot.max()) + 1)


@numba.njit(cache=True)
def _node_materials(cell_nodes, n_nodes, cell_material, material_volume, material_of_slot,
                    n_materials):  # pragma: no cover (compiled)
    """:func:`node_materials`: the most pure cells around the node, and among equals the
    larger share of the area around it — a tie of pure cells (frequent on crossed
    triangles) went to the lower material id, so the run depended on the order the scene
    lists its materials in.  The areas summed slot by slot, each over the cells in order."""
    n_cells, k = cell_nodes.shape
    pure_count = np.zeros((n_materials, n_nodes), dtype=np.int64)
    for c in range(n_cells):
        m = cell_material[c]
        if m >= 0:
            for i in range(k):
                pure_count[m, cell_nodes[c, i]] += 1
    share = np.zeros((n_materials, n_nodes))
    slot_share = np.empty((n_materials, n_nodes))
    for slot in range(material_of_slot.shape[0]):
        slot_share[:] = 0.0
        for c in range(n_cells):
            m = material_of_slot[slot, c]
            if m >= 0:
                for i in range(k):
                    slot_share[m, cell_nodes[c, i]] += material_volume[slot, c]
        for m in range(n_materials):
            for node in range(n_nodes):
                share[m, node] += slot_share[m, node]
    return _owners(pure_count, share)


@numba.njit(cache=True)
def _owners(pure_count, share):  # pragma: no cover (compiled)
    """The material each node lies in, from the pure cells of each material around it
    (``pure_count``) and each material's area around it (``share``), both (n_materials,
    n_nodes): the most pure cells, and among equals the larger share of the area; and
    which nodes have pure cells of two materials around them."""
    n_materials, n_nodes = share.shape
    owner = np.zeros(n_nodes, dtype=np.int64)
    two_pure = np.zeros(n_nodes, dtype=np.bool_)
    for node in range(n_nodes):
        total = share[0, node]
        for m in range(1, n_materials):
            total += share[m, node]
        best = -np.inf
        touching = 0
        for m in range(n_materials):
            fraction = share[m, node] / total if total > 0 else 0.0
            score = pure_count[m, node] + 0.5 * fraction
            if score > best:
                best, owner[node] = score, m
            touching += pure_count[m, node] > 0
        two_pure[node] = touching > 1
    return owner, two_pure


@numba.njit(cache=True)
def enriched_node_materials(cell_nodes, n_nodes, cell_material, volume):  # pragma: no cover (compiled)
    """:func:`node_materials` of two materials with enriched mixed cells (``cell_material``
    −1), ``volume`` (2, n_cells) each material's area: the slots of such a mesh — a pure
    cell's material with the cell's area, then, of a mixed cell, material 0 in slot 0 and
    material 1 in slot 1 — read without making them, the same sums in the same order (the
    slot arrays over the whole mesh took 1.4 ms a call at 200² crossed triangles)."""
    n_cells, k = cell_nodes.shape
    pure_count = np.zeros((2, n_nodes), dtype=np.int64)
    first_slot = np.zeros((2, n_nodes))  # slot 0's areas at the nodes, by material
    second_slot = np.zeros(n_nodes)  # slot 1's (material 1's in the mixed cells)
    for c in range(n_cells):
        m = cell_material[c]
        if m >= 0:
            area = volume[0, c] + volume[1, c]
            for i in range(k):
                pure_count[m, cell_nodes[c, i]] += 1
                first_slot[m, cell_nodes[c, i]] += area
        else:
            for i in range(k):
                first_slot[0, cell_nodes[c, i]] += volume[0, c]
                second_slot[cell_nodes[c, i]] += volume[1, c]
    # the slots' sums added as node_materials adds them, slot by slot from +0
    share = np.empty((2, n_nodes))
    for node in range(n_nodes):
        share[0, node] = (0.0 + first_slot[0, node]) + 0.0
        share[1, node] = (0.0 + first_slot[1, node]) + second_slot[node]
    return _owners(pure_count, share)


def condensed_masses(cut: CutCells, cell_nodes, node_material, mass, materials,
                     external_share: float = EXTERNAL_SHARE):
    """(masses, internal), each (2, n, k): each material's mass in each mixed cell lumped
    onto the cell's nodes that lie in it, or onto the node nearest its part when none does
    (module docstring), the external nodes keeping ``external_share`` of their consistent
    share; and which (material, node) of each cell is internal (carries the material's
    mass: its momentum row is the trapezoidal one; the others', the static equilibrium).
    ``mass`` (2, n): the materials' masses in the mixed cells; ``materials`` (2, n) their ids."""
    nodes = cell_nodes[cut.cells]
    shares = cut.vertex_integrals()  # (2, n, k)
    out = np.zeros_like(shares)
    internal = np.zeros(shares.shape, dtype=bool)
    for m in range(2):
        inside = node_material[nodes] == materials[m][:, None]
        weight = np.where(inside, shares[m], external_share * shares[m])
        sliver = ~np.any(inside & (shares[m] > 0.0), axis=1)
        nearest = np.argmax(shares[m], axis=1)
        weight[sliver, nearest[sliver]] = shares[m][sliver, nearest[sliver]]
        internal[m] = inside
        internal[m, sliver, nearest[sliver]] = True
        total = weight.sum(axis=1)
        # (a part of zero area has no mass to place)
        out[m] = mass[m][:, None] * np.divide(weight, total[:, None], out=np.zeros_like(weight),
                                              where=total[:, None] > 0.0)
    return out, internal


@numba.njit(cache=True)
def _fan_shape_integrals(vertices, polygons, points, weights, steps, tolerance):  # pragma: no cover (compiled)
    """(∫_polygon ψ_i (n, k), ∫_polygon ∇ψ_i (n, k, 2)) for the P1 (k = 3) or Q1 (k = 4)
    shape functions of cells with corners ``vertices`` (n, k, 2) going round, over polygons
    (n, m, 2) fanned from their first vertex into triangles, the reference triangle's rule
    ``points``, ``weights`` on each (the gradients through the inverse bilinear map on
    quadrilaterals, Newton's method to ``tolerance``)."""
    n, k, m = vertices.shape[0], vertices.shape[1], polygons.shape[1]
    values = np.zeros((n, k))
    gradients = np.zeros((n, k, 2))
    psi = np.empty(k)
    grad = np.empty((k, 2))
    tensor = np.empty((4, 2))
    for i in range(n):
        x = vertices[i]
        if k == 3:
            e1x, e1y, e2x, e2y = x[1, 0] - x[0, 0], x[1, 1] - x[0, 1], x[2, 0] - x[0, 0], x[2, 1] - x[0, 1]
            det = e1x * e2y - e1y * e2x
            grad[1, 0], grad[1, 1] = e2y / det, -e2x / det  # ∇λ₁
            grad[2, 0], grad[2, 1] = -e1y / det, e1x / det  # ∇λ₂
            grad[0, 0], grad[0, 1] = -grad[1, 0] - grad[2, 0], -grad[1, 1] - grad[2, 1]
        else:  # going round → tensor order
            for d in range(2):
                tensor[0, d], tensor[1, d], tensor[2, d], tensor[3, d] = x[0, d], x[1, d], x[3, d], x[2, d]
        for j in range(1, m - 1):
            for q in range(points.shape[0]):
                px, py, area = fan_point(polygons[i], j, points, q)
                if area == 0.0:
                    break
                w = area * weights[q]
                if k == 3:
                    l1, l2 = triangle_reference_point(x, px, py)
                    psi[0], psi[1], psi[2] = 1.0 - l1 - l2, l1, l2
                else:
                    s, t = reference_point(tensor, px, py, steps, tolerance)
                    # going-round order: (0,0), (1,0), (1,1), (0,1); ∇ψ = J⁻ᵀ ∇̂ψ̂
                    psi[0], psi[1], psi[2], psi[3] = (1 - s) * (1 - t), s * (1 - t), s * t, (1 - s) * t
                    a, b, c, d = bilinear_jacobian(tensor, s, t)
                    jac = a * d - b * c
                    reference = ((-(1 - t), -(1 - s)), (1 - t, -s), (t, s), (-t, 1 - s))
                    for r in range(4):
                        gs, gt = reference[r]
                        grad[r, 0] = (d * gs - c * gt) / jac
                        grad[r, 1] = (a * gt - b * gs) / jac
                for r in range(k):
                    values[i, r] += w * psi[r]
                    gradients[i, r, 0] += w * grad[r, 0]
                    gradients[i, r, 1] += w * grad[r, 1]
    return values, gradients


@dataclass
class InterfaceGeometry:
    """Where the interface lies on a 2D mesh with enriched mixed cells, material 0 as α in
    every mixed cell: the cut cells, the material each node lies in and the nodes with pure
    cells of both — what the interface system of a step is built on."""

    cut: CutCells
    owner: np.ndarray  # (n_nodes,) the material each node lies in
    tied: np.ndarray  # (n_nodes,) bool
    sliding: np.ndarray  # (n_nodes,) bool: tied, and Γ follows no mesh edge into the node
    cell_material: np.ndarray  # (n_cells,) each cell's material, −1 for the mixed cells


@dataclass
class EnrichedGeometry(InterfaceGeometry):
    """An :class:`InterfaceGeometry` with each material's corner masses — pure cells m_K/k
    at each corner, mixed cells condensed (:func:`condensed_masses`).  The Lagrange step's
    momentum rows and the remap's momentum use these same masses, so momentum passes
    between them exactly."""

    corner_mass: np.ndarray  # (2, k, n_cells) each material's mass at each corner
    node_mass: np.ndarray  # (2, n_nodes)
    internal: np.ndarray  # (2, n_nodes) bool: the node carries the material's mass


def interface_geometry(mesh, position, volume, mass, cells, normal: str = "youngs") -> InterfaceGeometry:
    """The :class:`InterfaceGeometry` of a mesh of triangles or quadrilaterals (``mesh``:
    its cell_nodes, n_nodes and cell type, as ``MeshArrays``) at ``position`` (2, n_nodes):
    ``volume``, ``mass`` (2, n_cells) each material's area and mass per cell, ``cells`` the
    mixed cells.  The interface: PLIC with Youngs' normals of material 0's fraction, LVIRA's
    with ``normal`` = "lvira" (as the remap reconstructs it: ale_xfem.model.plic)."""
    cell_nodes, n_nodes = mesh.cell_nodes, position.shape[1]
    cells = np.asarray(cells)
    volume = np.ascontiguousarray(volume, dtype=float)
    # (what is made of a cell of no area is not used: parallel/enriched_cells.py)
    fraction, cell_material = _fractions_and_materials(volume, np.ascontiguousarray(mass, dtype=float),
                                                       np.ascontiguousarray(cells, dtype=np.int64))
    normals = refined_normals(mesh, position, fraction, cells,
                              youngs_normals(mesh, position, fraction[None, :], cells)[0], normal)
    vertices = np.moveaxis(position[:, cell_nodes[cells]], 0, -1)
    reconstruction = reconstruct(vertices, normals, fraction[cells], cells)
    cut = cut_cells(cell_nodes, position, cells, reconstruction, cell_material, np.zeros(cells.size, dtype=np.int64))
    owner, tied = enriched_node_materials(np.ascontiguousarray(cell_nodes, dtype=np.int64), n_nodes, cell_material,
                                          volume)
    # a tied node slides (its normal parts tied only, under free slip) unless Γ reaches it
    # along a mesh edge between pure cells of the two materials (a kink: forms/enriched_interface.py)
    on_edge = _on_material_edges(*edges_of(cell_nodes), cell_material, n_nodes)
    return InterfaceGeometry(cut, owner, tied, tied & ~on_edge, cell_material)


def enriched_geometry(mesh, position, volume, mass, cells, normal: str = "youngs") -> EnrichedGeometry:
    """The :class:`EnrichedGeometry`: :func:`interface_geometry` (the same arguments) and
    each material's corner and nodal masses."""
    interface = interface_geometry(mesh, position, volume, mass, cells, normal)
    cell_nodes, cells = mesh.cell_nodes, np.asarray(cells)
    alpha = np.zeros(cells.size, dtype=np.int64)  # (material 0 is α in every mixed cell)
    condensed, internal_in_cell = condensed_masses(interface.cut, cell_nodes, interface.owner, mass[:, cells],
                                                   np.stack([alpha, 1 - alpha]))
    corner_mass, internal, node_mass = _material_corner_masses(
        np.ascontiguousarray(cell_nodes, dtype=np.int64), interface.cell_material, mass, cells, condensed,
        internal_in_cell, position.shape[1])
    return EnrichedGeometry(interface.cut, interface.owner, interface.tied, interface.sliding, interface.cell_material,
                            corner_mass,
                            node_mass, internal)


@numba.njit(cache=True)
def _fractions_and_materials(volume, mass, cells):  # pragma: no cover (compiled)
    """(material 0's fraction of each cell's area (n_cells,), 0 in a cell of no area — the
    cells a gather on several ranks leaves out, whose entries are zero; each cell's
    material (n_cells,): 1 where it holds mass of material 1, else 0, −1 for the mixed
    ``cells``) of ``volume``, ``mass`` (2, n_cells) by material."""
    n_cells = volume.shape[1]
    fraction = np.zeros(n_cells)
    cell_material = np.empty(n_cells, dtype=np.int64)
    for c in range(n_cells):
        total = volume[0, c] + volume[1, c]
        if total > 0.0:
            fraction[c] = volume[0, c] / total
        cell_material[c] = 1 if mass[1, c] > 0.0 else 0
    for j in range(cells.size):
        cell_material[cells[j]] = -1
    return fraction, cell_material


@numba.njit(cache=True)
def _on_material_edges(a, b, plus, minus, cell_material, n_nodes):  # pragma: no cover (compiled)
    """(n_nodes,) bool: the ends of the inner mesh edges (a → b between cells ``plus`` and
    ``minus``, −1 on the boundary) that join pure cells of two materials (``cell_material``,
    −1 for mixed cells)."""
    on_edge = np.zeros(n_nodes, dtype=np.bool_)
    for e in range(a.size):
        if minus[e] < 0:
            continue
        left, right = cell_material[plus[e]], cell_material[minus[e]]
        if left >= 0 and right >= 0 and left != right:
            on_edge[a[e]] = True
            on_edge[b[e]] = True
    return on_edge


def material_geometry(mesh, position, volume, mass, cells, normal: str = "youngs"):
    """(each material's corner masses (2, k, n_cells) and nodal masses (2, n_nodes), the
    material each node lies in (n_nodes,), which nodes carry each material's mass (2,
    n_nodes)) of a mesh whose mixed
    cells ``cells`` are enriched, ``volume`` and ``mass`` (2, n_cells) by material: the
    condensed masses of :func:`enriched_geometry`, or, with no cell cut, each cell's equal
    corner shares (each node then lies in the material of its cells).  What the set-up, the
    Lagrange step and the remap all hand each material's momentum to the nodes with
    (``normal``: PLIC's, :func:`enriched_geometry`)."""
    if np.asarray(cells).size:
        geometry = enriched_geometry(mesh, position, volume, mass, cells, normal)
        return geometry.corner_mass, geometry.node_mass, geometry.owner, geometry.internal
    k = mesh.cell_nodes.shape[1]
    corner_mass = np.repeat(mass[:, None, :] / k, k, axis=1)
    node_mass = _node_sums(mesh.cell_nodes, corner_mass, position.shape[1])
    return corner_mass, node_mass, np.argmax(node_mass, axis=0), node_mass > 0.0


@numba.njit(cache=True)
def _material_corner_masses(cell_nodes, cell_material, mass, cells, condensed, internal_in_cell,
                            n_nodes):  # pragma: no cover (compiled)
    """Each material's corner masses (2, k, n_cells): a pure cell's m_K/k at each corner,
    a mixed cell's ``condensed`` ones (2, n, k); which nodes carry each material's mass (2,
    n_nodes: the nodes of its pure cells, and its internal nodes of the mixed cells,
    ``internal_in_cell`` (2, n, k)); and the nodal masses (2, n_nodes), summed corner by
    corner, each over the cells in order (:func:`_corner_sums`)."""
    n_cells, k = cell_nodes.shape
    corner_mass = np.zeros((2, k, n_cells))
    internal = np.zeros((2, n_nodes), dtype=np.bool_)
    for m in range(2):
        for c in range(n_cells):
            if cell_material[c] == m:
                share = mass[m, c] / k
                for i in range(k):
                    corner_mass[m, i, c] = share
                    internal[m, cell_nodes[c, i]] = True
        for j in range(cells.size):
            c = cells[j]
            for i in range(k):
                corner_mass[m, i, c] = condensed[m, j, i]
                if internal_in_cell[m, j, i]:
                    internal[m, cell_nodes[c, i]] = True
    return corner_mass, internal, _corner_sums(cell_nodes, corner_mass, n_nodes)


@numba.njit(cache=True)
def _corner_sums(cell_nodes, corner_mass, n_nodes):  # pragma: no cover (compiled)
    """(2, n_nodes): each material's corner masses (2, k, n_cells) summed onto the nodes,
    corner by corner, each over the cells in order (np.bincount's order over the corners)."""
    n_cells, k = cell_nodes.shape
    node_mass = np.zeros((2, n_nodes))
    for m in range(2):
        for i in range(k):
            for c in range(n_cells):
                if corner_mass[m, i, c] != 0.0:  # (a material's absence: zeros, which change no sum from +0)
                    node_mass[m, cell_nodes[c, i]] += corner_mass[m, i, c]
    return node_mass


def _node_sums(cell_nodes, corner_mass, n_nodes):
    """(2, n_nodes): each material's corner masses (2, k, n_cells) summed onto the nodes."""
    return _corner_sums(np.ascontiguousarray(cell_nodes, dtype=np.int64), np.ascontiguousarray(corner_mass),
                        n_nodes)


edges_of = PerMesh(mesh_edges)  # mesh_edges of a mesh's cell_nodes, made once per mesh


def _node_edge_table(cell_nodes):
    """(first (n_nodes + 1,), edge): the edges (numbered as :data:`edges_of` numbers them) at
    each node, node i's in ``edge[first[i]:first[i + 1]]``."""
    a, b, _, _ = edges_of(cell_nodes)
    ends = np.concatenate([a, b])
    order = np.argsort(ends, kind="stable")
    first = np.zeros(int(cell_nodes.max()) + 2, dtype=np.int64)
    np.cumsum(np.bincount(ends, minlength=first.size - 1), out=first[1:])
    return first, np.tile(np.arange(a.size), 2)[order]


node_edges = PerMesh(_node_edge_table)  # the edges at each node of a mesh, made once per mesh


def by_material(values, cell_material) -> np.ndarray:
    """(2, n_cells): a per-slot array (S, n_cells) rearranged by material (0, 1), the
    materials of ``cell_material`` (S, n_cells); zero where a cell does not hold the
    material."""
    out = np.zeros((2, values.shape[1]))
    for slot in range(cell_material.shape[0]):
        for m in range(2):
            np.copyto(out[m], values[slot], where=cell_material[slot] == m)
    return out
