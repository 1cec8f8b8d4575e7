"""PLIC interface reconstruction in 2D cells (piecewise linear interface calculation).

In each mixed cell the interface is a straight segment {x : x·n = s} whose α side
{x·n ≤ s} ∩ K has exactly the cell's volume fraction of α.  The normal n comes from Youngs'
method: the volume fraction's gradient over the patch of cells around each node (the
divergence theorem on the patch, through the same corner gradients ∂A/∂x_i as the Wilkins
forces), averaged over the cell's nodes, n = −∇f/|∇f| pointing out of α
(:func:`ale_xfem.model.mesh.patch_gradient`).  The offset s is found
exactly: the clipped area is quadratic in s between the cell's vertex projections.

With ``[interface] normal = "lvira"`` Youngs' normal is only LVIRA's first guess (Puckett,
1991): the normal is the one whose line, cut to the cell's own fraction and extended over
the cells sharing a node with it, gives their fractions best in least squares — exact for
a straight interface on any mesh, where Youngs' normal is exact on triangles only (on
quadrilaterals it errs by about 1.6° on the slip line's 32² cells).

Everything is vectorised over the mixed cells; the loops run over bisection iterations and
over the corners of a cell.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from ale_xfem.geometry import polygon_kernels
from ale_xfem.geometry.polygon_kernels import KERNEL, area_below_line, cut_offset, maximum, minimum, shoelace
from ale_xfem.model.cell_kernels import CELL_TYPE_CODES, cell_shape, patch_gradients
from ale_xfem.model.mesh import patch_gradient
from ale_xfem.geometry.shapes import clip_half_plane, polygon_centroid


@dataclass
class Reconstruction:
    """The reconstructed interface of some cells (arrays over those cells)."""

    cells: np.ndarray  # (n,) the cells
    normal: np.ndarray  # (n, 2) unit, out of α
    offset: np.ndarray  # (n,) s: α is {x·n ≤ s}
    alpha: np.ndarray  # (n, m, 2) α's polygon (padded)
    beta: np.ndarray  # (n, m, 2) β's polygon
    start: np.ndarray  # (n, 2) the interface segment's ends
    end: np.ndarray

    @property
    def length(self) -> np.ndarray:
        return np.linalg.norm(self.end - self.start, axis=1)

    @property
    def centroid(self) -> np.ndarray:
        return 0.5 * (self.start + self.end)


def youngs_normals(mesh, node_position, fraction, cells=None, around=None) -> np.ndarray:
    """Unit normals pointing out of the material whose volume fraction per cell is
    ``fraction`` — (n_cells, 2), or (len(cells), 2) for the cells given (only the cells
    ``around`` their nodes are read); (0, 0) where the fraction is locally uniform.
    ``fraction`` (m, n_cells): m materials at once, (m, …, 2)."""
    grad = patch_gradient(mesh, node_position, fraction, cells, around)
    size = np.linalg.norm(grad, axis=-1)[..., None]
    return np.divide(-grad, size, out=np.zeros_like(grad), where=size > 0)


def refined_normals(mesh, node_position, fraction, cells, normals, normal: str) -> np.ndarray:
    """``normals`` (n, 2) of the cells ``cells`` out of the material whose fraction is
    ``fraction`` (n_cells,) — as they are for ``normal`` = "youngs", LVIRA's for "lvira"
    (:func:`lvira_normals`, with them as its first guess)."""
    if not normal_method(normal) or len(cells) == 0:
        return normals
    first, cell, _ = mesh.node_corners
    return lvira_normals(np.ascontiguousarray(node_position[:2], dtype=float), mesh.compiled_cell_nodes, first, cell,
                         np.asarray(cells, dtype=np.int64), np.ascontiguousarray(fraction, dtype=float)[None, :],
                         np.zeros(len(cells), dtype=np.int64), np.ascontiguousarray(normals, dtype=float))


def cut_offsets(vertices: np.ndarray, normal: np.ndarray, fraction: np.ndarray) -> np.ndarray:
    """s per cell with area({x·n ≤ s} ∩ K) = fraction · area(K), exactly: between two
    consecutive vertex projections the cut's length is linear in s, so the area is
    quadratic; the area at every vertex projection brackets the target, and the quadratic
    through the bracket's ends and middle is solved in it (compiled, cell by cell:
    ale_xfem.geometry.polygon_kernels.cut_offsets)."""
    return polygon_kernels.cut_offsets(np.ascontiguousarray(vertices, dtype=float),
                                       np.ascontiguousarray(normal, dtype=float),
                                       np.ascontiguousarray(fraction, dtype=float))


def reconstruct(vertices: np.ndarray, normal: np.ndarray, fraction: np.ndarray, cells=None) -> Reconstruction:
    """PLIC in cells with corners ``vertices`` (n, k, 2, counter-clockwise), unit normals
    (n, 2) out of α and α's volume fractions (n,)."""
    offset = cut_offsets(vertices, normal, fraction)
    alpha = clip_half_plane(vertices, normal, offset)
    beta = clip_half_plane(vertices, -normal, -offset)
    # the segment: the points of α's polygon on the line, the extreme two along it
    tangent = np.stack([-normal[:, 1], normal[:, 0]], axis=1)
    on_line = np.abs(np.einsum("nmd,nd->nm", alpha, normal) - offset[:, None]) <= 1e-9 * (
        np.abs(offset)[:, None] + np.linalg.norm(vertices, axis=2).max(axis=1)[:, None])
    along = np.einsum("nmd,nd->nm", alpha, tangent)
    first = np.argmin(np.where(on_line, along, np.inf), axis=1)
    last = np.argmax(np.where(on_line, along, -np.inf), axis=1)
    rows = np.arange(alpha.shape[0])
    start, end = alpha[rows, first], alpha[rows, last]
    return Reconstruction(np.arange(vertices.shape[0]) if cells is None else np.asarray(cells),
                          normal, offset, alpha, beta, start, end)


def part_centroids(reconstruction: Reconstruction) -> tuple[np.ndarray, np.ndarray]:
    """Centroids (n, 2) of α's and β's parts."""
    return polygon_centroid(reconstruction.alpha), polygon_centroid(reconstruction.beta)


def _mixed_cell_cuts(problem, state, layout, mixed, normal: str = "youngs"):
    """What PLIC needs of a state's mixed cells: their corners (n, k, 2), the normals
    (``normal``: "youngs" or "lvira") of their slot-0 (α) material and α's volume fractions
    (compiled: :func:`mixed_cell_cuts`)."""
    layout = problem.layout if layout is None else layout
    mixed = problem.mixed if mixed is None else mixed
    mesh = problem.mesh
    first, cell, _ = mesh.node_corners
    vertices, normals, fraction = mixed_cell_cuts(
        CELL_TYPE_CODES[mesh.cell_type.name], np.ascontiguousarray(state.node_position, dtype=float),
        mesh.compiled_cell_nodes, first, cell, np.asarray(mixed.cells, dtype=np.int64), layout.cell_material,
        state.material_volume, len(problem.materials), normal_method(normal))
    return mixed.cells, vertices, normals, fraction


@numba.njit(**KERNEL)
def mixed_cell_cuts(cell_type, x, cell_nodes, first, cell, cells, cell_material, material_volume,
                    n_materials, refine=False):  # pragma: no cover (compiled)
    """(corners (n, k, 2), Youngs' unit normals out of α (n, 2) — ``refine``: LVIRA's,
    :func:`lvira_normals` — α's volume fractions (n,))
    of the mixed cells ``cells``, α each one's slot-0 material: the materials' fractions in
    every cell sharing a node with them (``first``, ``cell``: ale_xfem.model.mesh.node_corners),
    each α material's patch gradients (cell_kernels.patch_gradients), normalised — what
    numpy computed here over those cells (kept in tests/oracles.py: mixed_cell_cuts), in its
    order of operations (a cell's area by cell_kernels.cell_shape, as the explicit step
    takes it: the same bits as mesh.cell_geometry's)."""
    n_cells, k = cell_nodes.shape
    n = cells.size
    # every cell sharing a node with the mixed cells, in increasing order
    seen = np.zeros(n_cells, dtype=np.bool_)
    reached = np.empty(n * k * 8 + 1, dtype=np.int64)
    count = 0
    for j in range(n):
        for i in range(k):
            node = cell_nodes[cells[j], i]
            for e in range(first[node], first[node + 1]):
                c = cell[e]
                if not seen[c]:
                    seen[c] = True
                    if count == reached.size:
                        grown = np.empty(2 * reached.size, dtype=np.int64)
                        grown[:count] = reached[:count]
                        reached = grown
                    reached[count] = c
                    count += 1
    around = np.sort(reached[:count])
    # the α materials present (np.unique's order) and each one's fractions there
    alpha_of = np.full(n_materials, -1, dtype=np.int64)
    for j in range(n):
        alpha_of[cell_material[0, cells[j]]] = 0
    m_count = 0
    for m in range(n_materials):
        if alpha_of[m] == 0:
            alpha_of[m] = m_count
            m_count += 1
    fractions = np.zeros((m_count, n_cells))
    at = (False, (0, 0, 0, 0))  # the nodes read through cell_nodes (cell_kernels.node_access's form)
    for j in range(around.size):
        c = around[j]
        area, _ = cell_shape(cell_type, x, cell_nodes, at, c, False)
        for slot in range(cell_material.shape[0]):
            m = cell_material[slot, c]
            if m >= 0 and alpha_of[m] >= 0:
                fractions[alpha_of[m], c] += material_volume[slot, c] / area
    n_nodes = x.shape[1]
    gradient = np.empty((m_count, n, 2))
    patch_gradients(x, cell_nodes, around, cells, fractions, gradient, np.empty(n_nodes), np.empty(n_nodes),
                    np.empty((n_nodes, 2)), np.empty((n_nodes, 2)))
    vertices = np.empty((n, k, 2))
    normals = np.empty((n, 2))
    for j in range(n):
        f = alpha_of[cell_material[0, cells[j]]]
        gx, gy = gradient[f, j, 0], gradient[f, j, 1]
        size = np.sqrt(gx * gx + gy * gy)
        if size > 0:
            normals[j, 0], normals[j, 1] = -gx / size, -gy / size
        else:
            normals[j, 0], normals[j, 1] = 0.0, 0.0
        for i in range(k):
            vertices[j, i, 0], vertices[j, i, 1] = x[0, cell_nodes[cells[j], i]], x[1, cell_nodes[cells[j], i]]
    area = polygon_kernels.polygon_areas(vertices)
    fraction = np.empty(n)
    for j in range(n):
        fraction[j] = material_volume[0, cells[j]] / area[j]
    if refine:
        which = np.empty(n, dtype=np.int64)
        for j in range(n):
            which[j] = alpha_of[cell_material[0, cells[j]]]
        normals = lvira_normals(x, cell_nodes, first, cell, cells, fractions, which, normals)
    return vertices, normals, fraction


# LVIRA's search: Gauss–Newton steps on the normal's angle (its derivative by a difference of
# LVIRA_DIFFERENCE rad), each at most LVIRA_MAX_STEP rad and halved (4 times at most) until
# the misfit falls, within LVIRA_HALF_WIDTH rad of Youngs' (14°: a larger error of Youngs'
# keeps the end of the range); done when the next step is below LVIRA_TOLERANCE rad, none
# of its halves lowers the misfit, or after LVIRA_STEPS steps
LVIRA_HALF_WIDTH = 0.25
LVIRA_MAX_STEP = 0.1
LVIRA_DIFFERENCE = 1e-7
LVIRA_TOLERANCE = 1e-7
LVIRA_STEPS = 12
NORMALS = ("youngs", "lvira")


def normal_method(normal: str) -> bool:
    """Whether ``normal`` (``[interface] normal``) asks for LVIRA's refinement."""
    if normal not in NORMALS:
        raise ValueError(f"normal {normal!r}: one of {NORMALS}")
    return normal == "lvira"


@numba.njit(**KERNEL)
def lvira_residuals(angle, px, py, k, fraction, around_x, around_y, around_area, around_fraction, count, projection,
                    below, residual):  # pragma: no cover (compiled)
    """LVIRA's residuals of a cell (its polygon ``px``, ``py`` of ``k`` points, α's
    ``fraction``) at the normal of ``angle``: the line cut to its fraction, extended over
    the ``count`` cells around it (polygons ``around_x``, ``around_y`` (·, k), areas, α's
    fractions), the fraction of each below the line less its own, into ``residual``;
    returns their sum of squares (the misfit)."""
    nx, ny = np.cos(angle), np.sin(angle)
    offset = cut_offset(px, py, k, nx, ny, fraction, projection, below)
    total = 0.0
    for j in range(count):
        predicted = area_below_line(around_x[j], around_y[j], k, nx, ny, offset) / around_area[j]
        residual[j] = minimum(maximum(predicted, 0.0), 1.0) - around_fraction[j]
        total += residual[j] * residual[j]
    return total


@numba.njit(**KERNEL)
def lvira_normals(x, cell_nodes, first, cell, cells, fractions, which, normals):  # pragma: no cover (compiled)
    """LVIRA's normals (n, 2) out of α of the mixed cells ``cells`` (Puckett 1991): in each,
    the angle whose line, cut to the cell's fraction, gives the cells sharing a node with
    it (``first``, ``cell``: ale_xfem.model.mesh.node_corners) their fractions best in least
    squares (:func:`lvira_residuals`), by safeguarded Gauss–Newton steps from ``normals``
    (n, 2; Youngs'; (0, 0) stays).  ``fractions`` (m, n_cells): α's fractions, row
    ``which`` (n,) for each mixed cell's α (the cells around it at least)."""
    n_cells, k = cell_nodes.shape
    n = cells.size
    out = normals.copy()
    widest = 0
    for node in range(first.size - 1):
        widest = max(widest, first[node + 1] - first[node])
    width = k * widest
    px, py = np.empty(k), np.empty(k)
    projection, below = np.empty(k), np.empty(k)
    around_x, around_y = np.empty((width, k)), np.empty((width, k))
    around_area, around_fraction = np.empty(width), np.empty(width)
    residual, moved, trial = np.empty(width), np.empty(width), np.empty(width)
    seen = np.full(n_cells, -1, dtype=np.int64)
    for j in range(n):
        if normals[j, 0] == 0.0 and normals[j, 1] == 0.0:
            continue
        own = cells[j]
        for i in range(k):
            px[i], py[i] = x[0, cell_nodes[own, i]], x[1, cell_nodes[own, i]]
        count = 0
        seen[own] = j
        for i in range(k):
            node = cell_nodes[own, i]
            for e in range(first[node], first[node + 1]):
                c = cell[e]
                if seen[c] == j:
                    continue
                seen[c] = j
                for q in range(k):
                    around_x[count, q], around_y[count, q] = x[0, cell_nodes[c, q]], x[1, cell_nodes[c, q]]
                around_area[count] = shoelace(around_x[count], around_y[count], k)
                around_fraction[count] = fractions[which[j], c]
                count += 1
        fraction = fractions[which[j], own]
        start = np.arctan2(normals[j, 1], normals[j, 0])
        angle = start
        misfit = lvira_residuals(angle, px, py, k, fraction, around_x, around_y, around_area, around_fraction, count,
                                 projection, below, residual)
        for _ in range(LVIRA_STEPS):
            lvira_residuals(angle + LVIRA_DIFFERENCE, px, py, k, fraction, around_x, around_y, around_area,
                            around_fraction, count, projection, below, moved)
            slope_squared, slope_residual = 0.0, 0.0
            for q in range(count):
                slope = (moved[q] - residual[q]) / LVIRA_DIFFERENCE
                slope_squared += slope * slope
                slope_residual += slope * residual[q]
            if slope_squared == 0.0:
                break
            step = minimum(maximum(-slope_residual / slope_squared, -LVIRA_MAX_STEP), LVIRA_MAX_STEP)
            if abs(step) < LVIRA_TOLERANCE:
                break
            accepted = False
            for _ in range(4):  # halved until the misfit falls
                candidate = minimum(maximum(angle + step, start - LVIRA_HALF_WIDTH), start + LVIRA_HALF_WIDTH)
                tried = lvira_residuals(candidate, px, py, k, fraction, around_x, around_y, around_area,
                                        around_fraction, count, projection, below, trial)
                if tried < misfit:
                    accepted = True
                    break
                step *= 0.5
            if not accepted:
                break
            angle, misfit = candidate, tried
            residual[:count] = trial[:count]
        out[j, 0], out[j, 1] = np.cos(angle), np.sin(angle)
    return out


def reconstruct_state(problem, state, layout=None, mixed=None, normal: str = "youngs") -> Reconstruction:
    """PLIC in the mixed cells of a state: α is each mixed cell's slot-0 material, its
    normal from Youngs' method on that material's fractions (``normal`` = "lvira":
    refined by LVIRA, :func:`lvira_normals`).  ``layout``, ``mixed``: those of the state
    when not the problem's (``problem`` needs only ``mesh`` and ``materials`` then)."""
    cells, vertices, normals, fraction = _mixed_cell_cuts(problem, state, layout, mixed, normal)
    return reconstruct(vertices, normals, fraction, cells)


def interface_lines(problem, state, layout=None, mixed=None, normal: str = "youngs"):
    """The lines of :func:`reconstruct_state` without the polygons and segments: (cells,
    normals (n, 2), offsets (n,)), α being {x·n ≤ s} in each cell — all the remap reads."""
    cells, vertices, normals, fraction = _mixed_cell_cuts(problem, state, layout, mixed, normal)
    return cells, normals, cut_offsets(vertices, normals, fraction)
