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
vertex (a zero-length edge changes no area).  Areas, the area below a line and one
clipping pass are compiled loops over the polygons (ale_xfem.geometry.polygon_kernels, which
the remap and PLIC call polygon by polygon); the other loops here run over the few vertices
of a polygon, never over cells.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ale_xfem.geometry import polygon_kernels


def polygon_area(vertices: np.ndarray) -> np.ndarray:
    """Signed (shoelace) areas of polygons (..., m, 2): > 0 counter-clockwise (compiled, one
    polygon at a time: polygon_kernels.shoelace)."""
    vertices = np.asarray(vertices, dtype=float)
    m = vertices.shape[-2]
    flat = np.ascontiguousarray(vertices.reshape(-1, m, 2))
    return polygon_kernels.polygon_areas(flat).reshape(vertices.shape[:-2])


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
    offset (n,) or scalar): one Sutherland–Hodgman pass (compiled, one polygon at a time:
    polygon_kernels.clip_by_line).  Returns (n, m', 2), padded with each polygon's last
    point; an empty result is m' copies of the origin (zero area)."""
    vertices, normal, offset = _batch(vertices, normal, offset)
    return polygon_kernels.clip_polygons(vertices, normal, offset)


def clipped_area(vertices: np.ndarray, normal: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """Signed area of clip_half_plane(vertices, normal, offset) without building the
    polygon (Green's theorem, A = ½ ∮ x × dx): each edge contributes ½ P × Q for its
    piece [P, Q] inside the half-plane, and each exit point E, joined along the line to the
    next entry point N (cyclically, as Sutherland–Hodgman joins them), ½ E × N (compiled,
    one polygon at a time: polygon_kernels.area_below_line)."""
    return polygon_kernels.areas_below_lines(*_batch(vertices, normal, offset))


def _batch(vertices, normal, offset):
    """Polygons (n, m, 2), normals (n, 2) and offsets (n,) as the compiled kernels take them."""
    vertices = np.ascontiguousarray(vertices, dtype=float)
    n = vertices.shape[0]
    normal = np.ascontiguousarray(np.broadcast_to(np.asarray(normal, dtype=float), (n, 2)))
    offset = np.ascontiguousarray(np.broadcast_to(np.asarray(offset, dtype=float), (n,)))
    return vertices, normal, offset


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
