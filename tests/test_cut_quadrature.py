"""Cut-cell integrals in forms compiled once (forms/cut_quadrature.py), against exact
polygon and segment moments (Green's theorem with Gauss–Legendre, below: the oracle)."""

import numpy as np
import pytest

import dolfinx_solver  # noqa: F401
import dolfinx
import ufl
from mpi4py import MPI

from ale_xfem.geometry.shapes import clip_half_plane, polygon_area
from forms.cut_quadrature import CutQuadrature, bilinear_map


def monomials(degree: int) -> list[tuple[int, int]]:
    """The exponents (a, b) of the monomials x^a y^b of total degree ≤ ``degree``, in the
    order :func:`polygon_moments` returns their integrals."""
    return [(total - b, b) for total in range(degree + 1) for b in range(total + 1)]


def polygon_moments(vertices: np.ndarray, degree: int) -> np.ndarray:
    """Exact ∫_P x^a y^b dA over polygons (n, m, 2) (any orientation: the integral over the
    region, padding vertices allowed) for the monomials of :func:`monomials`: (n, k).  By
    Green's theorem ∫_P x^a y^b dA = 1/(a+1) ∮ x^{a+1} y^b dy, each edge's integrand a
    polynomial of degree ≤ degree + 1 in its parameter, integrated exactly by Gauss–Legendre."""
    t, w = np.polynomial.legendre.leggauss(degree // 2 + 2)
    t, w = 0.5 * (t + 1.0), 0.5 * w
    start = np.asarray(vertices, dtype=float)
    step = np.roll(start, -1, axis=1) - start
    x = start[..., 0, None] + t * step[..., 0, None]  # (n, m, points)
    y = start[..., 1, None] + t * step[..., 1, None]
    dy = step[..., 1, None] * w
    sign = np.sign(polygon_area(start))
    moments = [sign * np.sum(x ** (a + 1) * y**b * dy, axis=(1, 2)) / (a + 1) for a, b in monomials(degree)]
    return np.stack(moments, axis=-1)


def segment_moments(start: np.ndarray, end: np.ndarray, degree: int) -> np.ndarray:
    """Exact ∫_S x^a y^b ds over segments S = [start, end] ((n, 2) each) for the monomials
    of :func:`monomials`: (n, k), by Gauss–Legendre along each segment."""
    t, w = np.polynomial.legendre.leggauss(degree // 2 + 1)
    t, w = 0.5 * (t + 1.0), 0.5 * w
    start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    length = np.linalg.norm(end - start, axis=-1)
    x = start[:, 0, None] + t * (end - start)[:, 0, None]
    y = start[:, 1, None] + t * (end - start)[:, 1, None]
    return np.stack([np.sum(x**a * y**b * w, axis=1) * length for a, b in monomials(degree)], axis=-1)


def test_polygon_moments_are_exact():
    """∫ x^a y^b over the unit square is 1/((a+1)(b+1)); over the triangle (0,0), (1,0),
    (0,1) it is a! b! / (a + b + 2)!; either orientation, padded vertices allowed."""
    from math import factorial

    square = np.array([[[0, 0], [1, 0], [1, 1], [0, 1], [0, 1]]], dtype=float)
    triangle = np.array([[[0, 0], [0, 1], [1, 0]]], dtype=float)  # clockwise
    got_square, got_triangle = polygon_moments(square, 4)[0], polygon_moments(triangle, 4)[0]
    for k, (a, b) in enumerate(monomials(4)):
        assert np.isclose(got_square[k], 1 / ((a + 1) * (b + 1)), rtol=1e-14)
        assert np.isclose(got_triangle[k], factorial(a) * factorial(b) / factorial(a + b + 2), rtol=1e-14)


def _cut_measure(mesh, normal, offset, cut=None):
    """The CutQuadrature of {x·normal ≤ offset} on ``mesh`` (``cut`` refilled, if given),
    and the region's polygon in the unit square."""
    cut = cut or CutQuadrature(mesh)
    nodes = cut._nodes
    corners = mesh.geometry.x[nodes, :2]  # (cells, 3, 2)
    distance = corners @ normal - offset
    full = np.flatnonzero((distance <= 0).all(axis=1))
    cells = np.flatnonzero((distance < 0).any(axis=1) & (distance > 0).any(axis=1))
    parts = clip_half_plane(corners[cells], normal, offset)
    cut.set_part_polygons(full, cells, parts)
    square = np.array([[[0, 0], [1, 0], [1, 1], [0, 1]]], dtype=float)
    return cut, clip_half_plane(square, normal, offset), cells


@pytest.mark.parametrize("size", [8, 64])
def test_cut_integrals_of_p1_products_are_exact_and_refit_without_compiling(size):
    """∫_part φ_i and ∫_part φ_i φ_j, assembled with one compiled form, give the part's
    exact ∫ 1, x, x y (on 64² too: the weights are fitted in each cell's reference
    coordinates, where the Vandermonde does not degrade with the cell's size).  Moving the
    part refills the weights; the same form objects assemble the new integrals."""
    mesh = dolfinx.mesh.create_unit_square(MPI.COMM_WORLD, size, size, dolfinx.mesh.CellType.triangle)
    V = dolfinx.fem.functionspace(mesh, ("Lagrange", 1))
    x, y = dolfinx.fem.Function(V), dolfinx.fem.Function(V)
    x.interpolate(lambda p: p[0])
    y.interpolate(lambda p: p[1])
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    cut = forms = None
    for angle, offset in ((0.4, 0.55), (2.0, -0.1)):
        normal = np.array([np.cos(angle), np.sin(angle)])
        cut, region, cells = _cut_measure(mesh, normal, offset, cut)  # the second time: refilled
        if forms is None:
            forms = (dolfinx.fem.form(cut.ratio * v * cut.measure), dolfinx.fem.form(cut.ratio * u * v * cut.measure))
        load = dolfinx.fem.assemble_vector(forms[0]).array
        mass = dolfinx.fem.assemble_matrix(forms[1]).to_dense()
        exact = polygon_moments(region, 2)[0]  # 1, x, y, x², xy, y²
        assert cells.size > 0 and np.isclose(load.sum(), exact[0], rtol=1e-12)
        assert np.isclose(load @ x.x.array, exact[1], rtol=1e-12)
        assert np.isclose(x.x.array @ mass @ y.x.array, exact[4], rtol=1e-11)
        assert np.isclose(polygon_area(region)[0], exact[0], rtol=1e-14)
    assert -0.05 < cut.stats["min_weight"] < 0  # measured: −0.024 of the cell's area at worst


def _skewed_quadrilaterals(n):
    """A unit square of n × n quadrilaterals, interior nodes moved so that no cell is a
    parallelogram (non-affine maps)."""
    mesh = dolfinx.mesh.create_unit_square(MPI.COMM_WORLD, n, n, dolfinx.mesh.CellType.quadrilateral)
    x = mesh.geometry.x
    inner = (x[:, 0] > 1e-9) & (x[:, 0] < 1 - 1e-9) & (x[:, 1] > 1e-9) & (x[:, 1] < 1 - 1e-9)
    x[inner, 0] += 0.2 / n * np.sin(7.0 * x[inner, 1] + 3.0 * x[inner, 0])
    x[inner, 1] += 0.2 / n * np.cos(5.0 * x[inner, 0] - 2.0 * x[inner, 1])
    return mesh


def _skewed_and_cut():
    """Skewed 6 × 6 quadrilaterals, their measure, their corners going round, and the line
    x·n = 0.8 at 0.7 rad across them: (mesh, cut, corners, n, offset, cells below it, cells
    it cuts)."""
    mesh = _skewed_quadrilaterals(6)
    cut = CutQuadrature(mesh)
    nodes = np.asarray(mesh.geometry.dofmaps[0])
    going_round = mesh.geometry.x[nodes][:, [0, 1, 3, 2], :2]
    normal, offset = np.array([np.cos(0.7), np.sin(0.7)]), 0.8
    distance = going_round @ normal - offset
    full = np.flatnonzero((distance <= 0).all(axis=1))
    cells = np.flatnonzero((distance < 0).any(axis=1) & (distance > 0).any(axis=1))
    return mesh, cut, going_round, normal, offset, full, cells


def _brute_force(cut, cells, polygons, integrand):
    """Σ over the polygons of ∫ integrand(ξ, J) dx by a degree-30 rule on their fans."""
    import basix

    points, weights = basix.make_quadrature(basix.CellType.triangle, 30)
    total = 0.0
    for j in range(1, polygons.shape[1] - 1):
        a, e1, e2 = polygons[:, 0], polygons[:, j] - polygons[:, 0], polygons[:, j + 1] - polygons[:, 0]
        area = np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
        physical = a[:, None] + points[None, :, :1] * e1[:, None] + points[None, :, 1:] * e2[:, None]
        xi = cut.reference_coordinates(cells, physical)
        total = total + np.einsum("nq...,q,n->n...", integrand(cells, xi), weights, area)
    return total


def test_cut_integrals_on_non_affine_quadrilaterals_are_exact():
    """On skewed quadrilaterals the integrands of Q1 forms are not polynomials in x, y; the
    weights are fitted in each cell's reference coordinates (to ∫ ξ^a η^b over the part's
    preimage), where ∫_part ∇ψ_i dx = ∫ adj(J)ᵀ ∇̂ψ̂_i dξ is a polynomial: assembled with
    one compiled form it matches a degree-30 brute-force integration to 1e-12."""
    mesh, cut, going_round, normal, offset, full, cells = _skewed_and_cut()
    parts = clip_half_plane(going_round[cells], normal, np.full(cells.size, offset))
    cut.set_part_polygons(full, cells, parts)
    V = dolfinx.fem.functionspace(mesh, ("Lagrange", 1))
    v = ufl.TestFunction(V)
    gradient_form = dolfinx.fem.form([cut.ratio * v.dx(0) * cut.measure, cut.ratio * v.dx(1) * cut.measure])
    area_form = dolfinx.fem.form(cut.ratio * cut.measure)
    area = dolfinx.fem.assemble_scalar(area_form)
    exact_area = np.abs(polygon_area(parts)).sum() + np.abs(polygon_area(going_round[full])).sum()
    assert abs(area - exact_area) < 1e-13
    # ∫_part ∂ψ_i/∂x_d over the cut cells, node by node, against brute force
    everything = np.r_[full, cells]
    polygons = np.concatenate([np.pad(going_round[full], ((0, 0), (0, parts.shape[1] - 4), (0, 0)), mode="edge"),
                               parts]) if parts.shape[1] >= 4 else None
    cell_dofs = np.asarray(V.dofmap.list)[everything]  # tensor order, as the geometry

    def shape_gradients(cells_, xi):
        x = cut.cell_vertices(cells_)
        s, t = xi[..., 0], xi[..., 1]
        ref = np.stack([np.stack([-(1 - t), -(1 - s)], -1), np.stack([1 - t, -s], -1),
                        np.stack([-t, 1 - s], -1), np.stack([t, s], -1)], axis=-2)  # (n, q, 4, 2)
        d_s = (x[:, None, 1] - x[:, None, 0]) * (1 - t)[..., None] + (x[:, None, 3] - x[:, None, 2]) * t[..., None]
        d_t = (x[:, None, 2] - x[:, None, 0]) * (1 - s)[..., None] + (x[:, None, 3] - x[:, None, 1]) * s[..., None]
        jacobian = np.stack([d_s, d_t], axis=-1)
        return np.einsum("nqij,nqkj->nqki", np.linalg.inv(jacobian).transpose(0, 1, 3, 2), ref)

    # the inverse map the brute force relies on, checked by mapping back
    probe = polygons.mean(axis=1)[:, None, :]
    back = bilinear_map(cut.cell_vertices(everything), cut.reference_coordinates(everything, probe))[0]
    assert np.abs(back - probe).max() < 1e-14
    reference = _brute_force(cut, everything, polygons, shape_gradients)  # (n, 4, 2)
    for d, form in enumerate(gradient_form):
        assembled = dolfinx.fem.assemble_vector(form).array
        expected = np.zeros_like(assembled)
        np.add.at(expected, cell_dofs.ravel(), reference[..., d].ravel())
        assert np.abs(assembled - expected).max() < 1e-12


def test_interface_integrals_of_p1_products_are_exact():
    """The same measure carries ∫_Γ: on each cut cell the weights reproduce the segment's
    moments, so ∫_Γ φ_i φ_j assembled gives the exact ∫_Γ 1, x and x y of the line
    x·n = s across the unit square."""
    mesh = dolfinx.mesh.create_unit_square(MPI.COMM_WORLD, 16, 16, dolfinx.mesh.CellType.triangle)
    V = dolfinx.fem.functionspace(mesh, ("Lagrange", 1))
    x, y = dolfinx.fem.Function(V), dolfinx.fem.Function(V)
    x.interpolate(lambda p: p[0])
    y.interpolate(lambda p: p[1])
    normal, offset = np.array([np.cos(0.4), np.sin(0.4)]), 0.55
    cut = CutQuadrature(mesh)
    corners = mesh.geometry.x[cut._nodes, :2]
    distance = corners @ normal - offset
    cells = np.flatnonzero((distance < 0).any(axis=1) & (distance > 0).any(axis=1))
    # each cut cell's segment: the line's crossings of the triangle's edges
    ends = []
    for i, j in ((0, 1), (1, 2), (2, 0)):
        di, dj = distance[cells, i], distance[cells, j]
        t = np.where(di * dj < 0, di / np.where(di * dj < 0, di - dj, 1.0), np.nan)
        ends.append(corners[cells, i] + t[:, None] * (corners[cells, j] - corners[cells, i]))
    ends = np.stack(ends, axis=1)  # (n, 3, 2), one edge not crossed (NaN)
    crossed = ~np.isnan(ends[..., 0])
    assert np.all(crossed.sum(axis=1) == 2)
    start, end = (ends[crossed].reshape(-1, 2, 2)[:, k] for k in (0, 1))
    cut.set_interface_segments(cells, start, end)
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    load = dolfinx.fem.assemble_vector(dolfinx.fem.form(cut.ratio * v * cut.measure)).array
    mass = dolfinx.fem.assemble_matrix(dolfinx.fem.form(cut.ratio * u * v * cut.measure)).to_dense()
    # the line across the square: from (s/n_x, 0) to the top edge, y = 1
    a, b = np.array([offset / normal[0], 0.0]), np.array([(offset - normal[1]) / normal[0], 1.0])
    exact = segment_moments(a[None], b[None], 2)[0]  # 1, x, y, x², xy, y²
    assert np.isclose(load.sum(), np.linalg.norm(b - a), rtol=1e-12) and np.isclose(load.sum(), exact[0], rtol=1e-12)
    assert np.isclose(load @ x.x.array, exact[1], rtol=1e-12)
    assert np.isclose(x.x.array @ mass @ y.x.array, exact[4], rtol=1e-11)


def test_interface_integrals_on_non_affine_quadrilaterals_are_exact():
    """∫_Γ ψ_i ψ_j (the Nitsche penalty's integrand, of degree 2 in each reference
    coordinate) over the segments of a line across skewed quadrilaterals, assembled with
    the interface weights, against 40 Gauss–Legendre points along each segment."""
    mesh, cut, going_round, normal, offset, _, cells = _skewed_and_cut()
    # the segment: where the cell's edges cross the line
    start, end = np.empty((cells.size, 2)), np.empty((cells.size, 2))
    for row, cell in enumerate(cells):
        crossings = []
        for k in range(4):
            a, b = going_round[cell, k], going_round[cell, (k + 1) % 4]
            da, db = a @ normal - offset, b @ normal - offset
            if (da < 0) != (db < 0):
                crossings.append(a + da / (da - db) * (b - a))
        start[row], end[row] = crossings[0], crossings[-1]
    cut.set_interface_segments(cells, start, end)
    V = dolfinx.fem.functionspace(mesh, ("Lagrange", 1))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    matrix = dolfinx.fem.assemble_matrix(dolfinx.fem.form(cut.ratio * u * v * cut.measure)).to_dense()
    t, w = np.polynomial.legendre.leggauss(40)
    t, w = 0.5 * (t + 1.0), 0.5 * w
    points = start[:, None] + t[None, :, None] * (end - start)[:, None]
    xi = cut.reference_coordinates(cells, points)
    s_, t_ = xi[..., 0], xi[..., 1]
    psi = np.stack([(1 - s_) * (1 - t_), s_ * (1 - t_), (1 - s_) * t_, s_ * t_], axis=-1)  # tensor order
    length = np.linalg.norm(end - start, axis=1)
    local = np.einsum("nqi,nqj,q,n->nij", psi, psi, w, length)
    expected = np.zeros_like(matrix)
    dofs = np.asarray(V.dofmap.list)[cells]
    for row in range(cells.size):
        expected[np.ix_(dofs[row], dofs[row])] += local[row]
    assert np.abs(matrix - expected).max() < 1e-13


def test_cut_integrals_on_intervals_are_exact():
    """The 1D case of the same measure (the 1D enriched cell): a part [x₀, x_Γ] of each of
    some cells, and the point x_Γ as the interface — ∫_part ψ_i, ∫_part ψ_i′ and ψ_i(x_Γ)
    assembled with one compiled form, against their closed forms."""
    mesh = dolfinx.mesh.create_interval(MPI.COMM_WORLD, 10, [0.0, 2.0])
    cut = CutQuadrature(mesh)
    nodes = np.asarray(mesh.geometry.dofmaps[0])
    x = mesh.geometry.x[nodes, 0]  # (cells, 2) in DOLFINx's order
    cells = np.array([2, 5, 7])
    left, right = x[cells].min(axis=1), x[cells].max(axis=1)
    interface = left + np.array([0.3, 1e-6, 0.999]) * (right - left)
    cut.set_part_polygons(np.zeros(0, dtype=np.int64), cells,
                          np.stack([left, interface], axis=1)[..., None])
    V = dolfinx.fem.functionspace(mesh, ("Lagrange", 1))
    v = ufl.TestFunction(V)
    values = dolfinx.fem.assemble_vector(dolfinx.fem.form(cut.ratio * v * cut.measure)).array
    slopes = dolfinx.fem.assemble_vector(dolfinx.fem.form(cut.ratio * v.dx(0) * cut.measure)).array
    dofs = np.asarray(V.dofmap.list)[cells]
    expected, expected_slopes = np.zeros_like(values), np.zeros_like(values)
    for row, cell in enumerate(cells):
        h, s = right[row] - left[row], interface[row] - left[row]
        for local, dof in enumerate(dofs[row]):
            at_left = np.isclose(x[cell, local], left[row])
            # ψ falls from 1 at its node: ∫_0^s ψ = s − s²/(2h) from the left node, s²/(2h) from the right
            expected[dof] += s - s * s / (2 * h) if at_left else s * s / (2 * h)
            expected_slopes[dof] += -s / h if at_left else s / h
    assert np.abs(values - expected).max() < 1e-15 and np.abs(slopes - expected_slopes).max() < 1e-14
    cut.set_interface_segments(cells, interface[:, None], interface[:, None])
    point = dolfinx.fem.assemble_vector(dolfinx.fem.form(cut.ratio * v * cut.measure)).array
    expected_point = np.zeros_like(point)
    for row, cell in enumerate(cells):
        t = (interface[row] - left[row]) / (right[row] - left[row])
        for local, dof in enumerate(dofs[row]):
            expected_point[dof] += 1 - t if np.isclose(x[cell, local], left[row]) else t
    assert np.abs(point - expected_point).max() < 1e-13


def _bilinear_in_numpy(x, xi):
    """The oracle of the bilinear map (what the compiled kernel replaced)."""
    s, t = xi[..., 0, None], xi[..., 1, None]
    x0, x1, x2, x3 = (x[:, None, i] for i in range(4))
    mapped = x0 * (1 - s) * (1 - t) + x1 * s * (1 - t) + x2 * (1 - s) * t + x3 * s * t
    d_s = (x1 - x0) * (1 - t) + (x3 - x2) * t
    d_t = (x2 - x0) * (1 - s) + (x3 - x1) * s
    return mapped, np.stack([d_s, d_t], axis=-1)


def _newton_in_numpy(x, points):
    """The oracle: the inverse bilinear map's Newton iteration written with numpy arrays (what
    the compiled kernel replaced), every point taking the same steps."""
    from forms.cut_quadrature import NEWTON_STEPS, NEWTON_TOLERANCE

    xi = np.full(points.shape, 0.5)
    for _ in range(NEWTON_STEPS):
        mapped, jacobian = _bilinear_in_numpy(x, xi)
        residual = points - mapped
        a, b = jacobian[..., 0, 0], jacobian[..., 0, 1]
        c, d = jacobian[..., 1, 0], jacobian[..., 1, 1]
        det = a * d - b * c
        step = np.stack([d * residual[..., 0] - b * residual[..., 1],
                         a * residual[..., 1] - c * residual[..., 0]], axis=-1) / det[..., None]
        xi += step
        if np.abs(step).max() < NEWTON_TOLERANCE:
            break
    return xi


def test_the_compiled_bilinear_map_and_its_inverse_are_the_numpy_ones_bit_for_bit():
    """Skewed, stretched and shifted quadrilaterals, points all over them: the compiled
    map and Jacobian, and the compiled Newton iteration, give the numpy ones' values exactly,
    and ξ maps back to the points."""
    from forms.cut_quadrature import bilinear_map, inverse_bilinear_map

    rng = np.random.default_rng(3)
    n, k = 200, 40
    unit = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])  # tensor order
    x = (unit[None] * rng.uniform(0.01, 3.0, (n, 1, 2)) + rng.uniform(-0.2, 0.2, (n, 4, 2)) * 0.01
         + rng.uniform(-50.0, 50.0, (n, 1, 2)))
    x[: n // 2] = unit[None] * 0.3 + rng.uniform(-0.1, 0.1, (n // 2, 4, 2))  # strongly skewed
    reference = rng.uniform(0.0, 1.0, (n, k, 2))
    points, jacobian = bilinear_map(x, reference)
    expected_points, expected_jacobian = _bilinear_in_numpy(x, reference)
    assert np.array_equal(points, expected_points) and np.array_equal(jacobian, expected_jacobian)
    xi = inverse_bilinear_map(x, points)
    assert np.array_equal(xi, _newton_in_numpy(x, points))
    assert np.abs(xi - reference).max() < 1e-10


def _fan_in_numpy(polygons, degree):
    """The oracle's fan quadrature: points (n, q, 2) and physical weights (n, q) over
    polygons (n, m, 2) fanned from their first vertex."""
    import basix

    points, weights = basix.make_quadrature(basix.CellType.triangle, degree)
    first = polygons[:, :1]
    e1, e2 = polygons[:, 1:-1] - first, polygons[:, 2:] - first
    area = np.abs(e1[..., 0] * e2[..., 1] - e1[..., 1] * e2[..., 0])
    physical = (first[:, :, None, :] + points[None, None, :, 0, None] * e1[:, :, None, :]
                + points[None, None, :, 1, None] * e2[:, :, None, :])
    n = polygons.shape[0]
    return physical.reshape(n, -1, 2), (area[..., None] * weights[None, None, :]).reshape(n, -1)


def _part_integrals_in_numpy(vertices, polygons, degree):
    """The oracle of ∫_part ψ_i and ∫_part ∇ψ_i written with numpy arrays (what the compiled
    kernel replaced): P1 by barycentric coordinates, Q1 through the inverse bilinear map."""
    from forms.cut_quadrature import bilinear_map, inverse_bilinear_map

    points, weights = _fan_in_numpy(polygons, degree)
    k = vertices.shape[1]
    if k == 3:
        x = vertices
        e1, e2 = x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]
        det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
        d = points - x[:, None, 0]
        l1 = (d[..., 0] * e2[:, None, 1] - d[..., 1] * e2[:, None, 0]) / det[:, None]
        l2 = (e1[:, None, 0] * d[..., 1] - e1[:, None, 1] * d[..., 0]) / det[:, None]
        psi = np.stack([1.0 - l1 - l2, l1, l2], axis=-1)
        g1 = np.stack([e2[:, 1], -e2[:, 0]], axis=-1) / det[:, None]
        g2 = np.stack([-e1[:, 1], e1[:, 0]], axis=-1) / det[:, None]
        grad = np.stack([-g1 - g2, g1, g2], axis=1)[:, None].repeat(points.shape[1], axis=1)
    else:
        tensor = vertices[:, [0, 1, 3, 2]]
        xi = inverse_bilinear_map(tensor, points)
        s, t = xi[..., 0], xi[..., 1]
        psi = np.stack([(1 - s) * (1 - t), s * (1 - t), s * t, (1 - s) * t], axis=-1)
        reference = np.stack([np.stack([-(1 - t), -(1 - s)], -1), np.stack([1 - t, -s], -1),
                              np.stack([t, s], -1), np.stack([-t, 1 - s], -1)], axis=-2)
        jacobian = bilinear_map(tensor, xi)[1]
        a, b, c, d = jacobian[..., 0, 0], jacobian[..., 0, 1], jacobian[..., 1, 0], jacobian[..., 1, 1]
        grad = np.stack([(d[..., None] * reference[..., 0] - c[..., None] * reference[..., 1]),
                         (a[..., None] * reference[..., 1] - b[..., None] * reference[..., 0])], axis=-1)
        grad /= (a * d - b * c)[..., None, None]
    return np.einsum("nqk,nq->nk", psi, weights), np.einsum("nqkd,nq->nkd", grad, weights)


@pytest.mark.parametrize("cell", ["triangle", "quadrilateral"])
def test_the_compiled_part_integrals_and_moments_agree_with_their_numpy_forms(cell):
    """The cut parts of a disk on a skewed mesh: the compiled ∫_part ψ_i, ∫_part ∇ψ_i
    (cut_cells_2d) and the reference moments of the cut weights (CutQuadrature) agree with
    the numpy forms they replaced to round-off (the sums run in another order)."""
    from ale_xfem.mixed.cut_cells_2d import PART_RULE
    from ale_xfem.studies.interface import InterfaceCase
    from forms.cut_quadrature import POLYGON_RULE, CutQuadrature, inverse_bilinear_map

    case = InterfaceCase(16, "disk", cell=cell)
    cut = case.cut
    k = cut.vertices.shape[1]
    values, gradients = cut.part_integrals()
    scale = np.abs(cut.vertices).max()
    for m, polygon in enumerate((cut.reconstruction.alpha, cut.reconstruction.beta)):
        expected_values, expected_gradients = _part_integrals_in_numpy(cut.vertices, polygon, PART_RULE[k])
        area = np.abs(cut.volume).max()
        assert np.abs(values[m] - expected_values).max() < 1e-14 * area
        assert np.abs(gradients[m] - expected_gradients).max() < 1e-14 * scale
    quadrature = CutQuadrature(case.dolfinx_mesh)
    cells = case.mixed  # the case's mesh numbers its cells as DOLFINx does
    polygons = cut.reconstruction.alpha
    moments = quadrature._polygon_moments(cells, polygons)
    points, weights = _fan_in_numpy(polygons, POLYGON_RULE[cell])
    x = quadrature.cell_vertices(cells)
    if cell == "triangle":
        axes = np.stack([x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]], axis=-1)
        xi = np.einsum("nij,nkj->nki", np.linalg.inv(axes), points - x[:, None, 0])
        det = np.abs(np.linalg.det(axes))[:, None]
    else:
        xi = inverse_bilinear_map(x, points)
        jacobian = _bilinear_in_numpy(x, xi)[1]
        det = np.abs(np.linalg.det(jacobian))
    expected = np.stack([np.sum(xi[..., 0] ** a * xi[..., 1] ** b * weights / det, axis=1)
                         for a, b in quadrature.exponents], axis=1)
    assert np.abs(moments - expected).max() < 1e-13 * np.abs(expected).max()


@pytest.mark.parametrize("cell", ["triangle", "quadrilateral"])
def test_a_partition_fits_the_larger_part_from_the_cell_less_the_smaller(cell):
    """set_partition integrates the smaller part's fan and gives the larger part the
    cell's exact moments less those.  On triangles (the fan rule exact) both parts' weights
    are each part's own fan's (set_part_polygons) to round-off.  On skewed quadrilaterals
    (the fan rule's integrand 1/|det J| is not a polynomial) the moments the weights fit are
    checked against a degree-30 brute force: the partition's are as accurate as the parts'
    own fans (the larger part carries the smaller's quadrature error instead of its own)."""
    if cell == "triangle":
        mesh = dolfinx.mesh.create_unit_square(MPI.COMM_WORLD, 6, 6)
        nodes = np.asarray(mesh.geometry.dofmaps[0])
        corners = mesh.geometry.x[nodes][:, :, :2]
    else:
        mesh = _skewed_quadrilaterals(6)
        nodes = np.asarray(mesh.geometry.dofmaps[0])
        corners = mesh.geometry.x[nodes][:, [0, 1, 3, 2], :2]
    normal, offset = np.array([np.cos(0.7), np.sin(0.7)]), 0.8
    distance = corners @ normal - offset
    cells = np.flatnonzero((distance < 0).any(axis=1) & (distance > 0).any(axis=1))
    parts = (clip_half_plane(corners[cells], normal, offset), clip_half_plane(corners[cells], -normal, -offset))
    assert (polygon_area(parts[0]) < polygon_area(parts[1])).any()
    assert (polygon_area(parts[0]) > polygon_area(parts[1])).any()
    ours = [CutQuadrature(mesh) for _ in range(2)]
    ours[0].set_partition(ours[1], cells, parts)
    own = [CutQuadrature(mesh) for _ in range(2)]
    for quadrature, part in zip(own, parts):
        quadrature.set_part_polygons(np.zeros(0, dtype=np.int64), cells, part)
    dofs = ours[0]._dofs[cells]
    if cell == "triangle":
        for a, b in zip(ours, own):
            assert np.allclose(a.ratio.x.array[dofs], b.ratio.x.array[dofs], rtol=0, atol=1e-13)
        return
    reference = own[0]
    vandermonde = np.stack([np.prod(reference.points ** np.asarray(e), axis=1) for e in reference.exponents])

    def fitted(quadrature):  # the moments Σ_q ω_q ξ_q^a η_q^b its weights reproduce
        return (quadrature.ratio.x.array[dofs] * reference.weights) @ vandermonde.T

    def inverse_jacobian_monomials(cells_, xi):
        x = reference.cell_vertices(cells_)
        s, t = xi[..., 0], xi[..., 1]
        d_s = (x[:, None, 1] - x[:, None, 0]) * (1 - t)[..., None] + (x[:, None, 3] - x[:, None, 2]) * t[..., None]
        d_t = (x[:, None, 2] - x[:, None, 0]) * (1 - s)[..., None] + (x[:, None, 3] - x[:, None, 1]) * s[..., None]
        det = np.abs(d_s[..., 0] * d_t[..., 1] - d_s[..., 1] * d_t[..., 0])
        return np.stack([s ** a * t ** b for a, b in reference.exponents], axis=-1) / det[..., None]

    errors = []
    for m, part in enumerate(parts):
        exact = _brute_force(reference, cells, part, inverse_jacobian_monomials)
        errors.append((np.abs(fitted(ours[m]) - exact).max(), np.abs(fitted(own[m]) - exact).max()))
    # (measured: 2.0e-11 and 2.0e-11 by the partition, 8.4e-11 and 9.8e-12 by each part's fan)
    partition, fans = max(e[0] for e in errors), max(e[1] for e in errors)
    assert partition <= 1e-10 and partition <= fans
