"""Compiled cell geometry: volumes, the shape each cell type's corner forces need, CFL
lengths and the tangle check; and each slot's density, m / V.

The cell types share one convention (``shape``, (3, 2, n_cells)):

- quadrilaterals (corners going round): ``shape[0]`` = x_0 − x_2 = p, ``shape[1]`` =
  x_1 − x_3 = r and ``shape[2]`` = x_0 − x_1 + x_2 − x_3 = h, the hourglass shape.  The
  area is A = ½ (p_x r_y − p_y r_x) and two corners are independent: ∂A/∂x_0 = ½ (r_y, −r_x)
  = −∂A/∂x_2 and ∂A/∂x_1 = ½ (−p_y, p_x) = −∂A/∂x_3, so Σ_i ∂A/∂x_i·v_i = g_0·(v_0 − v_2) +
  g_1·(v_1 − v_3) and a field's corner values enter only through the same three
  combinations (:func:`quad_combinations`);
- triangles: ``shape[i]`` = ∂A/∂x_i = ½ (y_{i+1} − y_{i−1}, x_{i−1} − x_{i+1});
- intervals: no shape (∂V/∂x_0 = −1, ∂V/∂x_1 = +1).

A loop computes a cell's shape once (:func:`cell_shape`), hands its six numbers to every
function that needs them and stores them once (:func:`store_shape`): reading back values
just written made a loop over 10⁵ quadrilaterals three times slower (2.1 ms against 0.64
ms, measured on the geometry alone).

A cell's nodes are read through :func:`node`, with an ``at`` made once per loop by
:func:`node_access`: from ``cell_nodes`` (n_cells, k), or, when every corner's nodes run on
(cell k's corner c is node k + runs[c], as on DOLFINx's interval meshes: :func:`corner_runs`),
without the index array, as contiguous reads the compiler can vectorise.

Each compiled loop is written once, for a cell type and a way of reading nodes given as
arguments, and called from its entry point with both as constants (``if cell_type ==
INTERVAL: loop(INTERVAL, True, …)``): the compiler drops the other branches from the loop
it runs.  A branch left in a loop, even one that never changes inside it, kept the
compiler from vectorising it: the 1D evaluation of a state took 0.70 ms at 10⁵ cells with
the CFL length's branch in it and 0.28 ms without.

Every formula keeps the order of operations of the numpy code it replaced, so results are
the same to the bit (tests/test_regression.py compares the shipped scenes byte by byte).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ale_xfem.eos.kernels import BODY, LOOP

INTERVAL, TRIANGLE, QUADRILATERAL = 0, 1, 2
CELL_TYPE_CODES = {"interval": INTERVAL, "triangle": TRIANGLE, "quadrilateral": QUADRILATERAL}


@numba.njit(**BODY)
def slot_density(mass, volume):  # pragma: no cover (compiled)
    """ρ = m / V of a slot, 0 where V is not positive (an empty slot, or NaN)."""
    return mass / volume if volume > 0.0 else 0.0


@numba.njit(**LOOP)
def slot_densities(mass, volume, density):  # pragma: no cover (compiled)
    """ρ = m / V of each slot of (S, n_cells) arrays, 0 where V is not positive (an empty
    slot, or NaN)."""
    for slot in range(mass.shape[0]):
        for cell in range(mass.shape[1]):
            density[slot, cell] = slot_density(mass[slot, cell], volume[slot, cell])


@numba.njit(**LOOP)
def finite_where_occupied(values, mass):  # pragma: no cover (compiled)
    """Whether every entry of (S, n_cells) ``values`` whose slot holds mass (m > 0; not a
    NaN mass) is finite."""
    finite = True
    for slot in range(mass.shape[0]):
        for cell in range(mass.shape[1]):
            finite &= (not mass[slot, cell] > 0.0) | math.isfinite(values[slot, cell])
    return finite


@numba.njit(**LOOP)
def same_slots(a, b):  # pragma: no cover (compiled)
    """Whether two (S, n_cells) integer arrays of one shape hold the same entries (an
    and-reduction in one pass, without the array of comparisons np.array_equal makes)."""
    same = True
    for slot in range(a.shape[0]):
        for cell in range(a.shape[1]):
            same &= a[slot, cell] == b[slot, cell]
    return same


@numba.njit(**LOOP)
def nan_max(a, b):  # pragma: no cover (compiled)
    """np.maximum of two numbers: NaN if either is (one select, which vectorises; ``|``, not
    ``or``, which branches)."""
    return a if (a >= b) | (a != a) else b


@numba.njit(**LOOP)
def nan_min(a, b):  # pragma: no cover (compiled)
    """np.minimum of two numbers: NaN if either is (one select, which vectorises; ``|``, not
    ``or``, which branches)."""
    return a if (a <= b) | (a != a) else b


@numba.njit(**LOOP)
def node_access(runs, running):  # pragma: no cover (compiled)
    """What :func:`node` reads beside ``cell_nodes``: (``running``, the corners' offsets),
    scalars a loop keeps in registers.  ``running`` is a constant of the loop (True only
    where ``runs`` says the corners run on: :func:`entry_layout`), so that the compiler drops
    the other way of reading nodes from it."""
    return running, (runs[0], runs[1], runs[2], runs[3])


@numba.njit(**LOOP)
def node(cell_nodes, at, k, c):  # pragma: no cover (compiled)
    """Corner c of cell k."""
    running, offsets = at
    if running:
        return k + offsets[c]
    return cell_nodes[k, c]


def corner_runs(cell_nodes) -> np.ndarray:
    """(5,): offsets[0:k] with cell k's corner c = node k + offsets[c] for every cell, and
    1 in the last entry; or zeros when the corners do not run on."""
    n, corners = cell_nodes.shape
    runs = np.zeros(5, dtype=np.int64)
    if n and np.array_equal(cell_nodes, np.arange(n)[:, None] + cell_nodes[0][None, :]):
        runs[:corners], runs[4] = cell_nodes[0], 1
    return runs


@numba.njit(**LOOP)
def quad_corner_values(values, cell_nodes, at, k, d, hourglass):  # pragma: no cover (compiled)
    """Component d of the corner combinations of quadrilateral k: (v_0 − v_2, v_1 − v_3,
    and with ``hourglass`` v_0 + v_2 − v_1 − v_3, else 0)."""
    v0, v1 = values[d, node(cell_nodes, at, k, 0)], values[d, node(cell_nodes, at, k, 1)]
    v2, v3 = values[d, node(cell_nodes, at, k, 2)], values[d, node(cell_nodes, at, k, 3)]
    return v0 - v2, v1 - v3, (v0 + v2 - v1 - v3) if hourglass else 0.0


@numba.njit(**LOOP)
def quad_combinations(values, cell_nodes, runs, hourglass, out):  # pragma: no cover (compiled)
    """The corner combinations of a node field (components, n_nodes) in quadrilaterals:
    out[0] = v_0 − v_2, out[1] = v_1 − v_3 and (``hourglass``) out[2] = v_0 − v_1 + v_2 −
    v_3, each (components, n_cells)."""
    at = node_access(runs, False)
    for d in range(values.shape[0]):
        for k in range(cell_nodes.shape[0]):
            first, second, third = quad_corner_values(values, cell_nodes, at, k, d, hourglass)
            out[0, d, k], out[1, d, k] = first, second
            if hourglass:
                out[2, d, k] = third


@numba.njit(**LOOP)
def cell_shape(cell_type, x, cell_nodes, at, k, hourglass):  # pragma: no cover (compiled)
    """The volume of cell k at positions x and its shape, six numbers kept in registers
    (:func:`store_shape` writes them to ``shape[:, :, k]``): a quadrilateral's (p_x, p_y,
    r_x, r_y, h_x, h_y), h only with ``hourglass`` (else 0); a triangle's ∂A/∂x_i, i = 0, 1,
    2, component by component; an interval's zeros."""
    if cell_type == INTERVAL:
        return x[0, node(cell_nodes, at, k, 1)] - x[0, node(cell_nodes, at, k, 0)], (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    if cell_type == TRIANGLE:
        n0, n1, n2 = node(cell_nodes, at, k, 0), node(cell_nodes, at, k, 1), node(cell_nodes, at, k, 2)
        x0, x1, x2 = x[0, n0], x[0, n1], x[0, n2]
        y0, y1, y2 = x[1, n0], x[1, n1], x[1, n2]
        area = 0.0
        area = area + x0 * y1 - x1 * y0
        area = area + x1 * y2 - x2 * y1
        area = area + x2 * y0 - x0 * y2
        return 0.5 * area, (0.5 * (y1 - y2), 0.5 * (x2 - x1), 0.5 * (y2 - y0), 0.5 * (x0 - x2), 0.5 * (y0 - y1),
                            0.5 * (x1 - x0))
    px, rx, hx = quad_corner_values(x, cell_nodes, at, k, 0, hourglass)
    py, ry, hy = quad_corner_values(x, cell_nodes, at, k, 1, hourglass)
    return (px * ry - py * rx) * 0.5, (px, py, rx, ry, hx, hy)


@numba.njit(**BODY)
def node_area_sums(first, cell, corner, node_index, area, values):  # pragma: no cover (compiled)
    """(Σ A_K, Σ A_K v_K of the two fields ``values`` (2, n_cells)) over the cells K around
    node ``node_index``, in the order of ale_xfem.model.mesh.Corners.scatter (the numpy
    code's, so its bits): corner by corner, each corner's cells in order, each corner's sum
    (from +0) then added.  The node is corner ``corner[j]`` of cell ``cell[j]`` for j in
    ``first[node]:first[node + 1]``, by corner then by cell
    (ale_xfem.model.mesh.node_corners): a loop over the nodes gathers each node's sums and
    writes them once (three sums a pass: each gathered by a pass of its own, the loop took
    1.7 times as long, and held in a scratch array, three times; swept_kernels_2d's
    corner_shares_at is the same gather of five sums)."""
    weight, sum0, sum1 = 0.0, 0.0, 0.0
    j, end = first[node_index], first[node_index + 1]
    while j < end:
        i = corner[j]
        part_weight, part0, part1 = 0.0, 0.0, 0.0
        while j < end and corner[j] == i:
            c = cell[j]
            part_weight += area[c]
            part0 += values[0, c] * area[c]
            part1 += values[1, c] * area[c]
            j += 1
        weight += part_weight
        sum0 += part0
        sum1 += part1
    return weight, sum0, sum1


@numba.njit(**BODY)
def cell_shapes(cell_type, x, cell_nodes, area, shape):  # pragma: no cover (compiled)
    """``area`` (n_cells,) and ``shape`` (6, n_cells) of every triangle or quadrilateral at
    positions ``x``, read through ``cell_nodes`` (:func:`cell_shape`, without the
    hourglass shape)."""
    at = (False, (0, 0, 0, 0))  # the nodes read through cell_nodes (node_access's form)
    for c in range(cell_nodes.shape[0]):
        area[c], (shape[0, c], shape[1, c], shape[2, c], shape[3, c], shape[4, c], shape[5, c]) = cell_shape(
            cell_type, x, cell_nodes, at, c, False)


@numba.njit(**LOOP)
def node_averaged_gradients(cell_type, x, cell_nodes, first, cell, corner, values, gradient, area, shape,
                            nodal):  # pragma: no cover (compiled)
    """``gradient`` (2, n_cells, 2): the gradient in every triangle or quadrilateral of two
    cell fields ``values`` (2, n_cells) averaged to the nodes by area: ∇v_K = (1/A_K) Σ_i
    v̄_i ∂A_K/∂x_i with v̄_i = Σ_K A_K v_K / Σ_K A_K over the cells around node i — what
    ale_xfem.model.mesh.node_averaged_gradient computed over the whole mesh in numpy (kept
    in tests/oracles.py), in its order of operations.  ``first``, ``cell``, ``corner``: the
    cells around each node (ale_xfem.model.mesh.node_corners), whose sums each node gathers
    (:func:`node_area_sums`).  Scratch: ``area`` (n_cells,), ``shape`` (6, n_cells),
    ``nodal`` (n_nodes, 2)."""
    cell_shapes(cell_type, x, cell_nodes, area, shape)
    for node_index in range(nodal.shape[0]):
        weight, sum0, sum1 = node_area_sums(first, cell, corner, node_index, area, values)
        nodal[node_index, 0] = sum0 / weight
        nodal[node_index, 1] = sum1 / weight
    for c in range(cell_nodes.shape[0]):
        s = (shape[0, c], shape[1, c], shape[2, c], shape[3, c], shape[4, c], shape[5, c])
        for f in range(2):
            gradient[f, c, 0], gradient[f, c, 1] = averaged_gradient(cell_type, cell_nodes, c, nodal, f, area[c], s)


@numba.njit(**BODY)
def averaged_gradient(cell_type, cell_nodes, c, nodal, column, area, s):  # pragma: no cover (compiled)
    """∇v_K = (1/A_K) Σ_i v̄_i ∂A_K/∂x_i of cell c (area, shape ``s``: :func:`cell_shape`)
    from its nodes' values ``nodal[:, column]`` (node rows): a quadrilateral's
    g_0 (v̄_0 − v̄_2) + g_1 (v̄_1 − v̄_3)."""
    if cell_type == QUADRILATERAL:
        across02 = nodal[cell_nodes[c, 0], column] - nodal[cell_nodes[c, 2], column]
        across13 = nodal[cell_nodes[c, 1], column] - nodal[cell_nodes[c, 3], column]
        px, py, rx, ry = s[0], s[1], s[2], s[3]
        gx = 0.5 * ry * across02 + -0.5 * py * across13
        gy = -0.5 * rx * across02 + 0.5 * px * across13
    else:
        gx = 0.0
        gy = 0.0
        for i in range(cell_nodes.shape[1]):
            v = nodal[cell_nodes[c, i], column]
            gx += v * s[2 * i]
            gy += v * s[2 * i + 1]
    return gx / area, gy / area


# |Σ_K ∂A_K/∂x_i| over √|P_i| above which a node's patch is open (the mesh's side): zero
# to round-off round an inner node, of the order of a cell's side at the mesh's side
OPEN_PATCH = 1e-8


@numba.njit(**LOOP)
def patch_gradients(x, cell_nodes, around, cells, values, gradient, weight, mean, first, total):  # pragma: no cover (compiled)
    """``gradient`` (m, len(cells), 2): in each of ``cells``, the mean over its nodes of the
    gradient of each cell field ``values`` (m, n_cells) over the node's patch (the cells
    around it), by the divergence theorem on the patch — Youngs' normals as Youngs wrote
    them: g_i = (1/|P_i|) Σ_{K∋i} (v_K − v̄_i)(−2 ∂A_K/∂x_i), where −2 ∂A_K/∂x_i is ∫ n over
    K's edges away from node i (the patch's boundary), v̄_i = Σ A_K v_K / Σ A_K (which makes
    a uniform field's gradient zero on the mesh's boundary too, where the patch is open).
    ``around``: every cell sharing a node with ``cells`` (:func:`ale_xfem.model.mesh.cells_around`);
    corners going round (either way), any number of them.  Scratch: ``weight``, ``mean`` (n_nodes,),
    ``first``, ``total`` (n_nodes, 2).  A node on the mesh's side has an open patch, whose
    gradient sees nothing across the side (the side's pieces take v̄_i): a cell averages
    its nodes with closed patches only, when it has any (a cell at a wall with a straight
    interface through it: its normal turned by up to 22° on quadrilaterals, 37° on
    triangles otherwise, within 5.3° and exact with closed patches only)."""
    k = cell_nodes.shape[1]
    for f in range(values.shape[0]):
        for j in range(around.size):
            for i in range(k):
                node = cell_nodes[around[j], i]
                weight[node] = 0.0
                mean[node] = 0.0
                first[node, 0] = 0.0
                first[node, 1] = 0.0
                total[node, 0] = 0.0
                total[node, 1] = 0.0
        for j in range(around.size):
            c = around[j]
            area = 0.0
            for i in range(k):
                a, b = cell_nodes[c, i], cell_nodes[c, (i + 1) % k]
                area += 0.5 * (x[0, a] * x[1, b] - x[0, b] * x[1, a])
            v = values[f, c]
            turn = 0.5 if area > 0.0 else -0.5  # (a cell going round clockwise: −A)
            area = abs(area)
            for i in range(k):
                node, after, before = cell_nodes[c, i], cell_nodes[c, (i + 1) % k], cell_nodes[c, (i + k - 1) % k]
                # ∂A_K/∂x_i = ½ (y_{i+1} − y_{i−1}, x_{i−1} − x_{i+1}) (counter-clockwise)
                dx = turn * (x[1, after] - x[1, before])
                dy = turn * (x[0, before] - x[0, after])
                weight[node] += area
                mean[node] += area * v
                first[node, 0] += v * dx
                first[node, 1] += v * dy
                total[node, 0] += dx
                total[node, 1] += dy
        for j in range(cells.size):
            gx, gy, closed = 0.0, 0.0, 0
            ox, oy = 0.0, 0.0
            for i in range(k):
                node = cell_nodes[cells[j], i]
                average = mean[node] / weight[node]
                nx = -2.0 * (first[node, 0] - average * total[node, 0]) / weight[node]
                ny = -2.0 * (first[node, 1] - average * total[node, 1]) / weight[node]
                # a patch closed round its node: Σ ∂A_K/∂x_i = 0 (on the mesh's side it is
                # open, its gradient blind across the side)
                if abs(total[node, 0]) + abs(total[node, 1]) <= OPEN_PATCH * np.sqrt(weight[node]):
                    gx += nx
                    gy += ny
                    closed += 1
                else:
                    ox += nx
                    oy += ny
            if closed > 0:
                gradient[f, j, 0] = gx / closed
                gradient[f, j, 1] = gy / closed
            else:
                gradient[f, j, 0] = ox / k
                gradient[f, j, 1] = oy / k


@numba.njit(**LOOP)
def store_shape(cell_type, s, hourglass, shape, k):  # pragma: no cover (compiled)
    """A cell's shape (:func:`cell_shape`) into shape[:, :, k] (quadrilaterals' h only with
    ``hourglass``; intervals have none)."""
    if cell_type == INTERVAL:
        return
    shape[0, 0, k], shape[0, 1, k], shape[1, 0, k], shape[1, 1, k] = s[0], s[1], s[2], s[3]
    if cell_type == TRIANGLE or hourglass:
        shape[2, 0, k], shape[2, 1, k] = s[4], s[5]


@numba.njit(**LOOP)
def load_shape(cell_type, shape, k):  # pragma: no cover (compiled)
    """The shape of cell k as :func:`cell_shape` gives it, read from shape[:, :, k]."""
    if cell_type == INTERVAL:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    return shape[0, 0, k], shape[0, 1, k], shape[1, 0, k], shape[1, 1, k], shape[2, 0, k], shape[2, 1, k]


@numba.njit(**LOOP)
def cfl_length(cell_type, x, cell_nodes, at, k, volume, s):  # pragma: no cover (compiled)
    """The sound-crossing length of cell k (shape ``s``): an interval's length; a
    triangle's least altitude 2A / longest edge; a quadrilateral's A over the longer of the
    two lines joining the midpoints of opposite edges, (p + r)/2 and (p − r)/2 (the smaller
    side of a rectangle)."""
    if cell_type == INTERVAL:
        return volume
    if cell_type == TRIANGLE:
        longest = 0.0
        for i in range(3):
            a, b = node(cell_nodes, at, k, i), node(cell_nodes, at, k, (i + 1) % 3)
            dx, dy = x[0, b] - x[0, a], x[1, b] - x[1, a]
            square = dx * dx + dy * dy
            longest = square if i == 0 else nan_max(longest, square)
        return 2.0 * volume / np.sqrt(longest)
    px, py, rx, ry = s[0], s[1], s[2], s[3]
    squares = px * px + py * py + rx * rx + ry * ry
    squares += abs(px * rx + py * ry) * 2.0
    return volume / (np.sqrt(squares) * 0.5)


@numba.njit(**LOOP)
def least_corner_jacobian(volume, s):  # pragma: no cover (compiled)
    """The least over a quadrilateral's four corners (shape ``s``) of det J = (x_{i+1} −
    x_i) × (x_{i−1} − x_i): J_0 + J_2 = J_1 + J_3 = 2A and J_0 − J_2 = h × r, J_1 − J_3 =
    p × h, so the least is A − ½ max(|h × r|, |h × p|), ≤ 0 when a corner has turned inside
    out even while the area stays positive."""
    px, py, rx, ry, hx, hy = s
    across_r = abs(hx * ry - hy * rx)
    across_p = abs(hx * py - hy * px)
    return nan_max(across_r, across_p) * -0.5 + volume


@numba.njit(**LOOP)
def geometry_of_cell(cell_type, x, cell_nodes, at, k, hourglass, volume, least_corner, with_length,
                     length):  # pragma: no cover (compiled)
    """Cell k's volume (written to ``volume``) and shape (returned, :func:`cell_shape`); and
    where asked its least corner det J (quadrilaterals, ``least_corner`` not empty) and its
    CFL length (2D, ``with_length``; an interval's is its volume), written to their arrays.
    Returns (volume, shape)."""
    v, s = cell_shape(cell_type, x, cell_nodes, at, k, hourglass)
    volume[k] = v
    if cell_type == QUADRILATERAL and least_corner.size:
        least_corner[k] = least_corner_jacobian(v, s)
    if cell_type != INTERVAL and with_length:
        length[k] = cfl_length(cell_type, x, cell_nodes, at, k, v, s)
    return v, s


@numba.njit(**BODY)
def geometry_loop(cell_type, running, x, cell_nodes, runs, hourglass, with_length, volume, shape, least_corner,
                  length):  # pragma: no cover (compiled)
    """Every cell's :func:`geometry_of_cell` and its shape stored (:func:`store_shape`): the
    loop of :func:`cell_geometry`, and the geometry loop of the compiled step's
    quadrilaterals of one gas (with their CFL lengths, ``with_length``)."""
    at = node_access(runs, running)
    for k in range(volume.size):
        _, s = geometry_of_cell(cell_type, x, cell_nodes, at, k, hourglass, volume, least_corner, with_length,
                                length)
        store_shape(cell_type, s, hourglass, shape, k)


@numba.njit(**LOOP)
def interval_geometry(x, cell_nodes, runs, hourglass, volume, shape, least_corner):  # pragma: no cover (compiled)
    """:func:`cell_geometry` of intervals."""
    if runs[4] == 1:
        geometry_loop(INTERVAL, True, x, cell_nodes, runs, hourglass, False, volume, shape, least_corner, volume)
    else:
        geometry_loop(INTERVAL, False, x, cell_nodes, runs, hourglass, False, volume, shape, least_corner, volume)


@numba.njit(**LOOP)
def triangle_geometry(x, cell_nodes, runs, hourglass, volume, shape, least_corner):  # pragma: no cover (compiled)
    """:func:`cell_geometry` of triangles."""
    geometry_loop(TRIANGLE, False, x, cell_nodes, runs, hourglass, False, volume, shape, least_corner, volume)


@numba.njit(**LOOP)
def quadrilateral_geometry(x, cell_nodes, runs, hourglass, volume, shape,
                           least_corner):  # pragma: no cover (compiled)
    """:func:`cell_geometry` of quadrilaterals."""
    geometry_loop(QUADRILATERAL, False, x, cell_nodes, runs, hourglass, False, volume, shape, least_corner, volume)


_GEOMETRY = {INTERVAL: interval_geometry, TRIANGLE: triangle_geometry, QUADRILATERAL: quadrilateral_geometry}


def cell_geometry(cell_type, x, cell_nodes, runs, hourglass, volume, shape, least_corner) -> None:
    """Each cell's volume and shape at node positions x (dim, n_nodes); ``hourglass``: also
    the quadrilaterals' hourglass shape and (``least_corner`` not empty) their least corner
    det J.  One compiled loop per cell type, so that a run compiles its own type's only."""
    _GEOMETRY[cell_type](x, cell_nodes, runs, hourglass, volume, shape, least_corner)
