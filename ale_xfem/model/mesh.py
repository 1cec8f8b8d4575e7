"""Mesh arrays taken from a DOLFINx mesh, and cell geometry for the explicit loop.

Read once from DOLFINx:

- ``node_position`` (dim, n_nodes): geometry nodes (P1 geometry: the vertices), stored
  component by component so that every per-step operation runs on contiguous rows;
- ``cell_nodes`` (n_cells, nodes_per_cell): the geometry dofmap, reordered so that the
  nodes of a quadrilateral go round the cell (DOLFINx stores them in tensor-product order)
  and every cell has positive volume.  A rectangle (or Saltzman mesh) of quadrilaterals is
  renumbered row by row instead (``MeshArrays.grid``; ``dolfinx_node``, ``dolfinx_cell``
  map back to DOLFINx's numbers for output), so that a corner of every cell is a strided
  view of a node field.

Cell geometry is written once per cell type as the volume V_K(x) and its gradient
∂V_K/∂x_i: for a cell of constant pressure P the corner force −∫_K σ:∇ψ_i = P ∫_K ∇·ψ_i
= P ∂V_K/∂x_i, so this gradient is all the Wilkins scheme needs.  The explicit step reads
it through the compiled loops of ``cell_kernels`` (and :meth:`MeshArrays.cell_volumes`
too); the arrays below serve the remap, the interface reconstruction and the outputs.

Per-corner arrays: a field gathered to the corners of the cells is a list over corners of
lists over components of (n_cells,) arrays, ``values[i][d]``.  A corner whose node indices
form a contiguous run (an interval mesh from DOLFINx: cell k has nodes k, k+1) is gathered
as a view and scattered by a slice addition, which costs a fraction of an indexed gather;
on a grid of quadrilaterals the same holds with 2D strided views (the corner combinations
are formed on flat slices of the node field: see ``Corners.quad_corners``).
Quadrilaterals use only the combinations v_0 − v_2, v_1 − v_3 and v_0 − v_1 + v_2 − v_3 of
their corner values (QuadCorners): two independent corner gradients (QuadGradient) and the
hourglass mode.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from ale_xfem.model import cell_kernels


class Corners:
    """Gather node fields to cell corners and scatter corner values back to nodes.

    ``grid`` (nx, ny): the nodes and quadrilaterals of a logically structured nx × ny mesh
    numbered row by row (node (i, j) = j (nx + 1) + i, cell (i, j) = j nx + i, corners
    (i, j), (i+1, j), (i+1, j+1), (i, j+1)): corner i of every cell is then a strided view of
    a node field seen as (ny + 1, nx + 1), so the quadrilaterals' corner combinations are
    read without gathers and scatters are slice additions."""

    GRID_VIEWS = ((slice(None, -1), slice(None, -1)), (slice(None, -1), slice(1, None)),
                  (slice(1, None), slice(1, None)), (slice(1, None), slice(None, -1)))

    def __init__(self, cell_nodes: np.ndarray, n_nodes: int, grid=None):
        self.n_nodes = n_nodes
        self.grid = grid
        self.index = []
        for column in np.ascontiguousarray(cell_nodes.T):
            run = column.size > 0 and np.all(np.diff(column) == 1)
            self.index.append(slice(int(column[0]), int(column[-1]) + 1) if run else column.copy())
        self.all_slices = all(isinstance(i, slice) for i in self.index)
        # every corner's node in one index: a (k, n_cells) block of corner values goes to
        # the nodes in one bincount
        self.flat_index = None if self.all_slices else np.ascontiguousarray(cell_nodes.T).ravel()

    def gather(self, node_values) -> list:
        """node_values (dim, n_nodes) → [corner][component] arrays (n_cells,)."""
        if self.grid is not None:  # strided copies
            views = [self._views(component) for component in node_values]
            return [[v[i].ravel() for v in views] for i in range(4)]
        return [[component[i] for component in node_values] for i in self.index]

    def _views(self, component):
        nx, ny = self.grid
        plane = component.reshape(ny + 1, nx + 1)
        return [plane[view] for view in self.GRID_VIEWS]

    def quad_corners(self, node_values, hourglass: bool = True):
        """The QuadCorners of a node field (dim, n_nodes) (``hourglass`` False: the
        diagonals only); on a grid from slices of the node field, without gathers."""
        if self.grid is None:
            return QuadCorners.gathered(self.gather(node_values), hourglass)
        # Seen on the (ny + 1) × (nx + 1) plane the corners are strided views, and numpy's
        # arithmetic on them runs at about half speed (a call for a two-component field took
        # 1.18 ms at 10⁵ cells, 0.94 ms now: BENCHMARKS.md).  Each combination is instead
        # formed on flat slices over the cells numbered j (nx + 1) + i — corner c of that
        # cell is node j (nx + 1) + i + (0, 1, nx + 2, nx + 1)[c]; i = nx, a cell that would
        # straddle two rows, pads each row — and the rows' nx real cells are copied out (a
        # strided copy is cheap).  The same operations on the same values: the same results
        # to the bit.
        nx, ny = self.grid
        width = nx + 1
        n_padded = ny * width - 1  # the last row's padding cell would need a node past the end
        plane = np.empty((ny, width))
        padded, real = plane.reshape(-1)[:n_padded], plane[:, :nx]

        def real_cells():
            out = np.empty(nx * ny)
            np.copyto(out.reshape(ny, nx), real)
            return out

        across02, across13, sums = [], [], []
        for component in node_values:
            v0, v1 = component[:n_padded], component[1:n_padded + 1]
            v2, v3 = component[width + 1:width + 1 + n_padded], component[width:width + n_padded]
            np.subtract(v0, v2, out=padded)
            across02.append(real_cells())
            np.subtract(v1, v3, out=padded)
            across13.append(real_cells())
            if hourglass:
                np.add(v0, v2, out=padded)
                padded -= v1
                padded -= v3
                sums.append(real_cells())
        return QuadCorners(across02, across13, sums if hourglass else None)

    def scatter(self, corner_values) -> np.ndarray:
        """Sum per-corner values (a sequence over corners of (n_cells,) arrays) onto nodes."""
        return self.scatter_scaled(list(corner_values), None)

    def scatter_scaled(self, coefficients, common, out=None) -> np.ndarray:
        """Σ over corners of coefficients[i] * common onto nodes (into ``out`` if given,
        overwritten); a coefficient may be a scalar (±1 for intervals, where it costs no
        multiplication) or an array; ``common`` None: the coefficients are the values."""
        if out is None:
            out = np.empty(self.n_nodes)
        if self.grid is not None:
            nx, ny = self.grid
            views = self._views(out)
            out.fill(0.0)
            for view, coefficient in zip(views, coefficients):
                values = coefficient if common is None else coefficient * common
                view += np.reshape(values, (ny, nx))
            return out
        first = self.index[0]
        if isinstance(first, slice):
            # The first corner is written, not added: only the nodes it misses start at 0.
            out[: first.start] = 0.0
            out[first.stop:] = 0.0
            _scaled(coefficients[0], common, out[first])
            rest = zip(self.index[1:], coefficients[1:])
        else:
            out.fill(0.0)
            rest = zip(self.index, coefficients)
        for index, coefficient in rest:
            if isinstance(coefficient, float) and coefficient in (1.0, -1.0) and isinstance(index, slice):
                segment = out[index]
                (np.add if coefficient > 0 else np.subtract)(segment, common, out=segment)
                continue
            values = coefficient if common is None else coefficient * common
            if isinstance(index, slice):
                segment = out[index]
                np.add(segment, values, out=segment)
            else:
                out += np.bincount(index, weights=values, minlength=self.n_nodes)
        return out

def _scaled(coefficient, values, out):
    if values is None:
        np.copyto(out, coefficient)
    elif isinstance(coefficient, float) and coefficient == 1.0:
        np.copyto(out, values)
    elif isinstance(coefficient, float) and coefficient == -1.0:
        np.negative(values, out=out)
    else:
        np.multiply(coefficient, values, out=out)


def cells_around(mesh, cells) -> np.ndarray:
    """The cells sharing a node with ``cells`` (theirs included), in increasing order."""
    return cells_at_nodes(mesh, mesh.cell_nodes[cells].ravel())


def csr_rows(first, entries, rows) -> np.ndarray:
    """The entries of ``rows`` of a compressed-row table (row i: ``entries[first[i]:first[i + 1]]``,
    entries ≥ 0), each once, in increasing order."""
    return _csr_rows(first, entries, np.asarray(rows, dtype=np.int64))


@numba.njit(cache=True)
def _csr_rows(first, entries, rows):  # pragma: no cover (compiled)
    """:func:`csr_rows`: the entries met marked in a table as long as the largest of them,
    then read off it in order (a sort of the rows' entries, np.unique's way, took a
    millisecond a step at 200² with 2D enriched cells)."""
    largest = -1
    for r in rows:
        for j in range(first[r], first[r + 1]):
            largest = max(largest, entries[j])
    seen = np.zeros(largest + 1, dtype=np.bool_)
    count = 0
    for r in rows:
        for j in range(first[r], first[r + 1]):
            if not seen[entries[j]]:
                seen[entries[j]] = True
                count += 1
    out = np.empty(count, dtype=entries.dtype)
    count = 0
    for entry in range(largest + 1):
        if seen[entry]:
            out[count] = entry
            count += 1
    return out


def cells_at_nodes(mesh, nodes) -> np.ndarray:
    """The cells one of whose nodes is one of ``nodes``, in increasing order (read from
    :func:`node_corners`: only the rows of ``nodes``, not the whole mesh)."""
    first, cell, _ = mesh.node_corners
    return csr_rows(first, cell, nodes)


def node_neighbour_cells(cell_nodes: np.ndarray, n_nodes: int) -> np.ndarray:
    """The cells sharing at least one node with each cell, itself excluded: (n_cells, w)
    rows in increasing order, padded with −1 (w: the most any cell has)."""
    n_cells, k = cell_nodes.shape
    # the cells around each node, padded with −1: (n_nodes, valence)
    nodes = cell_nodes.ravel()
    order = np.argsort(nodes, kind="stable")
    sorted_nodes = nodes[order]
    count = np.bincount(nodes, minlength=n_nodes)
    first = np.concatenate([[0], np.cumsum(count)[:-1]])
    rank = np.arange(nodes.size) - first[sorted_nodes]
    around = np.full((n_nodes, max(int(count.max(initial=0)), 1)), -1, dtype=np.int64)
    around[sorted_nodes, rank] = order // k
    candidates = np.sort(around[cell_nodes].reshape(n_cells, -1), axis=1)
    # a neighbour seen through several shared nodes, or the cell itself: dropped
    repeated = np.zeros(candidates.shape, dtype=bool)
    repeated[:, 1:] = candidates[:, 1:] == candidates[:, :-1]
    candidates[repeated | (candidates == np.arange(n_cells)[:, None]) | (candidates < 0)] = n_cells
    candidates.sort(axis=1)  # the dropped ones (n_cells) last
    width = max(int((candidates < n_cells).sum(axis=1).max(initial=0)), 1)
    neighbours = candidates[:, :width]
    neighbours[neighbours == n_cells] = -1
    return np.ascontiguousarray(neighbours)


def node_corners(cell_nodes: np.ndarray, n_nodes: int):
    """The cells around each node: (first (n_nodes + 1,), cell, corner), node i being corner
    ``corner[j]`` of cell ``cell[j]`` for j in first[i]:first[i + 1], by corner, then by
    cell — what the compiled loops that gather over a node's cells read
    (cell_kernels.node_area_sums)."""
    k = cell_nodes.shape[1]
    nodes = np.asarray(cell_nodes, dtype=np.int64).ravel()
    order = np.argsort(nodes * k + np.tile(np.arange(k), cell_nodes.shape[0]), kind="stable")
    first = np.zeros(n_nodes + 1, dtype=np.int64)
    np.cumsum(np.bincount(nodes, minlength=n_nodes), out=first[1:])
    return first, order // k, order % k


def node_averaged_gradient(mesh, node_position, values) -> np.ndarray:
    """The gradient in each cell of a 2D mesh of cell fields averaged to the nodes by area:
    ∇v_K = (1/A_K) Σ_i v̄_i ∂A_K/∂x_i with v̄_i = Σ_K A_K v_K / Σ_K A_K over the cells around
    node i (exact for a linear field: the remap's slopes, which
    ale_xfem.remap.swept_kernels_2d.second_order computes with its limiter in the same
    loops).  ``values`` (n_cells,) or (m, n_cells) → gradients (…, n_cells, 2); a compiled
    loop (cell_kernels.node_averaged_gradients)."""
    if mesh.cell_type.name not in ("triangle", "quadrilateral"):
        raise ValueError(f"node_averaged_gradient: a 2D mesh, not {mesh.cell_type.name}s")
    values = np.asarray(values)
    fields = values.reshape(-1, values.shape[-1])
    grad = np.empty((fields.shape[0] + fields.shape[0] % 2, mesh.n_cells, 2))
    x = np.ascontiguousarray(node_position, dtype=float)
    for f in range(0, fields.shape[0], 2):  # two fields a pass
        pair = np.ascontiguousarray(fields[f:f + 2] if f + 1 < fields.shape[0] else fields[[f, f]], dtype=float)
        cell_kernels.node_averaged_gradients(cell_kernels.CELL_TYPE_CODES[mesh.cell_type.name], x,
                                             mesh.compiled_cell_nodes, *mesh.node_corners, pair, grad[f:f + 2],
                                             np.empty(mesh.n_cells), np.empty((6, mesh.n_cells)),
                                             np.empty((mesh.n_nodes, 2)))
    return grad[:fields.shape[0]].reshape(values.shape[:-1] + grad.shape[1:])


def patch_gradient(mesh, node_position, values, cells=None, around=None) -> np.ndarray:
    """A gradient in each cell (or in ``cells``) of a 2D mesh of cell fields, for its
    direction: the mean over the cell's nodes of the field's mean gradient over each node's
    patch (the cells around it) by the divergence theorem, each cell's value on its side of
    the patch (cell_kernels.patch_gradients) — Youngs' normals.  The values lie half a cell
    in from the patch's side: on a uniform grid this is half the slope of a linear field,
    and on quadrilaterals there half :func:`node_averaged_gradient` (a cell at the mesh's
    side averages its inner nodes only).  Where the field is a material's volume fraction,
    a straight interface gives its exact normal on triangles, crossed or with their nodes
    moved, at the mesh's sides too (:func:`node_averaged_gradient`, the derivatives
    taken the other way round, those of nodal averages of different supports, turns them
    by 13° rms, 44° at worst, on crossed triangles).  ``values`` (n_cells,) or (m, n_cells) →
    gradients (…, n, 2); only the cells ``around`` the nodes of ``cells`` are read
    (:func:`cells_around`, when known)."""
    if mesh.cell_type.name not in ("triangle", "quadrilateral"):
        raise ValueError(f"patch_gradient: a 2D mesh, not {mesh.cell_type.name}s")
    if cells is None:
        cells = around = np.arange(mesh.n_cells)
    around = np.asarray(cells_around(mesh, cells) if around is None else around, dtype=np.int64)
    cells = np.asarray(cells, dtype=np.int64)
    values = np.asarray(values)
    fields = np.ascontiguousarray(values.reshape(-1, values.shape[-1]), dtype=float)
    grad = np.empty((fields.shape[0], cells.size, 2))
    cell_kernels.patch_gradients(np.ascontiguousarray(node_position, dtype=float), mesh.compiled_cell_nodes, around,
                                 cells, fields, grad, np.empty(mesh.n_nodes), np.empty(mesh.n_nodes),
                                 np.empty((mesh.n_nodes, 2)), np.empty((mesh.n_nodes, 2)))
    return grad.reshape(values.shape[:-1] + grad.shape[1:])


def mesh_edges(cell_nodes: np.ndarray):
    """Unique edges (a, b) of a 2D mesh, oriented counter-clockwise in cell ``plus``;
    ``minus`` the cell on the other side (−1 on the boundary)."""
    k = cell_nodes.shape[1]
    start, end = cell_nodes.ravel(), np.roll(cell_nodes, -1, axis=1).ravel()
    owner = np.repeat(np.arange(cell_nodes.shape[0]), k)
    key = np.stack([np.minimum(start, end), np.maximum(start, end)], axis=1)
    _, edge, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    edge = edge.ravel()
    order = np.argsort(edge, kind="stable")
    first = np.flatnonzero(np.r_[True, edge[order][1:] != edge[order][:-1]])
    plus = order[first]
    minus = np.full(first.size, -1, dtype=np.int64)
    shared = count[edge[plus]] == 2
    minus[shared] = owner[order[first[shared] + 1]]
    return start[plus], end[plus], owner[plus], minus


def corner_jacobians(vertices):
    """det J = (x_{i+1} − x_i) × (x_{i−1} − x_i) at each corner of polygons whose vertices
    (..., corners, 2) go round: positive while every corner is convex-oriented, ≤ 0 at a
    corner turned inside out even when the area is still positive.  For diagnostics and
    studies; the step reads the same through QuadGradient.least_corner_jacobian."""
    after, before = np.roll(vertices, -1, axis=-2) - vertices, np.roll(vertices, 1, axis=-2) - vertices
    return after[..., 0] * before[..., 1] - after[..., 1] * before[..., 0]


def _interval_geometry(x):
    """x[i][0], i = 0, 1 → V = x1 − x0, ∂V/∂x0 = −1, ∂V/∂x1 = +1 (scalars)."""
    return x[1][0] - x[0][0], [[-1.0], [1.0]]


def _polygon_geometry(x):
    """Shoelace area of a counter-clockwise polygon with corners x[i] = (x_i, y_i):
    ∂A/∂x_i = (y_{i+1} − y_{i−1})/2, ∂A/∂y_i = (x_{i−1} − x_{i+1})/2."""
    n = len(x)
    area = 0.0
    gradient = []
    for i in range(n):
        nxt, prv = x[(i + 1) % n], x[(i - 1) % n]
        area = area + x[i][0] * nxt[1] - nxt[0] * x[i][1]
        gradient.append([0.5 * (nxt[1] - prv[1]), 0.5 * (prv[0] - nxt[0])])
    return 0.5 * area, gradient


class QuadCorners:
    """The three combinations of a quadrilateral's corner values [corner][component] that
    the explicit loop needs, component by component: across02 = v_0 − v_2,
    across13 = v_1 − v_3 and the hourglass sum v_0 − v_1 + v_2 − v_3.  They are linear in
    the values: those of a sum of nodal fields are the sums of theirs (no new gather)."""

    __slots__ = ("across02", "across13", "hourglass")

    def __init__(self, across02, across13, hourglass):
        self.across02, self.across13, self.hourglass = across02, across13, hourglass

    @classmethod
    def gathered(cls, corner_values, hourglass: bool = True) -> "QuadCorners":
        """From values gathered to the corners (``hourglass`` False: the diagonals only)."""
        v0, v1, v2, v3 = corner_values
        across02, across13 = [a - c for a, c in zip(v0, v2)], [b - d for b, d in zip(v1, v3)]
        if not hourglass:
            return cls(across02, across13, None)
        sums = []
        for a, b, c, d in zip(v0, v1, v2, v3):
            total = a + c
            total -= b
            total -= d
            sums.append(total)
        return cls(across02, across13, sums)

class QuadGradient:
    """Area and ∂A/∂x_i of quadrilaterals (corners going round) from their diagonals, with
    p = x_0 − x_2 and r = x_1 − x_3 (a QuadCorners of the positions):
    A = ½ (p_x r_y − p_y r_x),  ∂A/∂x_0 = ½ (r_y, −r_x) = −∂A/∂x_2,
    ∂A/∂x_1 = ½ (−p_y, p_x) = −∂A/∂x_3.  Two corners are independent, so
    Σ_i ∂A/∂x_i·v_i = g_0·(v_0 − v_2) + g_1·(v_1 − v_3) and a cell's four corner forces
    come from two products.  Indexed or iterated it gives the [corner][component] lists
    of the other cell types (corners 2, 3 made on demand)."""

    def __init__(self, corners: QuadCorners):
        self.corners = corners
        (px, py), (rx, ry) = corners.across02, corners.across13
        area = px * ry
        area -= py * rx
        area *= 0.5
        self.area = area
        self.independent = ([0.5 * ry, -0.5 * rx], [-0.5 * py, 0.5 * px])

    def __len__(self) -> int:
        return 4

    def __getitem__(self, corner: int):
        if not 0 <= corner < 4:
            raise IndexError(corner)
        g = self.independent[corner % 2]
        return g if corner < 2 else [-g[0], -g[1]]

    def __iter__(self):
        return (self[i] for i in range(4))


@dataclass(frozen=True)
class CellType:
    name: str
    dimension: int
    nodes_per_cell: int

    def volume_and_gradient(self, corner_positions):
        """[corner][component] positions → (V_K (n_cells,), ∂V_K/∂x_i [corner][component])."""
        if self.name == "interval":
            return _interval_geometry(corner_positions)
        if self.name == "quadrilateral":
            gradient = QuadGradient(QuadCorners.gathered(corner_positions))
            return gradient.area, gradient
        return _polygon_geometry(corner_positions)

    def viscosity_length(self, volume):
        """The length L of the artificial viscosity's velocity jump Δu = L ∇·u (1D: the cell
        length; 2D: √A, the choice explained in ale_xfem.lagrange.kernels.velocity_jump);
        the time step's viscous signal speed is scaled by it over the CFL length."""
        return volume if self.dimension == 1 else np.sqrt(volume)

CELL_TYPES = {
    "interval": CellType("interval", 1, 2),
    "triangle": CellType("triangle", 2, 3),
    "quadrilateral": CellType("quadrilateral", 2, 4),
}


@dataclass
class MeshArrays:
    """Node and cell arrays of a mesh, read from DOLFINx (see module docstring)."""

    cell_type: CellType
    node_position: np.ndarray  # (dim, n_nodes)
    cell_nodes: np.ndarray  # (n_cells, nodes_per_cell), int
    dolfinx_mesh: object = None
    grid: tuple | None = None  # (nx, ny): numbered as a structured grid (Corners)
    dolfinx_node: np.ndarray | None = None  # DOLFINx geometry node of each node (None: the same)
    dolfinx_cell: np.ndarray | None = None  # DOLFINx cell of each cell (None: the same)

    def __post_init__(self):
        self.corners = Corners(self.cell_nodes, self.node_position.shape[1], self.grid)
        # what the compiled loops take (ale_xfem.model.cell_kernels): unsigned, so that a
        # node read through it needs no guard against a negative index (numba wraps signed
        # ones as Python does), 32 bits, half the bytes of int64 (BENCHMARKS.md, "2D
        # explicit loop")
        if self.n_nodes > np.iinfo(np.uint32).max:
            raise ValueError(f"a mesh of {self.n_nodes} nodes: at most {np.iinfo(np.uint32).max} are numbered")
        self.compiled_cell_nodes = np.ascontiguousarray(self.cell_nodes, dtype=np.uint32)
        self.corner_runs = cell_kernels.corner_runs(self.compiled_cell_nodes)
        self._node_corners = None

    @property
    def node_corners(self):
        """The cells around each node, for the compiled loops that gather over them
        (:func:`node_corners`; made on first use)."""
        if self._node_corners is None:
            self._node_corners = node_corners(self.compiled_cell_nodes, self.n_nodes)
        return self._node_corners

    @property
    def n_nodes(self) -> int:
        return self.node_position.shape[1]

    @property
    def n_cells(self) -> int:
        return self.cell_nodes.shape[0]

    @property
    def dimension(self) -> int:
        return self.cell_type.dimension

    def cell_geometry(self, node_position=None, cells=None):
        """(volumes, ∂V/∂x_i) of every cell, or of ``cells`` only (their corners gathered);
        quadrilaterals from their diagonals, read for every cell as the explicit loop reads
        them (grid views, no gather): a QuadGradient."""
        x = self.node_position if node_position is None else node_position
        if cells is not None:
            nodes = self.cell_nodes[cells]
            return self.cell_type.volume_and_gradient(
                [[x[d, nodes[:, i]] for d in range(x.shape[0])] for i in range(nodes.shape[1])])
        if self.cell_type.name == "quadrilateral":
            gradient = QuadGradient(self.corners.quad_corners(x, hourglass=False))
            return gradient.area, gradient
        return self.cell_type.volume_and_gradient(self.corners.gather(x))

    def cell_volumes(self, node_position=None):
        """Cell volumes (areas in 2D), from the compiled loop the explicit step uses."""
        x = self.node_position if node_position is None else node_position
        volume = np.empty(self.n_cells)
        shape = np.empty((3, 2, self.n_cells if self.dimension > 1 else 0))
        cell_kernels.cell_geometry(cell_kernels.CELL_TYPE_CODES[self.cell_type.name], np.ascontiguousarray(x,
                                   dtype=float),
                      self.compiled_cell_nodes, self.corner_runs, False, volume, shape, np.zeros(0))
        return volume

    def cell_vertex_positions(self, node_position=None):
        """(n_cells, nodes_per_cell, dim), for output and set-up (not per step)."""
        x = self.node_position if node_position is None else node_position
        return np.moveaxis(x[:, self.cell_nodes], 0, -1)

    def cell_centroids(self, node_position=None):
        return self.cell_vertex_positions(node_position).mean(axis=1)

    def nodes_where(self, predicate) -> np.ndarray:
        """Indices of nodes whose position satisfies predicate(x) (x: (dim, n_nodes))."""
        return np.flatnonzero(predicate(self.node_position))


def distributed_mesh(comm, cell_numbers, topology, x, element, keep: bool = True):
    """A DOLFINx mesh on ``comm`` of the cells this rank hands in — ``topology``: each cell's
    nodes (rows of ``x``, every node's coordinates, the same array on every rank) in
    DOLFINx's order; ``cell_numbers``: their numbers — without ghost cells: each rank keeps
    the cells it hands in (``keep``) or DOLFINx's partitioner shares them out.  Returns (the
    mesh, the number of each of its geometry nodes (its row of ``x``), of each of its
    cells)."""
    import dolfinx

    size, rank = comm.size, comm.rank
    partitioner = None
    if keep:
        def partitioner(partition_comm, parts, cell_types, cell_lists):  # each cell stays
            count = sum(np.asarray(c).size for c in cell_lists) // topology.shape[1]
            destinations = dolfinx.graph.adjacencylist(np.full(count, partition_comm.rank, dtype=np.int32))
            return getattr(destinations, "_cpp_object", destinations)
    # every rank hands a block of the nodes in (their input numbers: their rows of x)
    first, last = x.shape[0] * rank // size, x.shape[0] * (rank + 1) // size
    mesh = dolfinx.mesh.create_mesh(comm, np.asarray(topology, dtype=np.int64), element, x[first:last],
                                    partitioner)
    held = mesh.topology.index_map(mesh.topology.dim).size_local
    handed = np.concatenate(comm.allgather(np.asarray(cell_numbers, dtype=np.int64)))  # in rank order
    cell_number = handed[np.asarray(mesh.topology.original_cell_index[:held], dtype=np.int64)]
    return mesh, np.asarray(mesh.geometry.input_global_indices, dtype=np.int64), cell_number


def from_dolfinx(mesh) -> MeshArrays:
    """Read node and cell arrays from a DOLFINx mesh with P1 geometry."""
    name = mesh.topology.cell_name()
    if name not in CELL_TYPES:
        raise ValueError(f"mesh cell type {name!r}: one of {', '.join(CELL_TYPES)} is supported")
    cell_type = CELL_TYPES[name]
    dim = cell_type.dimension
    position = np.ascontiguousarray(mesh.geometry.x[:, :dim].T, dtype=float)
    cell_nodes = np.array(mesh.geometry.dofmaps[0], dtype=np.int64)
    if cell_nodes.shape[1] != cell_type.nodes_per_cell:
        raise ValueError("only P1 (affine / bilinear) geometry is supported")
    if name == "quadrilateral":
        cell_nodes = cell_nodes[:, [0, 1, 3, 2]]  # tensor-product order → going round
    volume = MeshArrays(cell_type, position, cell_nodes).cell_volumes()
    if dim > 1:  # orient every cell counter-clockwise
        flip = volume < 0
        cell_nodes[flip] = cell_nodes[flip, ::-1]
    arrays = MeshArrays(cell_type, position, cell_nodes, mesh)
    if np.any(arrays.cell_volumes() <= 0):
        raise ValueError("mesh has cells of zero or negative volume")
    return arrays


def _grid_numbering(mesh, extent, cells):
    """Row-by-row numbers of the nodes and cells of a DOLFINx rectangle of quadrilaterals
    (before any skew): (node number of each DOLFINx node, cell number of each DOLFINx
    cell, cell_nodes in the new numbering going round from (i, j))."""
    (x0, x1), (y0, y1) = extent
    nx, ny = cells
    x = mesh.geometry.x
    i = np.rint((x[:, 0] - x0) / (x1 - x0) * nx).astype(np.int64)
    j = np.rint((x[:, 1] - y0) / (y1 - y0) * ny).astype(np.int64)
    node_number = j * (nx + 1) + i
    dofmap = np.asarray(mesh.geometry.dofmaps[0])
    ci, cj = i[dofmap].min(axis=1), j[dofmap].min(axis=1)
    cell_number = cj * nx + ci
    start = (np.arange(ny)[:, None] * (nx + 1) + np.arange(nx)[None, :]).ravel()
    cell_nodes = np.stack([start, start + 1, start + nx + 2, start + nx + 1], axis=1)
    # the same four nodes as DOLFINx's cell, each node and cell numbered once
    if not (np.array_equal(np.sort(node_number), np.arange((nx + 1) * (ny + 1)))
            and np.array_equal(np.sort(cell_number), np.arange(nx * ny))
            and np.array_equal(np.sort(cell_nodes[cell_number], axis=1), np.sort(node_number[dofmap], axis=1))):
        return None
    return node_number, cell_number, cell_nodes


def from_structured_dolfinx(mesh, numbering, cells) -> MeshArrays:
    """A DOLFINx rectangle of quadrilaterals read with the row-by-row numbering of
    _grid_numbering (its nodes may have been moved since, as Saltzman's are)."""
    node_number, cell_number, cell_nodes = numbering
    position = np.empty((2, node_number.size))
    position[:, node_number] = mesh.geometry.x[:, :2].T
    dolfinx_node = np.empty_like(node_number)
    dolfinx_node[node_number] = np.arange(node_number.size)
    dolfinx_cell = np.empty_like(cell_number)
    dolfinx_cell[cell_number] = np.arange(cell_number.size)
    arrays = MeshArrays(CELL_TYPES["quadrilateral"], position, cell_nodes, mesh, tuple(cells),
                        dolfinx_node, dolfinx_cell)
    if np.any(arrays.cell_volumes() <= 0):
        raise ValueError("mesh has cells of zero or negative volume")
    return arrays


def _dolfinx():
    import dolfinx_solver  # noqa: F401  (must come before dolfinx: it loads MPI and PETSc)
    import dolfinx
    from mpi4py import MPI

    return dolfinx, MPI


def interval_mesh(extent, cells: int) -> MeshArrays:
    dolfinx, MPI = _dolfinx()
    mesh = dolfinx.mesh.create_interval(MPI.COMM_SELF, cells, list(extent))
    return from_dolfinx(mesh)


def _rectangle(extent, cells, cell_type):
    """The DOLFINx rectangle mesh.  Triangles: each rectangle cut along both diagonals into
    four ("crossed").  With one diagonal per rectangle, constant-pressure triangles lock (too
    few velocity degrees of freedom for their volume constraints): Noh on 50 × 50 broke down
    at t = 0.48 with "right" diagonals, and the Saltzman plateau ranged 3.4–5.0."""
    dolfinx, MPI = _dolfinx()
    (x0, x1), (y0, y1) = extent
    if cell_type == "triangle":
        return dolfinx.mesh.create_rectangle(MPI.COMM_SELF, [[x0, y0], [x1, y1]], list(cells),
                                             dolfinx.mesh.CellType.triangle,
                                             diagonal=dolfinx.mesh.DiagonalType.crossed)
    return dolfinx.mesh.create_rectangle(MPI.COMM_SELF, [[x0, y0], [x1, y1]], list(cells),
                                         dolfinx.mesh.CellType.quadrilateral)


def rectangle_mesh(extent, cells, cell_type: str = "quadrilateral") -> MeshArrays:
    mesh = _rectangle(extent, cells, cell_type)
    numbering = _grid_numbering(mesh, extent, cells) if cell_type == "quadrilateral" else None
    return from_dolfinx(mesh) if numbering is None else from_structured_dolfinx(mesh, numbering, cells)


def saltzman_mesh(extent, cells, cell_type: str = "quadrilateral") -> MeshArrays:
    """Saltzman's skewed mesh: the rectangle's nodes moved along x by
    (y1 − y) sin(π (x − x0)/(x1 − x0)) (on [0, 1] × [0, 0.1] with 100 × 10 cells, the classic
    x = ξ + (0.1 − η) sin πξ).  The left and right sides stay straight."""
    (x0, x1), (y0, y1) = extent
    mesh = _rectangle(extent, cells, cell_type)
    numbering = _grid_numbering(mesh, extent, cells) if cell_type == "quadrilateral" else None
    x = mesh.geometry.x
    x[:, 0] += (y1 - x[:, 1]) * np.sin(np.pi * (x[:, 0] - x0) / (x1 - x0))
    return from_dolfinx(mesh) if numbering is None else from_structured_dolfinx(mesh, numbering, cells)


def file_mesh(path) -> MeshArrays:
    """A 2D mesh of triangles or quadrilaterals from an XDMF file (its mesh named "mesh",
    as DOLFINx writes it)."""
    dolfinx, MPI = _dolfinx()
    import dolfinx.io

    with dolfinx.io.XDMFFile(MPI.COMM_SELF, str(path), "r") as handle:
        mesh = handle.read_mesh(name="mesh")
    return from_dolfinx(mesh)
