"""Compiled cell geometry: volumes, the shape each cell type's corner forces need, CFL
lengths and the tangle check.

The cell types share one convention (``shape``, (3, 2, n_cells)):

- quadrilaterals (corners going round): ``shape[0]`` = x_0 − x_2 = p, ``shape[1]`` =
  x_1 − x_3 = r and ``shape[2]`` = x_0 − x_1 + x_2 − x_3 = h, the hourglass shape.  The
  area is A = ½ (p_x r_y − p_y r_x) and two corners are independent: ∂A/∂x_0 = ½ (r_y, −r_x)
  = −∂A/∂x_2 and ∂A/∂x_1 = ½ (−p_y, p_x) = −∂A/∂x_3, so Σ_i ∂A/∂x_i·v_i = g_0·(v_0 − v_2) +
  g_1·(v_1 − v_3) and a field's corner values enter only through the same three
  combinations (:func:`quad_combinations`);
- triangles: ``shape[i]`` = ∂A/∂x_i = ½ (y_{i+1} − y_{i−1}, x_{i−1} − x_{i+1});
- intervals: no shape (∂V/∂x_0 = −1, ∂V/∂x_1 = +1).

A cell's nodes are read through :func:`node`, with an ``at`` made once per loop by
:func:`node_access`: from ``cell_nodes`` (n_cells, k), or, when every corner's nodes run on
(cell k's corner c is node k + runs[c], as on DOLFINx's interval meshes: :func:`corner_runs`),
without the index array.

Each compiled loop is written once, for a cell type given as an argument, and called from
its entry point with the cell type as a constant (``if cell_type == INTERVAL:
loop(INTERVAL, …)``), so that the compiler drops the other cell types' branches from the
loop it runs.

Every formula keeps the order of operations of the numpy code it replaced, so results are
the same to the bit (tests/test_regression.py compares the shipped scenes byte by byte).
"""

from __future__ import annotations

import numba
import numpy as np

from ale_xfem.eos.kernels import BODY, LOOP

INTERVAL, TRIANGLE, QUADRILATERAL = 0, 1, 2
CELL_TYPE_CODES = {"interval": INTERVAL, "triangle": TRIANGLE, "quadrilateral": QUADRILATERAL}


@numba.njit(**LOOP)
def nan_max(a, b):  # pragma: no cover (compiled)
    """np.maximum of two numbers: NaN if either is (one select, which vectorises)."""
    return a if (a >= b or a != a) else b


@numba.njit(**LOOP)
def nan_min(a, b):  # pragma: no cover (compiled)
    """np.minimum of two numbers: NaN if either is (one select, which vectorises)."""
    return a if (a <= b or a != a) else b


@numba.njit(**LOOP)
def node_access(runs):  # pragma: no cover (compiled)
    """What :func:`node` reads beside ``cell_nodes``: (whether the corners run on, their
    offsets), scalars a loop keeps in registers."""
    return runs[4] == 1, (runs[0], runs[1], runs[2], runs[3])


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
def quad_corner_values(values, cell_nodes, at, k, d, out, hourglass):  # pragma: no cover (compiled)
    """Component d of the corner combinations of cell k into out[:, d, k]."""
    v0, v1 = values[d, node(cell_nodes, at, k, 0)], values[d, node(cell_nodes, at, k, 1)]
    v2, v3 = values[d, node(cell_nodes, at, k, 2)], values[d, node(cell_nodes, at, k, 3)]
    out[0, d, k] = v0 - v2
    out[1, d, k] = v1 - v3
    if hourglass:
        out[2, d, k] = v0 + v2 - v1 - v3


@numba.njit(**LOOP)
def quad_combinations(values, cell_nodes, runs, hourglass, out):  # pragma: no cover (compiled)
    """The corner combinations of a node field (components, n_nodes) in quadrilaterals:
    out[0] = v_0 − v_2, out[1] = v_1 − v_3 and (``hourglass``) out[2] = v_0 − v_1 + v_2 −
    v_3, each (components, n_cells)."""
    at = node_access(runs)
    for d in range(values.shape[0]):
        for k in range(cell_nodes.shape[0]):
            quad_corner_values(values, cell_nodes, at, k, d, out, hourglass)


@numba.njit(**LOOP)
def cell_volume(cell_type, x, cell_nodes, at, k, hourglass, shape):  # pragma: no cover (compiled)
    """The volume of cell k; its shape written to shape[:, :, k] (2D)."""
    if cell_type == INTERVAL:
        return x[0, node(cell_nodes, at, k, 1)] - x[0, node(cell_nodes, at, k, 0)]
    if cell_type == TRIANGLE:
        area = 0.0
        for i in range(3):
            a, b = node(cell_nodes, at, k, i), node(cell_nodes, at, k, (i + 1) % 3)
            c = node(cell_nodes, at, k, (i + 2) % 3)  # the corner before a
            area = area + x[0, a] * x[1, b] - x[0, b] * x[1, a]
            shape[i, 0, k] = 0.5 * (x[1, b] - x[1, c])
            shape[i, 1, k] = 0.5 * (x[0, c] - x[0, b])
        return 0.5 * area
    quad_corner_values(x, cell_nodes, at, k, 0, shape, hourglass)
    quad_corner_values(x, cell_nodes, at, k, 1, shape, hourglass)
    return (shape[0, 0, k] * shape[1, 1, k] - shape[0, 1, k] * shape[1, 0, k]) * 0.5


@numba.njit(**LOOP)
def cfl_length(cell_type, x, cell_nodes, at, k, volume, shape):  # pragma: no cover (compiled)
    """The sound-crossing length of cell k: an interval's length; a triangle's least
    altitude 2A / longest edge; a quadrilateral's A over the longer of the two lines joining
    the midpoints of opposite edges, (p + r)/2 and (p − r)/2 (the smaller side of a
    rectangle)."""
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
    px, py, rx, ry = shape[0, 0, k], shape[0, 1, k], shape[1, 0, k], shape[1, 1, k]
    squares = px * px + py * py + rx * rx + ry * ry
    squares += abs(px * rx + py * ry) * 2.0
    return volume / (np.sqrt(squares) * 0.5)


@numba.njit(**LOOP)
def least_corner_jacobian(volume, shape, k):  # pragma: no cover (compiled)
    """The least over quadrilateral k's four corners of det J = (x_{i+1} − x_i) ×
    (x_{i−1} − x_i): J_0 + J_2 = J_1 + J_3 = 2A and J_0 − J_2 = h × r, J_1 − J_3 = p × h, so
    the least is A − ½ max(|h × r|, |h × p|), ≤ 0 when a corner has turned inside out even
    while the area stays positive."""
    px, py, rx, ry = shape[0, 0, k], shape[0, 1, k], shape[1, 0, k], shape[1, 1, k]
    hx, hy = shape[2, 0, k], shape[2, 1, k]
    across_r = abs(hx * ry - hy * rx)
    across_p = abs(hx * py - hy * px)
    return nan_max(across_r, across_p) * -0.5 + volume


@numba.njit(**BODY)
def _cell_geometry(cell_type, x, cell_nodes, runs, hourglass, volume, shape, least_corner):  # pragma: no cover
    at = node_access(runs)
    for k in range(volume.size):
        volume[k] = cell_volume(cell_type, x, cell_nodes, at, k, hourglass, shape)
        if least_corner.size:
            least_corner[k] = least_corner_jacobian(volume[k], shape, k)


@numba.njit(**LOOP)
def cell_geometry(cell_type, x, cell_nodes, runs, hourglass, volume, shape,
                  least_corner):  # pragma: no cover (compiled)
    """Each cell's volume and shape at node positions x (dim, n_nodes); ``hourglass``: also
    the quadrilaterals' hourglass shape and (``least_corner`` not empty) their least corner
    det J."""
    if cell_type == INTERVAL:
        _cell_geometry(INTERVAL, x, cell_nodes, runs, hourglass, volume, shape, least_corner)
    elif cell_type == TRIANGLE:
        _cell_geometry(TRIANGLE, x, cell_nodes, runs, hourglass, volume, shape, least_corner)
    else:
        _cell_geometry(QUADRILATERAL, x, cell_nodes, runs, hourglass, volume, shape, least_corner)
