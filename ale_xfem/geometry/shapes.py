"""2D region shapes and exact polygon geometry, vectorised over cells.

A scene's 2D regions are shapes; each cell of the initial mesh takes from a shape the exact
area of their intersection:

- ``box`` [[x0, x1], [y0, y1]] and ``polygon`` [[x, y], ...] (simple, either orientation,
  not necessarily convex): the shape clipped by the cell's edges (Sutherland–Hodgman, exact
  for a convex cell whatever the shape);
- ``half_plane`` {point, normal}: the points x with (x − point)·normal ≤ 0 (the normal points
  out of the region): the cell clipped by one line;
- ``disk`` {center, radius}: the area of a circle and a convex polygon in closed form, edge
  by edge (triangle where the edge is inside the circle, circular sector where outside).

Polygons in batches are (n, m, 2) arrays of vertices in order, padded by repeating the last
vertex (a zero-length edge changes no area); every loop here runs over the few vertices of
a polygon, never over cells.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def polygon_area(vertices: np.ndarray) -> np.ndarray:
    """Signed (shoelace) areas of polygons (n, m, 2): > 0 counter-clockwise."""
    x, y = vertices[..., 0], vertices[..., 1]
    m = vertices.shape[-2]
    total = x[..., m - 1] * y[..., 0] - x[..., 0] * y[..., m - 1]
    for i in range(m - 1):  # a loop over the polygon's vertices, vectorised over polygons
        total += x[..., i] * y[..., i + 1] - x[..., i + 1] * y[..., i]
    total *= 0.5
    return total


def corner_centroid(xs, ys):
    """Areas and centroids of polygons given as lists over their vertices of coordinate
    arrays (xs[i], ys[i]: vertex i of every polygon): (area, cx, cy); a polygon of zero area
    gets the mean of its vertices.  Fanned into triangles from vertex 0, coordinates
    relative to it (signed: exact for any polygon, and no cancellation of large
    coordinates in thin ones)."""
    m = len(xs)
    x0, y0 = xs[0], ys[0]
    dx = [x - x0 for x in xs[1:]]
    dy = [y - y0 for y in ys[1:]]
    area = cx = cy = None  # twice the area, six times the first moments about vertex 0
    for i in range(m - 2):
        cross = dx[i] * dy[i + 1]
        cross -= dx[i + 1] * dy[i]
        tx, ty = dx[i] + dx[i + 1], dy[i] + dy[i + 1]
        tx *= cross
        ty *= cross
        if area is None:
            area, cx, cy = cross, tx, ty
        else:
            area += cross
            cx += tx
            cy += ty
    area *= 0.5
    empty = area == 0.0
    scale = 1.0 / (6.0 * np.where(empty, 1.0, area))
    cx *= scale
    cy *= scale
    if np.any(empty):
        cx[empty] = sum(x[empty] for x in dx) / m
        cy[empty] = sum(y[empty] for y in dy) / m
    cx += x0
    cy += y0
    return area, cx, cy


def polygon_centroid(vertices: np.ndarray) -> np.ndarray:
    """Centroids (n, 2) of polygons (n, m, 2); that of the vertices where the area is 0."""
    m = vertices.shape[-2]
    _, cx, cy = corner_centroid([vertices[..., i, 0] for i in range(m)], [vertices[..., i, 1] for i in range(m)])
    return np.stack([cx, cy], axis=-1)


def clip_half_plane(vertices: np.ndarray, normal: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """The part of each polygon (n, m, 2) where x·normal ≤ offset (normal (n, 2) or (2,),
    offset (n,) or scalar): one Sutherland–Hodgman pass.  Returns (n, m', 2), padded with
    each polygon's last point; an empty result is m' copies of the origin (zero area).

    Points are handled as complex numbers x + iy, a view of the same bytes: a point then
    moves as one element in numpy's fancy indexing, several times faster than a row of two
    floats.  The cut points a + t (b − a), t real, come out as component by component: the
    zero imaginary part of t only adds zeros to each product (checked bit for bit against
    the real-arithmetic version)."""
    n, m, _ = vertices.shape
    vertices = np.ascontiguousarray(vertices, dtype=float)
    normal = np.broadcast_to(np.asarray(normal, dtype=float), (n, 2))
    offset = np.broadcast_to(np.asarray(offset, dtype=float), (n,))
    distance = np.einsum("nmd,nd->nm", vertices, normal) - offset[:, None]
    inside = distance <= 0.0
    following = (np.arange(m) + 1) % m  # the next vertex
    d0, d1 = distance, distance[:, following]
    crossing = inside != inside[:, following]
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(crossing, d0 / (d0 - d1), 0.0)
    z = vertices.view(np.complex128)[..., 0]
    cut = z[:, following] - z
    cut *= t
    cut += z
    # each edge emits its start if inside, then the crossing point if it crosses
    points = np.stack([z, cut], axis=2).reshape(n, 2 * m)
    emitted = np.stack([inside, crossing], axis=2).reshape(n, 2 * m)
    # the emitted points packed to the front of each row, in order (np.nonzero goes row by
    # row), the rest of the row filled with the polygon's last point
    row, column = np.nonzero(emitted)
    count = np.bincount(row, minlength=n)
    width = max(int(count.max(initial=0)), 1)
    start = np.cumsum(count)
    last = start - 1  # where each row's last point is in (row, column)
    start -= count
    result = np.zeros((n, width), dtype=np.complex128)
    some = count > 0
    result[some] = points[row[last[some]], column[last[some]]][:, None]
    result[row, np.arange(row.size) - start[row]] = points[row, column]
    return result.view(np.float64).reshape(n, width, 2)


def clipped_area(vertices: np.ndarray, normal: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """Signed area of clip_half_plane(vertices, normal, offset) without building the
    polygon (Green's theorem, A = ½ ∮ x × dx): each edge contributes ½ P × Q for its
    piece [P, Q] inside the half-plane, and each exit point E, joined along the line to the
    next entry point N (cyclically, as Sutherland–Hodgman joins them), ½ E × N."""
    n, m, _ = vertices.shape
    normal = np.broadcast_to(np.asarray(normal, dtype=float), (n, 2))
    offset = np.broadcast_to(np.asarray(offset, dtype=float), (n,))
    x, y = [vertices[:, i, 0] for i in range(m)], [vertices[:, i, 1] for i in range(m)]
    distance = [x[i] * normal[:, 0] + y[i] * normal[:, 1] - offset for i in range(m)]
    inside = [d <= 0.0 for d in distance]
    area = np.zeros(n)
    exit_x, exit_y, first_x, first_y = (np.zeros(n) for _ in range(4))
    pending, first = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
    for i in range(m):
        j = (i + 1) % m
        crossing = inside[i] != inside[j]
        with np.errstate(invalid="ignore", divide="ignore"):
            t = np.where(crossing, distance[i] / (distance[i] - distance[j]), 0.0)
        cut_x, cut_y = x[i] + t * (x[j] - x[i]), y[i] + t * (y[j] - y[i])
        px, py = np.where(inside[i], x[i], cut_x), np.where(inside[i], y[i], cut_y)
        qx, qy = np.where(inside[j], x[j], cut_x), np.where(inside[j], y[j], cut_y)
        area += np.where(inside[i] | inside[j], px * qy - qx * py, 0.0)
        entering = ~inside[i] & inside[j]
        joined = entering & pending  # the chord from the pending exit to this entry
        area += np.where(joined, exit_x * cut_y - cut_x * exit_y, 0.0)
        opening = entering & ~pending & ~first  # an entry before any exit: joined at the end
        first_x, first_y = np.where(opening, cut_x, first_x), np.where(opening, cut_y, first_y)
        first |= opening
        pending &= ~joined
        leaving = inside[i] & ~inside[j]
        exit_x, exit_y = np.where(leaving, cut_x, exit_x), np.where(leaving, cut_y, exit_y)
        pending |= leaving
    area += np.where(pending & first, exit_x * first_y - first_x * exit_y, 0.0)
    return 0.5 * area


def _edge_half_planes(clip: np.ndarray, i: int):
    """The outward unit normal and offset of edge i of convex counter-clockwise polygons
    (a zero-length edge: offset ∞, it clips nothing)."""
    k = clip.shape[1]
    a, b = clip[:, i], clip[:, (i + 1) % k]
    edge = b - a
    outward = np.stack([edge[:, 1], -edge[:, 0]], axis=1)  # right of a ccw edge
    length = np.linalg.norm(outward, axis=1)
    degenerate = length == 0.0
    outward = outward / np.where(degenerate, 1.0, length)[:, None]
    offset = np.einsum("nd,nd->n", outward, a)
    return outward, np.where(degenerate, np.inf, offset)


def clip_convex(subject: np.ndarray, clip: np.ndarray) -> np.ndarray:
    """subject (n, m, 2) polygons (any shape) clipped by convex counter-clockwise polygons
    clip (n, k, 2): their intersection, exact."""
    result = subject
    for i in range(clip.shape[1]):  # one pass per edge of the clipping polygon
        result = clip_half_plane(result, *_edge_half_planes(clip, i))
    return result


def intersection_area(subject: np.ndarray, clip: np.ndarray) -> np.ndarray:
    """polygon_area(clip_convex(subject, clip)), the last pass giving only the area
    (clipped_area)."""
    result = subject
    k = clip.shape[1]
    for i in range(k - 1):
        result = clip_half_plane(result, *_edge_half_planes(clip, i))
    return clipped_area(result, *_edge_half_planes(clip, k - 1))


def _sector(u, v, radius):
    """Signed area of the circular sector from direction u to direction v."""
    cross = u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]
    dot = np.einsum("...d,...d->...", u, v)
    return 0.5 * radius**2 * np.arctan2(cross, dot)


def _triangle(u, v):
    return 0.5 * (u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0])


def disk_polygon_area(vertices: np.ndarray, center, radius: float) -> np.ndarray:
    """Area of the intersection of the disk and each polygon (n, m, 2), counter-clockwise
    (signed: clockwise polygons give minus the area), edge by edge: the signed area of the
    disk ∩ triangle (centre, edge).  Each edge is cut where it crosses the circle: its
    parts inside count as triangles, its parts outside as sectors."""
    a = vertices - np.asarray(center, dtype=float)
    b = np.roll(a, -1, axis=1)
    d = b - a
    A = np.einsum("...d,...d->...", d, d)
    B = 2.0 * np.einsum("...d,...d->...", a, d)
    C = np.einsum("...d,...d->...", a, a) - radius**2
    discriminant = B * B - 4.0 * A * C
    meets = (discriminant > 0.0) & (A > 0.0)
    root = np.sqrt(np.where(meets, discriminant, 0.0))
    safe = np.where(A > 0.0, 2.0 * A, 1.0)
    s1 = np.where(meets, np.clip((-B - root) / safe, 0.0, 1.0), 1.0)
    s2 = np.where(meets, np.clip((-B + root) / safe, 0.0, 1.0), 1.0)
    p1 = a + s1[..., None] * d
    p2 = a + s2[..., None] * d
    area = _sector(a, p1, radius) + _triangle(p1, p2) + _sector(p2, b, radius)
    area = np.where(A > 0.0, area, 0.0)
    return area.sum(axis=-1)


# ----------------------------------------------------------------------------- shapes


@dataclass(frozen=True)
class Box:
    lower: tuple[float, float]
    upper: tuple[float, float]

    def polygon(self) -> np.ndarray:
        (x0, y0), (x1, y1) = self.lower, self.upper
        return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=float)

    def bounds(self):
        return np.array(self.lower), np.array(self.upper)

    def area_in(self, cells: np.ndarray) -> np.ndarray:
        return _polygon_area_in(self.polygon(), self.bounds(), cells)

    def contains(self, points: np.ndarray) -> np.ndarray:
        (x0, y0), (x1, y1) = self.lower, self.upper
        return (points[..., 0] >= x0) & (points[..., 0] <= x1) & (points[..., 1] >= y0) & (points[..., 1] <= y1)


@dataclass(frozen=True)
class HalfPlane:
    point: tuple[float, float]
    normal: tuple[float, float]  # points out of the region

    def area_in(self, cells: np.ndarray) -> np.ndarray:
        normal = np.asarray(self.normal, dtype=float)
        normal = normal / np.linalg.norm(normal)
        kept = clip_half_plane(cells, normal, float(normal @ np.asarray(self.point, dtype=float)))
        return polygon_area(kept)

    def contains(self, points: np.ndarray) -> np.ndarray:
        return (points - np.asarray(self.point)) @ np.asarray(self.normal, dtype=float) <= 0.0


@dataclass(frozen=True)
class Disk:
    center: tuple[float, float]
    radius: float

    def area_in(self, cells: np.ndarray) -> np.ndarray:
        area = np.zeros(cells.shape[0])
        near = _near(cells, np.asarray(self.center) - self.radius, np.asarray(self.center) + self.radius)
        area[near] = disk_polygon_area(cells[near], self.center, self.radius)
        return area

    def contains(self, points: np.ndarray) -> np.ndarray:
        return np.linalg.norm(points - np.asarray(self.center), axis=-1) <= self.radius


@dataclass(frozen=True)
class Polygon:
    vertices: tuple[tuple[float, float], ...]

    def polygon(self) -> np.ndarray:
        vertices = np.array(self.vertices, dtype=float)
        return vertices if polygon_area(vertices[None])[0] > 0 else vertices[::-1].copy()

    def bounds(self):
        vertices = np.array(self.vertices, dtype=float)
        return vertices.min(axis=0), vertices.max(axis=0)

    def area_in(self, cells: np.ndarray) -> np.ndarray:
        return _polygon_area_in(self.polygon(), self.bounds(), cells)

    def contains(self, points: np.ndarray) -> np.ndarray:
        """Even–odd rule."""
        vertices = np.array(self.vertices, dtype=float)
        x, y = points[..., 0], points[..., 1]
        inside = np.zeros(x.shape, dtype=bool)
        for (xa, ya), (xb, yb) in zip(vertices, np.roll(vertices, -1, axis=0)):
            crosses = (ya > y) != (yb > y)
            with np.errstate(divide="ignore", invalid="ignore"):
                x_cross = xa + (y - ya) * (xb - xa) / (yb - ya)
            inside ^= crosses & (x < x_cross)
        return inside


def _near(cells, lower, upper):
    """Cells whose bounding box meets [lower, upper]."""
    return np.all(cells.max(axis=1) >= lower, axis=1) & np.all(cells.min(axis=1) <= upper, axis=1)


def _polygon_area_in(polygon, bounds, cells):
    area = np.zeros(cells.shape[0])
    near = _near(cells, *bounds)
    if np.any(near):
        subject = np.broadcast_to(polygon, (int(near.sum()),) + polygon.shape)
        area[near] = intersection_area(np.ascontiguousarray(subject), cells[near])
    return area


SHAPES = ("box", "half_plane", "disk", "polygon")
