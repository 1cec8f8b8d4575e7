"""Compiled kernels (numba) of polygon geometry, one polygon at a time, for the loops of
the remap and the interface reconstruction: area, centroid, one clipping pass by a
half-plane, the area below a line, and PLIC's cut (the offset of the line that leaves a
given area below it).

Each computes what the vectorised numpy functions of ale_xfem.geometry.shapes compute for a
batch (and PLIC's cut what model/plic.py computed before, kept in tests/oracles.py), with
the same operations in the same order, so the results are the same to the bit (tests
compare them).  ``maximum`` and ``minimum``
are numpy's np.maximum and np.minimum of two numbers.
"""

from __future__ import annotations

import numba
import numpy as np

# cached on disk, IEEE division (x/0 is ±inf or NaN, as numpy gives); it allocates its results
KERNEL = {"cache": True, "error_model": "numpy"}


@numba.njit(**KERNEL)
def maximum(a, b):  # pragma: no cover (compiled)
    """np.maximum of two numbers (NaN if either is; b when they are equal)."""
    return a if (a != a) | (a > b) else b


@numba.njit(**KERNEL)
def minimum(a, b):  # pragma: no cover (compiled)
    """np.minimum of two numbers (NaN if either is; b when they are equal)."""
    return a if (a != a) | (a < b) else b


@numba.njit(**KERNEL)
def fan_centroid(x0, y0, x1, y1, x2, y2, x3, y3, m):  # pragma: no cover (compiled)
    """(area, cx, cy) of a triangle (``m`` = 3: the first three points) or a quadrilateral,
    as ale_xfem.geometry.shapes.corner_centroid computes it for each polygon of a batch:
    fanned from vertex 0, coordinates relative to it; a polygon of zero area gets the mean
    of its vertices.  Straight-line code, so that the loops calling it vectorise."""
    dx1, dy1 = x1 - x0, y1 - y0
    dx2, dy2 = x2 - x0, y2 - y0
    cross = dx1 * dy2
    cross -= dx2 * dy1
    area = cross
    cx = (dx1 + dx2) * cross
    cy = (dy1 + dy2) * cross
    sx, sy = dx1 + dx2, dy1 + dy2
    if m == 4:
        dx3, dy3 = x3 - x0, y3 - y0
        cross = dx2 * dy3
        cross -= dx3 * dy2
        area += cross
        cx += (dx2 + dx3) * cross
        cy += (dy2 + dy3) * cross
        sx += dx3
        sy += dy3
    area *= 0.5
    empty = area == 0.0
    scale = 1.0 / (6.0 * (1.0 if empty else area))
    cx = sx / m if empty else cx * scale
    cy = sy / m if empty else cy * scale
    return area, cx + x0, cy + y0


@numba.njit(**KERNEL)
def shoelace(px, py, m):  # pragma: no cover (compiled)
    """Signed area of the polygon of the first ``m`` points (geometry.shapes.polygon_area's
    order: the closing edge first)."""
    total = px[m - 1] * py[0] - px[0] * py[m - 1]
    for i in range(m - 1):
        total += px[i] * py[i + 1] - px[i + 1] * py[i]
    return total * 0.5


@numba.njit(**KERNEL)
def clip_by_line(px, py, m, nx, ny, offset, out_x, out_y):  # pragma: no cover (compiled)
    """One Sutherland–Hodgman pass (geometry.shapes.clip_half_plane): the part of the
    polygon of the first ``m`` points where x·n ≤ offset into ``out_x``, ``out_y``; returns
    its number of points (0: empty)."""
    count = 0
    for i in range(m):
        j = (i + 1) % m
        d0 = px[i] * nx + py[i] * ny - offset
        d1 = px[j] * nx + py[j] * ny - offset
        inside0, inside1 = d0 <= 0.0, d1 <= 0.0
        if inside0:
            out_x[count], out_y[count] = px[i], py[i]
            count += 1
        if inside0 != inside1:
            t = d0 / (d0 - d1)
            out_x[count] = (px[j] - px[i]) * t + px[i]
            out_y[count] = (py[j] - py[i]) * t + py[i]
            count += 1
    return count


@numba.njit(**KERNEL)
def area_below_line(px, py, m, nx, ny, offset):  # pragma: no cover (compiled)
    """Signed area of the part of a polygon where x·n ≤ offset, by Green's theorem, as
    geometry.shapes.clipped_area computes it."""
    area = 0.0
    exit_x = exit_y = first_x = first_y = 0.0
    pending = first = False
    for i in range(m):
        j = (i + 1) % m
        di = px[i] * nx + py[i] * ny - offset
        dj = px[j] * nx + py[j] * ny - offset
        inside_i, inside_j = di <= 0.0, dj <= 0.0
        t = di / (di - dj) if inside_i != inside_j else 0.0
        cut_x, cut_y = px[i] + t * (px[j] - px[i]), py[i] + t * (py[j] - py[i])
        if inside_i | inside_j:
            qx, qy = (px[j], py[j]) if inside_j else (cut_x, cut_y)
            ax, ay = (px[i], py[i]) if inside_i else (cut_x, cut_y)
            area += ax * qy - qx * ay
        else:
            area += 0.0
        entering = (not inside_i) & inside_j
        joined = entering & pending
        area += exit_x * cut_y - cut_x * exit_y if joined else 0.0
        opening = entering & (not pending) & (not first)
        if opening:
            first_x, first_y = cut_x, cut_y
        first |= opening
        pending &= not joined
        leaving = inside_i & (not inside_j)
        if leaving:
            exit_x, exit_y = cut_x, cut_y
        pending |= leaving
    area += exit_x * first_y - first_x * exit_y if pending & first else 0.0
    return 0.5 * area


@numba.njit(**KERNEL)
def cut_offset(px, py, k, nx, ny, fraction, projection, below):  # pragma: no cover (compiled)
    """PLIC's cut in one cell, the polygon of the first ``k`` points of ``px``, ``py``: the
    offset s with area({x·n ≤ s} ∩ K) = fraction · area(K), n = (``nx``, ``ny``) a unit
    normal (``projection``, ``below``: scratch of k numbers).  Between two consecutive vertex
    projections the cut's length is linear in s, so the area is quadratic: the bracket from
    the areas below the projections, the quadratic through its ends and middle solved in it."""
    for i in range(k):
        projection[i] = px[i] * nx + py[i] * ny
    projection.sort()
    target = fraction * shoelace(px, py, k)
    count = 0
    for i in range(k):
        below[i] = area_below_line(px, py, k, nx, ny, projection[i])
        count += below[i] < target
    j = min(max(count - 1, 0), k - 2)
    lo, hi = projection[j], projection[j + 1]
    a_lo, a_hi = below[j], below[j + 1]
    a_mid = area_below_line(px, py, k, nx, ny, 0.5 * (lo + hi))
    # A(lo + t (hi − lo)) = a_lo + β t + γ t², t ∈ [0, 1]; the root of γt² + βt = rhs in
    # [0, 1] as t = 2 rhs / (β + √(β² + 4γ rhs)), free of cancellation, γ = 0 allowed
    gamma = 2.0 * (a_hi + a_lo - 2.0 * a_mid)
    beta = a_hi - a_lo - gamma
    rhs = maximum(target - a_lo, 0.0)
    denominator = beta + np.sqrt(maximum(beta * beta + 4.0 * gamma * rhs, 0.0))
    t = 2.0 * rhs / denominator if denominator > 0 else 0.0
    return lo + minimum(maximum(t, 0.0), 1.0) * (hi - lo)


@numba.njit(**KERNEL)
def cut_offsets(vertices, normal, fraction):  # pragma: no cover (compiled)
    """PLIC's cut in each cell (ale_xfem.model.plic.cut_offsets; :func:`cut_offset`), for
    cells with corners ``vertices`` (n, k, 2), unit normals (n, 2) and fractions (n,)."""
    n, k = vertices.shape[0], vertices.shape[1]
    offset = np.empty(n)
    px, py = np.empty(k), np.empty(k)
    projection = np.empty(k)
    below = np.empty(k)
    for c in range(n):
        for i in range(k):
            px[i], py[i] = vertices[c, i, 0], vertices[c, i, 1]
        offset[c] = cut_offset(px, py, k, normal[c, 0], normal[c, 1], fraction[c], projection, below)
    return offset


@numba.njit(**KERNEL)
def load_polygon(vertices, p, px, py):  # pragma: no cover (compiled)
    """Polygon p of ``vertices`` (n, m, 2) into the coordinate arrays ``px``, ``py`` (m,)."""
    for i in range(px.size):
        px[i], py[i] = vertices[p, i, 0], vertices[p, i, 1]


@numba.njit(**KERNEL)
def polygon_areas(vertices):  # pragma: no cover (compiled)
    """Signed areas (n,) of polygons (n, m, 2) (:func:`shoelace` each)."""
    n, m = vertices.shape[0], vertices.shape[1]
    area = np.empty(n)
    px, py = np.empty(m), np.empty(m)
    for p in range(n):
        load_polygon(vertices, p, px, py)
        area[p] = shoelace(px, py, m)
    return area


@numba.njit(**KERNEL)
def areas_below_lines(vertices, normal, offset):  # pragma: no cover (compiled)
    """Signed areas (n,) of the parts of polygons (n, m, 2) where x·normal ≤ offset
    (:func:`area_below_line` each; ``normal`` (n, 2), ``offset`` (n,))."""
    n, m = vertices.shape[0], vertices.shape[1]
    area = np.empty(n)
    px, py = np.empty(m), np.empty(m)
    for p in range(n):
        load_polygon(vertices, p, px, py)
        area[p] = area_below_line(px, py, m, normal[p, 0], normal[p, 1], offset[p])
    return area


@numba.njit(**KERNEL)
def clip_polygons(vertices, normal, offset):  # pragma: no cover (compiled)
    """The parts of polygons (n, m, 2) where x·normal ≤ offset (:func:`clip_by_line` each):
    (n, w, 2), w the most points a part has (at least 1), each part padded with its last
    point, an empty part w copies of the origin (zero area)."""
    n, m = vertices.shape[0], vertices.shape[1]
    px, py = np.empty(m), np.empty(m)
    out_x, out_y = np.empty((n, 2 * m)), np.empty((n, 2 * m))
    count = np.empty(n, dtype=np.int64)
    width = 1
    for p in range(n):
        load_polygon(vertices, p, px, py)
        count[p] = clip_by_line(px, py, m, normal[p, 0], normal[p, 1], offset[p], out_x[p], out_y[p])
        width = max(width, count[p])
    result = np.zeros((n, width, 2))
    for p in range(n):
        c = count[p]
        for i in range(width):
            j = min(i, c - 1)
            if c > 0:
                result[p, i, 0], result[p, i, 1] = out_x[p, j], out_y[p, j]
    return result
