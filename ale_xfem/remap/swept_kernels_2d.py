"""Compiled kernels of the 2D remap's whole-mesh pass (ale_xfem.remap.remapper_2d): the
per-material arrays of the state's slots, the swept region of every edge and the volumes
pure donors give, the mixed donors' regions clipped by their cells and PLIC lines, the
outflow cap, each material's density and energy density in the donors and the fluxes at
order 1, the limited linear reconstruction of order 2, the exchange of the fluxes between
the cells, one velocity field's momentum through the cells or (2D enriched cells) each
material's, the kinetic energy one velocity field's remap lost returned as heat, the trace
search, and the remapped cells' slots.

Each loop computes, per edge, per cell or per node, what the numpy code it replaced computed
over whole arrays, with the same operations in the same order, so the results are the same
to the bit (tests/test_2d.py compares them with that code, kept in tests/oracles.py, and
tests/test_regression.py compares the shipped scenes).  Comparisons follow numpy's
(``geometry.polygon_kernels.maximum``/``minimum``; ``clip_unit`` for np.clip with scalar
bounds, which keeps a −0).  Where a term would only add zeros to a sum that starts at +0
(a material absent from a cell, a corner or an edge; a donor the outflow cap leaves as it
is), the loops skip it: the sums keep their bits.
"""

from __future__ import annotations

import numba
import numpy as np

from ale_xfem.geometry.polygon_kernels import (KERNEL, area_below_line, clip_by_line, fan_centroid, maximum,
                                               minimum, shoelace)
from ale_xfem.model.cell_kernels import QUADRILATERAL, TRIANGLE, averaged_gradient, cell_shapes, node_area_sums


@numba.njit(**KERNEL)
def clip_unit(x):  # pragma: no cover (compiled)
    """np.clip(x, 0.0, 1.0) of one number, as numpy clips with scalar bounds (NaN stays NaN,
    −0 stays −0)."""
    return 0.0 if x < 0.0 else (1.0 if x > 1.0 else x)


@numba.njit(**KERNEL)
def by_material(cell_material, volume, mass, specific_energy, n_materials):  # pragma: no cover (compiled)
    """A state's slots (S, n_cells) as dense arrays by material (n_materials, n_cells):
    volume, mass and internal energy (mass × specific energy), zero where a cell does not
    hold the material."""
    n_slots, n_cells = cell_material.shape
    out_volume = np.zeros((n_materials, n_cells))
    out_mass = np.zeros((n_materials, n_cells))
    out_energy = np.zeros((n_materials, n_cells))
    for slot in range(n_slots):
        for c in range(n_cells):
            m = cell_material[slot, c]
            if m >= 0:  # (a material is in one slot of a cell at most)
                out_volume[m, c] += volume[slot, c]
                out_mass[m, c] += mass[slot, c]
                out_energy[m, c] += mass[slot, c] * specific_energy[slot, c]
    return out_volume, out_mass, out_energy


@numba.njit(**KERNEL)
def material_slots(volume, mass, energy, area, standing, trace):  # pragma: no cover (compiled)
    """The remapped cells' materials back in slots: the materials that count in each cell
    (above ``trace`` of its ``area``, or a ``standing`` trace with mass), slot 0 the one of
    largest volume, slot 1 (when some cell holds two) the next, of equal volumes the lower
    material first (model.state.ranked_materials).  Returns (how many materials count in
    each cell (n_cells,), the slots' materials (S, n_cells) (−1: none), and their masses,
    volumes and specific internal energies (S, n_cells))."""
    n_materials, n_cells = volume.shape
    count = np.zeros(n_cells, dtype=np.int64)
    values = np.empty((n_materials, n_cells))
    for m in range(n_materials):
        for c in range(n_cells):
            present = (volume[m, c] > trace * area[c]) | (standing[m, c] & (mass[m, c] != 0.0))
            values[m, c] = volume[m, c] if present else -1.0
            count[c] += present
    slots = 1
    for c in range(n_cells):
        if count[c] == 2:
            slots = 2
            break
    cell_material = np.full((slots, n_cells), -1, dtype=np.int64)
    slot_mass = np.zeros((slots, n_cells))
    slot_volume = np.zeros((slots, n_cells))
    slot_energy = np.zeros((slots, n_cells))
    for c in range(n_cells):
        for rank in range(slots):
            best, chosen = values[0, c], 0
            for m in range(1, n_materials):
                if values[m, c] > best:
                    chosen = m
                best = maximum(best, values[m, c])
            if rank == 0 or count[c] == 2:
                cell_material[rank, c] = chosen
                slot_mass[rank, c] = mass[chosen, c]
                slot_volume[rank, c] = volume[chosen, c]
                slot_energy[rank, c] = energy[chosen, c] / mass[chosen, c]
            values[chosen, c] = -np.inf
    return count, cell_material, slot_mass, slot_volume, slot_energy


@numba.njit(**KERNEL)
def standing_traces(volume, area, trace):  # pragma: no cover (compiled)
    """The materials below ``trace`` of their cell's ``area`` before a remap (``volume``
    (n_materials, n_cells)): (a mask (n_materials, n_cells), their (material, cell) pairs in
    np.nonzero's order (2, n), their volumes (n,)) — what :func:`untouched_traces` reads
    after the fluxes."""
    n_materials, n_cells = volume.shape
    standing = np.zeros((n_materials, n_cells), dtype=np.bool_)
    count = 0
    for m in range(n_materials):
        for c in range(n_cells):
            here = (volume[m, c] > 0.0) & (volume[m, c] <= trace * area[c])
            standing[m, c] = here
            count += here
    where = np.empty((2, count), dtype=np.int64)
    before = np.empty(count)
    j = 0
    for m in range(n_materials):
        for c in range(n_cells):
            if standing[m, c]:
                where[0, j], where[1, j], before[j] = m, c, volume[m, c]
                j += 1
    return standing, where, before


@numba.njit(**KERNEL)
def untouched_traces(standing, where, before, volume):  # pragma: no cover (compiled)
    """A standing trace (:func:`standing_traces`) whose volume the fluxes changed by more than
    10⁻⁶ of it is no longer standing (``standing`` changed in place)."""
    for j in range(before.size):
        m, c = where[0, j], where[1, j]
        if abs(volume[m, c] - before[j]) > 1e-6 * before[j]:
            standing[m, c] = False


@numba.njit(**KERNEL)
def present_materials(volume, area, standing, trace):  # pragma: no cover (compiled)
    """(n_materials, n): whether each material counts in each of the cells whose areas
    ``area`` (n,) are given — above ``trace`` of the area, or a ``standing`` trace with
    volume (numerics.trace_fraction: remapper_2d, "Traces")."""
    n_materials, n = volume.shape
    present = np.empty((n_materials, n), dtype=np.bool_)
    for m in range(n_materials):
        for c in range(n):
            present[m, c] = (volume[m, c] > trace * area[c]) | (standing[m, c] & (volume[m, c] > 0.0))
    return present


@numba.njit(**KERNEL)
def traces(volume, mass, area, standing, trace):  # pragma: no cover (compiled)
    """The (material, cell) pairs, in np.nonzero's order, of the materials with mass that
    do not count in their cells (:func:`present_materials`)."""
    n_materials, n_cells = volume.shape
    count = 0
    for m in range(n_materials):
        for c in range(n_cells):
            present = (volume[m, c] > trace * area[c]) | (standing[m, c] & (volume[m, c] > 0.0))
            count += (not present) & (mass[m, c] != 0.0)
    material = np.empty(count, dtype=np.int64)
    cells = np.empty(count, dtype=np.int64)
    k = 0
    for m in range(n_materials):
        for c in range(n_cells):
            present = (volume[m, c] > trace * area[c]) | (standing[m, c] & (volume[m, c] > 0.0))
            if (not present) & (mass[m, c] != 0.0):
                material[k], cells[k] = m, c
                k += 1
    return material, cells


@numba.njit(**KERNEL)
def cap_outflow(volume, donor, flux_volume):  # pragma: no cover (compiled)
    """No donor gives more of a material than it holds (the swept regions of two edges
    overlap near a moving node): material by material, an overdrawn donor's regions give its volume
    in proportion, and the rest of each region is of its other materials, shared by what
    they already have in it (equally where they have none), in place."""
    n_materials, n_cells = volume.shape
    n = donor.size
    out = np.empty(n_cells)
    for m in range(n_materials):
        out[:] = 0.0
        for j in range(n):
            out[donor[j]] += flux_volume[m, j]
        overdrawn = False
        for j in range(n):
            if (out[donor[j]] > volume[m, donor[j]]) & (flux_volume[m, j] > 0):
                overdrawn = True
                break
        if not overdrawn:
            continue
        for j in range(n):
            d = donor[j]
            if not out[d] > volume[m, d]:
                # a donor that gives no more than it holds: its regions keep their volumes,
                # what the other materials gain is +0 (which turns a −0 into +0, as below)
                for o in range(n_materials):
                    if o != m:
                        flux_volume[o, j] += 0.0
                continue
            ratio = volume[m, d] / out[d]
            kept = flux_volume[m, j] * ratio
            moved = flux_volume[m, j] - kept
            flux_volume[m, j] = kept
            total = 0.0
            first = True
            for o in range(n_materials):
                if o != m:
                    share = maximum(flux_volume[o, j], 0.0)
                    total = share if first else total + share
                    first = False
            for o in range(n_materials):
                if o != m:
                    share = maximum(flux_volume[o, j], 0.0)
                    share = share / total if total > 0 else 1.0 / (n_materials - 1)
                    flux_volume[o, j] += share * moved


@numba.njit(**KERNEL)
def swept_edges(x, target_a, target_b, a, b, plus, minus, is_mixed, material,
                n_materials):  # pragma: no cover (compiled)
    """The regions the interior edges sweep from the Lagrangian mesh ``x`` (2, n_nodes) to
    the target mesh (edge ends ``target_a``, ``target_b`` (2, n_edges)): each edge a→b
    sweeps the quadrilateral (x_a, X_a, X_b, x_b) of signed area
    S = ½ (X_b − x_a) × (x_b − X_a), from the cell on its other side into the cell on its left
    (``plus``) where S > 0, the other way where S < 0 — or, where the Lagrangian and target
    edges cross at P beside a mixed cell or between two materials, its two lobes
    (x_p, X_p, P, P) and (P, P, X_q, x_q) (p the lower-numbered end), each the same way by the
    sign of its own area (the module docstring of ale_xfem.remap.remapper_2d).  Returns, over the regions of nonzero area in the order of
    the edges: their donors, receivers, |S|, their quadrilaterals (2, 4, n) and each
    material's volume in them (n_materials, n) — a pure donor's material's |S|, zero from mixed
    donors (``is_mixed``: their share is clipped by their polygons; ``material``: each cell's
    first material)."""
    n_edges = a.size
    # each edge's region, or its two lobes where the Lagrangian and target edges cross at P:
    # (x_a, X_a, P) and (P, X_b, x_b), each from the cell on its own side (the ends of an
    # edge that Γ cuts move with different materials, so the edge turns about P).  The
    # lobes are made from the edge's lower-numbered end, whichever way the edge goes (its
    # direction follows the numbering of its cells): on several MPI ranks their areas and
    # their order are the serial run's, to the bit.
    lobes = np.empty((3, n_edges))  # (S, S at the lower end, S at the higher end: where twisted)
    twisted = np.zeros(n_edges, dtype=np.bool_)
    cross_at = np.empty((2, n_edges))
    count = 0
    for j in range(n_edges):
        if minus[j] < 0:
            continue
        xa0, xa1, xb0, xb1 = x[0, a[j]], x[1, a[j]], x[0, b[j]], x[1, b[j]]
        ta0, ta1, tb0, tb1 = target_a[0, j], target_a[1, j], target_b[0, j], target_b[1, j]
        s = 0.5 * ((tb0 - xa0) * (xb1 - ta1) - (tb1 - xa1) * (xb0 - ta0))
        lobes[0, j] = s
        if not (is_mixed[plus[j]] or is_mixed[minus[j]] or material[plus[j]] != material[minus[j]]):
            count += int(s != 0.0)  # one material on both sides: its lobes would differ by their donors' densities only
            continue
        sign = 1.0
        if a[j] > b[j]:  # from the lower end: p, q
            xa0, xa1, xb0, xb1, ta0, ta1, tb0, tb1 = xb0, xb1, xa0, xa1, tb0, tb1, ta0, ta1
            sign = -1.0
        # sides of x_p, x_q about the target edge, and of X_p, X_q about the Lagrangian edge
        dp = (tb0 - ta0) * (xa1 - ta1) - (tb1 - ta1) * (xa0 - ta0)
        dq = (tb0 - ta0) * (xb1 - ta1) - (tb1 - ta1) * (xb0 - ta0)
        if dp * dq >= 0.0:  # (most edges: both ends on one side)
            count += int(s != 0.0)
            continue
        ep = (xb0 - xa0) * (ta1 - xa1) - (xb1 - xa1) * (ta0 - xa0)
        eq = (xb0 - xa0) * (tb1 - xa1) - (xb1 - xa1) * (tb0 - xa0)
        if ep * eq < 0.0:
            twisted[j] = True
            t = ep / (ep - eq)
            p0, p1 = ta0 + t * (tb0 - ta0), ta1 + t * (tb1 - ta1)
            cross_at[0, j], cross_at[1, j] = p0, p1
            lobes[1, j] = sign * 0.5 * ((ta0 - xa0) * (p1 - xa1) - (ta1 - xa1) * (p0 - xa0))
            lobes[2, j] = sign * 0.5 * ((tb0 - p0) * (xb1 - p1) - (tb1 - p1) * (xb0 - p0))
            count += int(lobes[1, j] != 0.0) + int(lobes[2, j] != 0.0)
        elif s != 0.0:
            count += 1
    donor = np.empty(count, dtype=np.int64)
    receiver = np.empty(count, dtype=np.int64)
    size = np.empty(count)
    swept = np.empty((2, 4, count))
    flux_volume = np.zeros((n_materials, count))
    k = 0
    for j in range(n_edges):
        if minus[j] < 0:
            continue
        first, last = (0, 1) if not twisted[j] else (1, 3)
        low, high = (a[j], b[j]) if a[j] < b[j] else (b[j], a[j])
        forward = a[j] < b[j]
        for lobe in range(first, last):
            s = lobes[lobe, j]
            if s == 0.0:
                continue
            if s > 0:
                donor[k], receiver[k] = minus[j], plus[j]
            else:
                donor[k], receiver[k] = plus[j], minus[j]
            size[k] = abs(s)
            for d in range(2):
                if lobe == 0:  # (x_a, X_a, X_b, x_b)
                    swept[d, 0, k], swept[d, 1, k] = x[d, a[j]], target_a[d, j]
                    swept[d, 2, k], swept[d, 3, k] = target_b[d, j], x[d, b[j]]
                elif lobe == 1:  # (x_p, X_p, P, P), p the lower end
                    swept[d, 0, k] = x[d, low]
                    swept[d, 1, k] = target_a[d, j] if forward else target_b[d, j]
                    swept[d, 2, k], swept[d, 3, k] = cross_at[d, j], cross_at[d, j]
                else:  # (P, P, X_q, x_q)
                    swept[d, 0, k], swept[d, 1, k] = cross_at[d, j], cross_at[d, j]
                    swept[d, 2, k] = target_b[d, j] if forward else target_a[d, j]
                    swept[d, 3, k] = x[d, high]
            if not is_mixed[donor[k]]:
                flux_volume[material[donor[k]], k] = size[k]
            k += 1
    return donor, receiver, size, swept, flux_volume


@numba.njit(**KERNEL)
def donor_fluxes(flux_volume, volume, mass, energy, donor):  # pragma: no cover (compiled)
    """Each material's density and energy density in every cell (mass and internal energy
    over volume, zero where it has none: (n_materials, n_cells) each) and the mass and
    energy its swept volumes ``flux_volume`` (n_materials, n) carry at its donors'."""
    n_materials, n_cells = volume.shape
    rho = np.empty((n_materials, n_cells))
    eps = np.empty((n_materials, n_cells))
    for m in range(n_materials):
        for c in range(n_cells):
            v = volume[m, c]
            if v > 0:
                rho[m, c] = mass[m, c] / v
                eps[m, c] = energy[m, c] / v
            else:
                rho[m, c] = 0.0
                eps[m, c] = 0.0
    flux_mass = np.empty(flux_volume.shape)
    flux_energy = np.empty(flux_volume.shape)
    for m in range(n_materials):
        for j in range(donor.size):
            flux_mass[m, j] = flux_volume[m, j] * rho[m, donor[j]]
            flux_energy[m, j] = flux_volume[m, j] * eps[m, donor[j]]
    return rho, eps, flux_mass, flux_energy


@numba.njit(**KERNEL)
def slot_values(rho, eps, material):  # pragma: no cover (compiled)
    """(2, n_cells): each cell's density and energy density of its slot-0 material
    ``material`` (n_cells,), from ``rho``, ``eps`` (n_materials, n_cells) — the fields the
    order-2 reconstruction limits (:func:`second_order`)."""
    n_cells = material.size
    value = np.empty((2, n_cells))
    for c in range(n_cells):
        value[0, c] = rho[material[c], c]
        value[1, c] = eps[material[c], c]
    return value


@numba.njit(**KERNEL)
def second_order(cell_type, x, cell_nodes, first, cell, corner, material, is_mixed, value, swept, donor,
                 flux_volume, flux_mass, flux_energy):  # pragma: no cover (compiled)
    """:func:`second_order_loops` compiled for ``cell_type`` (cell_kernels' code), a constant
    of its loops."""
    if cell_type == QUADRILATERAL:
        second_order_loops(QUADRILATERAL, x, cell_nodes, first, cell, corner, material, is_mixed, value, swept,
                           donor, flux_volume, flux_mass, flux_energy)
    else:
        second_order_loops(TRIANGLE, x, cell_nodes, first, cell, corner, material, is_mixed, value, swept, donor,
                           flux_volume, flux_mass, flux_energy)


@numba.njit(**KERNEL, inline="always")
def second_order_loops(cell_type, x, cell_nodes, first, cell, corner, material, is_mixed, value, swept, donor,
                       flux_volume, flux_mass, flux_energy):  # pragma: no cover (compiled)
    """Order 2 (remapper_2d's module docstring): in pure donors whose every node touches
    cells of their own material alone, a linear density and energy density (``value`` (2,
    n_cells), :func:`slot_values`), their gradients averaged to the nodes by area
    (ale_xfem.model.mesh.node_averaged_gradient, computed here in the same loops) and
    limited by Barth–Jespersen so that the corners stay within the node-neighbour range,
    evaluated at the swept region's centroid: ``flux_mass`` and ``flux_energy`` corrected in
    place.  ``cell_type``: cell_kernels' code; ``first``, ``cell``, ``corner``: the cells
    around each node (ale_xfem.model.mesh.node_corners).

    Three passes before the regions': the cells' geometry; each node's averages and
    ranges, gathered from its cells and kept in one row per node (position, the two
    averages, the two ranges, the range of its cells' materials), so that the third pass,
    each cell's gradients and limiters, reads a node's values together (scattered over
    seven node arrays, the limiters alone took 0.86 ms at 200², together 0.62 ms).  A
    node's ranges are taken over its cells by corner, then by cell: the extremes of a set,
    whose order changes nothing but the sign of a zero where +0 and −0 tie."""
    n_cells, k = cell_nodes.shape
    n_nodes = x.shape[1]
    last = k - 1
    area = np.empty(n_cells)
    shape = np.empty((6, n_cells))
    centre = np.empty((2, n_cells))
    cell_shapes(cell_type, x, cell_nodes, area, shape)
    for c in range(n_cells):
        n0, n1, n2, n3 = cell_nodes[c, 0], cell_nodes[c, 1], cell_nodes[c, 2], cell_nodes[c, last]
        _, centre[0, c], centre[1, c] = fan_centroid(x[0, n0], x[1, n0], x[0, n1], x[1, n1], x[0, n2], x[1, n2],
                                                     x[0, n3], x[1, n3], k)
    # each node's row, one cache line: x, y, the two fields' averages, lowest and highest
    # of each over its cells; and the material of all its cells (−1: mixed cells only; −2:
    # several)
    block = np.empty((n_nodes + 1) * 8)
    shift = (64 - block.ctypes.data % 64) % 64 // 8
    row = block[shift:shift + 8 * n_nodes].reshape((n_nodes, 8))
    node_material = np.empty(n_nodes, dtype=np.int64)
    for node_index in range(n_nodes):
        weight, sum0, sum1 = node_area_sums(first, cell, corner, node_index, area, value)
        low_tag, high_tag = np.iinfo(np.int64).max, -2
        low0, high0, low1, high1 = np.inf, -np.inf, np.inf, -np.inf
        for j in range(first[node_index], first[node_index + 1]):
            c = cell[j]
            tag = -1 if is_mixed[c] else material[c]
            low_tag = min(low_tag, tag)
            high_tag = max(high_tag, tag)
            low0 = minimum(low0, value[0, c])
            high0 = maximum(high0, value[0, c])
            low1 = minimum(low1, value[1, c])
            high1 = maximum(high1, value[1, c])
        row[node_index, 0], row[node_index, 1] = x[0, node_index], x[1, node_index]
        row[node_index, 2], row[node_index, 3] = sum0 / weight, sum1 / weight
        row[node_index, 4], row[node_index, 5], row[node_index, 6], row[node_index, 7] = low0, high0, low1, high1
        node_material[node_index] = low_tag if low_tag == high_tag else -2
    slope = np.zeros((2, 2, n_cells))
    for c in range(n_cells):
        if is_mixed[c]:
            continue
        inside = True
        for i in range(k):
            inside &= node_material[cell_nodes[c, i]] == material[c]
        s = (shape[0, c], shape[1, c], shape[2, c], shape[3, c], shape[4, c], shape[5, c])
        cx, cy = centre[0, c], centre[1, c]
        for f in range(2):
            gx, gy = averaged_gradient(cell_type, cell_nodes, c, row, 2 + f, area[c], s)
            if not inside:  # no slope (numpy's zero limiter: a non-finite gradient gives NaN)
                slope[f, 0, c] = gx * 0.0
                slope[f, 1, c] = gy * 0.0
                continue
            v = value[f, c]
            limiter = 1.0
            for i in range(k):
                node = cell_nodes[c, i]
                delta = gx * (row[node, 0] - cx)
                delta += gy * (row[node, 1] - cy)
                # room ≥ 0 where δ = 0 (a cell's range holds its value): the bound is +∞ or
                # NaN there, and NaN sets no bound (np.fmin; of equals, the bound)
                high, low = row[node, 5 + 2 * f], row[node, 4 + 2 * f]
                room = (high if delta >= 0 else low) - v
                bound = clip_unit(room / delta)
                limiter = limiter if (bound != bound) | (limiter < bound) else bound
            slope[f, 0, c] = gx * limiter
            slope[f, 1, c] = gy * limiter
    # the swept regions' centroids (every region's, in a loop that vectorises), then the
    # pure donors' corrections
    n = donor.size
    centroid = np.empty((2, n))
    for j in range(n):
        _, centroid[0, j], centroid[1, j] = fan_centroid(swept[0, 0, j], swept[1, 0, j], swept[0, 1, j],
                                                         swept[1, 1, j], swept[0, 2, j], swept[1, 2, j],
                                                         swept[0, 3, j], swept[1, 3, j], 4)
    for j in range(n):
        source = donor[j]
        if is_mixed[source]:
            continue
        sx = centroid[0, j] - centre[0, source]
        sy = centroid[1, j] - centre[1, source]
        volume = flux_volume[0, j]
        for m in range(1, flux_volume.shape[0]):
            volume += flux_volume[m, j]
        m = material[source]
        correction = slope[0, 0, source] * sx
        correction += slope[0, 1, source] * sy
        flux_mass[m, j] += correction * volume
        correction = slope[1, 0, source] * sx
        correction += slope[1, 1, source] * sy
        flux_energy[m, j] += correction * volume


# a swept quadrilateral clipped by a cell's k edges has at most 4 · 2^k vertices (each pass
# emits at most two points an edge)
MAX_CLIPPED = 64


@numba.njit(**KERNEL)
def mixed_donor_parts(swept, edges, x, cell_nodes, donor, size, normal, offset, line):  # pragma: no cover (compiled)
    """Of each swept region ``edges`` (indices into the moving edges) whose donor is a
    mixed cell: the part inside the donor (the region, counter-clockwise, clipped by the
    donor's counter-clockwise cell), of that the part {x·n ≤ s} of the donor's PLIC line
    (``line[j]``: the row of ``normal``, ``offset``) — each clipped to [0, what holds it] —
    and the part {x·n ≤ s} of the whole region, the line extended beyond the donor.
    Returns (inside, alpha, alpha_whole), each (len(edges),)."""
    n = edges.size
    k = cell_nodes.shape[1]
    inside = np.empty(n)
    alpha = np.empty(n)
    alpha_whole = np.empty(n)
    ax, ay = np.empty(MAX_CLIPPED), np.empty(MAX_CLIPPED)
    bx, by = np.empty(MAX_CLIPPED), np.empty(MAX_CLIPPED)
    cx, cy = np.empty(k), np.empty(k)
    for r in range(n):
        e = edges[r]
        for v in range(4):
            ax[v], ay[v] = swept[0, v, e], swept[1, v, e]
        if shoelace(ax, ay, 4) < 0:  # counter-clockwise
            for v in range(2):
                ax[v], ax[3 - v] = ax[3 - v], ax[v]
                ay[v], ay[3 - v] = ay[3 - v], ay[v]
        j = line[r]
        alpha_whole[r] = area_below_line(ax, ay, 4, normal[j, 0], normal[j, 1], offset[j])
        cell = donor[e]
        for v in range(k):
            cx[v], cy[v] = x[0, cell_nodes[cell, v]], x[1, cell_nodes[cell, v]]
        if shoelace(cx, cy, k) < 0:
            for v in range(k // 2):
                cx[v], cx[k - 1 - v] = cx[k - 1 - v], cx[v]
                cy[v], cy[k - 1 - v] = cy[k - 1 - v], cy[v]
        m = 4
        for v in range(k):  # one pass per edge of the cell (geometry.shapes.clip_convex)
            w = (v + 1) % k
            ex, ey = cx[w] - cx[v], cy[w] - cy[v]
            ox, oy = ey, -ex  # right of a counter-clockwise edge
            length = np.sqrt(ox * ox + oy * oy)
            if length == 0.0:  # a zero-length edge clips nothing
                continue
            ox, oy = ox / length, oy / length
            m = clip_by_line(ax, ay, m, ox, oy, ox * cx[v] + oy * cy[v], bx, by)
            ax, bx = bx, ax
            ay, by = by, ay
            if m == 0:
                break
        part = shoelace(ax, ay, m) if m > 0 else 0.0
        inside[r] = minimum(maximum(part, 0.0), size[e])
        cut = area_below_line(ax, ay, m, normal[j, 0], normal[j, 1], offset[j]) if m > 0 else 0.0
        alpha[r] = minimum(maximum(cut, 0.0), inside[r])
    return inside, alpha, alpha_whole


@numba.njit(**KERNEL, inline="always")
def corner_shares_at(first, cell, corner, node_index, share):  # pragma: no cover (compiled)
    """The five cell fields ``share`` (5, n_cells) of :func:`cell_momentum` summed over the
    cells around node ``node_index`` in cell_kernels.node_area_sums' order (that gather, of
    three sums, written for five: a width given at run time kept its sums in memory, three
    times slower): corner by corner, each corner's cells in order, each corner's sum (from
    +0) then added (``first``,
    ``cell``, ``corner``: ale_xfem.model.mesh.node_corners, by corner then by cell)."""
    t0, t1, t2, t3, t4 = 0.0, 0.0, 0.0, 0.0, 0.0
    j, end = first[node_index], first[node_index + 1]
    while j < end:
        i = corner[j]
        p0, p1, p2, p3, p4 = 0.0, 0.0, 0.0, 0.0, 0.0
        while j < end and corner[j] == i:
            c = cell[j]
            p0 += share[0, c]
            p1 += share[1, c]
            p2 += share[2, c]
            p3 += share[3, c]
            p4 += share[4, c]
            j += 1
        t0 += p0
        t1 += p1
        t2 += p2
        t3 += p3
        t4 += p4
    return t0, t1, t2, t3, t4


@numba.njit(**KERNEL)
def cell_momentum(u, cell_nodes, first, cell, corner, old_cell_mass, new_cell_mass, flux_mass, donor,
                  receiver):  # pragma: no cover (compiled)
    """Nodal momentum through the cells (remapper_2d's module docstring), one velocity field
    ``u`` (2, n_nodes): each cell holds the momentum of its corners at m_K/k each, the
    swept regions carry their mass at the donor cell's mean velocity, each node receives its
    cells' change by corner share.  Returns (velocity (2, n_nodes), node masses, and per
    node the kinetic energy before and what the remap dissipated: that, plus what the
    fluxes brought, less the kinetic energy after).  ``first``, ``cell``, ``corner``: the
    cells around each node (ale_xfem.model.mesh.node_corners), from which each node gathers
    its five corner shares in one pass (:func:`corner_shares_at`; scattered by the cells,
    corner by corner, they were twenty passes)."""
    n_cells, k = cell_nodes.shape
    dim, n_nodes = u.shape
    cell_velocity = np.zeros((dim, n_cells))
    for d in range(dim):
        for c in range(n_cells):
            total = 0.0
            for i in range(k):
                total += u[d, cell_nodes[c, i]]
            cell_velocity[d, c] = total / k
    n = donor.size
    total_flux = flux_mass[0].copy()
    for m in range(1, flux_mass.shape[0]):
        total_flux += flux_mass[m]
    into, out = np.zeros((dim + 1, n_cells)), np.zeros((dim + 1, n_cells))
    for j in range(n):
        speed2 = 0.0
        for d in range(dim):
            v = cell_velocity[d, donor[j]]
            flux = total_flux[j] * v
            into[d, receiver[j]] += flux
            out[d, donor[j]] += flux
            speed2 = speed2 + v * v if d > 0 else v * v
        kinetic = 0.5 * total_flux[j] * speed2
        into[dim, receiver[j]] += kinetic
        out[dim, donor[j]] += kinetic
    # each corner's share: the old and new masses, the momentum's change per component and
    # the kinetic energy the fluxes brought
    share = np.empty((5, n_cells))
    for c in range(n_cells):
        share[0, c] = old_cell_mass[c] / k
        share[1, c] = new_cell_mass[c] / k
        share[2, c] = (into[0, c] - out[0, c]) / k
        share[3, c] = (into[1, c] - out[1, c]) / k
        share[4, c] = (into[2, c] - out[2, c]) / k
    velocity = np.empty((dim, n_nodes))
    node_mass = np.empty(n_nodes)
    kinetic_before = np.empty(n_nodes)
    loss = np.empty(n_nodes)
    for node in range(n_nodes):
        old_mass, new_mass, moved0, moved1, kinetic_in = corner_shares_at(first, cell, corner, node, share)
        node_mass[node] = new_mass
        u0, u1 = u[0, node], u[1, node]
        v0 = (u0 * old_mass + moved0) / new_mass
        v1 = (u1 * old_mass + moved1) / new_mass
        velocity[0, node], velocity[1, node] = v0, v1
        kinetic_before[node] = 0.5 * old_mass * (u0 * u0 + u1 * u1)
        loss[node] = kinetic_before[node] + kinetic_in - 0.5 * new_mass * (v0 * v0 + v1 * v1)
    return velocity, node_mass, kinetic_before, loss


@numba.njit(**KERNEL)
def deposit_heat(cell_nodes, per_mass, mass, energy):  # pragma: no cover (compiled)
    """The kinetic energy a remap lost, ``per_mass`` at each node (loss over nodal mass),
    into the materials' internal energies (n_materials, n_cells), in place: each cell takes
    its corners' Σ_i per_mass_i · m_K/k, shared by its materials' masses (remapper_2d's
    ``_deposit``, one velocity field)."""
    n_materials, n_cells = mass.shape
    k = cell_nodes.shape[1]
    for c in range(n_cells):
        cell_mass = mass[0, c]
        for m in range(1, n_materials):
            cell_mass += mass[m, c]
        total = 0.0
        for i in range(k):
            total += per_mass[cell_nodes[c, i]]
        heat = total * (cell_mass / k)
        for m in range(n_materials):
            energy[m, c] += heat * (mass[m, c] / cell_mass if cell_mass > 0 else 0.0)


@numba.njit(**KERNEL)
def deposit_corner_heat(cell_nodes, per_mass, corner_mass, energy):  # pragma: no cover (compiled)
    """The kinetic energy a remap lost, ``per_mass`` at each node (loss over nodal mass),
    into each material's internal energy (2, n_cells), in place: each cell takes its
    corners' Σ_i per_mass_i c_mi, c the material's own corner masses (2, k, n_cells;
    remapper_2d's ``_deposit``, 2D enriched cells), summed corner by corner."""
    n_cells, k = cell_nodes.shape
    for m in range(corner_mass.shape[0]):
        for c in range(n_cells):
            total = per_mass[cell_nodes[c, 0]] * corner_mass[m, 0, c]
            for i in range(1, k):
                total += per_mass[cell_nodes[c, i]] * corner_mass[m, i, c]
            energy[m, c] += total


@numba.njit(**KERNEL)
def material_momentum_fluxes(cell_nodes, corner_mass, node_velocity, node_internal, flux_mass, donor,
                             receiver, added_mass, added_momentum, added_kinetic):  # pragma: no cover (compiled)
    """2D enriched cells, each material on its own (remapper_2d's
    ``_material_momentum_fluxes``): each cell holds Σ_i c_mi u_mi over its corners (c: the
    material's corner masses (2, k, n_cells)) and what the materials' crossings of the
    Lagrangian edges brought it (``added_mass`` (2, n_cells), ``added_momentum`` (2
    components, 2 materials, n_cells), ``added_kinetic`` (2, n_cells)); a swept region
    carries each material's mass flux at the donor's mean velocity of that material.
    Returns (each material's momentum per cell after the fluxes (2 components, 2
    materials, n_cells), the kinetic energy the crossings and fluxes bring each cell (2,
    n_cells), each corner's velocity less its cell's mean at the material's internal
    nodes (2 materials, 2 components, k, n_cells))."""
    n_cells, k = cell_nodes.shape
    n = donor.size
    momentum = np.zeros((2, 2, n_cells))
    kinetic_in = np.zeros((2, n_cells))
    deviation = np.empty((2, 2, k, n_cells))
    cell_velocity = np.zeros((2, n_cells))
    into, out = np.empty((3, n_cells)), np.empty((3, n_cells))
    for m in range(2):
        for c in range(n_cells):
            cell_mass = corner_mass[m, 0, c]
            empty = corner_mass[m, 0, c] == 0.0
            for i in range(1, k):
                cell_mass += corner_mass[m, i, c]
                empty &= corner_mass[m, i, c] == 0.0
            if empty and added_mass[m, c] == 0.0:  # the material is not in the cell: its sums are zeros
                for d in range(2):
                    momentum[d, m, c] = 0.0 + added_momentum[d, m, c]
                    cell_velocity[d, c] = 0.0
                    for i in range(k):
                        deviation[m, d, i, c] = 0.0
                continue
            cell_mass += added_mass[m, c]
            for d in range(2):
                total = corner_mass[m, 0, c] * node_velocity[m, d, cell_nodes[c, 0]]
                for i in range(1, k):
                    total += corner_mass[m, i, c] * node_velocity[m, d, cell_nodes[c, i]]
                total += added_momentum[d, m, c]
                momentum[d, m, c] = total
                mean = total / cell_mass if cell_mass > 0 else 0.0
                cell_velocity[d, c] = mean
                for i in range(k):
                    node = cell_nodes[c, i]
                    internal = cell_mass > 0 and node_internal[m, node]
                    deviation[m, d, i, c] = node_velocity[m, d, node] - mean if internal else 0.0
        into[:] = 0.0
        out[:] = 0.0
        for j in range(n):
            if flux_mass[m, j] == 0.0:  # (it would add zeros: sums that start at +0 keep their bits)
                continue
            v0, v1 = cell_velocity[0, donor[j]], cell_velocity[1, donor[j]]
            f0, f1 = flux_mass[m, j] * v0, flux_mass[m, j] * v1
            kinetic = 0.5 * flux_mass[m, j] * (v0 * v0 + v1 * v1)
            into[0, receiver[j]] += f0
            out[0, donor[j]] += f0
            into[1, receiver[j]] += f1
            out[1, donor[j]] += f1
            into[2, receiver[j]] += kinetic
            out[2, donor[j]] += kinetic
        for c in range(n_cells):
            momentum[0, m, c] += into[0, c] - out[0, c]
            momentum[1, m, c] += into[1, c] - out[1, c]
            kinetic_in[m, c] = into[2, c] - out[2, c] + added_kinetic[m, c]
    return momentum, kinetic_in, deviation


@numba.njit(**KERNEL)
def material_node_velocities(cell_nodes, corner_mass, node_mass, owner, momentum, deviation, old_node_mass,
                             old_velocity, old_corner_mass, kinetic_in):  # pragma: no cover (compiled)
    """2D enriched cells (remapper_2d's ``_material_velocities``): each corner of a cell
    takes the cell's new mean velocity of the material plus its old ``deviation`` less the
    new-mass-weighted mean of the deviations, weighted at the nodes by the material's new
    corner masses; a material absent from a node moves with it (the node's own material's
    velocity).  Returns (each material's nodal velocity (2, 2, n_nodes), the mesh's
    velocity (2, n_nodes), the kinetic energy before per node, and per node what the remap
    dissipated: that kinetic energy, plus what the fluxes brought by corner shares — the new
    ones, or the old ones in a cell the material has left — and what the new shares moved
    to the node from the cell's other corners (its old mass re-lumped, at the cell's new
    mean velocity), less the kinetic energy after).  A uniform velocity then loses nothing
    at any node, however the condensation's shares change: counted as lost, the re-lumped
    mass's kinetic energy heated the cells a moving interface crosses (a disk carried by a
    uniform flow: pressures 15 % off around it by t = 0.2)."""
    n_cells, k = cell_nodes.shape
    n_nodes = node_mass.shape[1]
    cell_mass = np.empty((2, n_cells))
    old_cell_mass = np.empty((2, n_cells))
    for m in range(2):
        for c in range(n_cells):
            total, old = corner_mass[m, 0, c], old_corner_mass[m, 0, c]
            for i in range(1, k):
                total += corner_mass[m, i, c]
                old += old_corner_mass[m, i, c]
            cell_mass[m, c], old_cell_mass[m, c] = total, old
    # each corner's share of its cell's new mass of the material (kept for the fluxes'
    # kinetic energy below), each cell's mean velocity of the material and the
    # new-mass-weighted mean of its corners' deviations, the same for its k corners: formed
    # once a cell (formed for each corner, their divisions took most of the kernel's time),
    # in loops over the cells that vectorise
    shares = np.empty((2, k, n_cells))
    mean_velocity, spread = np.empty((2, 2, n_cells)), np.empty((2, 2, n_cells))
    for m in range(2):
        for r in range(k):
            for c in range(n_cells):
                mass = cell_mass[m, c]
                shares[m, r, c] = corner_mass[m, r, c] / mass if mass > 0 else 0.0
        for d in range(2):
            for c in range(n_cells):
                mass = cell_mass[m, c]
                mean_velocity[m, d, c] = momentum[d, m, c] / mass if mass > 0 else 0.0
            for c in range(n_cells):
                spread[m, d, c] = shares[m, 0, c] * deviation[m, d, 0, c]
            for r in range(1, k):
                for c in range(n_cells):
                    spread[m, d, c] = spread[m, d, c] + shares[m, r, c] * deviation[m, d, r, c]
    # corner by corner, each over the cells in order: each material's momentum at the nodes
    # (node_sums[:, 2 m + d]) and the kinetic energy the fluxes bring them (node_sums[:, 4]),
    # by the corners' shares of the cell's new mass of the material, or of its old mass in a
    # cell the material has left — one pass over the corners for the five sums
    node_sums = np.zeros((n_nodes, 5))
    for i in range(k):
        for c in range(n_cells):
            node = cell_nodes[c, i]
            for m in range(2):
                if corner_mass[m, i, c] == 0.0:  # (zeros: the material is not at this corner)
                    continue
                for d in range(2):
                    corner_velocity = mean_velocity[m, d, c] + deviation[m, d, i, c] - spread[m, d, c]
                    node_sums[node, 2 * m + d] += corner_mass[m, i, c] * corner_velocity
            brought = 0.0
            for m in range(2):
                if cell_mass[m, c] > 0:
                    share = shares[m, i, c]
                elif old_cell_mass[m, c] > 0:
                    share = old_corner_mass[m, i, c] / old_cell_mass[m, c]
                else:
                    share = 1.0 / k
                part = share * kinetic_in[m, c]
                if cell_mass[m, c] > 0:
                    # the mass the new shares move between the cell's corners (zero over
                    # them) goes with its kinetic energy at the cell's mean velocity
                    relumped = share * old_cell_mass[m, c] - old_corner_mass[m, i, c]
                    u0, u1 = mean_velocity[m, 0, c], mean_velocity[m, 1, c]
                    part += 0.5 * relumped * (u0 * u0 + u1 * u1)
                brought = part if m == 0 else brought + part
            node_sums[node, 4] += brought
    velocity = np.zeros((2, 2, n_nodes))
    for t in range(4):
        m, d = t // 2, t % 2
        for node in range(n_nodes):
            if node_mass[m, node] > 0:
                velocity[m, d, node] = node_sums[node, t] / node_mass[m, node]
    mesh_velocity = np.empty((2, n_nodes))
    for node in range(n_nodes):
        for d in range(2):
            mesh_velocity[d, node] = velocity[owner[node], d, node]
        for m in range(2):
            if node_mass[m, node] <= 0:
                velocity[m, 0, node], velocity[m, 1, node] = mesh_velocity[0, node], mesh_velocity[1, node]
    kinetic_before = np.empty(n_nodes)
    loss = np.empty(n_nodes)
    for node in range(n_nodes):
        before = old_node_mass[0, node] * (old_velocity[0, 0, node] * old_velocity[0, 0, node])
        after = node_mass[0, node] * (velocity[0, 0, node] * velocity[0, 0, node])
        for t in range(1, 4):
            m, d = t // 2, t % 2
            before += old_node_mass[m, node] * (old_velocity[m, d, node] * old_velocity[m, d, node])
            after += node_mass[m, node] * (velocity[m, d, node] * velocity[m, d, node])
        kinetic_before[node] = 0.5 * before
        loss[node] = kinetic_before[node] + node_sums[node, 4] - 0.5 * after
    return velocity, mesh_velocity, kinetic_before, loss


@numba.njit(**KERNEL)
def exchange(quantity, flux, donor, receiver):  # pragma: no cover (compiled)
    """Each cell's ``quantity`` (n_materials, n_cells) plus what the fluxes (n_materials, n)
    bring in less what they take out, in place (the sums over the edges in their order)."""
    n_materials, n_cells = quantity.shape
    into = np.empty(n_cells)
    out = np.empty(n_cells)
    for m in range(n_materials):
        into[:] = 0.0
        out[:] = 0.0
        for j in range(donor.size):
            into[receiver[j]] += flux[m, j]
            out[donor[j]] += flux[m, j]
        for c in range(n_cells):
            quantity[m, c] += into[c] - out[c]
