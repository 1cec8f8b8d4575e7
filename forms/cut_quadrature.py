"""Integrals over a material's part of cut cells in DOLFINx forms compiled once: fixed
reference quadrature points, per-cell weights fitted to exact moments (the first route of the
cut-cell integrals in docs/design.md).

A quadrature-element Function ``ratio`` holds, at the points of the measure's rule, the
ratio of each cell's fitted weight to the rule's own (w_q |det J|): ``ratio * f * measure``
then integrates f over the part — 1 on a cell the part covers, 0 where it is absent, and on
a cut cell weights fitted to the part's moments (below), exact for the monomials of degree
≤ ``exact_degree``.  Moving the part refills ``ratio``: nothing compiles.

The part is given by its polygon (``set_part_polygons``; on an interval, the
sub-interval) and the interface by its segment (``set_interface_segments``; on an
interval, the point); the weights are fitted in each cell's *reference* coordinates (of
order one on any cell, however small or far from the origin: the fitting stays well
conditioned).  On a non-affine quadrilateral the
integrands of Q1 forms are not polynomials in x, y, but f |det J| is one in ξ, η (∇ψ |det J|
= adj(J)ᵀ ∇̂ψ̂): the weights ω_q with Σ_q ω_q ξ_q^a η_q^b = ∫_preimage ξ^a η^b dξ make
Σ_q ω_q |det J_q| f(x_q) = ∫_part f dx exact for them.  Those moments are
∫_part ξ^a η^b / |det J| dx, integrated over the polygon's fan of triangles (a degree-10
rule on quadrilaterals) with the inverse map (smooth integrand: round-off, measured against a degree-30 brute
force in tests/test_cut_quadrature.py).  A tensor rule of 4 × 4 points fits the monomials
of degree ≤ 3 in each reference coordinate (it cannot fit ξ⁴: the Vandermonde of total
degree 4 has condition 10¹⁸).

With the default rule (degree 4: six points) and exact_degree 2 (six monomials) the
system is square; its weights can be negative (on a straight cut about 1.3 a cut cell,
the least −2.4 % of the cell's area on 8² to 256²; ``stats``): the integrals stay exact,
which is what the forms need; a lumped mass built from such weights would not be positive.
"""

from __future__ import annotations

import math

import basix
import basix.ufl
import dolfinx_solver  # noqa: F401  (before dolfinx: it loads MPI and PETSc)
import dolfinx
import numba
import numpy as np
import ufl


# per cell type: (the rule's degree, the monomials' degree the weights are exact for).
# Triangles: six points, degree 2 (P1 products, the quadratic ∇·(b n) of a cubic bubble).
# Quadrilaterals: sixteen points (4 × 4), degree 3 in each of ξ and η (adj(J)ᵀ∇̂b̂ of the Q2
# bubble, Q1 products on Γ; a tensor rule of 4 × 4 points cannot fit ξ⁴).
# Intervals: three points, degree 2 (the 1D mixed cell as the same forms' case).
RULES = {"interval": (4, 2), "triangle": (4, 2), "quadrilateral": (6, 3)}
# the rule on the triangles of a fanned polygon (reference moments): on a triangle the
# integrand ξ^a η^b / |det J| is a polynomial of degree ≤ 2, integrated exactly; on a
# quadrilateral it is smooth, and degree 10 reproduces a degree-30 brute force to 1e-13
POLYGON_RULE = {"triangle": 2, "quadrilateral": 10}
SEGMENT_POINTS = 12  # Gauss–Legendre points along an interface segment


def _segment_rule():
    """The Gauss–Legendre rule of SEGMENT_POINTS points on [0, 1]: (positions, weights)."""
    t, w = np.polynomial.legendre.leggauss(SEGMENT_POINTS)
    return 0.5 * (t + 1.0), 0.5 * w


SEGMENT_RULE = _segment_rule()  # made once: the same at every step
NEWTON_STEPS = 30  # at most, for the inverse bilinear map
NEWTON_TOLERANCE = 1e-12  # a step below this (ξ is of order one) leaves an error of order its square


class CutQuadrature:
    """The measure ``ratio * measure`` of one material's part of the cells of ``mesh``, or
    of the interface segments in them (:meth:`set_interface`)."""

    def __init__(self, mesh, rule_degree: int | None = None, exact_degree: int | None = None):
        cell_name = mesh.topology.cell_name()
        if cell_name not in RULES:
            raise ValueError(f"cut-cell quadrature on {cell_name} cells: one of {', '.join(RULES)}")
        default_rule, default_exact = RULES[cell_name]
        rule_degree = default_rule if rule_degree is None else rule_degree
        exact_degree = default_exact if exact_degree is None else exact_degree
        self.cell_name = cell_name
        self.mesh, self.exact_degree = mesh, exact_degree
        element = basix.ufl.quadrature_element(cell_name, value_shape=(), scheme="default", degree=rule_degree)
        self.space = dolfinx.fem.functionspace(mesh, element)
        self.ratio = dolfinx.fem.Function(self.space)
        self.measure = ufl.Measure("dx", domain=mesh, metadata={"quadrature_degree": rule_degree,
                                                                "quadrature_scheme": "default"})
        self.points, self.weights = basix.make_quadrature(basix.CellType[cell_name], rule_degree)
        if cell_name == "interval":
            self.exponents = [(a,) for a in range(exact_degree + 1)]
        elif cell_name == "triangle":  # total degree ≤ exact_degree
            self.exponents = [(total - b, b) for total in range(exact_degree + 1) for b in range(total + 1)]
        else:  # degree ≤ exact_degree in each reference coordinate (a tensor rule fits no more)
            self.exponents = [(a, b) for a in range(exact_degree + 1) for b in range(exact_degree + 1)]
        if len(self.exponents) > self.weights.size:
            raise ValueError(f"exact_degree {exact_degree} needs {len(self.exponents)} points; the rule of degree "
                             f"{rule_degree} has {self.weights.size}")
        self.stats = {"min_weight": 1.0, "negative_weights": 0}
        self._fitting = None  # the moments → weights map (the Vandermonde's pseudo-inverse), made once
        self._dofs = np.asarray(self.space.dofmap.list)  # (cells, points)
        self._nodes = np.asarray(mesh.geometry.dofmaps[0])

    # -- from the cut geometry, in each cell's reference coordinates (both cell types) ------

    def set_part_polygons(self, full_cells, cut_cells, polygons) -> None:
        """The part covers ``full_cells`` and, of each of ``cut_cells``, the polygon given
        (n, m, 2) (physical coordinates, padding vertices allowed).  Weights are fitted in
        the cell's reference coordinates: Σ_q ω_q ξ_q^a η_q^b = ∫_preimage ξ^a η^b dξ, so
        that Σ_q ω_q |det J_q| f(x_q) = ∫_part f dx for every f with f |det J| a polynomial
        of degree ≤ exact_degree in ξ — on a quadrilateral the integrands of P1/Q1 forms
        (∇ψ |det J| = adj(J)ᵀ ∇̂ψ̂ is polynomial) — exactly."""
        cut_cells = np.asarray(cut_cells, dtype=np.int64)
        polygons = np.asarray(polygons, dtype=float)
        if self.cell_name == "interval":  # the part [x₀, x₁] (n, 2, 1): ∫ ξ^a dξ exactly
            ends = np.sort(self.reference_coordinates(cut_cells, polygons)[..., 0], axis=1)
            moments = np.stack([(ends[:, 1] ** (a + 1) - ends[:, 0] ** (a + 1)) / (a + 1)
                                for (a,) in self.exponents], axis=1)
        else:
            moments = self._polygon_moments(cut_cells, polygons)
        self._fill(full_cells, cut_cells, moments, with_jacobian=False)

    def set_partition(self, other, cut_cells, polygons) -> None:
        """This measure and ``other``'s (a CutQuadrature of the same mesh) as the two parts of
        each of ``cut_cells`` (2D), ``polygons`` (2, n, m, 2) this part's and the other's,
        which tile the cell: the moments of the smaller part by its fan, the larger's the
        cell's (exact) less them — half the work; the larger part's moments then carry the
        smaller's quadrature error instead of their own (exact on triangles; on skewed
        quadrilaterals 2 × 10⁻¹¹ at most against a degree-30 brute force, where each part's
        own fan gave 8 × 10⁻¹¹: tests/test_cut_quadrature.py)."""
        cut_cells = np.asarray(cut_cells, dtype=np.int64)
        # (each part's polygons padded by repeating their last vertex, to one length)
        length = max(np.shape(polygon)[1] for polygon in polygons)
        polygons = np.stack([np.pad(np.asarray(polygon, dtype=float), ((0, 0), (0, length - np.shape(polygon)[1]),
                                                                        (0, 0)), mode="edge")
                             for polygon in polygons])
        x, y = polygons[..., 0], polygons[..., 1]
        area = 0.5 * np.abs(np.sum(x * np.roll(y, -1, axis=-1) - np.roll(x, -1, axis=-1) * y, axis=-1))
        smaller = area[0] <= area[1]
        moments = self._polygon_moments(cut_cells, np.where(smaller[:, None, None], polygons[0], polygons[1]))
        rest = self.cell_moments()[None, :] - moments
        none = np.zeros(0, dtype=np.int64)
        self._fill(none, cut_cells, np.where(smaller[:, None], moments, rest), with_jacobian=False)
        other._fill(none, cut_cells, np.where(smaller[:, None], rest, moments), with_jacobian=False)

    def cell_moments(self) -> np.ndarray:
        """(e,): ∫ ξ^a η^b over the whole reference cell, exactly — the unit square's
        1/((a+1)(b+1)), the unit triangle's a! b!/(a+b+2)!."""
        if self.cell_name == "quadrilateral":
            return np.array([1.0 / ((a + 1) * (b + 1)) for a, b in self.exponents])
        if self.cell_name == "triangle":
            return np.array([math.factorial(a) * math.factorial(b) / math.factorial(a + b + 2)
                             for a, b in self.exponents])
        raise ValueError(f"cell_moments: triangles and quadrilaterals, not {self.cell_name}")

    def set_interface_segments(self, cut_cells, start, end) -> None:
        """The measure of the interface: the segment [start, end] (n, 2) of each cut cell
        (a line integral carried by the cell's interior points): Σ_q ν_q p(ξ_q) =
        ∫_Γ p(ξ(x)) ds for the reference monomials p of degree ≤ exact_degree."""
        cut_cells = np.asarray(cut_cells, dtype=np.int64)
        if self.cell_name == "interval":  # Γ a point: ∫_Γ p = p(ξ_Γ)
            xi = self.reference_coordinates(cut_cells, np.asarray(start, dtype=float)[:, None, :])[:, 0, 0]
            moments = np.stack([xi ** a for (a,) in self.exponents], axis=1)
            self._fill(np.zeros(0, dtype=np.int64), cut_cells, moments, with_jacobian=True, record=False)
            return
        t, w = SEGMENT_RULE
        start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
        points = start[:, None, :] + t[None, :, None] * (end - start)[:, None, :]  # (n, k, 2)
        length = np.linalg.norm(end - start, axis=1)
        xi = self.reference_coordinates(cut_cells, points)
        moments = np.stack([np.sum(xi[..., 0] ** a * xi[..., 1] ** b * w, axis=1) * length
                            for a, b in self.exponents], axis=1)
        self._fill(np.zeros(0, dtype=np.int64), cut_cells, moments, with_jacobian=True, record=False)

    def cell_vertices(self, cells):
        """(n, k, gdim) the cells' geometry nodes in DOLFINx's order (quadrilaterals: tensor
        order (0,0), (1,0), (0,1), (1,1))."""
        gdim = 1 if self.cell_name == "interval" else 2
        return self.mesh.geometry.x[self._nodes[np.asarray(cells, dtype=np.int64)], :gdim]

    def reference_coordinates(self, cells, points):
        """ξ (n, k, tdim) of physical points (n, k, gdim) in each of ``cells``: the affine
        inverse on intervals and triangles, Newton's method on the bilinear map of quadrilaterals."""
        x = self.cell_vertices(cells)
        if self.cell_name == "interval":
            return (points - x[:, None, 0]) / (x[:, None, 1] - x[:, None, 0])
        if self.cell_name == "triangle":
            axes = np.stack([x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]], axis=-1)  # (n, 2, 2) columns
            return np.einsum("nij,nkj->nki", np.linalg.inv(axes), points - x[:, None, 0])
        return inverse_bilinear_map(x, points)

    def _polygon_moments(self, cells, polygons):
        """∫_preimage ξ^a η^b dξ = ∫_polygon ξ^a η^b / |det J| dx: each polygon fanned into
        triangles from its first vertex, a POLYGON_RULE rule on each (exact on
        triangles, where the integrand is a polynomial; on quadrilaterals the integrand is
        smooth and the rule converges to round-off: measured in tests/test_cut_quadrature.py)."""
        points, weights = basix.make_quadrature(basix.CellType.triangle, POLYGON_RULE[self.cell_name])
        x = np.ascontiguousarray(self.cell_vertices(cells))
        return _fan_moments(x, np.ascontiguousarray(polygons, dtype=float), points, weights,
                            np.asarray(self.exponents, dtype=np.int64), self.cell_name == "quadrilateral",
                            NEWTON_STEPS, NEWTON_TOLERANCE)

    def _fill(self, full_cells, cut_cells, moments, with_jacobian: bool, record: bool = True) -> None:
        """ratio = ω/w (parts) or ν/(w |det J|) (the interface), ω fitted to ``moments``."""
        values = self.ratio.x.array
        values[:] = 0.0
        values[self._dofs[np.asarray(full_cells, dtype=np.int64)]] = 1.0
        if cut_cells.size:
            if self._fitting is None:  # the rule's points and the moments' exponents are fixed
                vandermonde = np.stack([np.prod(self.points ** np.asarray(e), axis=1) for e in self.exponents])
                self._fitting = np.linalg.pinv(vandermonde).T
            fitted = moments @ self._fitting  # (n, points)
            ratio = fitted / self.weights
            if with_jacobian:
                x = self.cell_vertices(cut_cells)
                if self.cell_name == "interval":
                    det = np.abs(x[:, 1] - x[:, 0])
                elif self.cell_name == "triangle":
                    det = _triangle_jacobians(x)[:, None]
                else:
                    det = np.abs(np.linalg.det(bilinear_map(x, np.broadcast_to(self.points, (x.shape[0],) +
                                                                              self.points.shape))[1]))
                ratio = ratio / det
            values[self._dofs[cut_cells]] = ratio
            if record:  # relative to the reference cell's measure
                reference = {"interval": 1.0, "triangle": 0.5, "quadrilateral": 1.0}[self.cell_name]
                self.stats["min_weight"] = float(min(self.stats["min_weight"], (fitted / reference).min()))
                self.stats["negative_weights"] += int(np.sum(fitted < 0))
        self.ratio.x.scatter_forward()


def bilinear_map(x, xi):
    """The bilinear map of quadrilaterals with nodes x (n, 4, 2) in tensor order, at ξ (n,
    k, 2): (positions (n, k, 2), Jacobians (n, k, 2, 2), columns ∂x/∂ξ, ∂x/∂η)."""
    x = np.ascontiguousarray(x, dtype=float)
    xi = np.ascontiguousarray(xi, dtype=float)
    mapped = np.empty(xi.shape)
    jacobian = np.empty(xi.shape + (2,))
    _bilinear(x, xi, mapped, jacobian)
    return mapped, jacobian


@numba.njit(cache=True)
def bilinear_point(x, s, t):  # pragma: no cover (compiled)
    """x(ξ) = x₀(1−s)(1−t) + x₁s(1−t) + x₂(1−s)t + x₃st of the quadrilateral with nodes x
    (4, 2) in tensor order, at (ξ, η) = (s, t): (x, y)."""
    return (x[0, 0] * (1 - s) * (1 - t) + x[1, 0] * s * (1 - t) + x[2, 0] * (1 - s) * t + x[3, 0] * s * t,
            x[0, 1] * (1 - s) * (1 - t) + x[1, 1] * s * (1 - t) + x[2, 1] * (1 - s) * t + x[3, 1] * s * t)


@numba.njit(cache=True)
def bilinear_jacobian(x, s, t):  # pragma: no cover (compiled)
    """J = [[a, b], [c, d]] = [∂x/∂ξ, ∂x/∂η] of the bilinear map of x (4, 2) at (s, t):
    (a, b, c, d) — the one Jacobian every kernel of the cut geometry uses."""
    a = (x[1, 0] - x[0, 0]) * (1 - t) + (x[3, 0] - x[2, 0]) * t
    c = (x[1, 1] - x[0, 1]) * (1 - t) + (x[3, 1] - x[2, 1]) * t
    b = (x[2, 0] - x[0, 0]) * (1 - s) + (x[3, 0] - x[1, 0]) * s
    d = (x[2, 1] - x[0, 1]) * (1 - s) + (x[3, 1] - x[1, 1]) * s
    return a, b, c, d


@numba.njit(cache=True)
def _bilinear(x, xi, mapped, jacobian):  # pragma: no cover (compiled)
    """The bilinear map and its Jacobian at every point ξ (n, k, 2) of the cells x (n, 4, 2)."""
    for i in range(xi.shape[0]):
        for q in range(xi.shape[1]):
            s, t = xi[i, q, 0], xi[i, q, 1]
            mapped[i, q, 0], mapped[i, q, 1] = bilinear_point(x[i], s, t)
            a, b, c, d = bilinear_jacobian(x[i], s, t)
            jacobian[i, q, 0, 0], jacobian[i, q, 0, 1] = a, b
            jacobian[i, q, 1, 0], jacobian[i, q, 1, 1] = c, d


def inverse_bilinear_map(x, points):
    """ξ (n, k, 2) of physical points (n, k, 2) in quadrilaterals with nodes x (n, 4, 2) in
    tensor order, by Newton's method from the centre: every point takes the same number of
    steps, until the largest step is below NEWTON_TOLERANCE (quadratic convergence: the next
    one is round-off), at most NEWTON_STEPS."""
    x = np.ascontiguousarray(x, dtype=float)
    points = np.ascontiguousarray(points, dtype=float)
    xi = np.full(points.shape, 0.5)
    _newton_bilinear(x, points, xi, NEWTON_STEPS, NEWTON_TOLERANCE)
    return xi


@numba.njit(cache=True)
def _newton_bilinear(x, points, xi, steps, tolerance):  # pragma: no cover (compiled)
    """Newton's method on the bilinear map, in place on ξ (n, k, 2), each operation in the
    order of :func:`bilinear_map` (the results are those of its numpy form, bit for bit).
    J = [[a, b], [c, d]] = [∂x/∂ξ, ∂x/∂η] at each point, solved in closed form."""
    n, k = points.shape[0], points.shape[1]
    step = np.empty((n, k, 2))
    for _ in range(steps):
        largest, failed = 0.0, False
        for i in range(n):
            for q in range(k):
                step[i, q, 0], step[i, q, 1] = _newton_step(x[i], points[i, q, 0], points[i, q, 1],
                                                            xi[i, q, 0], xi[i, q, 1])
        for i in range(n):
            for q in range(k):
                for j in range(2):
                    xi[i, q, j] += step[i, q, j]
                    size = abs(step[i, q, j])
                    if size != size:  # NaN (a degenerate cell): numpy's max would be NaN too
                        failed = True
                    elif size > largest:
                        largest = size
        if not failed and largest < tolerance:
            break


@numba.njit(cache=True)
def _newton_step(x, px, py, s, t):  # pragma: no cover (compiled)
    """Newton's step (Δξ, Δη) towards the physical point (px, py) from (ξ, η) = (s, t) in the
    quadrilateral with nodes x (4, 2) in tensor order, each operation in the order of
    :func:`bilinear_map`; J = [[a, b], [c, d]] = [∂x/∂ξ, ∂x/∂η], solved in closed form."""
    mx, my = bilinear_point(x, s, t)
    a, b, c, d = bilinear_jacobian(x, s, t)
    rx, ry = px - mx, py - my
    det = a * d - b * c
    return (d * rx - b * ry) / det, (a * ry - c * rx) / det


@numba.njit(cache=True)
def fan_point(polygon, j, r, q):  # pragma: no cover (compiled)
    """The q-th point (px, py) of the rule ``r`` (q, 2) of the reference triangle on the
    j-th triangle of the fan of ``polygon`` (m, 2) from its first vertex, and that
    triangle's |det| (twice its area; the rule's weights sum to ½)."""
    e1x, e1y = polygon[j, 0] - polygon[0, 0], polygon[j, 1] - polygon[0, 1]
    e2x, e2y = polygon[j + 1, 0] - polygon[0, 0], polygon[j + 1, 1] - polygon[0, 1]
    return (polygon[0, 0] + r[q, 0] * e1x + r[q, 1] * e2x, polygon[0, 1] + r[q, 0] * e1y + r[q, 1] * e2y,
            abs(e1x * e2y - e1y * e2x))


@numba.njit(cache=True)
def reference_point(x, px, py, steps, tolerance):  # pragma: no cover (compiled)
    """(ξ, η) of the physical point (px, py) in the quadrilateral with nodes x (4, 2) in
    tensor order: Newton's method from the centre, until its step is below ``tolerance``
    (at most ``steps``) — the iteration of :func:`inverse_bilinear_map`, point by point."""
    s, t = 0.5, 0.5
    for _ in range(steps):
        ds, dt = _newton_step(x, px, py, s, t)
        s += ds
        t += dt
        if abs(ds) < tolerance and abs(dt) < tolerance:
            break
    return s, t


@numba.njit(cache=True)
def triangle_reference_point(x, px, py):  # pragma: no cover (compiled)
    """(ξ, η) of the physical point (px, py) in the triangle with vertices x (3, 2): the
    affine map's inverse, its barycentric coordinates λ₁, λ₂ — the one every kernel of the
    cut geometry uses."""
    ax, ay = x[1, 0] - x[0, 0], x[1, 1] - x[0, 1]
    bx, by = x[2, 0] - x[0, 0], x[2, 1] - x[0, 1]
    det = ax * by - ay * bx
    dx, dy = px - x[0, 0], py - x[0, 1]
    return (dx * by - dy * bx) / det, (ax * dy - ay * dx) / det


@numba.njit(cache=True)
def _fan_moments(x, polygons, points, weights, exponents, quadrilateral, steps, tolerance):  # pragma: no cover
    """(n, e): ∫_polygon ξ^a η^b / |det J| dx over each polygon (n, m, 2) fanned from its
    first vertex into triangles, the reference triangle's rule ``points``, ``weights`` on
    each; ξ of the cell with nodes x (n, k, 2) (tensor order on quadrilaterals)."""
    n, m, e = polygons.shape[0], polygons.shape[1], exponents.shape[0]
    out = np.zeros((n, e))
    for i in range(n):
        if quadrilateral:
            det = 0.0
        else:  # |det J| of the affine map
            det = ((x[i, 1, 0] - x[i, 0, 0]) * (x[i, 2, 1] - x[i, 0, 1])
                   - (x[i, 1, 1] - x[i, 0, 1]) * (x[i, 2, 0] - x[i, 0, 0]))
        for j in range(1, m - 1):
            for q in range(points.shape[0]):
                px, py, area = fan_point(polygons[i], j, points, q)
                if area == 0.0:
                    break
                if quadrilateral:
                    s, t = reference_point(x[i], px, py, steps, tolerance)
                    a, b, c, d = bilinear_jacobian(x[i], s, t)
                    jacobian = abs(a * d - b * c)
                else:
                    s, t = triangle_reference_point(x[i], px, py)
                    jacobian = abs(det)
                weight = area * weights[q] / jacobian
                for r in range(e):
                    out[i, r] += weight * integer_power(s, exponents[r, 0]) * integer_power(t, exponents[r, 1])
    return out


@numba.njit(cache=True)
def integer_power(x, n):  # pragma: no cover (compiled)
    """x ** n for an integer n ≥ 0, by the squarings numba compiles float ** int to: the
    kernels' plain-Python run (NUMBA_DISABLE_JIT=1) then gives the compiled bits, where
    numpy's float ** int calls the C library's pow."""
    result = 1.0
    while n != 0:
        if n & 1:
            result *= x
        n >>= 1
        x *= x
    return result


def _triangle_jacobians(x):
    """|det J| of triangles with nodes x (n, 3, 2)."""
    e1, e2 = x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]
    return np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
