"""Material-by-material volume-intersection remap in 1D (the paper's §2.2.2).

After the Lagrange phase every material occupies a set of *pieces*: a pure cell is one
piece, a mixed cell two (α on [x_a, x_Γ], β on [x_Γ, x_b]).  Each piece carries its
material's mass, internal energy and, split into *parts* owned by nodes, the nodal
momentum: a pure cell's two halves belong to its two nodes, a mixed cell's α piece to its
internal node a and its β piece to b (the mass condensation of the Lagrange phase).

The pieces are intersected with the cells of the regularised mesh, material by material:
a new cell receives from each old piece the integral over the overlap of that material's
density, energy density and momentum density, so nothing crosses Γ, and a tangential
(transverse) velocity cannot diffuse across it.  Material boundaries keep their positions;
a new cell holding a boundary strictly inside becomes the new mixed cell (the interface
moves on to the neighbour cell when it passes a node).

Order 1: densities constant per piece, velocities constant per part.  Order 2: densities
linear per piece and velocities linear per part, with minmod-limited slopes taken from the
neighbours *of the same material*; a material's velocity field in a mixed cell is used in
full, external node included: α's velocity is the line through (x_a, u_a) and (x_Γ, u_Γ).
Slopes are centred on each piece's centroid and each part's centre of mass, so mass,
internal energy and momentum are conserved to round-off at either order; the kinetic
energy changes (it is dissipated), and that change is returned.

All integrals are exact (Simpson's rule on products of linear functions); the loops are
over the few materials and momentum components, never over cells.
"""

from __future__ import annotations

import numpy as np

from ale_xfem.remap.failure import RemapFailure
from ale_xfem.remap.pieces_1d import (RemapResult, deposit_kinetic_loss, integrate_linear,
                                      lump_kinetic, minmod, piece_slopes)


def _segments(edges_a, edges_b):
    """Cut [min, max] at every edge of both sorted edge sets; return segment ends and, for
    each segment, the index of the interval of a and of b holding it."""
    cuts = np.unique(np.concatenate([edges_a, edges_b]))
    lo, hi = cuts[:-1], cuts[1:]
    keep = hi - lo > 0.0
    lo, hi = lo[keep], hi[keep]
    middle = 0.5 * (lo + hi)
    in_a = np.clip(np.searchsorted(edges_a, middle, side="right") - 1, 0, edges_a.size - 2)
    in_b = np.clip(np.searchsorted(edges_b, middle, side="right") - 1, 0, edges_b.size - 2)
    return lo, hi, in_a, in_b


def remap_1d(order_of_cells, cell_left_node, cell_right_node, node_position, target_position,
             cell_material, material_mass, material_energy, material_volume, corner_mass,
             node_velocity, mixed_cells, interface_velocity, n_materials,
             order: int = 2, condensed: bool = True, heat: bool = True) -> RemapResult:
    """Remap a 1D state onto target node positions.

    order_of_cells: cells sorted left to right; cell_left_node / cell_right_node: (n_cells,)
    nodes of each cell; node_position, target_position: (n_nodes,); per-material arrays
    (S, n_cells) with slot 0 the left material of a mixed cell; node_velocity
    (components, n_nodes); mixed_cells (n_mixed,) and interface_velocity (n_mixed,).
    ``heat``: the kinetic energy the momentum remap loses at each node goes into the
    internal energy of the cells around it (:func:`deposit_kinetic_loss`)."""
    n_cells = cell_left_node.size
    n_nodes = node_position.size
    is_mixed = np.zeros(n_cells, dtype=bool)
    is_mixed[mixed_cells] = True
    slot_of = np.zeros(n_cells, dtype=np.int64)  # position of a mixed cell in mixed_cells
    slot_of[mixed_cells] = np.arange(mixed_cells.size)

    # -- old pieces, left to right -----------------------------------------------------
    cells = order_of_cells
    x_left = node_position[cell_left_node[cells]]
    x_right = node_position[cell_right_node[cells]]
    mixed_here = is_mixed[cells]
    count = np.where(mixed_here, 2, 1)
    start = np.concatenate([[0], np.cumsum(count)[:-1]])
    n_pieces = int(count.sum())
    piece_cell = np.repeat(cells, count)
    piece_slot = np.zeros(n_pieces, dtype=np.int64)
    piece_slot[start[mixed_here] + 1] = 1
    interface = x_left + material_volume[0, cells]  # meaningful for mixed cells only
    piece_lo = np.repeat(x_left, count)
    piece_hi = np.repeat(x_right, count)
    first, second = start[mixed_here], start[mixed_here] + 1
    piece_hi[first] = interface[mixed_here]
    piece_lo[second] = interface[mixed_here]
    piece_material = cell_material[piece_slot, piece_cell]
    piece_mass = material_mass[piece_slot, piece_cell]
    piece_energy = piece_mass * material_energy[piece_slot, piece_cell]
    width = piece_hi - piece_lo
    centre = 0.5 * (piece_lo + piece_hi)
    density = piece_mass / width
    energy_density = piece_energy / width
    density_slope, energy_slope = piece_slopes(centre, width, density, energy_density, piece_material, order)

    # -- new cells, left to right, and their material content ------------------------------
    t_left = target_position[cell_left_node[cells]]
    t_right = target_position[cell_right_node[cells]]
    target_edges = np.concatenate([t_left, t_right[-1:]])
    piece_edges = np.concatenate([piece_lo, piece_hi[-1:]])
    lo, hi, in_piece, in_cell = _segments(piece_edges, target_edges)
    seg_material = piece_material[in_piece]
    seg_volume = hi - lo
    seg_mass = integrate_linear(density[in_piece], density_slope[in_piece], centre[in_piece], lo, hi)
    seg_energy = integrate_linear(energy_density[in_piece], energy_slope[in_piece], centre[in_piece], lo, hi)
    key = seg_material * n_cells + in_cell  # in_cell indexes the sorted cells
    size = n_materials * n_cells
    volume_by = np.bincount(key, seg_volume, size).reshape(n_materials, n_cells)
    mass_by = np.bincount(key, seg_mass, size).reshape(n_materials, n_cells)
    energy_by = np.bincount(key, seg_energy, size).reshape(n_materials, n_cells)
    # Material boundaries keep their positions; a new cell holding one strictly inside is
    # mixed, its left material (slot 0) the one at its left end.  Two in one cell: the
    # interfaces have met, which this method does not represent.
    target_width = t_right - t_left
    boundaries = piece_hi[:-1][piece_material[1:] != piece_material[:-1]]
    inside = (np.searchsorted(boundaries, t_right - 1e-12 * target_width, side="right")
              - np.searchsorted(boundaries, t_left + 1e-12 * target_width, side="left"))
    if np.any(inside > 1):
        bad = int(np.flatnonzero(inside > 1)[0])
        raise RemapFailure(f"cell {int(cells[bad])} [{t_left[bad]:.6g}, {t_right[bad]:.6g}]: two "
                           "interfaces meet in one cell (a layer thinner than a cell); refine the mesh")
    holds = 1 + inside
    neighbours = np.flatnonzero((inside[1:] == 1) & (inside[:-1] == 1))
    if neighbours.size:
        bad = int(neighbours[0])
        raise RemapFailure(f"cells {int(cells[bad])} and {int(cells[bad + 1])}: interfaces in "
                           "neighbouring cells (a layer about one cell thick); the mixed-cell "
                           "solve needs a pure cell between them: refine the mesh")
    left_piece = np.clip(np.searchsorted(piece_edges, t_left + 1e-12 * target_width, side="right") - 1,
                         0, n_pieces - 1)
    right_piece = np.clip(np.searchsorted(piece_edges, t_right - 1e-12 * target_width, side="right") - 1,
                          0, n_pieces - 1)
    left_material = piece_material[left_piece]
    right_material = piece_material[right_piece]
    new_mixed_sorted = np.flatnonzero(holds == 2)
    slots = 2 if new_mixed_sorted.size else 1
    columns = np.arange(n_cells)
    material_sorted = np.full((slots, n_cells), -1, dtype=np.int64)
    material_sorted[0] = left_material
    if slots == 2:
        material_sorted[1, new_mixed_sorted] = right_material[new_mixed_sorted]
    new_mass = np.zeros((slots, n_cells))
    new_energy_total = np.zeros((slots, n_cells))
    new_volume = np.zeros((slots, n_cells))
    for slot in range(slots):
        occupied = material_sorted[slot] >= 0
        m = material_sorted[slot][occupied]
        c = columns[occupied]
        new_mass[slot, c] = mass_by[m, c]
        new_energy_total[slot, c] = energy_by[m, c]
        new_volume[slot, c] = volume_by[m, c]
    pure_sorted = holds == 1
    new_volume[0, pure_sorted] = target_width[pure_sorted]  # absorb round-off

    # -- momentum: old parts → new parts ------------------------------------------------------
    # A part is the share of a piece that one node carries: a piece splits at its cell's
    # middle between the cell's two nodes, except (enriched) a mixed cell's pieces, which
    # belong whole to their internal nodes (the mass condensation).
    piece_is_mixed = np.repeat(mixed_here, count)
    cell_middle = 0.5 * (node_position[cell_left_node] + node_position[cell_right_node])
    part_piece, part_lo, part_hi, part_side = _parts(piece_lo, piece_hi, piece_cell, piece_slot,
                                                     piece_is_mixed, cell_middle, condensed)
    part_cell = piece_cell[part_piece]
    part_owner = np.where(part_side == 1, cell_right_node[part_cell], cell_left_node[part_cell])
    part_mass = integrate_linear(density[part_piece], density_slope[part_piece], centre[part_piece],
                                  part_lo, part_hi)
    # The lumped (corner) mass of the Lagrange phase, shared among the parts of a corner in
    # proportion to their mass.
    corner_key = 2 * part_cell + part_side
    corner_total = np.bincount(corner_key, part_mass, 2 * n_cells)
    part_share = corner_mass[part_side, part_cell] * part_mass / corner_total[corner_key]
    first_moment = _first_moment(density[part_piece], density_slope[part_piece], centre[part_piece],
                                 part_lo, part_hi)
    part_centroid = first_moment / part_mass

    components = node_velocity.shape[0]
    part_velocity = node_velocity[:, part_owner]  # (components, n_parts)
    part_slope = np.zeros_like(part_velocity)
    if order == 2:
        part_material = piece_material[part_piece] if condensed else np.zeros(part_piece.size, dtype=np.int64)
        part_slope = _velocity_slopes(node_position, node_velocity, cell_left_node, cell_right_node,
                                      cells, is_mixed & condensed, slot_of, interface_velocity,
                                      material_volume, part_owner, part_material, part_piece, piece_cell,
                                      part_side)

    # New parts, from the new cells and their interfaces.
    new_is_mixed = holds == 2
    new_interface = t_left + new_volume[0]
    new_piece_count = np.where(new_is_mixed, 2, 1)
    new_piece_cell = np.repeat(np.arange(n_cells), new_piece_count)  # index into sorted cells
    new_start = np.concatenate([[0], np.cumsum(new_piece_count)[:-1]])
    new_piece_slot = np.zeros(new_piece_cell.size, dtype=np.int64)
    new_piece_slot[new_start[new_is_mixed] + 1] = 1
    new_piece_lo = t_left[new_piece_cell].copy()
    new_piece_hi = t_right[new_piece_cell].copy()
    new_piece_hi[new_start[new_is_mixed]] = new_interface[new_is_mixed]
    new_piece_lo[new_start[new_is_mixed] + 1] = new_interface[new_is_mixed]
    new_part_piece, new_part_lo, new_part_hi, new_part_side = _parts(
        new_piece_lo, new_piece_hi, new_piece_cell, new_piece_slot, new_is_mixed[new_piece_cell],
        0.5 * (t_left + t_right), condensed)
    new_part_cell = new_piece_cell[new_part_piece]  # sorted index
    new_part_owner = np.where(new_part_side == 1, cell_right_node[cells][new_part_cell],
                              cell_left_node[cells][new_part_cell])

    old_edges = np.concatenate([part_lo, part_hi[-1:]])
    new_edges = np.concatenate([new_part_lo, new_part_hi[-1:]])
    lo, hi, in_old, in_new = _segments(old_edges, new_edges)
    p = part_piece[in_old]
    scale = part_share[in_old] / part_mass[in_old]  # each old part carries its lumped share
    # New corner masses: the lumped masses carried into each new part.  Dividing momentum
    # by them keeps a uniform velocity exactly uniform (no new extrema), and their sum is
    # the total mass.
    segment_mass = integrate_linear(density[p], density_slope[p], centre[p], lo, hi) * scale
    new_part_mass = np.bincount(in_new, segment_mass, new_part_owner.size)
    momentum = np.zeros((components, n_nodes))
    segment_momentum = np.empty((components, lo.size))
    for k in range(components):
        segment_momentum[k] = _simpson_product(density[p], density_slope[p], centre[p],
                                               part_velocity[k, in_old], part_slope[k, in_old],
                                               part_centroid[in_old], lo, hi) * scale
        momentum[k] = np.bincount(new_part_owner[in_new], segment_momentum[k], n_nodes)

    # -- back to cell order, new lumped masses and velocities ------------------------------
    cell_material_new = np.full((slots, n_cells), -1, dtype=np.int64)
    cell_material_new[:, cells] = material_sorted
    mass_new = np.zeros((slots, n_cells))
    mass_new[:, cells] = new_mass
    volume_new = np.zeros((slots, n_cells))
    volume_new[:, cells] = new_volume
    energy_new = np.zeros((slots, n_cells))
    with np.errstate(invalid="ignore", divide="ignore"):
        energy_new[:, cells] = np.where(new_mass > 0, new_energy_total / np.where(new_mass > 0, new_mass, 1.0), 0.0)
    corner_mass_new = np.bincount(cells[new_part_cell] * 2 + new_part_side, new_part_mass,
                                  2 * n_cells).reshape(n_cells, 2).T.copy()
    node_mass = np.bincount(new_part_owner, new_part_mass, n_nodes)
    velocity = momentum / node_mass
    old_node_mass = np.bincount(part_owner, part_share, n_nodes)
    kinetic_before = 0.5 * np.sum(old_node_mass * node_velocity**2)
    kinetic_after = 0.5 * np.sum(node_mass * velocity**2)
    if heat:
        # What each old part hands to another node, as one lump per (part, new node): its
        # kinetic energy ½ p²/m leaves the old node and reaches the new one.
        old_owner, new_owner = part_owner[in_old], new_part_owner[in_new]
        starts = np.concatenate([[True], (in_old[1:] != in_old[:-1]) | (new_owner[1:] != new_owner[:-1])])
        group = np.cumsum(starts) - 1
        lump_mass = np.bincount(group, segment_mass)
        lump_momentum = np.array([np.bincount(group, m) for m in segment_momentum])
        loss = 0.5 * old_node_mass * (node_velocity**2).sum(axis=0) - 0.5 * node_mass * (velocity**2).sum(axis=0)
        loss += _handed_over(lump_mass, lump_momentum, old_owner[starts], new_owner[starts], n_nodes)
        energy_new = deposit_kinetic_loss(loss, corner_mass_new, node_mass, cell_left_node, cell_right_node,
                                          cell_material_new, mass_new, energy_new, cells[new_mixed_sorted],
                                          condensed, positive_only=heat == "positive")
    return RemapResult(cell_material_new, mass_new, energy_new, volume_new, corner_mass_new, node_mass, velocity,
                       cells[new_mixed_sorted], kinetic_after - kinetic_before, momentum)


def _handed_over(mass, momentum, from_node, to_node, n_nodes):
    """Kinetic energy per node received minus given: lumps of (mass, momentum) going from
    one node to another carry ½ |p|²/m."""
    moving = from_node != to_node
    kinetic = lump_kinetic(mass[moving], momentum[:, moving])
    return np.bincount(to_node[moving], kinetic, n_nodes) - np.bincount(from_node[moving], kinetic, n_nodes)


def _parts(piece_lo, piece_hi, piece_cell, piece_slot, piece_is_mixed, cell_middle, condensed):
    """Split pieces into node parts: at the cell middle when it lies strictly inside the
    piece (and the piece is not a condensed mixed piece).  Returns (piece index, lo, hi,
    side: 0 left node, 1 right node) per part, left to right."""
    middle = cell_middle[piece_cell]
    keep_whole = piece_is_mixed & condensed
    split = ~keep_whole & (middle > piece_lo) & (middle < piece_hi)
    part_piece = np.repeat(np.arange(piece_lo.size), np.where(split, 2, 1))
    second = np.zeros(part_piece.size, dtype=bool)
    second[1:] = part_piece[1:] == part_piece[:-1]
    first = np.zeros(part_piece.size, dtype=bool)
    first[:-1] = part_piece[:-1] == part_piece[1:]
    lo = piece_lo[part_piece].copy()
    hi = piece_hi[part_piece].copy()
    hi[first] = middle[part_piece[first]]
    lo[second] = middle[part_piece[second]]
    whole_side = np.where(keep_whole, piece_slot,
                          (0.5 * (piece_lo + piece_hi) > middle).astype(np.int64))
    side = np.where(second, 1, np.where(first, 0, whole_side[part_piece]))
    return part_piece, lo, hi, side


def _first_moment(value, slope, centre, lo, hi):
    """∫_lo^hi x (value + slope (x − centre)) dx, by Simpson's rule (exact: quadratic)."""
    mid = 0.5 * (lo + hi)
    f = lambda x: x * (value + slope * (x - centre))  # noqa: E731
    return (hi - lo) / 6.0 * (f(lo) + 4.0 * f(mid) + f(hi))


def _simpson_product(rho, rho_slope, rho_centre, u, u_slope, u_centre, lo, hi):
    """∫_lo^hi (ρ + σ(x − c))(u + τ(x − x̄)) dx, exact by Simpson's rule."""
    mid = 0.5 * (lo + hi)
    f = lambda x: (rho + rho_slope * (x - rho_centre)) * (u + u_slope * (x - u_centre))  # noqa: E731
    return (hi - lo) / 6.0 * (f(lo) + 4.0 * f(mid) + f(hi))


def _velocity_slopes(x, u, cell_left_node, cell_right_node, cells, is_mixed, slot_of,
                     interface_velocity, material_volume, part_owner, part_material,
                     part_piece, piece_cell, part_side):
    """Minmod slope of each part's owner velocity from its neighbours in the same material.

    Neighbours are the other node of each cell the material occupies around the owner:
    in a pure cell the cell's other node; in a mixed cell, the material's external node,
    whose velocity comes from the material's full field (the line through its internal
    node and Γ for the normal component; the internal value for transverse components)."""
    components = u.shape[0]
    n_parts = part_owner.size
    # For each part: the cell it lies in and the neighbour node value on each side.
    cell = piece_cell[part_piece]
    left_node, right_node = cell_left_node[cell], cell_right_node[cell]
    owner_is_left = part_side == 0
    other = np.where(owner_is_left, right_node, left_node)
    x_owner, x_other = x[part_owner], x[other]
    u_other = u[:, other].copy()
    mixed = is_mixed[cell]
    if np.any(mixed):
        where = np.flatnonzero(mixed)
        k = slot_of[cell[where]]
        xa, xb = x[left_node[where]], x[right_node[where]]
        xg = xa + material_volume[0, cell[where]]
        ug = interface_velocity[k]
        own = u[0, part_owner[where]]
        # line through (x_owner, u_owner) and (x_Γ, u_Γ), evaluated at the external node
        u_other[0, where] = own + (ug - own) * (x_other[where] - x_owner[where]) / (xg - x_owner[where])
        for comp in range(1, components):
            u_other[comp, where] = u[comp, part_owner[where]]
    # one-sided differences on the part's own side; the neighbour part of the same owner in
    # the adjacent cell provides the other side
    gradient_here = (u_other - u[:, part_owner]) / (x_other - x_owner)
    # pair each part with the other part of the same owner (the other cell around the node)
    order = np.argsort(part_owner, kind="stable")
    owners_sorted = part_owner[order]
    pair = np.full(n_parts, -1)
    same = owners_sorted[1:] == owners_sorted[:-1]
    a, b = order[:-1][same], order[1:][same]
    pair[a], pair[b] = b, a
    has_pair = (pair >= 0) & (part_material[np.maximum(pair, 0)] == part_material)
    gradient_there = np.where(has_pair, gradient_here[:, np.maximum(pair, 0)], 0.0)
    slope = np.where(has_pair, minmod(gradient_here, gradient_there), 0.0)
    return slope


