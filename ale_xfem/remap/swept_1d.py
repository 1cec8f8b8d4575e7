"""The 1D remap in swept-region (face-flux) form: the same result as
:func:`ale_xfem.remap.intersection_1d.remap_1d` when every node and every dual face moves by less than
the pieces around it (always, with a CFL-limited step), at about a hundred passes over
n_cells.

A new cell [X_j, X_{j+1}] holds the old cell j, plus what the swept interval between x_j
and X_j (and x_{j+1}, X_{j+1}) brings in or takes out.  The swept interval lies in one
old cell, the *donor*; where the donor is mixed it is cut at Γ, material by material.
Nodal momentum moves the same way through the faces of the dual cells (a pure cell's
middle, or Γ in an enriched mixed cell), from the parts of the donor node.  Everything is
added once and subtracted once, so mass, energy and momentum are conserved to round-off.

Two levels:

- the compiled kernel :func:`ale_xfem.remap.swept_kernels.pure_cells` does this over the
  whole mesh as if it were one material in pure cells, with every node moving by at most
  half a cell: closed-form fluxes, no gather.
- :func:`_swept_sorted` does it material by material (mixed cells, materials entering a
  cell, nodes moving up to a whole cell) on a window of cells around each interface and
  each node that moved further; its results replace the kernel's on the window's inner
  cells, where the kernel's assumptions do not hold.  The window margins cover every
  dependence (donor, slopes, node parts), so the two agree wherever both are valid.

The reconstruction (piece densities and slopes, part velocities and slopes, lumped shares)
is the one of :mod:`ale_xfem.remap.pieces_1d`; only the way it is integrated differs.  Returns None
when a displacement is too large, and the caller uses the general intersection.
"""

from __future__ import annotations

import numpy as np

from ale_xfem.remap import swept_kernels
from ale_xfem.remap.failure import RemapFailure
from ale_xfem.remap.pieces_1d import RemapResult, deposit_kinetic_loss, integrate_linear, piece_slopes


def _clipped_integral(value, slope, centre, lo, hi, a, b):
    """∫ over [a, b] ∩ [lo, hi] of value + slope (x − centre); and the overlap length."""
    start = np.maximum(a, lo)
    end = np.minimum(b, hi)
    length = np.maximum(end - start, 0.0)
    end = start + length
    return integrate_linear(value, slope, centre, start, end), length, start, end


def remap_1d_swept(order_of_cells, cell_left_node, cell_right_node, node_position, target_position,
                   cell_material, material_mass, material_energy, material_volume, corner_mass,
                   node_velocity, mixed_cells, interface_velocity, n_materials, order: int = 2,
                   heat: bool = True):
    """The remap of :func:`ale_xfem.remap.intersection_1d.remap_1d` (same arguments; mixed cells sorted left
    to right): the pure-cell kernel over the whole mesh, then the cells around each
    interface (mixed cells and node-aligned material boundaries) redone material by
    material in a window that holds them.  None when a step is out of the swept form's
    reach (the caller then uses the general intersection)."""
    cells = order_of_cells
    n = cells.size
    in_order = _in_order(cells, cell_left_node, cell_right_node)
    if in_order:  # DOLFINx interval meshes: sorted arrays are views
        nodes = slice(None)
        by_cell = lambda array: array  # noqa: E731
    else:
        nodes = np.concatenate([cell_left_node[cells[:1]], cell_right_node[cells]])
        by_cell = lambda array: array[..., cells]  # noqa: E731
    x, X = node_position[nodes], target_position[nodes]
    if X[0] != x[0] or X[-1] != x[-1]:
        return _too_far("the ends of the domain move")
    m0 = by_cell(cell_material[0])
    mass0, energy0 = by_cell(material_mass[0]), by_cell(material_energy[0])
    corner = by_cell(corner_mass)
    u = node_velocity[:, nodes]
    rank = np.arange(n) if in_order else _rank(cells, cell_left_node.size)
    mixed_j = rank[mixed_cells]
    boundaries = np.flatnonzero(m0[:-1] != m0[1:])
    # two slots when a window may put a second material in a cell
    contiguous = [np.ascontiguousarray(a, dtype=float) for a in (x, X, mass0, energy0, corner, u)]
    new_mass, new_energy, corner_new, node_mass, momentum, kinetic_start, kinetic, far_nodes = \
        swept_kernels.pure_cells(*contiguous, order, 2 if mixed_j.size or boundaries.size else 1, bool(heat))
    kinetic_before = float(kinetic_start.sum())
    if not heat:
        kinetic = None
    right_corner = corner_new[1]

    # -- windows around the interfaces ---------------------------------------------------
    special = np.union1d(mixed_j, boundaries)
    special = np.union1d(np.union1d(special, special + 1), np.union1d(far_nodes - 1, far_nodes))
    special = special[special < n]
    slots = 1
    taken_cells = []
    if special.size:
        if mixed_cells.size:
            mixed_data = (material_volume[0, mixed_cells], cell_material[1, mixed_cells],
                          material_mass[1, mixed_cells], material_energy[1, mixed_cells], interface_velocity)
        else:  # one slot: no mixed cell yet
            mixed_data = (np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0), np.zeros(0))
        slot_material = np.empty((2, n), dtype=np.int64)
        slot_material[0] = m0
        slot_material[1].fill(-1)
        if new_mass.shape[0] == 1:  # far-moving nodes only: the kernel gave one slot
            new_mass = np.vstack([new_mass, np.zeros(n)])
            new_energy = np.vstack([new_energy, np.zeros(n)])
        new_volume = np.empty((2, n))
        np.subtract(X[1:], X[:-1], out=new_volume[0])
        new_volume[1].fill(0.0)
        for taken, window in _windows(special, n):
            local = slice(window[0], window[1])
            inside = (mixed_j >= window[0]) & (mixed_j < window[1])
            result = _swept_sorted(
                x[window[0]:window[1] + 1], X[window[0]:window[1] + 1], m0[local], mass0[local],
                energy0[local], corner[:, local], u[:, window[0]:window[1] + 1], mixed_j[inside] - window[0],
                *(values[inside] for values in mixed_data), n_materials, order,
                cut=(window[0] > 0, window[1] < n))
            if result is None:
                return None
            t = slice(taken[0] - window[0], taken[1] - window[0])  # the window's cells taken
            j = slice(taken[0], taken[1])
            slot_material[:, j] = result["slot_material"][:, t]
            new_mass[:, j] = result["mass"][:, t]
            new_energy[:, j] = result["energy"][:, t]
            new_volume[:, j] = result["volume"][:, t]
            right_corner[j] = result["corner"][1, t]
            # nodes strictly inside the taken cells: both their dual faces are in the window
            k = slice(taken[0] + 1, taken[1])
            kt = slice(taken[0] + 1 - window[0], taken[1] - window[0])
            node_mass[k] = result["node_mass"][kt]
            momentum[:, k] = result["node_momentum"][:, kt]
            if heat:
                kinetic[k] = result["kinetic"][kt]
            taken_cells.append(np.arange(taken[0], taken[1]))
        new_mixed_j = np.flatnonzero(slot_material[1] >= 0)
        if np.any(np.abs(new_mixed_j[1:] - new_mixed_j[:-1]) <= 1):
            bad = int(new_mixed_j[np.flatnonzero(np.abs(new_mixed_j[1:] - new_mixed_j[:-1]) <= 1)[0]])
            raise RemapFailure(f"cells {int(cells[bad])} and {int(cells[bad + 1])}: interfaces in "
                               "neighbouring cells (a layer about one cell thick); the mixed-cell "
                               "solve needs a pure cell between them: refine the mesh")
        slots = 2 if new_mixed_j.size else 1
        slot_material, new_mass, new_energy, new_volume = (
            a[:slots] for a in (slot_material, new_mass, new_energy, new_volume))
    else:
        new_mixed_j = np.zeros(0, dtype=np.int64)
        slot_material = m0[None, :]
        new_volume = (X[1:] - X[:-1])[None, :]
    if np.any(node_mass <= 0):
        return _too_far("a node lost all its mass")
    specific = new_energy / new_mass[:1] if slots == 1 else _specific(new_energy, new_mass, taken_cells)
    velocity, kinetic_new, loss = swept_kernels.node_velocities_and_losses(
        node_mass, momentum, right_corner, corner_new[0], kinetic if heat else node_mass, bool(heat))
    kinetic_change = float(np.sum(kinetic_new)) - kinetic_before

    # -- back to cell (node) order ------------------------------------------------------
    if in_order:
        result = RemapResult(np.ascontiguousarray(slot_material), new_mass, specific, new_volume, corner_new,
                             node_mass, velocity, cells[new_mixed_j], kinetic_change, momentum)
    else:
        cell_material_new = np.empty_like(slot_material)
        out = [np.empty_like(a) for a in (new_mass, specific, new_volume, corner_new)]
        for target, values in zip([cell_material_new, *out],
                                  (slot_material, new_mass, specific, new_volume, corner_new)):
            target[:, cells] = values
        node_mass_out = np.empty_like(node_mass)
        node_mass_out[nodes] = node_mass
        velocity_out, momentum_out = np.empty_like(velocity), np.empty_like(momentum)
        velocity_out[:, nodes], momentum_out[:, nodes] = velocity, momentum
        if heat:
            loss_out = np.empty_like(loss)
            loss_out[nodes] = loss
            loss = loss_out
        result = RemapResult(cell_material_new, out[0], out[1], out[2], out[3], node_mass_out, velocity_out,
                             cells[new_mixed_j], kinetic_change, momentum_out)
    if heat:
        deposit_kinetic_loss(loss, result.corner_mass, result.node_mass, cell_left_node, cell_right_node,
                             result.cell_material, result.material_mass, result.material_energy, result.mixed_cells,
                             in_order=in_order, positive_only=heat == "positive")
    return result


_ORDER_CACHE: dict = {}


def _in_order(cells, left_node, right_node) -> bool:
    """Whether cell j lies between nodes j and j + 1 for every j (checked once per mesh)."""
    key = (id(cells), id(left_node), id(right_node))
    if key not in _ORDER_CACHE:
        n = cells.size
        _ORDER_CACHE.clear()
        _ORDER_CACHE[key] = (cells, left_node, right_node, bool(
            np.array_equal(cells, np.arange(n)) and np.array_equal(left_node, np.arange(n))
            and np.array_equal(right_node, np.arange(1, n + 1))))
    return _ORDER_CACHE[key][3]


def _rank(cells, n_cells):
    rank = np.empty(n_cells, dtype=np.int64)
    rank[cells] = np.arange(cells.size)
    return rank


def _specific(energy, mass, taken_cells):
    """Specific energies: slot 0 everywhere, slot 1 only where the windows put material."""
    specific = np.empty_like(energy)
    np.divide(energy[0], mass[0], out=specific[0])
    specific[1].fill(0.0)
    j = np.concatenate(taken_cells)
    present = mass[1, j] > 0
    specific[1, j[present]] = energy[1, j[present]] / mass[1, j[present]]
    return specific


# Cells around an interface taken from its window, and the window's margin on each side:
# a new cell's content depends on the old cells up to two away (donor and its slope), a
# node's momentum on the parts and velocity slopes up to three away.
TAKEN_MARGIN, WINDOW_MARGIN = 3, 4


def _windows(special, n):
    """(taken cells, window) pairs of [first, last) sorted cell ranges around the special
    cells, merged where they overlap."""
    lo = np.maximum(special - TAKEN_MARGIN, 0)
    hi = np.minimum(special + TAKEN_MARGIN + 1, n)
    starts = np.flatnonzero(np.concatenate([[True], lo[1:] > hi[:-1]]))
    ends = np.concatenate([starts[1:] - 1, [special.size - 1]])
    for first, last in zip(lo[starts], hi[ends]):
        yield (int(first), int(last)), (max(int(first) - WINDOW_MARGIN, 0), min(int(last) + WINDOW_MARGIN, n))


def _swept_sorted(x, X, m0, mass0, specific0, corner_sorted, u, mixed_j, volume0_mixed, m1, mass1,
                  specific1, mixed_velocity, n_materials, order, cut=(False, False)):
    """The swept remap of a run of sorted cells (all of them, or a window of them: ``cut``
    says which ends are inside the mesh, whose end nodes move and whose results near that
    end the caller discards).  Mixed cells hold two materials; returns the new contents
    in sorted order, or None when a step is beyond the swept form's reach."""
    n = m0.size
    if (X[0] != x[0] and not cut[0]) or (X[-1] != x[-1] and not cut[1]):
        return _too_far("the ends of the domain move")
    mixed_sorted_mask = np.zeros(n, dtype=bool)
    mixed_sorted_mask[mixed_j] = True

    # -- pieces: slot 0 over every cell, slot 1 over the mixed cells ---------------------------
    xl, xr = x[:-1], x[1:]
    energy0 = mass0 * specific0
    hi0 = xr.copy()
    gamma = xl[mixed_j] + volume0_mixed
    hi0[mixed_j] = gamma
    width0 = hi0 - xl
    rho0 = mass0 / width0
    eps0 = energy0 / width0
    centre0 = 0.5 * (xl + hi0)
    energy1 = mass1 * specific1
    lo1, hi1 = gamma, xr[mixed_j]
    width1 = hi1 - lo1
    rho1, eps1, centre1 = mass1 / width1, energy1 / width1, 0.5 * (lo1 + hi1)
    # slopes over the piece sequence (slot 1 pieces interleaved after their slot 0)
    if order == 2:
        count = np.where(mixed_sorted_mask, 2, 1)
        start = np.concatenate([[0], np.cumsum(count)[:-1]])
        total = int(count.sum())
        seq_centre, seq_rho, seq_eps, seq_mat = (np.empty(total), np.empty(total), np.empty(total),
                                                 np.empty(total, dtype=np.int64))
        for arr, v0, v1 in ((seq_centre, centre0, centre1), (seq_rho, rho0, rho1), (seq_eps, eps0, eps1),
                            (seq_mat, m0, m1)):
            arr[start] = v0
            arr[start[mixed_j] + 1] = v1
        w_seq = np.empty(total)
        w_seq[start] = width0
        w_seq[start[mixed_j] + 1] = width1
        srho, seps = piece_slopes(seq_centre, w_seq, seq_rho, seq_eps, seq_mat, order)
        srho0, seps0 = srho[start], seps[start]
        srho1, seps1 = srho[start[mixed_j] + 1], seps[start[mixed_j] + 1]
    else:
        srho0 = seps0 = np.zeros(n)
        srho1 = seps1 = np.zeros(mixed_j.size)

    # -- node fluxes --------------------------------------------------------------------------
    # Interior node k (1..n−1) between cells k−1 and k.  d < 0: [X_k, x_k] leaves cell k−1
    # for cell k; d > 0: [x_k, X_k] leaves cell k for cell k−1.
    d = X[1:-1] - x[1:-1]
    to_right = d < 0
    donor = np.where(to_right, np.arange(n - 1), np.arange(1, n))
    if np.any(to_right & (X[1:-1] < xl[donor])) or np.any(~to_right & (X[1:-1] > xr[donor])):
        return _too_far("a node moved beyond its neighbouring cell")
    a = np.minimum(X[1:-1], x[1:-1])
    b = np.maximum(X[1:-1], x[1:-1])
    flux_mass0, flux_volume0, *_ = _clipped_integral(rho0[donor], srho0[donor], centre0[donor],
                                                     xl[donor], hi0[donor], a, b)
    flux_energy0, *_ = _clipped_integral(eps0[donor], seps0[donor], centre0[donor],
                                         xl[donor], hi0[donor], a, b)
    flux_material0 = m0[donor]
    # slot-1 parts of mixed donors (sparse)
    slot1_of = np.full(n, -1)
    slot1_of[mixed_j] = np.arange(mixed_j.size)
    s1 = slot1_of[donor]
    sparse = np.flatnonzero(s1 >= 0)
    k1 = s1[sparse]
    flux_mass1, flux_volume1, *_ = _clipped_integral(rho1[k1], srho1[k1], centre1[k1], lo1[k1], hi1[k1],
                                                     a[sparse], b[sparse])
    flux_energy1, *_ = _clipped_integral(eps1[k1], seps1[k1], centre1[k1], lo1[k1], hi1[k1],
                                         a[sparse], b[sparse])
    flux_material1 = m1[k1]

    # -- new cell contents: the common case, one material around -------------------------
    # Signed inflow to cell j through its left node (k = j) and right node (k = j + 1).
    new_mass = mass0.copy()
    new_energy = energy0.copy()
    into = np.where(to_right, 1.0, -1.0)
    # node k: +flux into cell k when to_right, −flux out of cell k otherwise; the opposite
    # for cell k−1.
    new_mass[1:] += into * flux_mass0
    new_mass[:-1] -= into * flux_mass0
    new_energy[1:] += into * flux_energy0
    new_energy[:-1] -= into * flux_energy0
    # Cells touched by another material, a mixed cell, or a mixed donor, are redone below.
    special = mixed_sorted_mask.copy()
    differ = flux_material0 != np.where(to_right, m0[1:], m0[:-1])  # material entering a cell
    receiving = np.where(to_right, np.arange(1, n), np.arange(n - 1))
    special[receiving[differ & (flux_volume0 > 0)]] = True
    touched = np.zeros(n, dtype=bool)
    touched[donor[sparse]] = True
    special |= touched
    special[np.clip(np.flatnonzero(touched) - 1, 0, n - 1)] = True
    special[np.clip(np.flatnonzero(touched) + 1, 0, n - 1)] = True
    special[np.clip(mixed_j - 1, 0, n - 1)] = True
    special[np.clip(mixed_j + 1, 0, n - 1)] = True

    target_width = X[1:] - X[:-1]
    new_slot_material = np.full((2, n), -1, dtype=np.int64)
    new_slot_material[0] = m0
    new = {"mass": np.zeros((2, n)), "energy": np.zeros((2, n)), "volume": np.zeros((2, n))}
    new["mass"][0], new["energy"][0], new["volume"][0] = new_mass, new_energy, target_width
    special_j = np.flatnonzero(special)
    if special_j.size:
        _finish_special_cells(special_j, n, n_materials, new, new_slot_material, to_right, donor, X, x,
                              m0, mass0, energy0, width0, mixed_j, m1, mass1, energy1, width1, gamma,
                              flux_mass0, flux_energy0, flux_volume0, flux_material0,
                              sparse, flux_mass1, flux_energy1, flux_volume1, flux_material1)
    new_mixed_j = np.flatnonzero(new_slot_material[1] >= 0)

    # -- momentum through the dual faces ---------------------------------------------------
    result = _momentum(n, x, X, xl, xr, mixed_j, gamma, new_mixed_j, X[:-1] + new["volume"][0],
                       rho0, srho0, centre0, rho1, srho1, centre1, corner_sorted, u, order,
                       mixed_velocity, m0, m1, cut)
    if result is None:
        return None
    node_mass, momentum, corner_new, kinetic = result
    return {"slot_material": new_slot_material, "mass": new["mass"], "energy": new["energy"],
            "volume": new["volume"], "corner": corner_new, "node_mass": node_mass,
            "node_momentum": momentum, "new_mixed_j": new_mixed_j, "kinetic": kinetic}


def _finish_special_cells(special_j, n, n_materials, new, new_slot_material, to_right, donor, X, x,
                          m0, mass0, energy0, width0, mixed_j, m1, mass1, energy1, width1, gamma,
                          flux_mass0, flux_energy0, flux_volume0, flux_material0,
                          sparse, flux_mass1, flux_energy1, flux_volume1, flux_material1):
    """Per-material content of the few cells where materials meet: own pieces, minus what
    leaves through their nodes, plus what enters, gathered in a (cells, materials) table."""
    index = np.full(n, -1)
    index[special_j] = np.arange(special_j.size)
    table = {k: np.zeros((special_j.size, n_materials)) for k in ("mass", "energy", "volume")}

    def add(cells_, materials, mass, energy, volume, sign):
        keep = index[cells_] >= 0
        rows, mats = index[cells_[keep]], materials[keep]
        np.add.at(table["mass"], (rows, mats), sign * mass[keep])
        np.add.at(table["energy"], (rows, mats), sign * energy[keep])
        np.add.at(table["volume"], (rows, mats), sign * volume[keep])

    add(np.arange(n), m0, mass0, energy0, width0, 1.0)
    add(mixed_j, m1, mass1, energy1, width1, 1.0)
    receiving = np.where(to_right, np.arange(1, n), np.arange(n - 1))
    add(receiving, flux_material0, flux_mass0, flux_energy0, flux_volume0, 1.0)
    add(donor, flux_material0, flux_mass0, flux_energy0, flux_volume0, -1.0)
    add(receiving[sparse], flux_material1, flux_mass1, flux_energy1, flux_volume1, 1.0)
    add(donor[sparse], flux_material1, flux_mass1, flux_energy1, flux_volume1, -1.0)

    width = X[special_j + 1] - X[special_j]
    present = table["volume"] > 1e-12 * width[:, None]
    count = present.sum(axis=1)
    if np.any(count > 2):
        bad = int(special_j[np.flatnonzero(count > 2)[0]])
        raise RemapFailure(f"sorted cell {bad}: two interfaces meet in one cell (a layer thinner "
                           "than a cell); refine the mesh")
    # left material: the material at X_j (of the donor there); right: at X_{j+1}
    left = _material_at(X[special_j], x, m0, mixed_j, m1, gamma, side=+1)
    right = _material_at(X[special_j + 1], x, m0, mixed_j, m1, gamma, side=-1)
    rows = np.arange(special_j.size)
    for slot, mats in ((0, left), (1, right)):
        use = np.ones(special_j.size, dtype=bool) if slot == 0 else (count == 2)
        j, r, m = special_j[use], rows[use], mats[use]
        new_slot_material[slot, j] = m
        new["mass"][slot, j] = table["mass"][r, m]
        new["energy"][slot, j] = table["energy"][r, m]
        new["volume"][slot, j] = table["volume"][r, m]
    pure = count == 1
    new["volume"][0, special_j[pure]] = width[pure]
    both = count == 2
    new["volume"][1, special_j[both]] = width[both] - new["volume"][0, special_j[both]]


def _material_at(position, x, m0, mixed_j, m1, gamma, side):
    """Material just right (side +1) or left (side −1) of each position in the old layout."""
    cell = np.clip(np.searchsorted(x, position, side="right" if side > 0 else "left") - 1, 0, m0.size - 1)
    material = m0[cell].copy()
    slot1_of = np.full(m0.size, -1)
    slot1_of[mixed_j] = np.arange(mixed_j.size)
    k = slot1_of[cell]
    g = gamma[np.maximum(k, 0)] if gamma.size else np.zeros_like(position)
    beyond = (k >= 0) & ((position >= g) if side > 0 else (position > g))
    material[beyond] = m1[k[beyond]]
    return material


def _momentum(n, x, X, xl, xr, mixed_j, gamma, new_mixed_j, new_gamma, rho0, srho0, centre0,
              rho1, srho1, centre1, corner_sorted, u, order, mixed_velocity, m0, m1_of_mixed, cut):
    """Nodal momentum and lumped masses through the dual faces (compiled:
    :func:`ale_xfem.remap.swept_kernels.window_momentum`): (new node masses, momenta, corner
    masses, kinetic energies), or None when a face or a corner moves beyond the parts the
    swept form reads."""
    face = 0.5 * (xl + xr)
    face[mixed_j] = gamma
    # the parts' L³ as numpy's power gives them (the C library's pow differs in the last bit)
    left_cube = (np.append(face, x[-1]) - np.append(xl, x[-1])) ** 3
    right_cube = (xr - face) ** 3
    status, node_mass, momentum, corners, kinetic = swept_kernels.window_momentum(
        x, X, mixed_j, gamma, new_mixed_j, new_gamma, rho0, srho0, centre0, rho1, srho1, centre1,
        np.ascontiguousarray(corner_sorted), np.ascontiguousarray(u), order, mixed_velocity, m0,
        m1_of_mixed, bool(cut[0]), bool(cut[1]), left_cube, right_cube)
    if status:
        return _too_far(swept_kernels.WINDOW_FAILURES[status - 1])
    return node_mass, momentum, corners, kinetic


def _too_far(reason: str):
    """The swept form does not apply this step; the caller uses the general intersection."""
    _too_far.last_reason = reason
    return None


