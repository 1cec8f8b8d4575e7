"""PLIC interface reconstruction in 2D cells (piecewise linear interface calculation).

In each mixed cell the interface is a straight segment {x : x·n = s} whose α side
{x·n ≤ s} ∩ K has exactly the cell's volume fraction of α.  The normal n comes from Youngs'
method: the volume fraction's gradient over the patch of cells around each node (the
divergence theorem on the patch, through the same corner gradients ∂A/∂x_i as the Wilkins
forces), averaged over the cell's nodes, n = −∇f/|∇f| pointing out of α
(:func:`ale_xfem.model.mesh.patch_gradient`).  The offset s is found
exactly: the clipped area is quadratic in s between the cell's vertex projections.

Everything is vectorised over the mixed cells; the loops run over bisection iterations and
over the corners of a cell.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ale_xfem.geometry import polygon_kernels
from ale_xfem.model.mesh import cells_around, patch_gradient
from ale_xfem.geometry.shapes import clip_half_plane, polygon_area, polygon_centroid


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


def material_fractions(problem, state, layout=None, cells=None) -> np.ndarray:
    """(n_materials, n_cells): each material's share of each cell's area (``cells``: of
    those cells only, 0 elsewhere)."""
    layout = problem.layout if layout is None else layout
    mesh = problem.mesh
    cells = np.arange(mesh.n_cells) if cells is None else cells
    area = mesh.cell_geometry(state.node_position, cells)[0]
    fractions = np.zeros((len(problem.materials), mesh.n_cells))
    for slot in range(layout.cell_material.shape[0]):
        material = layout.cell_material[slot, cells]
        here = material >= 0
        # (a material appears once per cell in a slot: no repeated index)
        fractions[material[here], cells[here]] += state.material_volume[slot, cells[here]] / area[here]
    return fractions


def _mixed_cell_cuts(problem, state, layout, mixed):
    """What PLIC needs of a state's mixed cells: their corners (n, k, 2), Youngs' normals
    of their slot-0 (α) material and α's volume fractions."""
    layout = problem.layout if layout is None else layout
    mixed = problem.mixed if mixed is None else mixed
    mesh, cells = problem.mesh, mixed.cells
    around = cells_around(mesh, cells)  # all Youngs' normals read
    fractions = material_fractions(problem, state, layout, around)
    alpha = layout.cell_material[0, cells]
    materials = np.unique(alpha)  # each α material's normals, in one pass
    normals = youngs_normals(mesh, state.node_position, fractions[materials], cells, around)
    normals = normals[np.searchsorted(materials, alpha), np.arange(cells.size)]
    vertices = np.moveaxis(state.node_position[:, mesh.cell_nodes[cells]], 0, -1)  # the mixed cells only
    return cells, vertices, normals, state.material_volume[0, cells] / polygon_area(vertices)


def reconstruct_state(problem, state, layout=None, mixed=None) -> Reconstruction:
    """PLIC in the mixed cells of a state: α is each mixed cell's slot-0 material, its
    normal from Youngs' method on that material's fractions.  ``layout``, ``mixed``: those
    of the state when not the problem's (``problem`` needs only ``mesh`` and ``materials``
    then)."""
    cells, vertices, normals, fraction = _mixed_cell_cuts(problem, state, layout, mixed)
    return reconstruct(vertices, normals, fraction, cells)


def interface_lines(problem, state, layout=None, mixed=None):
    """The lines of :func:`reconstruct_state` without the polygons and segments: (cells,
    normals (n, 2), offsets (n,)), α being {x·n ≤ s} in each cell — all the remap reads."""
    cells, vertices, normals, fraction = _mixed_cell_cuts(problem, state, layout, mixed)
    return cells, normals, cut_offsets(vertices, normals, fraction)
