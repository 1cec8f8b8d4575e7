"""Compiled kernels of the 1D remap: the limited slopes of the pieces, the integral of a
linear piece, a lump's kinetic energy and the deposit of the kinetic energy the remap
loses, which both remaps use (ale_xfem.remap.pieces_1d); and the
swept-region remap's (ale_xfem.remap.swept_1d) whole-mesh pass over pure cells
(:func:`pure_cells`), the nodes' velocities and losses after it, and its windows around the
interfaces, material by material (:func:`window_contents`, :func:`window_momentum`).

Each is the numpy code it replaced, written per cell and per node in the same order of
operations, so the results are the same to the bit (tests/test_remap.py compares each with
that code, kept as the oracle in tests/oracles.py, and tests/test_regression.py compares the
shipped scenes byte by byte).  Comparisons
follow numpy's: ``np.maximum(a, b)`` gives b unless a > b (or a is NaN), and np.clip with
array bounds clips the same way, which fixes the sign of a zero when a = ±0 = b.  The two tests are combined with
``|``, not ``or``: ``or`` branches, and a minmod written with it took three times as long
(0.8 ms against 0.3 ms over 10⁵ values).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ale_xfem.geometry.polygon_kernels import KERNEL, maximum, minimum
from ale_xfem.model.cell_kernels import slot_density


@numba.njit(**KERNEL)
def minmod(a, b):  # pragma: no cover (compiled)
    """pieces_1d.minmod of two numbers: a held between 0 and b."""
    return minimum(maximum(a, minimum(b, 0.0)), maximum(b, 0.0))


@numba.njit(**KERNEL)
def limited_slopes(value, inverse_spacing, bounded, width, same_material):  # pragma: no cover (compiled)
    """Minmod slopes of ``value`` over sorted pieces (1 / spacing of their centres given),
    zero in the first and last piece and next to a piece of another material
    (``same_material[k]``: pieces k and k + 1 hold the same material), so that no
    information crosses Γ; ``bounded``: clipped to ±2|value|/width, in one clip (the left
    gradient held between 0 and the right one, that one first held within ±bound)."""
    n = value.size
    slope = np.zeros(n)
    if n < 3:
        return slope
    # (two loops without a branch, which vectorise: a slope across Γ is formed and dropped)
    if bounded:
        for j in range(1, n - 1):
            left = (value[j] - value[j - 1]) * inverse_spacing[j - 1]
            right = (value[j + 1] - value[j]) * inverse_spacing[j]
            bound = abs(value[j]) * (2.0 / width[j])
            low = minimum(maximum(right, -bound), 0.0)
            high = minimum(maximum(right, 0.0), bound)
            limited = minimum(maximum(left, low), high)
            slope[j] = limited if same_material[j - 1] & same_material[j] else 0.0
    else:
        for j in range(1, n - 1):
            left = (value[j] - value[j - 1]) * inverse_spacing[j - 1]
            right = (value[j + 1] - value[j]) * inverse_spacing[j]
            limited = minmod(left, right)
            slope[j] = limited if same_material[j - 1] & same_material[j] else 0.0
    return slope


@numba.njit(**KERNEL)
def below_zero_or_nan(value):  # pragma: no cover (compiled)
    """Whether ``value`` is below 0 or NaN: not (min(0, values) >= 0) over values, as an
    or-reduction of this (a slope's bound is formed then)."""
    return not value >= 0.0


@numba.njit(**KERNEL)
def moved_far(displacement, left_width, right_width):  # pragma: no cover (compiled)
    """Whether a node moved by more than half of the narrower of its two cells (the swept
    whole-mesh pass leaves it to a window)."""
    return abs(displacement) > 0.5 * minimum(left_width, right_width)


@numba.njit(**KERNEL)
def piece_slopes(centre, width, density, energy_density, order, same_material):  # pragma: no cover (compiled)
    """The limited slopes of a material's density and energy density over the pieces
    (sorted left to right; ``same_material``: see :func:`limited_slopes`): minmod within
    one material, zero at Γ, and no more than keeps the reconstruction of the same sign at
    both ends of the piece.  A minmod slope keeps both ends of a piece between its
    neighbours' values (the spacing of the centres is at least half the piece): a field
    with no negative value stays non-negative without the bound ±2|f|/w, which then cannot
    bind and is not formed (densities always; energy densities unless some are negative).
    Order 1: zero."""
    n = density.size
    if order != 2:
        return np.zeros(n), np.zeros(n)
    negative_density, negative_energy = False, False
    for j in range(n):
        negative_density |= below_zero_or_nan(density[j])
        negative_energy |= below_zero_or_nan(energy_density[j])
    return bounded_piece_slopes(centre, width, density, energy_density, order, same_material, negative_density,
                                negative_energy)


@numba.njit(**KERNEL)
def bounded_piece_slopes(centre, width, density, energy_density, order, same_material, negative_density,
                         negative_energy):  # pragma: no cover (compiled)
    """:func:`piece_slopes` with the choice of bounding the density's and the energy
    density's slopes made by the caller (``negative_…``: some value below 0 or NaN, over
    the whole mesh when the pieces are a window of it)."""
    n = density.size
    if order != 2:
        return np.zeros(n), np.zeros(n)
    inverse_spacing = np.empty(max(n - 1, 0))
    for j in range(n - 1):
        inverse_spacing[j] = 1.0 / (centre[j + 1] - centre[j])
    return (limited_slopes(density, inverse_spacing, negative_density, width, same_material),
            limited_slopes(energy_density, inverse_spacing, negative_energy, width, same_material))


@numba.njit(**KERNEL)
def far_nodes_looked_for(half_d, width):  # pragma: no cover (compiled)
    """Whether the largest |d|/2 of the nodes' displacements exceeds a quarter of the
    narrowest cell (False with a NaN in either)."""
    largest, smallest, narrowest = 0.0, 0.0, np.inf
    for k in range(half_d.size):
        largest = maximum(largest, half_d[k])
        smallest = minimum(smallest, half_d[k])
    for j in range(width.size):
        narrowest = minimum(narrowest, width[j])
    return maximum(largest, -smallest) > 0.25 * narrowest


# The whole-mesh pass goes over the mesh in blocks of this many cells, each with its own
# work arrays (about thirty), which then stay in a core's L2 cache: over 10⁵ cells a cell
# cost 30 ns in one block, 24–25 ns in blocks of one to four thousand (on an Intel Xeon
# with 2 MiB of L2 a core; the whole-mesh decisions and the outputs are the rest).  A block
# reads BLOCK_MARGIN cells beyond its own on each side, which is as far as a result's
# dependence reaches (a cell's new mass reads its nodes' fluxes, a node's flux its two
# cells' slopes, a slope its cell's neighbours): the two cells and nodes at each end of the
# window, which it computes as if the mesh ended there, are not used (with a margin of one
# the results differ: tests/test_remap.py).
PURE_CELLS_BLOCK = 2048
BLOCK_MARGIN = 2


@numba.njit(**KERNEL)
def pure_cells(x, X, mass, specific_energy, corner, u, order, slots, heat, block=PURE_CELLS_BLOCK):  # pragma: no cover (compiled)
    """The swept-region remap of a mesh's cells as if all were pure cells of one material
    (swept_1d's whole-mesh pass; its docstring gives the formulas).  Returns (new masses
    and total energies (slots, n) with slot 0 filled, the corner masses (2, n) with the right
    ones filled, node masses, node momenta, each node's ½ M u² before, each node's
    kinetic-energy balance (``heat``; else zeros), the nodes that moved by more than half a
    neighbouring cell).  Done ``block`` cells at a time (the results do not depend on it)."""
    n = mass.size
    if n == 0:
        raise ValueError("pure_cells: a mesh of no cells")
    if block < 1:
        raise ValueError("pure_cells: blocks of no cells")
    components = u.shape[0]
    negative_density, negative_energy, far = whole_mesh_decisions(x, X, mass, specific_energy)
    # (every entry is written below but the second slots' and the left corners', zero)
    new_mass, new_energy = np.empty((slots, n)), np.empty((slots, n))
    new_mass[1:], new_energy[1:] = 0.0, 0.0
    corner_new = np.empty((2, n))
    corner_new[0] = 0.0
    node_mass, momentum = np.empty(n + 1), np.empty((components, n + 1))
    kinetic_start, kinetic = np.empty(n + 1), np.empty(n + 1)
    for first in range(0, n, block):
        last = min(first + block, n)
        low, high = max(first - BLOCK_MARGIN, 0), min(last + BLOCK_MARGIN, n)
        window_mass, window_energy, right_corner, window_node_mass, window_momentum, window_start, window_kinetic = \
            pure_cells_window(x[low:high + 1], X[low:high + 1], mass[low:high], specific_energy[low:high],
                              np.ascontiguousarray(corner[:, low:high]), np.ascontiguousarray(u[:, low:high + 1]),
                              order, heat, negative_density,
                              negative_energy)
        # the block's cells, and its nodes: the left one of each cell, the mesh's last
        new_mass[0, first:last] = window_mass[first - low:last - low]
        new_energy[0, first:last] = window_energy[first - low:last - low]
        corner_new[1, first:last] = right_corner[first - low:last - low]
        end = last + 1 if last == n else last
        node_mass[first:end] = window_node_mass[first - low:end - low]
        kinetic_start[first:end] = window_start[first - low:end - low]
        kinetic[first:end] = window_kinetic[first - low:end - low]
        momentum[:, first:end] = window_momentum[:, first - low:end - low]
    return new_mass, new_energy, corner_new, node_mass, momentum, kinetic_start, kinetic, far


@numba.njit(**KERNEL)
def whole_mesh_decisions(x, X, mass, specific_energy):  # pragma: no cover (compiled)
    """What :func:`pure_cells` decides over the whole mesh before its blocks: whether some
    density, and some energy density, is negative or NaN (their slopes are then bounded,
    as :func:`piece_slopes` decides), and the nodes that moved by more than half a
    neighbouring cell (looked for node by node only when the largest |d|/2 exceeds a
    quarter of the narrowest cell, never with a NaN anywhere, as the numpy code did)."""
    n = mass.size
    negative_density, negative_energy = False, False
    for j in range(n):  # (the densities pure_cells_window forms, formed the same way)
        w = x[j + 1] - x[j]
        negative_density |= below_zero_or_nan(mass[j] / w)
        negative_energy |= below_zero_or_nan((mass[j] * specific_energy[j]) / w)
    any_far = False
    for k in range(n - 1):  # (an or-reduction, without a branch)
        any_far |= moved_far(X[k + 1] - x[k + 1], x[k + 1] - x[k], x[k + 2] - x[k + 1])
    far = np.empty(max(n - 1, 0), dtype=np.int64)
    far_count = 0
    if any_far:  # (rare: the arrays of the test made only here)
        width, half_d = np.empty(n), np.empty(n - 1)
        for j in range(n):
            width[j] = x[j + 1] - x[j]
        for k in range(n - 1):
            half_d[k] = 0.5 * (X[k + 1] - x[k + 1])
        if far_nodes_looked_for(half_d, width):
            for k in range(n - 1):
                if moved_far(X[k + 1] - x[k + 1], width[k], width[k + 1]):
                    far[far_count] = k + 1
                    far_count += 1
    return negative_density, negative_energy, far[:far_count]


@numba.njit(**KERNEL)
def pure_cells_window(x, X, mass, specific_energy, corner, u, order, heat, negative_density, negative_energy):  # pragma: no cover (compiled)
    """:func:`pure_cells` on a window of cells as if the mesh ended at its ends, the
    slopes bounded as the whole mesh decided: (new masses and total energies, right corner
    masses, node masses, node momenta, ½ M u² before, kinetic-energy balances or zeros)."""
    n = mass.size
    components = u.shape[0]
    width, half_width, centre = np.empty(n), np.empty(n), np.empty(n)
    energy, rho, eps = np.empty(n), np.empty(n), np.empty(n)
    for j in range(n):
        w = x[j + 1] - x[j]
        width[j] = w
        half_width[j] = 0.5 * w
        centre[j] = x[j] + half_width[j]
        energy[j] = mass[j] * specific_energy[j]
        rho[j] = mass[j] / w
        eps[j] = energy[j] / w
    srho, seps = bounded_piece_slopes(centre, width, rho, eps, order, np.ones(max(n - 1, 0), dtype=np.bool_),
                                      negative_density, negative_energy)

    # nodes 1 … n − 1 move by d.  (The loops over the cells and nodes below are written
    # without a branch or a running reduction, the ends taken apart, so that the compiler
    # vectorises them: the selects read both candidates, the formulas are those of the numpy
    # code, in its order.)
    inner = max(n - 1, 0)
    d, half_d = np.empty(inner), np.empty(inner)
    for k in range(inner):
        d[k] = X[k + 1] - x[k + 1]
        half_d[k] = 0.5 * d[k]

    # cell fluxes through the nodes, from each node's donor cell (the right one when d > 0)
    flux_mass, flux_energy = np.empty(inner), np.empty(inner)
    for k in range(inner):
        right_donor = d[k] > 0.0
        offset = half_d[k] + x[k + 1]
        offset -= centre[k + 1] if right_donor else centre[k]  # x_k + d/2 − c_D
        minus_d = -d[k]
        flux = (srho[k + 1] if right_donor else srho[k]) * offset
        flux += rho[k + 1] if right_donor else rho[k]
        flux_mass[k] = flux * minus_d
        flux = (seps[k + 1] if right_donor else seps[k]) * offset
        flux += eps[k + 1] if right_donor else eps[k]
        flux_energy[k] = flux * minus_d
    new_mass, new_energy = np.zeros((1, n)), np.zeros((1, n))
    for j in range(n):  # the cell's own mass, what its left node brings, what its right one takes
        new_mass[0, j], new_energy[0, j] = mass[j], energy[j]
    if n > 1:
        new_mass[0, 0] -= flux_mass[0]
        new_energy[0, 0] -= flux_energy[0]
        for j in range(1, n - 1):
            m = mass[j] + flux_mass[j - 1]
            new_mass[0, j] = m - flux_mass[j]
            e = energy[j] + flux_energy[j - 1]
            new_energy[0, j] = e - flux_energy[j]
        new_mass[0, n - 1] += flux_mass[n - 2]
        new_energy[0, n - 1] += flux_energy[n - 2]

    # nodal momentum through the dual faces: cell j's part beside node j moves by the node's
    # displacement (the mean of its two faces' half displacements), from the side it leaves
    delta_of = np.empty(n)
    if n == 1 or inner == 0:
        delta_of[0] = 0.0
    else:
        delta_of[0] = half_d[0]
        for j in range(1, n - 1):
            delta_of[j] = half_d[j - 1] + half_d[j]
        delta_of[n - 1] = half_d[inner - 1]
    swept, moment, from_left = np.empty(n), np.empty(n), np.empty(n, dtype=np.bool_)
    scale_left, scale_right = np.empty(n), np.empty(n)
    for j in range(n):
        mass_left = srho[j] * half_width[j]
        mass_left *= -0.5
        mass_left += rho[j]
        mass_left *= half_width[j]  # ∫ over L_j = [x_j, c_j]
        mass_right = mass[j] - mass_left
        scale_left[j] = corner[0, j] / mass_left
        scale_right[j] = corner[1, j] / mass_right
        delta = delta_of[j]
        left = delta < 0.0
        from_left[j] = left
        half_delta = 0.5 * delta
        s = srho[j] * half_delta
        s += rho[j]
        s *= -delta
        scale = scale_left[j] if left else scale_right[j]
        part_centre = width[j] * width[j]
        part_centre *= width[j]
        part_centre *= srho[j]
        part_centre *= 1.0 / 96.0
        part_centre /= mass_left if left else mass_right
        part_centre += math.copysign(0.25 * width[j], delta)
        m = half_delta - part_centre
        m *= s
        cube = delta * delta
        cube *= delta
        cube *= srho[j]
        cube *= 1.0 / 12.0
        m -= cube
        moment[j] = m * scale
        swept[j] = s * scale
    # each node's limited velocity slope (zero at the ends), then what each lump carries
    # from its donor node (node j when it leaves to the left, j + 1 otherwise)
    moved = np.empty((components, n))
    tau, gradient = np.zeros(n + 1), np.empty(n)
    for c in range(components):
        if order == 2:
            for j in range(n):  # (each cell's once: a node's minmod reads its two cells')
                gradient[j] = (u[c, j + 1] - u[c, j]) / width[j]
            for i in range(1, n):
                tau[i] = minmod(gradient[i - 1], gradient[i])
            for j in range(n):
                value = (tau[j] if from_left[j] else tau[j + 1]) * moment[j]
                value += (u[c, j] if from_left[j] else u[c, j + 1]) * swept[j]
                moved[c, j] = value
        else:
            for j in range(n):
                value = 0.0
                value += (u[c, j] if from_left[j] else u[c, j + 1]) * swept[j]
                moved[c, j] = value

    old_node_mass, node_mass = np.empty(n + 1), np.empty(n + 1)
    old_node_mass[0] = corner[0, 0]
    node_mass[0] = old_node_mass[0] - swept[0]
    for k in range(1, n):
        old = corner[0, k] + corner[1, k - 1]
        old_node_mass[k] = old
        new = old - swept[k]
        node_mass[k] = new + swept[k - 1]
    old_node_mass[n] = 0.0 + corner[1, n - 1]
    node_mass[n] = old_node_mass[n] + swept[n - 1]
    momentum = np.empty((components, n + 1))
    for c in range(components):
        momentum[c, 0] = u[c, 0] * old_node_mass[0] - moved[c, 0]
        for k in range(1, n):
            p = u[c, k] * old_node_mass[k] - moved[c, k]
            momentum[c, k] = p + moved[c, k - 1]
        momentum[c, n] = u[c, n] * old_node_mass[n] + moved[c, n - 1]
    # ½ M u², less what is handed over, plus what comes in
    kinetic_start, kinetic = np.empty(n + 1), np.zeros(n + 1)
    for k in range(n + 1):
        square = u[0, k] * u[0, k]
        for c in range(1, components):
            square += u[c, k] * u[c, k]
        square *= old_node_mass[k]
        kinetic_start[k] = square * 0.5
    if heat:
        lump = np.empty(n)
        for j in range(n):  # ½ |p|²/m of each swept lump, signed like its mass
            energy_of_lump = moved[0, j] * moved[0, j]
            for c in range(1, components):
                energy_of_lump += moved[c, j] * moved[c, j]
            energy_of_lump *= 0.5
            quotient = energy_of_lump / swept[j]
            energy_of_lump = quotient if swept[j] != 0.0 else 0.0
            lump[j] = math.copysign(energy_of_lump, swept[j])
        kinetic[0] = kinetic_start[0] - lump[0]
        for k in range(1, n):
            balance = kinetic_start[k] - lump[k]
            kinetic[k] = balance + lump[k - 1]
        kinetic[n] = kinetic_start[n] + lump[n - 1]

    # right corner of new cell j: R_j + what the face moved into it − the node's swept mass
    # in the part beside the node
    corner_new = np.zeros((2, n))
    for j in range(n - 1):
        right = corner[1, j] + swept[j]
        corner_new[1, j] = right - (scale_left[j + 1] if d[j] > 0.0 else scale_right[j]) * flux_mass[j]
    corner_new[1, n - 1] = corner[1, n - 1] + swept[n - 1]
    return new_mass[0], new_energy[0], corner_new[1], node_mass, momentum, kinetic_start, kinetic




@numba.njit(**KERNEL)
def window_ranges(mixed_j, boundaries, far_nodes, n, taken_margin, window_margin):  # pragma: no cover (compiled)
    """The windows around the cells where the whole-mesh pass does not hold (sorted cells
    of n: each mixed cell and the one after it, the two cells at each node where the
    material changes (``boundaries``: the cell before it) and at each node that moved far):
    the cells within ``taken_margin`` of them, merged where they meet, and each such range
    widened by ``window_margin``.  Returns (k, 4) rows: the taken range [first, last) and
    its window [first, last), left to right."""
    special = np.empty(2 * (mixed_j.size + boundaries.size + far_nodes.size), dtype=np.int64)
    count = 0
    for values, shift in ((mixed_j, 0), (boundaries, 0), (far_nodes, -1)):
        for v in values:
            special[count] = v + shift
            special[count + 1] = v + shift + 1
            count += 2
    special = np.sort(special[:count])
    ranges = np.empty((count, 4), dtype=np.int64)
    k = 0
    for i in range(count):
        j = special[i]
        if j >= n or (i > 0 and j == special[i - 1]):
            continue
        lo, hi = max(j - taken_margin, 0), min(j + taken_margin + 1, n)
        if k > 0 and lo <= ranges[k - 1, 1]:  # meets the range before it
            ranges[k - 1, 1] = hi
        else:
            ranges[k, 0], ranges[k, 1] = lo, hi
            k += 1
    for r in range(k):
        ranges[r, 2] = max(ranges[r, 0] - window_margin, 0)
        ranges[r, 3] = min(ranges[r, 1] + window_margin, n)
    return ranges[:k]


@numba.njit(**KERNEL)
def two_slots(material, X):  # pragma: no cover (compiled)
    """The two slots a swept remap of sorted cells fills in (its windows put a second
    material in some cells): (each slot's material, −1 in slot 1; each slot's volume, the
    new cell's length X_{j+1} − X_j in slot 0, 0 in slot 1), in one pass."""
    n = material.size
    slot_material, volume = np.empty((2, n), dtype=np.int64), np.empty((2, n))
    for j in range(n):
        slot_material[0, j] = material[j]
        slot_material[1, j] = -1
        volume[0, j] = X[j + 1] - X[j]
        volume[1, j] = 0.0
    return slot_material, volume


@numba.njit(**KERNEL)
def node_velocities_and_losses(node_mass, momentum, right_corner, left_corner, kinetic, heat):  # pragma: no cover (compiled)
    """The end of the swept remap over the sorted nodes: each cell's left corner mass (its
    left node's new mass less what the cell before lumps on it), each node's velocity
    p / M, ½ p·u, and (``heat``) its kinetic-energy loss, what it held less ½ p·u.  Returns
    (velocity, ½ p·u, loss or an empty array)."""
    components, nodes = momentum.shape
    left_corner[0] = node_mass[0]
    for j in range(1, nodes - 1):
        left_corner[j] = node_mass[j] - right_corner[j - 1]
    velocity = np.empty((components, nodes))
    for c in range(components):
        for k in range(nodes):
            velocity[c, k] = momentum[c, k] / node_mass[k]
    kinetic_new = np.empty(nodes)
    for k in range(nodes):
        kinetic_new[k] = momentum[0, k] * velocity[0, k]
    for c in range(1, components):
        for k in range(nodes):
            kinetic_new[k] += momentum[c, k] * velocity[c, k]
    for k in range(nodes):
        kinetic_new[k] *= 0.5
    loss = np.empty(nodes if heat else 0)
    if heat:
        for k in range(nodes):
            loss[k] = kinetic[k] - kinetic_new[k]
    return velocity, kinetic_new, loss


@numba.njit(**KERNEL)
def loss_per_unit_mass(loss, node_mass):  # pragma: no cover (compiled)
    """A node's kinetic-energy loss per unit of its mass (nothing from a node without mass)."""
    return loss / node_mass if node_mass > 0.0 else 0.0


@numba.njit(**KERNEL)
def cell_heat(left_per_mass, right_per_mass, left_corner, right_corner):  # pragma: no cover (compiled)
    """The kinetic-energy loss a cell takes from its two nodes (each node's loss per unit
    of mass times the corner mass the cell lumps on it): (its right corner's share, the
    whole)."""
    right = right_per_mass * right_corner
    return right, left_per_mass * left_corner + right


@numba.njit(**KERNEL)
def second_slot_specific_energies(specific, mass, energy, slot1_cells):  # pragma: no cover (compiled)
    """Slot 1's specific energies, in place: E / m in ``slot1_cells`` (the cells the swept
    remap's windows redid) where the slot holds mass, 0 elsewhere."""
    specific[1] = 0.0
    for j in slot1_cells:
        if mass[1, j] > 0.0:
            specific[1, j] = energy[1, j] / mass[1, j]


@numba.njit(**KERNEL)
def end_of_swept_remap(node_mass, momentum, corner, kinetic, mass, energy, volume, slot1_cells, mixed_cells):  # pragma: no cover (compiled)
    """The end of the swept remap of enriched cells on a mesh whose cell j lies between
    nodes j and j + 1, every loss deposited: :func:`node_velocities_and_losses` (the left
    corners filled in ``corner``), the specific energies of the new total energies and
    masses (slots, n) (slot 1 only in ``slot1_cells``, where it holds mass; 0 elsewhere),
    :func:`deposit_losses` on them, and the densities (``cell_kernels.slot_densities``: slot
    1 has no volume outside ``slot1_cells``), in one pass over the cells.  Returns
    (velocity, ½ p·u, specific energies, densities)."""
    velocity, kinetic_new, loss = node_velocities_and_losses(node_mass, momentum, corner[1], corner[0], kinetic,
                                                             True)
    nodes = node_mass.size
    slots, cells = mass.shape
    per_mass = np.empty(nodes)
    for k in range(nodes):
        per_mass[k] = loss_per_unit_mass(loss[k], node_mass[k])
    specific, density = np.empty((slots, cells)), np.empty((slots, cells))
    for j in range(cells):  # energy / mass, then heat / mass added, as the two passes did
        _, heat = cell_heat(per_mass[j], per_mass[j + 1], corner[0, j], corner[1, j])
        e = energy[0, j] / mass[0, j]
        specific[0, j] = e + heat / mass[0, j]
        density[0, j] = slot_density(mass[0, j], volume[0, j])
    if slots > 1:
        second_slot_specific_energies(specific, mass, energy, slot1_cells)
        density[1] = 0.0
        for j in slot1_cells:
            density[1, j] = slot_density(mass[1, j], volume[1, j])
        for c in mixed_cells:  # the right corner's share heats slot 1
            right, heat = cell_heat(per_mass[c], per_mass[c + 1], corner[0, c], corner[1, c])
            heat -= right
            specific[1, c] += right / mass[1, c]
            e = energy[0, c] / mass[0, c]
            specific[0, c] = e + heat / mass[0, c]
    return velocity, kinetic_new, specific, density


@numba.njit(**KERNEL)
def deposit_losses(loss, corner_mass, node_mass, left_node, right_node, in_order, mixed_cells, condensed,
                   material_mass, material_energy):  # pragma: no cover (compiled)
    """pieces_1d.deposit_kinetic_loss with every loss deposited (its docstring gives the
    rule), in place on ``material_energy`` (specific): each node's loss per unit of its
    mass, times each corner mass lumped on it, heats that corner's cell; in a mixed cell the
    right corner's share goes to slot 1 (``condensed``) or the cell's heat is shared by
    mass."""
    nodes, cells = loss.size, corner_mass.shape[1]
    per_mass = np.empty(nodes)
    for k in range(nodes):
        per_mass[k] = loss_per_unit_mass(loss[k], node_mass[k])
    heat, right = np.empty(cells), np.empty(cells)
    if in_order:
        for j in range(cells):
            right[j], heat[j] = cell_heat(per_mass[j], per_mass[j + 1], corner_mass[0, j], corner_mass[1, j])
    else:
        for j in range(cells):
            right[j], heat[j] = cell_heat(per_mass[left_node[j]], per_mass[right_node[j]], corner_mass[0, j],
                                          corner_mass[1, j])
    for c in mixed_cells:
        if condensed:
            to_second = right[c]
        else:
            to_second = heat[c] * material_mass[1, c] / (material_mass[0, c] + material_mass[1, c])
        heat[c] -= to_second
        material_energy[1, c] += to_second / material_mass[1, c]
    for j in range(cells):
        material_energy[0, j] += heat[j] / material_mass[0, j]


# -- the nodal momentum of a window (swept_1d._swept_sorted) ------------------------------
# A window's node parts: cell j's L_j = [x_j, f_j], owned by node j, and R_j = [f_j,
# x_{j+1}], owned by node j + 1, f_j the cell's middle or, in an enriched mixed cell, Γ (the
# mass condensation).  Each carries its density piece (value, slope, centre), the factor
# taking its reconstructed mass to its lumped corner mass, and the centroid of that mass:
# rows of a (PARTS, count) array; its owner's velocity and slope in (components, count).
LO, HI, RHO, SLOPE, CENTRE, SCALE, CENTROID, PARTS = 0, 1, 2, 3, 4, 5, 6, 7
# why a window's nodal momentum is out of the swept form's reach (the caller then takes the
# general intersection): WINDOW_FAILURES[status − 1]
WINDOW_FAILURES = ("a dual face moved beyond the parts of its donor node", "a node lost all its mass",
                   "a new corner reaches beyond the parts around its node")


@numba.njit(**KERNEL)
def node_parts(parts, lo, hi, rho, srho, centre, share, cube):  # pragma: no cover (compiled)
    """Fill the rows of ``parts`` (PARTS, count): each part's interval, density piece,
    the factor taking its reconstructed mass to its lumped share and the centroid of that
    mass, (M·mid + σ L³/12) / M; an empty part takes nothing.  ``cube``: L³ (numpy's power,
    whose bits the C library's pow does not always give)."""
    for k in range(lo.size):
        length = hi[k] - lo[k]
        middle = 0.5 * (lo[k] + hi[k])
        mass = length * (rho[k] + srho[k] * (middle - centre[k]))
        safe = 1.0 if mass <= 0.0 else mass
        parts[LO, k], parts[HI, k], parts[RHO, k], parts[SLOPE, k], parts[CENTRE, k] = \
            lo[k], hi[k], rho[k], srho[k], centre[k]
        parts[SCALE, k] = 0.0 if mass <= 0.0 else share[k] / safe
        parts[CENTROID, k] = middle + srho[k] * cube[k] / (12.0 * safe)


@numba.njit(**KERNEL)
def overlap(parts, k, a, b):  # pragma: no cover (compiled)
    """Length and middle of [a, b] ∩ part k (length 0 where they do not meet)."""
    start = maximum(a, parts[LO, k])
    length = minimum(b, parts[HI, k])
    length -= start
    length = maximum(length, 0.0)
    middle = 0.5 * length
    middle += start
    return length, middle


@numba.njit(**KERNEL)
def overlap_mass(parts, k, a, b):  # pragma: no cover (compiled)
    """Lumped mass of part k over [a, b] ∩ part."""
    length, mass = overlap(parts, k, a, b)
    mass -= parts[CENTRE, k]
    mass *= parts[SLOPE, k]
    mass += parts[RHO, k]
    mass *= length
    mass *= parts[SCALE, k]
    return mass


@numba.njit(**KERNEL)
def overlap_mass_momentum(parts, velocity, slope, k, a, b, momentum):  # pragma: no cover (compiled)
    """Lumped mass of part k over [a, b] ∩ part, its momentum into ``momentum``
    (components,).  The velocity is linear on a part, u + τ (x − x̄), so ∫ρu = M (u + τ (x_M
    − x̄)) with x_M the centre of mass of the overlap: M x_M = M·mid + σ L³/12."""
    length, middle = overlap(parts, k, a, b)
    mass = middle - parts[CENTRE, k]
    mass *= parts[SLOPE, k]
    mass += parts[RHO, k]
    mass *= length  # M (unscaled)
    offset = length * length
    offset *= length
    offset *= parts[SLOPE, k]
    offset *= 1.0 / 12.0  # σ L³/12 = M (x_M − mid)
    offset += (middle - parts[CENTROID, k]) * mass  # M (x_M − x̄)
    mass *= parts[SCALE, k]
    offset *= parts[SCALE, k]
    for c in range(momentum.size):
        value = slope[c, k] * offset
        value += velocity[c, k] * mass
        momentum[c] = value
    return mass


@numba.njit(**KERNEL)
def lump_kinetic(mass, momentum):  # pragma: no cover (compiled)
    """½ |p|²/m of a lump (0 for an empty one)."""
    kinetic = momentum[0] * momentum[0]
    for c in range(1, momentum.size):
        kinetic += momentum[c] * momentum[c]
    kinetic *= 0.5
    return kinetic / mass if mass != 0.0 else 0.0


@numba.njit(**KERNEL)
def lump_kinetics(mass, momentum, kinetic):  # pragma: no cover (compiled)
    """:func:`lump_kinetic` of lumps (n,), their momenta (components, n), into ``kinetic``."""
    for i in range(mass.size):
        kinetic[i] = lump_kinetic(mass[i], momentum[:, i])


@numba.njit(**KERNEL)
def integrate_linear(value, slope, centre, lo, hi):  # pragma: no cover (compiled)
    """∫_lo^hi value + slope (x − centre) dx."""
    return value * (hi - lo) + 0.5 * slope * ((hi - centre) ** 2 - (lo - centre) ** 2)


@numba.njit(**KERNEL)
def linear_integrals(value, slope, centre, lo, hi, integral):  # pragma: no cover (compiled)
    """:func:`integrate_linear` of flat arrays, into ``integral``."""
    for i in range(value.size):
        integral[i] = integrate_linear(value[i], slope[i], centre[i], lo[i], hi[i])


@numba.njit(**KERNEL)
def node_velocity_slopes(u, x, mixed_j, gamma, mixed_velocity, m0, m1_of_mixed):  # pragma: no cover (compiled)
    """Minmod slope of each node's velocity from the cells on either side, within one
    material (the general intersection's slopes).  A mixed cell gives each of its internal
    nodes the gradient of that material's full field: the line through the node and (x_Γ,
    u_Γ) for the normal component, none for a transverse one."""
    components, nodes = u.shape
    n = nodes - 1
    left_part, right_part = np.empty((components, n)), np.empty((components, n))  # of cell j: seen from j, j + 1
    for c in range(components):
        for j in range(n):
            left_part[c, j] = (u[c, j + 1] - u[c, j]) / (x[j + 1] - x[j])
            right_part[c, j] = left_part[c, j]
    material_right_part = m0.copy()
    for k in range(mixed_j.size):
        j = mixed_j[k]
        for c in range(components):
            left_part[c, j], right_part[c, j] = 0.0, 0.0
        left_part[0, j] = (mixed_velocity[k] - u[0, j]) / (gamma[k] - x[j])
        right_part[0, j] = (mixed_velocity[k] - u[0, j + 1]) / (gamma[k] - x[j + 1])
        material_right_part[j] = m1_of_mixed[k]
    slope = np.zeros((components, nodes))
    for c in range(components):
        for k in range(1, n):  # node k: the right part of cell k − 1, the left part of cell k
            limited = minmod(right_part[c, k - 1], left_part[c, k])
            slope[c, k] = limited if material_right_part[k - 1] == m0[k] else 0.0
    return slope


@numba.njit(**KERNEL)
def window_momentum(x, X, mixed_j, gamma, new_mixed_j, new_gamma, rho0, srho0, centre0, rho1, srho1, centre1,
                    corner, u, order, mixed_velocity, m0, m1_of_mixed, cut_left, cut_right, left_cube,
                    right_cube):  # pragma: no cover (compiled)
    """Nodal momentum and lumped masses of a window through the dual faces (enriched: a
    mixed cell's face is Γ; a pure cell's its middle).  A face's swept interval lies in its
    own cell (the parts L_j, R_j) except where Γ moves into a neighbouring cell; those few
    faces also take the neighbours' parts R_{j−1}, L_{j+1}.  ``cut_left``, ``cut_right``:
    the window's ends are inside the mesh (their end nodes move; the caller discards what
    depends on what lies beyond).  ``left_cube``, ``right_cube``: the parts' L³.  Returns
    (status, new node masses, momenta, corner masses (2, n), each node's ½ M u² less what it
    handed over plus what it received); status 0, or 1 + the index of WINDOW_FAILURES."""
    components, nodes = u.shape
    n = nodes - 1
    face = np.empty(n)
    for j in range(n):
        face[j] = 0.5 * (x[j] + x[j + 1])
    for k in range(mixed_j.size):
        face[mixed_j[k]] = gamma[k]
    new_face = np.empty(n)
    for j in range(n):
        new_face[j] = 0.5 * (X[j] + X[j + 1])
    for k in range(new_mixed_j.size):
        new_face[new_mixed_j[k]] = new_gamma[new_mixed_j[k]]
    if order == 2:
        node_slope = node_velocity_slopes(u, x, mixed_j, gamma, mixed_velocity, m0, m1_of_mixed)
    else:
        node_slope = np.zeros((components, nodes))
    # L_0 … L_{n−1} and an empty L_n at the right end; R_0 … R_{n−1}
    left, right = np.empty((PARTS, nodes)), np.empty((PARTS, n))
    zeros = np.zeros(nodes)
    lo, hi = np.empty(nodes), np.empty(nodes)
    lo[:n], hi[:n] = x[:n], face
    lo[n], hi[n] = x[n], x[n]
    node_parts(left, lo, hi, np.append(rho0, 0.0), np.append(srho0, 0.0), np.append(centre0, 0.0),
               np.append(corner[0], 0.0), left_cube)
    left_u, left_tau = np.zeros((components, nodes)), np.zeros((components, nodes))
    left_u[:, :n], left_tau[:, :n] = u[:, :n], node_slope[:, :n]
    r_rho, r_srho, r_cen = rho0.copy(), srho0.copy(), centre0.copy()
    for k in range(mixed_j.size):
        r_rho[mixed_j[k]], r_srho[mixed_j[k]], r_cen[mixed_j[k]] = rho1[k], srho1[k], centre1[k]
    node_parts(right, face, x[1:], r_rho, r_srho, r_cen, corner[1], right_cube)
    right_u, right_tau = u[:, 1:], node_slope[:, 1:]

    # Face j: the swept interval between f_j and F_j moves to node j + 1 what lies in node
    # j's parts (R_{j−1}, L_j) and to node j what lies in node j + 1's (R_j, L_{j+1}).
    moved_mass, moved_momentum, kinetic_flux = np.empty(n), np.empty((components, n)), np.empty(n)
    to_right, to_left, extra = np.empty(components), np.empty(components), np.empty(components)
    for j in range(n):
        a, b = minimum(new_face[j], face[j]), maximum(new_face[j], face[j])
        right_mass = overlap_mass_momentum(left, left_u, left_tau, j, a, b, to_right)
        left_mass = overlap_mass_momentum(right, right_u, right_tau, j, a, b, to_left)
        flux = lump_kinetic(right_mass, to_right) - lump_kinetic(left_mass, to_left)
        far = ((a < x[j]) | (b > x[j + 1])) & ((j > 0) | (not cut_left)) & ((j < n - 1) | (not cut_right))
        if far:
            width = x[j + 1] - x[j]
            before = max(j - 1, 0)
            if ((j == 0) & (a < x[j])) | (a < right[LO, before] - 1e-12 * width) | \
                    (b > left[HI, j + 1] + 1e-12 * width):
                return 1, zeros, node_slope, corner, zeros
            m = overlap_mass_momentum(right, right_u, right_tau, before, a, b, extra)
            if j == 0:
                m = 0.0
                extra[:] = 0.0
            right_mass += m
            for c in range(components):
                to_right[c] += extra[c]
            flux += lump_kinetic(m, extra)
            m = overlap_mass_momentum(left, left_u, left_tau, j + 1, a, b, extra)
            left_mass += m
            for c in range(components):
                to_left[c] += extra[c]
            flux -= lump_kinetic(m, extra)
        moved_mass[j] = right_mass - left_mass
        for c in range(components):
            moved_momentum[c, j] = to_right[c] - to_left[c]
        kinetic_flux[j] = flux
    old_mass = np.zeros(nodes)
    for j in range(n):
        old_mass[j] += corner[0, j]
    for j in range(n):
        old_mass[j + 1] += corner[1, j]
    new_mass = old_mass.copy()
    for j in range(n):
        new_mass[j] -= moved_mass[j]
    for j in range(n):
        new_mass[j + 1] += moved_mass[j]
    new_momentum = np.empty((components, nodes))
    for c in range(components):
        for k in range(nodes):
            new_momentum[c, k] = u[c, k] * old_mass[k]
        for j in range(n):
            new_momentum[c, j] -= moved_momentum[c, j]
        for j in range(n):
            new_momentum[c, j + 1] += moved_momentum[c, j]
    for k in range(1 if cut_left else 0, n if cut_right else nodes):
        if new_mass[k] <= 0:
            return 2, zeros, node_slope, corner, zeros
    # New corners: the right corner of new cell j is [F_j, X_{j+1}]; F_j lies in old cell j
    # (parts L_j, R_j) and X_{j+1} in R_j or L_{j+1}, except where Γ moved into a
    # neighbouring cell: there the parts R_{j−1} and R_{j+1} are added too.
    corners = np.empty((2, n))
    for j in range(n):
        a, b = new_face[j], X[j + 1]
        right_corner = overlap_mass(left, j, a, b)
        right_corner += overlap_mass(right, j, a, b)
        right_corner += overlap_mass(left, j + 1, a, b)
        far = ((a < x[j]) | (b > left[HI, j + 1])) & ((j > 0) | (not cut_left)) & ((j < n - 1) | (not cut_right))
        if far:
            before, after = max(j - 1, 0), min(j + 1, n - 1)
            if (a < right[LO, before]) | (b > right[HI, after]):
                return 3, zeros, node_slope, corner, zeros
            beside = overlap_mass(right, before, a, b)
            if j == 0:
                beside = 0.0
            beyond = overlap_mass(right, after, a, b)
            if j == n - 1:
                beyond = 0.0
            right_corner += beside + beyond
        corners[1, j] = right_corner
    corners[0, 0] = new_mass[0] - 0.0
    for j in range(1, n):
        corners[0, j] = new_mass[j] - corners[1, j - 1]
    # ½M u² of each node, less the kinetic energy it handed over, plus what it received
    kinetic = np.empty(nodes)
    for k in range(nodes):
        square = u[0, k] * u[0, k]
        for c in range(1, components):
            square += u[c, k] * u[c, k]
        kinetic[k] = (0.5 * old_mass[k]) * square
    for j in range(n):
        kinetic[j] -= kinetic_flux[j]
    for j in range(n):
        kinetic[j + 1] += kinetic_flux[j]
    return 0, new_mass, new_momentum, corners, kinetic


# -- the new contents of a window's cells (swept_1d._swept_sorted) ------------------------
# why a window's contents are out of the swept form's reach (status 1, 2), or the remap
# fails (status 3: the caller raises, naming the window's sorted cell)
CONTENT_FAILURES = ("the ends of the domain move", "a node moved beyond its neighbouring cell",
                    "two interfaces meet in one cell (a layer thinner than a cell); refine the mesh")


@numba.njit(**KERNEL)
def clipped_integral(value, slope, centre, lo, hi, a, b):  # pragma: no cover (compiled)
    """∫ over [a, b] ∩ [lo, hi] of value + slope (x − centre), and the overlap's length."""
    start = maximum(a, lo)
    end = minimum(b, hi)
    length = maximum(end - start, 0.0)
    end = start + length
    return integrate_linear(value, slope, centre, start, end), length


@numba.njit(**KERNEL)
def material_at(position, x, m0, slot1_of, m1, gamma, right_of):  # pragma: no cover (compiled)
    """The material just right (``right_of``) or just left of a position in the old layout
    of sorted cells (``slot1_of``: each cell's index among the mixed cells, or −1)."""
    n = m0.size
    cell = np.searchsorted(x, position, side="right") if right_of else np.searchsorted(x, position, side="left")
    cell = min(max(cell - 1, 0), n - 1)
    k = slot1_of[cell]
    if k < 0:
        return m0[cell]
    beyond = position >= gamma[k] if right_of else position > gamma[k]
    return m1[k] if beyond else m0[cell]


@numba.njit(**KERNEL)
def window_contents(x, X, m0, mass0, specific0, mixed_j, volume0_mixed, m1, mass1, specific1, n_materials, order,
                    cut_left, cut_right):  # pragma: no cover (compiled)
    """The new contents of a run of sorted cells (swept_1d._swept_sorted; ``cut_left``,
    ``cut_right``: that end is inside the mesh, and its end node moves): each cell's own
    pieces (slot 0 over every cell, slot 1 over the mixed cells, whose Γ lies
    ``volume0_mixed`` from their left node), their limited slopes over the piece sequence,
    the fluxes through the nodes from each node's donor, and the cells where materials meet
    redone material by material.  Returns (status, the sorted cell it names, slot
    materials, masses, total energies, volumes (2, n) each, Γ of the old mixed cells, and
    the pieces' densities, slopes and centres of slot 0 (n) and slot 1 (mixed));
    status 0, or 1 + the index of CONTENT_FAILURES."""
    n = m0.size
    n_mixed = mixed_j.size
    slot1_of = np.full(n, -1, dtype=np.int64)
    for k in range(n_mixed):
        slot1_of[mixed_j[k]] = k
    # -- pieces: slot 0 over every cell, slot 1 over the mixed cells ----------------------
    energy0, hi0 = np.empty(n), x[1:].copy()
    gamma = np.empty(n_mixed)
    for k in range(n_mixed):
        gamma[k] = x[mixed_j[k]] + volume0_mixed[k]
        hi0[mixed_j[k]] = gamma[k]
    width0, rho0, eps0, centre0 = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    for j in range(n):
        energy0[j] = mass0[j] * specific0[j]
        width0[j] = hi0[j] - x[j]
        rho0[j] = mass0[j] / width0[j]
        eps0[j] = energy0[j] / width0[j]
        centre0[j] = 0.5 * (x[j] + hi0[j])
    energy1, width1, rho1, eps1, centre1 = (np.empty(n_mixed), np.empty(n_mixed), np.empty(n_mixed),
                                            np.empty(n_mixed), np.empty(n_mixed))
    for k in range(n_mixed):
        energy1[k] = mass1[k] * specific1[k]
        width1[k] = x[mixed_j[k] + 1] - gamma[k]
        rho1[k], eps1[k] = mass1[k] / width1[k], energy1[k] / width1[k]
        centre1[k] = 0.5 * (gamma[k] + x[mixed_j[k] + 1])
    empty = (np.zeros((2, n), dtype=np.int64), np.zeros((2, n)), np.zeros((2, n)), np.zeros((2, n)))
    if ((X[0] != x[0]) & (not cut_left)) | ((X[n] != x[n]) & (not cut_right)):
        return (1, -1, *empty, gamma, rho0, rho0, rho0, rho1, rho1, rho1)
    # slopes over the piece sequence (slot 1's piece right after its slot 0's)
    srho0, seps0, srho1, seps1 = np.zeros(n), np.zeros(n), np.zeros(n_mixed), np.zeros(n_mixed)
    if order == 2:
        start = np.empty(n, dtype=np.int64)
        total = 0
        for j in range(n):
            start[j] = total
            total += 2 if slot1_of[j] >= 0 else 1
        centre, width, rho, eps = np.empty(total), np.empty(total), np.empty(total), np.empty(total)
        material = np.empty(total, dtype=np.int64)
        for j in range(n):
            i = start[j]
            centre[i], width[i], rho[i], eps[i], material[i] = centre0[j], width0[j], rho0[j], eps0[j], m0[j]
        for k in range(n_mixed):
            i = start[mixed_j[k]] + 1
            centre[i], width[i], rho[i], eps[i], material[i] = centre1[k], width1[k], rho1[k], eps1[k], m1[k]
        same = np.empty(max(total - 1, 0), dtype=np.bool_)
        for i in range(total - 1):
            same[i] = material[i + 1] == material[i]
        srho, seps = piece_slopes(centre, width, rho, eps, order, same)
        for j in range(n):
            srho0[j], seps0[j] = srho[start[j]], seps[start[j]]
        for k in range(n_mixed):
            srho1[k], seps1[k] = srho[start[mixed_j[k]] + 1], seps[start[mixed_j[k]] + 1]
    # -- node fluxes: interior node k + 1 (k = 0 … n − 2) between cells k and k + 1 ---------
    # d < 0: [X, x] leaves cell k for cell k + 1; d > 0: [x, X] leaves cell k + 1 for cell k
    inner = max(n - 1, 0)
    to_right, donor = np.empty(inner, dtype=np.bool_), np.empty(inner, dtype=np.int64)
    for k in range(inner):
        to_right[k] = X[k + 1] - x[k + 1] < 0
        donor[k] = k if to_right[k] else k + 1
    for k in range(inner):
        if to_right[k] & (X[k + 1] < x[donor[k]]):
            return (2, -1, *empty, gamma, rho0, srho0, centre0, rho1, srho1, centre1)
    for k in range(inner):
        if (not to_right[k]) & (X[k + 1] > x[donor[k] + 1]):
            return (2, -1, *empty, gamma, rho0, srho0, centre0, rho1, srho1, centre1)
    flux0 = np.empty((3, inner))  # mass, energy, volume
    flux1 = np.zeros((3, inner))  # of the slot-1 parts of mixed donors
    from_mixed = np.zeros(inner, dtype=np.bool_)
    for k in range(inner):
        d = donor[k]
        a, b = minimum(X[k + 1], x[k + 1]), maximum(X[k + 1], x[k + 1])
        flux0[0, k], flux0[2, k] = clipped_integral(rho0[d], srho0[d], centre0[d], x[d], hi0[d], a, b)
        flux0[1, k], _ = clipped_integral(eps0[d], seps0[d], centre0[d], x[d], hi0[d], a, b)
        s = slot1_of[d]
        if s >= 0:
            from_mixed[k] = True
            flux1[0, k], flux1[2, k] = clipped_integral(rho1[s], srho1[s], centre1[s], gamma[s], x[d + 1], a, b)
            flux1[1, k], _ = clipped_integral(eps1[s], seps1[s], centre1[s], gamma[s], x[d + 1], a, b)
    # -- new cell contents: the common case, one material around -----------------------
    new_mass, new_energy = mass0.copy(), energy0.copy()
    for k in range(inner):  # signed inflow: into cell k + 1 when to_right, out of it otherwise
        into = 1.0 if to_right[k] else -1.0
        new_mass[k + 1] += into * flux0[0, k]
    for k in range(inner):
        into = 1.0 if to_right[k] else -1.0
        new_mass[k] -= into * flux0[0, k]
    for k in range(inner):
        into = 1.0 if to_right[k] else -1.0
        new_energy[k + 1] += into * flux0[1, k]
    for k in range(inner):
        into = 1.0 if to_right[k] else -1.0
        new_energy[k] -= into * flux0[1, k]
    # cells touched by another material, a mixed cell, or a mixed donor are redone below
    special = slot1_of >= 0
    receiving = np.empty(inner, dtype=np.int64)
    for k in range(inner):
        receiving[k] = k + 1 if to_right[k] else k
        entering = m0[donor[k]] != (m0[k + 1] if to_right[k] else m0[k])
        if entering & (flux0[2, k] > 0):
            special[receiving[k]] = True
    touched = np.zeros(n, dtype=np.bool_)
    for k in range(inner):
        if from_mixed[k]:
            touched[donor[k]] = True
    for j in range(n):
        if touched[j]:
            special[j] = True
            special[max(j - 1, 0)] = True
            special[min(j + 1, n - 1)] = True
    for k in range(n_mixed):
        special[max(mixed_j[k] - 1, 0)] = True
        special[min(mixed_j[k] + 1, n - 1)] = True
    slot_material = np.full((2, n), -1, dtype=np.int64)
    mass, energy, volume = np.zeros((2, n)), np.zeros((2, n)), np.zeros((2, n))
    for j in range(n):
        slot_material[0, j] = m0[j]
        mass[0, j], energy[0, j], volume[0, j] = new_mass[j], new_energy[j], X[j + 1] - X[j]
    # -- where materials meet: each material's own pieces, less what leaves, plus what enters
    row = np.full(n, -1, dtype=np.int64)
    count = 0
    for j in range(n):
        if special[j]:
            row[j] = count
            count += 1
    table = np.zeros((3, count, n_materials))  # mass, energy, volume
    for j in range(n):
        if row[j] >= 0:
            table[0, row[j], m0[j]] += 1.0 * mass0[j]
            table[1, row[j], m0[j]] += 1.0 * energy0[j]
            table[2, row[j], m0[j]] += 1.0 * width0[j]
    for k in range(n_mixed):
        r = row[mixed_j[k]]
        if r >= 0:
            table[0, r, m1[k]] += 1.0 * mass1[k]
            table[1, r, m1[k]] += 1.0 * energy1[k]
            table[2, r, m1[k]] += 1.0 * width1[k]
    for slot in range(2):  # the pure parts' fluxes, then the mixed donors' slot-1 parts
        for sign in (1.0, -1.0):  # into the receiving cells, then out of the donors
            for k in range(inner):
                if (slot == 1) & (not from_mixed[k]):
                    continue
                r = row[receiving[k]] if sign > 0 else row[donor[k]]
                if r < 0:
                    continue
                m = m0[donor[k]] if slot == 0 else m1[slot1_of[donor[k]]]
                flux = flux0 if slot == 0 else flux1
                for q in range(3):
                    table[q, r, m] += sign * flux[q, k]
    present = np.zeros(count, dtype=np.int64)  # the materials each special cell holds
    for j in range(n):
        r = row[j]
        if r < 0:
            continue
        for m in range(n_materials):
            present[r] += table[2, r, m] > 1e-12 * (X[j + 1] - X[j])
        if present[r] > 2:
            return (3, j, *empty, gamma, rho0, srho0, centre0, rho1, srho1, centre1)
    for j in range(n):
        r = row[j]
        if r < 0:
            continue
        width = X[j + 1] - X[j]
        # left material: the one at X_j (of the donor there); right: at X_{j+1}
        left = material_at(X[j], x, m0, slot1_of, m1, gamma, True)
        slot_material[0, j] = left
        mass[0, j], energy[0, j], volume[0, j] = table[0, r, left], table[1, r, left], table[2, r, left]
        if present[r] == 2:
            right = material_at(X[j + 1], x, m0, slot1_of, m1, gamma, False)
            slot_material[1, j] = right
            mass[1, j], energy[1, j], volume[1, j] = table[0, r, right], table[1, r, right], table[2, r, right]
        if present[r] == 1:
            volume[0, j] = width
        elif present[r] == 2:
            volume[1, j] = width - volume[0, j]
    return (0, -1, slot_material, mass, energy, volume, gamma, rho0, srho0, centre0, rho1, srho1, centre1)
