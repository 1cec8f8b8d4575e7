"""Readable numpy references of compiled kernels, kept as oracles for the tests: each is
the code the kernel replaced, and the kernel must give its results to the bit."""

from __future__ import annotations

import math

import numpy as np

from ale_xfem.remap.failure import RemapFailure
from ale_xfem.remap.pieces_1d import component_dot, minmod


def integrate_linear(value, slope, centre, lo, hi):
    """∫_lo^hi value + slope (x − centre) dx (pieces_1d's numpy code before it was compiled
    into swept_kernels.integrate_linear)."""
    return value * (hi - lo) + 0.5 * slope * ((hi - centre) ** 2 - (lo - centre) ** 2)


def lump_kinetic(mass, momentum):
    """½ |p|²/m of lumps, 0 for empty ones (pieces_1d's numpy code before it was compiled
    into swept_kernels.lump_kinetic)."""
    kinetic = component_dot(momentum, momentum)
    kinetic *= 0.5
    if mass.all():
        kinetic /= mass
        return kinetic
    np.divide(kinetic, mass, out=kinetic, where=mass != 0.0)
    kinetic[mass == 0.0] = 0.0
    return kinetic


def libm_power(x, exponent: float):
    """x ** exponent element by element through the C library's pow, as compiled code takes
    it (numpy's array power — 2.5.5 here — has its own implementation, one ulp from pow's at about
    5 % of points; a square is exact both ways)."""
    return np.vectorize(math.pow, otypes=[float])(x, exponent)


def limited_slopes(value, inverse_spacing, one_material, bound):
    """Minmod slopes of value over sorted pieces (1 / spacing of their centres given),
    clipped to ±bound (None: no bound); zero in the first and last piece and —
    ``one_material[k]``: pieces k and k + 1 hold the same material; None: all do — next to
    a piece of another material, so no information crosses Γ."""
    if value.size < 3:
        return np.zeros_like(value)
    slope = np.empty_like(value)
    slope[0] = slope[-1] = 0.0
    gradient = np.diff(value)
    gradient *= inverse_spacing
    right = gradient[1:]
    if bound is None:
        minmod(gradient[:-1], right, out=slope[1:-1])
    else:
        # minmod(g_left, g_right) clipped to ±bound in one clip: g_left held between
        # 0 and g_right, g_right first held within ±bound
        bound = bound[1:-1]
        np.clip(gradient[:-1], np.clip(right, -bound, 0.0), np.clip(right, 0.0, bound), out=slope[1:-1])
    inner = slope[1:-1]
    if one_material is not None:
        inner[~(one_material[:-1] & one_material[1:])] = 0.0
    return slope


def piece_slopes(centre, width, density, energy_density, material, order):
    """The limited slopes of a material's density and energy density over the pieces
    (sorted left to right): minmod within one material, zero at Γ, and no more than keeps
    the reconstruction of the same sign at both ends of the piece.  ``material``: per
    piece, or None when all pieces hold one material.  Order 1: zero."""
    if order != 2:
        return np.zeros_like(density), np.zeros_like(energy_density)
    inverse_spacing = np.diff(centre)
    np.divide(1.0, inverse_spacing, out=inverse_spacing)
    one_material = None if material is None else material[1:] == material[:-1]
    # A minmod slope keeps both ends of a piece between its neighbours' values (the
    # spacing of the centres is at least half the piece): a field with no negative value
    # stays non-negative without the bound ±2|f|/w, which then cannot bind and is not
    # formed (densities always; energy densities unless some are negative).
    bounds = [None if field.min(initial=0.0) >= 0.0 else np.abs(field) * (2.0 / width)
              for field in (density, energy_density)]
    density_slope = limited_slopes(density, inverse_spacing, one_material, bounds[0])
    energy_slope = limited_slopes(energy_density, inverse_spacing, one_material, bounds[1])
    return density_slope, energy_slope


def pure_kernel(x, X, mass, specific_energy, corner, u, order, slots=1, heat=True):
    """The swept-region remap of pure cells of one material, in flux form over the sorted
    cells (what the windows then redo near interfaces does not matter here).  Returns the
    new cell masses and total energies, the corner masses (2, n) with the right ones
    filled, node masses and momenta, the kinetic energy before and each node's kinetic
    energy balance (see :func:`deposit_kinetic_loss`), and the nodes that moved by more
    than half a neighbouring cell (the kernel's results around them are to be redone).
    ``heat`` False: the kinetic energy is only reported, and no balance is formed (None).
    The new masses and energies come as (slots, n) arrays with slot 0 filled and any
    further slot zero (the windows put second materials there): no row is copied after.

    Node k (between cells k − 1 and k) moving by d = X_k − x_k sweeps [x_k, X_k] of its
    donor cell (k − 1 if d < 0, k if d > 0): the mass −d (ρ_D + σ_D (x_k + d/2 − c_D))
    crosses it rightward, energy likewise.  The dual face of cell j, its middle c_j, moves
    by δ = (d_j + d_{j+1})/2 through the node part L_j (δ < 0, mass to node j + 1) or R_j
    (δ > 0, to node j): mass −δ (ρ_j + σ_j δ/2) times the part's lumping factor, momentum
    that mass times the part velocity at the swept mass's centre."""
    width = x[1:] - x[:-1]
    half_width = 0.5 * width
    centre = x[:-1] + half_width
    energy = mass * specific_energy
    rho = mass / width
    eps = energy / width
    srho, seps = piece_slopes(centre, width, rho, eps, None, order)  # one material: no test at Γ
    d = X[1:-1] - x[1:-1]
    half_d = 0.5 * d
    # Nodes that move by more than half a neighbouring cell: the cells around them are
    # redone in windows, like those around an interface.
    far_nodes = np.zeros(0, dtype=np.int64)
    if max(half_d.max(initial=0.0), -half_d.min(initial=0.0)) > 0.25 * width.min():
        far_nodes = np.flatnonzero(np.abs(d) > 0.5 * np.minimum(width[:-1], width[1:])) + 1
    right_donor = d > 0.0
    offset = half_d + x[1:-1]
    offset -= np.where(right_donor, centre[1:], centre[:-1])  # x_k + d/2 − c_D
    flux_mass = np.where(right_donor, srho[1:], srho[:-1])
    flux_mass *= offset
    flux_mass += np.where(right_donor, rho[1:], rho[:-1])
    minus_d = np.negative(d)
    flux_mass *= minus_d
    flux_energy = np.where(right_donor, seps[1:], seps[:-1])
    flux_energy *= offset
    flux_energy += np.where(right_donor, eps[1:], eps[:-1])
    flux_energy *= minus_d
    new_mass, new_energy = np.empty((slots, width.size)), np.empty((slots, width.size))
    new_mass[1:].fill(0.0)
    new_energy[1:].fill(0.0)
    new_mass[0] = mass
    new_mass[0, 1:] += flux_mass
    new_mass[0, :-1] -= flux_mass
    new_energy[0] = energy
    new_energy[0, 1:] += flux_energy
    new_energy[0, :-1] -= flux_energy

    # -- nodal momentum through the dual faces -------------------------------------------
    share_left, share_right = corner[0], corner[1]
    mass_left = srho * half_width
    mass_left *= -0.5  # σ (−w/4), a power of two apart: the same bits
    mass_left += rho
    mass_left *= half_width  # ∫ over L_j = [x_j, c_j]
    mass_right = mass - mass_left
    scale_left = share_left / mass_left
    scale_right = share_right / mass_right
    delta = np.zeros(width.size)
    if half_d.size:
        np.add(half_d[:-1], half_d[1:], out=delta[1:-1])
        delta[0], delta[-1] = half_d[0], half_d[-1]
    from_left = delta < 0.0
    half_delta = 0.5 * delta
    swept = srho * half_delta
    swept += rho
    swept *= -delta  # signed: > 0 moves from node j to node j + 1
    scale = np.where(from_left, scale_left, scale_right)
    # centre of the chosen part's mass, from c_j: ∓w/4 + σ w³ / (96 M_part)
    part_centre = width * width
    part_centre *= width
    part_centre *= srho
    part_centre *= 1.0 / 96.0
    part_centre /= np.where(from_left, mass_left, mass_right)
    quarter = np.multiply(0.25, width)
    np.copysign(quarter, delta, out=quarter)  # −w/4 for L_j (δ < 0), +w/4 for R_j
    part_centre += quarter
    # signed first moment about the part centre: M (δ/2 − x̄) − σ δ³/12
    moment = np.subtract(half_delta, part_centre)
    moment *= swept
    cube = delta * delta
    cube *= delta
    cube *= srho
    cube *= 1.0 / 12.0
    moment -= cube
    moment *= scale
    swept *= scale
    if order == 2:
        gradient = np.diff(u, axis=1)
        gradient /= width
        tau = np.empty_like(u)
        tau[:, 0] = tau[:, -1] = 0.0
        minmod(gradient[:, :-1], gradient[:, 1:], out=tau[:, 1:-1])
        moved_momentum = np.where(from_left, tau[:, :-1], tau[:, 1:])
        moved_momentum *= moment
    else:
        moved_momentum = np.zeros_like(u[:, :-1])
    part_velocity = np.where(from_left, u[:, :-1], u[:, 1:])
    part_velocity *= swept
    moved_momentum += part_velocity
    old_node_mass = np.empty(x.size)
    old_node_mass[:-1] = share_left
    old_node_mass[-1] = 0.0
    old_node_mass[1:] += share_right
    node_mass = old_node_mass.copy()
    node_mass[:-1] -= swept
    node_mass[1:] += swept
    momentum = u * old_node_mass
    momentum[:, :-1] -= moved_momentum
    momentum[:, 1:] += moved_momentum
    kinetic = component_dot(u, u)  # ½M u², less what is handed over, plus what comes in
    kinetic *= old_node_mass
    kinetic *= 0.5
    kinetic_before = float(kinetic.sum())
    if heat:
        kinetic_flux = lump_kinetic(swept, moved_momentum)
        np.copysign(kinetic_flux, swept, out=kinetic_flux)  # signed like the mass: > 0 rightward
        kinetic[:-1] -= kinetic_flux
        kinetic[1:] += kinetic_flux
    else:
        kinetic = None
    # right corner of new cell j = [F_j, X_{j+1}] = R_j + what the face moved into it −
    # ∫ from x_{j+1} to X_{j+1} (the node's swept mass in the part beside the node)
    corner_new = np.empty((2, width.size))  # row 1 (right corners) filled here, row 0 by the caller
    right_corner = np.add(share_right, swept, out=corner_new[1])
    donor_scale = np.where(right_donor, scale_left[1:], scale_right[:-1])
    donor_scale *= flux_mass
    right_corner[:-1] -= donor_scale
    return new_mass, new_energy, corner_new, node_mass, momentum, kinetic_before, kinetic, far_nodes


def _clipped_integral(value, slope, centre, lo, hi, a, b):
    """∫ over [a, b] ∩ [lo, hi] of value + slope (x − centre); and the overlap length."""
    start = np.maximum(a, lo)
    end = np.minimum(b, hi)
    length = np.maximum(end - start, 0.0)
    end = start + length
    return integrate_linear(value, slope, centre, start, end), length, start, end


def windows(mixed_j, boundaries, far_nodes, n, taken_margin, window_margin):
    """swept_1d's windows before they were compiled (swept_kernels.window_ranges): the
    special cells, then (taken cells, window) pairs of [first, last) sorted ranges around
    them, merged where they overlap."""
    special = np.unique(np.concatenate([mixed_j, mixed_j + 1, boundaries, boundaries + 1, far_nodes - 1, far_nodes]))
    special = special[special < n]
    lo = np.maximum(special - taken_margin, 0)
    hi = np.minimum(special + taken_margin + 1, n)
    starts = np.flatnonzero(np.concatenate([[True], lo[1:] > hi[:-1]]))
    ends = np.concatenate([starts[1:] - 1, [special.size - 1]])
    return [((int(first), int(last)), (max(int(first) - window_margin, 0), min(int(last) + window_margin, n)))
            for first, last in zip(lo[starts], hi[ends])] if special.size else []


def swept_sorted(x, X, m0, mass0, specific0, corner_sorted, u, mixed_j, volume0_mixed, m1, mass1,
                  specific1, mixed_velocity, n_materials, order, cut=(False, False)):
    """The swept remap of a run of sorted cells (all of them, or a window of them: ``cut``
    says which ends are inside the mesh, whose end nodes move and whose results near that
    end the caller discards).  Mixed cells hold two materials; returns the new contents
    in sorted order, or None when a step is beyond the swept form's reach (swept_1d's
    numpy code before it was compiled into swept_kernels.window_contents and
    window_momentum)."""
    n = m0.size
    if (X[0] != x[0] and not cut[0]) or (X[-1] != x[-1] and not cut[1]):
        return None
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
        return None
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
    result = window_momentum(n, x, X, xl, xr, mixed_j, gamma, new_mixed_j, X[:-1] + new["volume"][0],
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


class _Parts:
    """The node parts of the old cells, one array per quantity: L_j = [x_j, f_j] (owner:
    sorted node j) and R_j = [f_j, x_{j+1}] (owner j + 1), f_j the cell's middle or, in an
    enriched mixed cell, Γ.  Each carries its density piece (value, slope, centre), the
    factor taking its reconstructed mass to the lumped corner mass, the centroid of that
    mass, and its owner's velocity and slope.  The L arrays have one more entry, an empty
    part at the right end of the domain, so that L_{j+1} is a slice for j = 0..n−1."""

    def __init__(self, lo, hi, rho, srho, cen, share, u, tau, pad_at=None):
        if pad_at is not None:  # the empty part [pad_at, pad_at]
            lo, hi = np.append(lo, pad_at), np.append(hi, pad_at)
            rho, srho, cen, share = (np.append(v, 0.0) for v in (rho, srho, cen, share))
            u, tau = (np.concatenate([v, np.zeros((v.shape[0], 1))], axis=1) for v in (u, tau))
        self.lo, self.hi, self.rho, self.srho, self.cen, self.u, self.tau = lo, hi, rho, srho, cen, u, tau
        length = hi - lo
        mass = length * (rho + srho * (0.5 * (lo + hi) - cen))
        empty = mass <= 0.0
        safe = np.where(empty, 1.0, mass)
        self.scale = np.where(empty, 0.0, share / safe)
        # centroid of the part's mass: (M·mid + σ L³/12) / M
        self.centroid = 0.5 * (lo + hi) + srho * length**3 / (12.0 * safe)

    def take(self, index):
        """The parts at an index array (a few, for the cells where Γ moves far)."""
        part = object.__new__(_Parts)
        for name in ("lo", "hi", "rho", "srho", "cen", "scale", "centroid"):
            setattr(part, name, getattr(self, name)[index])
        part.u, part.tau = self.u[:, index], self.tau[:, index]
        return part

    def window(self, first, count):
        """Parts first .. first + count − 1 as views."""
        part = object.__new__(_Parts)
        for name in ("lo", "hi", "rho", "srho", "cen", "scale", "centroid"):
            setattr(part, name, getattr(self, name)[first:first + count])
        part.u, part.tau = self.u[:, first:first + count], self.tau[:, first:first + count]
        return part


def _overlap(part, a, b):
    """Length and middle of [a, b] ∩ part (length 0 where they do not meet)."""
    start = np.maximum(a, part.lo)
    length = np.minimum(b, part.hi)
    length -= start
    np.maximum(length, 0.0, out=length)
    mid = 0.5 * length
    mid += start
    return length, mid


def _overlap_mass(part, a, b):
    """Lumped mass of the parts over [a, b] ∩ part (zero where they do not meet)."""
    length, mass = _overlap(part, a, b)
    mass -= part.cen
    mass *= part.srho
    mass += part.rho
    mass *= length
    mass *= part.scale
    return mass


def _overlap_mass_momentum(part, a, b):
    """Lumped mass and momentum of the parts over [a, b] ∩ part.  The velocity is linear
    on a part, u + τ (x − x̄), so ∫ρu = M (u + τ (x_M − x̄)) with x_M the centre of mass of
    the overlap: M x_M = M·mid + σ L³/12 (exactly the general intersection's integral)."""
    length, mid = _overlap(part, a, b)
    mass = mid - part.cen
    mass *= part.srho
    mass += part.rho
    mass *= length  # M (unscaled)
    offset = length * length
    offset *= length
    offset *= part.srho
    offset *= 1.0 / 12.0  # σ L³/12 = M (x_M − mid)
    offset += (mid - part.centroid) * mass  # M (x_M − x̄)
    mass *= part.scale
    offset *= part.scale
    momentum = part.tau * offset
    momentum += part.u * mass
    return mass, momentum


def window_momentum(n, x, X, xl, xr, mixed_j, gamma, new_mixed_j, new_gamma, rho0, srho0, centre0,
              rho1, srho1, centre1, corner_sorted, u, order, mixed_velocity, m0, m1_of_mixed, cut):
    """Nodal momentum and lumped masses through the dual faces (swept_1d._momentum before
    it was compiled into swept_kernels.window_momentum; None where the swept form does not
    reach) (enriched: a mixed cell's face is Γ; a pure cell's its middle).  A face's swept interval lies in its own cell
    (the parts L_j, R_j) except where Γ moves into a neighbouring cell; those few faces
    also take the neighbours' parts R_{j−1}, L_{j+1}."""
    face = 0.5 * (xl + xr)
    face[mixed_j] = gamma
    new_face = 0.5 * (X[:-1] + X[1:])
    new_face[new_mixed_j] = new_gamma[new_mixed_j]
    if order == 2:
        node_slope = _node_velocity_slopes(u, x, mixed_j, gamma, mixed_velocity, m0, m1_of_mixed)
    else:
        node_slope = np.zeros_like(u)
    left = _Parts(xl, face, rho0, srho0, centre0, corner_sorted[0], u[:, :-1], node_slope[:, :-1],
                  pad_at=x[-1])
    r_rho, r_srho, r_cen = rho0.copy(), srho0.copy(), centre0.copy()
    r_rho[mixed_j], r_srho[mixed_j], r_cen[mixed_j] = rho1, srho1, centre1
    right = _Parts(face, xr, r_rho, r_srho, r_cen, corner_sorted[1], u[:, 1:], node_slope[:, 1:])

    # Face j: the swept interval between f_j and F_j moves to node j + 1 what lies in node
    # j's parts (R_{j−1}, L_j) and to node j what lies in node j + 1's (R_j, L_{j+1}).
    a, b = np.minimum(new_face, face), np.maximum(new_face, face)
    to_right_mass, to_right_momentum = _overlap_mass_momentum(left.window(0, n), a, b)
    to_left_mass, to_left_momentum = _overlap_mass_momentum(right, a, b)
    # kinetic energy handed to the next node (rightward) less that handed back, one lump
    # per old part (the general intersection's grouping)
    kinetic_flux = lump_kinetic(to_right_mass, to_right_momentum) - lump_kinetic(to_left_mass, to_left_momentum)
    far = _inside_cut(np.flatnonzero((a < xl) | (b > xr)), n, cut)
    if far.size:
        width = xr[far] - xl[far]
        before, after = np.maximum(far - 1, 0), far + 1
        if np.any((far == 0) & (a[far] < xl[far])) or np.any(
                (a[far] < right.lo[before] - 1e-12 * width) | (b[far] > left.hi[after] + 1e-12 * width)):
            return None
        m, mom = _overlap_mass_momentum(right.take(before), a[far], b[far])
        m[far == 0], mom[:, far == 0] = 0.0, 0.0
        to_right_mass[far] += m
        to_right_momentum[:, far] += mom
        kinetic_flux[far] += lump_kinetic(m, mom)
        m, mom = _overlap_mass_momentum(left.take(after), a[far], b[far])
        to_left_mass[far] += m
        to_left_momentum[:, far] += mom
        kinetic_flux[far] -= lump_kinetic(m, mom)
    moved_mass = to_right_mass - to_left_mass
    moved_momentum = to_right_momentum - to_left_momentum
    old_mass = np.zeros(n + 1)
    old_mass[:-1] += corner_sorted[0]
    old_mass[1:] += corner_sorted[1]
    old_momentum = u * old_mass
    new_mass = old_mass.copy()
    new_mass[:-1] -= moved_mass
    new_mass[1:] += moved_mass
    new_momentum = old_momentum.copy()
    new_momentum[:, :-1] -= moved_momentum
    new_momentum[:, 1:] += moved_momentum
    inner = new_mass[1 if cut[0] else 0:new_mass.size - 1 if cut[1] else new_mass.size]
    if np.any(inner <= 0):
        return None
    # New corners: the right corner of new cell j is [F_j, X_{j+1}]; F_j lies in old cell j
    # (parts L_j, R_j) and X_{j+1} in R_j or L_{j+1}, except where Γ moved into a
    # neighbouring cell: there the parts R_{j−1} and R_{j+1} are added too.
    a, b = new_face, X[1:]
    right_corner = _overlap_mass(left.window(0, n), a, b)
    right_corner += _overlap_mass(right, a, b)
    right_corner += _overlap_mass(left.window(1, n), a, b)
    far = _inside_cut(np.flatnonzero((a < xl) | (b > left.hi[1:])), n, cut)
    if far.size:
        before, after = np.maximum(far - 1, 0), np.minimum(far + 1, n - 1)
        if np.any((a[far] < right.lo[before]) | (b[far] > right.hi[after])):
            return None
        extra = _overlap_mass(right.take(before), a[far], b[far])
        extra[far == 0] = 0.0
        beyond = _overlap_mass(right.take(after), a[far], b[far])
        beyond[far == n - 1] = 0.0
        right_corner[far] += extra + beyond
    left_corner = new_mass[:-1] - np.concatenate([[0.0], right_corner[:-1]])
    # ½M u² of each node, less the kinetic energy it handed over, plus what it received
    kinetic = 0.5 * old_mass * component_dot(u, u)
    kinetic[:-1] -= kinetic_flux
    kinetic[1:] += kinetic_flux
    return new_mass, new_momentum, np.stack([left_corner, right_corner]), kinetic


def _inside_cut(index, n, cut):
    """Drop the first / last cell of a window cut out of a larger mesh: its end node moves
    and what lies beyond it is not in the window (the caller discards those cells)."""
    keep = np.ones(index.size, dtype=bool)
    if cut[0]:
        keep &= index > 0
    if cut[1]:
        keep &= index < n - 1
    return index[keep]


def _node_velocity_slopes(u, x, mixed_j, gamma, mixed_velocity, m0, m1_of_mixed):
    """Minmod slope of each node's velocity from the cells on either side, within one
    material (the same slopes as :func:`ale_xfem.remap.intersection_1d._velocity_slopes`).  A mixed cell
    gives each of its internal nodes the gradient of that material's full field: the line
    through the node and (x_Γ, u_Γ) for the normal component, none for a transverse one."""
    gradient_left_part = (u[:, 1:] - u[:, :-1]) / (x[1:] - x[:-1])  # seen from cell j's left node
    gradient_right_part = gradient_left_part.copy()  # seen from its right node
    if mixed_j.size:
        xa, xb = x[mixed_j], x[mixed_j + 1]
        gradient_left_part[:, mixed_j] = 0.0
        gradient_right_part[:, mixed_j] = 0.0
        gradient_left_part[0, mixed_j] = (mixed_velocity - u[0, mixed_j]) / (gamma - xa)
        gradient_right_part[0, mixed_j] = (mixed_velocity - u[0, mixed_j + 1]) / (gamma - xb)
    # node k (1..n−1): right part of cell k−1 and left part of cell k
    material_right_part = m0.copy()
    material_right_part[mixed_j] = m1_of_mixed
    same = material_right_part[:-1] == m0[1:]
    slope = np.zeros((u.shape[0], u.shape[1]))
    slope[:, 1:-1] = np.where(same, minmod(gradient_right_part[:, :-1], gradient_left_part[:, 1:]), 0.0)
    return slope


def _node_extremes(mesh, cell_values, low_start, high_start):
    """The least and greatest of ``cell_values`` (n_cells,) over the cells around each node
    (ale_xfem.model.mesh.Corners.node_extremes, which the remap's numpy pass used)."""
    low = np.full(mesh.n_nodes, low_start, dtype=cell_values.dtype)
    high = np.full(mesh.n_nodes, high_start, dtype=cell_values.dtype)
    for index in mesh.cell_nodes.T:
        np.minimum.at(low, index, cell_values)
        np.maximum.at(high, index, cell_values)
    return low, high


def swept_pass_2d(mesh, x, target_a, target_b, edges, is_mixed, material, volume, mass, energy, order):
    """The 2D remap's whole-mesh pass over pure donors (ale_xfem.remap.remapper_2d, before it
    was compiled into ale_xfem.remap.swept_kernels_2d): the regions the interior edges
    sweep from ``x`` to the target (edge ends ``target_a``, ``target_b``), the volumes pure
    donors give (mixed donors give none here: the remapper clips theirs), each material's
    density and energy density, the fluxes at order 1 or 2, and the cells' ``volume``,
    ``mass`` and ``energy`` (n_materials, n_cells) after the exchange, in place.  ``edges``:
    (a, b, plus, minus) of mesh_edges.  Returns (donor, receiver, size, swept, flux_volume,
    flux_mass, flux_energy, rho, eps)."""
    from ale_xfem.geometry.shapes import corner_centroid

    a, b, plus, minus = edges
    n_materials, n_cells = volume.shape
    xa, xb = x.take(a, axis=1), x.take(b, axis=1)
    Xa, Xb = target_a, target_b
    S = (Xb[0] - xa[0]) * (xb[1] - Xa[1])
    S -= (Xb[1] - xa[1]) * (xb[0] - Xa[0])
    S *= 0.5
    # a twisted edge (the Lagrangian and target edges cross at P) beside a mixed cell or
    # between two materials: two lobes, made from its lower-numbered end p, the other q
    reverse = a > b
    xp, xq = np.where(reverse, xb, xa), np.where(reverse, xa, xb)
    Xp, Xq = np.where(reverse, Xb, Xa), np.where(reverse, Xa, Xb)
    dp = (Xq[0] - Xp[0]) * (xp[1] - Xp[1]) - (Xq[1] - Xp[1]) * (xp[0] - Xp[0])
    dq = (Xq[0] - Xp[0]) * (xq[1] - Xp[1]) - (Xq[1] - Xp[1]) * (xq[0] - Xp[0])
    ep = (xq[0] - xp[0]) * (Xp[1] - xp[1]) - (xq[1] - xp[1]) * (Xp[0] - xp[0])
    eq = (xq[0] - xp[0]) * (Xq[1] - xp[1]) - (xq[1] - xp[1]) * (Xq[0] - xp[0])
    interior = minus >= 0
    other = np.where(interior, minus, plus)
    split = is_mixed[plus] | is_mixed[other] | (material[plus] != material[other])
    twisted = interior & split & (dp * dq < 0.0) & (ep * eq < 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = ep / (ep - eq)
    P = Xp + t * (Xq - Xp)
    sign = np.where(reverse, -1.0, 1.0)
    Sp = sign * 0.5 * ((Xp[0] - xp[0]) * (P[1] - xp[1]) - (Xp[1] - xp[1]) * (P[0] - xp[0]))
    Sq = sign * 0.5 * ((Xq[0] - P[0]) * (xq[1] - P[1]) - (Xq[1] - P[1]) * (xq[0] - P[0]))
    # regions, edge by edge: the whole quadrilateral, or the lobe at p then the lobe at q
    areas = np.stack([S, Sp, Sq], axis=1)
    kept = np.stack([interior & ~twisted & (S != 0.0), twisted & (Sp != 0.0), twisted & (Sq != 0.0)], axis=1)
    vertices = [np.stack([xa, xp, P], axis=-1), np.stack([Xa, Xp, P], axis=-1), np.stack([Xb, P, Xq], axis=-1),
                np.stack([xb, P, xq], axis=-1)]  # (2, n_edges, 3) each: vertex 0 … 3 of each kind
    edge_of = np.repeat(np.arange(a.size), 3).reshape(-1, 3)[kept]
    S_e = areas[kept]
    swept = tuple([v[d][kept] for v in vertices] for d in range(2))
    donor = np.where(S_e > 0, minus[edge_of], plus[edge_of])
    receiver = np.where(S_e > 0, plus[edge_of], minus[edge_of])
    size = np.abs(S_e)
    flux_volume = np.zeros((n_materials, S_e.size))
    pure = ~is_mixed[donor]
    from_pure = np.flatnonzero(pure)
    entry = material.take(donor[from_pure])
    entry *= S_e.size
    entry += from_pure
    flux_volume.reshape(-1)[entry] = size[from_pure]
    with np.errstate(invalid="ignore", divide="ignore"):
        rho = np.where(volume > 0, mass / np.where(volume > 0, volume, 1.0), 0.0)
        eps = np.where(volume > 0, energy / np.where(volume > 0, volume, 1.0), 0.0)
    flux_mass = flux_volume * rho.take(donor, axis=1)
    flux_energy = flux_volume * eps.take(donor, axis=1)
    if order == 2:
        k = mesh.cell_type.nodes_per_cell
        cell_rho = rho[material, np.arange(n_cells)]
        cell_eps = eps[material, np.arange(n_cells)]
        corners = mesh.corners
        corner_x = [c[0] for c in corners.gather(x[:1])]
        corner_y = [c[0] for c in corners.gather(x[1:])]
        _, centre_x, centre_y = corner_centroid(corner_x, corner_y)
        tag = np.where(is_mixed, -1, material)
        low_tag, high_tag = _node_extremes(mesh, tag, np.iinfo(np.int64).max, -2)
        inside = ~is_mixed
        for low_i, high_i in zip(corners.gather(low_tag[None]), corners.gather(high_tag[None])):
            inside &= (low_i[0] == tag) & (high_i[0] == tag)
        relative = [(cx - centre_x, cy - centre_y) for cx, cy in zip(corner_x, corner_y)]
        slopes = []
        gradients = node_averaged_gradient(mesh, x, np.stack([cell_rho, cell_eps]))
        for value, grad in zip((cell_rho, cell_eps), gradients):
            low, high = _node_extremes(mesh, value, np.inf, -np.inf)
            gx, gy = np.ascontiguousarray(grad[:, 0]), np.ascontiguousarray(grad[:, 1])
            limiter = np.ones(n_cells)
            corner_low, corner_high = corners.gather(low[None]), corners.gather(high[None])
            for i in range(k):
                delta = gx * relative[i][0]
                delta += gy * relative[i][1]
                room = np.where(delta >= 0, corner_high[i][0], corner_low[i][0])
                room -= value
                with np.errstate(divide="ignore", invalid="ignore"):
                    bound = np.divide(room, delta, out=room)
                np.clip(bound, 0.0, 1.0, out=bound)
                np.fmin(limiter, bound, out=limiter)
            limiter[~inside] = 0.0
            slopes.append((gx * limiter, gy * limiter))
        where = np.flatnonzero(pure)
        source = donor[where]
        m = material[source]
        _, swept_x, swept_y = corner_centroid(*swept)
        swept_x = swept_x[where] - centre_x[source]
        swept_y = swept_y[where] - centre_y[source]
        total = flux_volume.sum(axis=0)[where]
        entry = m * flux_mass.shape[1]
        entry += where
        for (sx, sy), flux in ((slopes[0], flux_mass), (slopes[1], flux_energy)):
            correction = sx[source] * swept_x
            correction += sy[source] * swept_y
            correction *= total
            flux.reshape(-1)[entry] += correction
    for quantity, flux in ((volume, flux_volume), (mass, flux_mass), (energy, flux_energy)):
        for m in range(n_materials):
            quantity[m] += np.bincount(receiver, flux[m], n_cells) - np.bincount(donor, flux[m], n_cells)
    return donor, receiver, size, swept, flux_volume, flux_mass, flux_energy, rho, eps


def cell_momentum_2d(mesh, u, old_cell_mass, new_cell_mass, flux_mass, donor, receiver):
    """Nodal momentum through the cells in the 2D remap (ale_xfem.remap.remapper_2d, before it
    was compiled into swept_kernels_2d.cell_momentum).  Returns (velocity, node masses,
    kinetic energy before, loss) per node."""
    corners = mesh.corners
    k = mesh.cell_type.nodes_per_cell
    n_cells = mesh.n_cells
    old_node_mass = corners.scatter([old_cell_mass / k] * k)
    cell_velocity = np.stack([sum(c[0] for c in corners.gather(u[d:d + 1])) / k for d in range(u.shape[0])])
    total_flux = flux_mass.sum(axis=0)
    donor_velocity = cell_velocity.take(donor, axis=1)
    momentum_flux = total_flux * donor_velocity
    kinetic_flux = 0.5 * total_flux * np.sum(donor_velocity ** 2, axis=0)
    change = np.stack([np.bincount(receiver, f, n_cells) - np.bincount(donor, f, n_cells) for f in momentum_flux])
    kinetic_change_cells = np.bincount(receiver, kinetic_flux, n_cells) - np.bincount(donor, kinetic_flux, n_cells)
    node_mass = corners.scatter([new_cell_mass / k] * k)
    momentum = u * old_node_mass + np.stack([corners.scatter([c / k] * k) for c in change])
    velocity = momentum / node_mass
    kinetic_before = 0.5 * old_node_mass * np.sum(u * u, axis=0)
    kinetic_in = corners.scatter([kinetic_change_cells / k] * k)
    loss = kinetic_before + kinetic_in - 0.5 * node_mass * np.sum(velocity * velocity, axis=0)
    return velocity, node_mass, kinetic_before, loss


def deposit_heat_2d(mesh, per_mass, mass, energy):
    """The kinetic energy the 2D remap lost into the materials' internal energies, one
    velocity field (ale_xfem.remap.remapper_2d._deposit, before it was compiled into
    swept_kernels_2d.deposit_heat), in place: each cell's corners' Σ per_mass_i · m_K/k,
    shared by its materials' masses."""
    k = mesh.cell_type.nodes_per_cell
    new_cell_mass = mass.sum(axis=0)
    gathered = mesh.corners.gather(per_mass[None, :])
    heat = sum(g[0] for g in gathered) * (new_cell_mass / k)
    with np.errstate(invalid="ignore", divide="ignore"):
        energy += heat * np.where(new_cell_mass > 0, mass / np.where(new_cell_mass > 0, new_cell_mass, 1), 0)


def cap_outflow(volume, donor, flux_volume):
    """No donor gives more of a material than it holds (ale_xfem.remap.remapper_2d, before
    it was compiled into swept_kernels_2d.cap_outflow), in place."""
    n_materials, n_cells = volume.shape
    for m in range(n_materials):
        out = np.bincount(donor, flux_volume[m], n_cells)
        over = out > volume[m]
        if not np.any(over[donor] & (flux_volume[m] > 0)):
            continue
        ratio = np.where(over, volume[m] / np.where(over, out, 1.0), 1.0)
        kept = flux_volume[m] * ratio[donor]
        moved = flux_volume[m] - kept
        flux_volume[m] = kept
        others = [o for o in range(n_materials) if o != m]
        share = np.maximum(flux_volume[others], 0.0)
        total = share.sum(axis=0)
        share = np.where(total > 0, share / np.where(total > 0, total, 1.0), 1.0 / len(others))
        flux_volume[others] += share * moved


def cut_offsets(vertices, normal, fraction):
    """PLIC's cut offsets, vectorised over the cells (ale_xfem.model.plic, before it was
    compiled into geometry.polygon_kernels.cut_offsets)."""
    n, k, _ = vertices.shape
    projection = np.sort(np.einsum("nmd,nd->nm", vertices, normal), axis=1)
    total = polygon_area(vertices)
    target = fraction * total
    below = clipped_area(np.repeat(vertices, k, axis=0), np.repeat(normal, k, axis=0),
                         projection.ravel()).reshape(n, k)
    j = np.clip((below < target[:, None]).sum(axis=1) - 1, 0, k - 2)
    rows = np.arange(n)
    lo, hi = projection[rows, j], projection[rows, j + 1]
    a_lo, a_hi = below[rows, j], below[rows, j + 1]
    middle = 0.5 * (lo + hi)
    a_mid = clipped_area(vertices, normal, middle)
    gamma = 2.0 * (a_hi + a_lo - 2.0 * a_mid)
    beta = a_hi - a_lo - gamma
    rhs = np.maximum(target - a_lo, 0.0)
    denominator = beta + np.sqrt(np.maximum(beta * beta + 4.0 * gamma * rhs, 0.0))
    t = np.divide(2.0 * rhs, denominator, out=np.zeros_like(rhs), where=denominator > 0)
    return lo + np.clip(t, 0.0, 1.0) * (hi - lo)


def material_momentum_fluxes(cell_nodes, corner_mass, node_velocity, node_internal, flux_mass, donor, receiver,
                             added_mass=None, added_momentum=None, added_kinetic=None):
    """Each material's momentum per cell after the fluxes, the kinetic energy the fluxes
    bring, and each corner's deviation from its cell's mean velocity (2D enriched cells:
    ale_xfem.remap.remapper_2d, before it was compiled into
    swept_kernels_2d.material_momentum_fluxes); ``added_*``: what the materials' crossings
    of the Lagrangian edges brought each cell before the fluxes (default none).  Returns
    (momentum (2 components, 2 materials, n_cells), kinetic_in (2, n_cells), deviation (2,
    2, k, n_cells))."""
    n_cells = cell_nodes.shape[0]
    added_mass = np.zeros((2, n_cells)) if added_mass is None else added_mass
    added_momentum = np.zeros((2, 2, n_cells)) if added_momentum is None else added_momentum
    added_kinetic = np.zeros((2, n_cells)) if added_kinetic is None else added_kinetic
    cell_mass = corner_mass.sum(axis=1) + added_mass
    momentum = [np.zeros((2, n_cells)) for _ in range(2)]
    kinetic_in = np.zeros((2, n_cells))
    nodes = cell_nodes.T
    deviation = np.zeros((2, 2) + nodes.shape)
    for m in range(2):
        u = node_velocity[m]
        cell_velocity = np.empty((2, n_cells))
        for d in range(2):
            corner_velocity = u[d][nodes]
            momentum[d][m] = np.sum(corner_mass[m] * corner_velocity, axis=0) + added_momentum[d, m]
            np.divide(momentum[d][m], cell_mass[m], out=cell_velocity[d], where=cell_mass[m] > 0)
            cell_velocity[d][cell_mass[m] <= 0] = 0.0
            deviation[m, d] = np.where((cell_mass[m] > 0) & node_internal[m][nodes],
                                       corner_velocity - cell_velocity[d], 0.0)
        donor_velocity = cell_velocity.take(donor, axis=1)
        for d in range(2):
            flux = flux_mass[m] * donor_velocity[d]
            momentum[d][m] += np.bincount(receiver, flux, n_cells) - np.bincount(donor, flux, n_cells)
        kinetic = 0.5 * flux_mass[m] * np.sum(donor_velocity**2, axis=0)
        kinetic_in[m] = (np.bincount(receiver, kinetic, n_cells) - np.bincount(donor, kinetic, n_cells)
                         + added_kinetic[m])
    return np.stack(momentum), kinetic_in, deviation


def material_node_velocities(cell_nodes, corner_mass, node_mass, owner, momentum, deviation, old_node_mass,
                             old_velocity, old_corner_mass, kinetic_in):
    """Each material's nodal velocities on the remapped mesh, the mesh's velocity (each
    node's own material's) and the kinetic energy the remap dissipated per node (2D
    enriched cells: ale_xfem.remap.remapper_2d, before it was compiled into
    swept_kernels_2d.material_node_velocities; with the kinetic energy of the mass the new
    shares re-lump, as the kernel has it since)."""
    n_cells, k = cell_nodes.shape
    n_nodes = node_mass.shape[1]
    flat = cell_nodes.T.ravel()
    cell_mass = corner_mass.sum(axis=1)
    share = np.divide(corner_mass, cell_mass[:, None, :], out=np.zeros_like(corner_mass),
                      where=cell_mass[:, None, :] > 0)
    velocity = np.zeros((2, 2, n_nodes))
    means = np.zeros((2, 2, n_cells))
    for m in range(2):
        for d in range(2):
            mean = np.divide(momentum[d][m], cell_mass[m], out=np.zeros(n_cells), where=cell_mass[m] > 0)
            means[m, d] = mean
            corner_velocity = mean + deviation[m, d] - np.sum(share[m] * deviation[m, d], axis=0)
            node_momentum = np.bincount(flat, (corner_mass[m] * corner_velocity).ravel(), n_nodes)
            np.divide(node_momentum, node_mass[m], out=velocity[m, d], where=node_mass[m] > 0)
    mesh_velocity = velocity[owner, :, np.arange(n_nodes)].T.copy()
    for m in range(2):
        velocity[m][:, node_mass[m] <= 0] = mesh_velocity[:, node_mass[m] <= 0]
    kinetic_before = 0.5 * np.sum(old_node_mass[:, None] * old_velocity**2, axis=(0, 1))
    old_cell_mass = old_corner_mass.sum(axis=1)
    old_share = np.divide(old_corner_mass, old_cell_mass[:, None, :], out=np.full_like(old_corner_mass, 1.0 / k),
                          where=old_cell_mass[:, None, :] > 0)
    flux_share = np.where(cell_mass[:, None, :] > 0, share, old_share)
    brought = flux_share * kinetic_in[:, None, :]
    # the old mass the new shares move between a cell's corners, at the cell's new mean velocity
    relumped = share * old_cell_mass[:, None, :] - old_corner_mass
    speed2 = means[:, 0] * means[:, 0] + means[:, 1] * means[:, 1]
    brought = np.where(cell_mass[:, None, :] > 0, brought + 0.5 * relumped * speed2[:, None, :], brought)
    in_nodes = np.bincount(flat, brought.sum(axis=0).ravel(), n_nodes)
    loss = kinetic_before + in_nodes - 0.5 * np.sum(node_mass[:, None] * velocity**2, axis=(0, 1))
    return velocity, mesh_velocity, kinetic_before, loss


def node_materials(cell_nodes, n_nodes, cell_material, material_volume, material_of_slot):
    """The material each node lies in, and the nodes with pure cells of two materials
    around them (ale_xfem.mixed.cut_cells_2d, before it was compiled)."""
    n_materials = int(material_of_slot.max()) + 1
    size = n_materials * n_nodes
    k = cell_nodes.shape[1]
    pure = cell_material >= 0
    pure_count = np.bincount(np.repeat(cell_material[pure], k) * n_nodes + cell_nodes[pure].ravel(),
                             minlength=size).reshape(n_materials, n_nodes)
    share = np.zeros(size)
    for slot in range(material_of_slot.shape[0]):
        present = material_of_slot[slot] >= 0
        share += np.bincount(np.repeat(material_of_slot[slot, present], k) * n_nodes + cell_nodes[present].ravel(),
                             np.repeat(material_volume[slot, present], k), minlength=size)
    share = share.reshape(n_materials, n_nodes)
    total = share.sum(axis=0)
    fraction = np.divide(share, total, out=np.zeros_like(share), where=total > 0)
    owner = np.argmax(pure_count + 0.5 * fraction, axis=0)
    two_pure = (pure_count > 0).sum(axis=0) > 1
    return owner, two_pure


def node_averaged_gradient(mesh, node_position, values):
    """The gradient in every cell of cell fields averaged to the nodes by area
    (ale_xfem.model.mesh.node_averaged_gradient over the whole mesh, before it was compiled
    into cell_kernels.node_averaged_gradients): the mesh's own corner gathers and scatters
    (grid views on a structured quadrilateral mesh).  ``values`` (m, n_cells) → (m, n_cells, 2)."""
    from ale_xfem.model.mesh import QuadGradient

    corners = mesh.corners
    k = mesh.cell_type.nodes_per_cell
    area, gradient = mesh.cell_geometry(node_position)
    weight = corners.scatter([area] * k)
    grad = np.empty((values.shape[0], mesh.n_cells, 2))
    for f, field in enumerate(values):
        nodal = corners.scatter([field * area] * k) / weight
        if isinstance(gradient, QuadGradient):
            diagonals = corners.quad_corners(nodal[None], hourglass=False)
            across02, across13 = diagonals.across02[0], diagonals.across13[0]
            (g0x, g0y), (g1x, g1y) = gradient.independent
            gx, gy = g0x * across02 + g1x * across13, g0y * across02 + g1y * across13
        else:
            corner_values = [nodal[mesh.cell_nodes[:, i]] for i in range(k)]
            gx = sum(v * g[0] for v, g in zip(corner_values, gradient))
            gy = sum(v * g[1] for v, g in zip(corner_values, gradient))
        grad[f, :, 0], grad[f, :, 1] = gx / area, gy / area
    return grad


def material_slots(volume, mass, energy, area, standing, trace):
    """The remapped cells' materials back in slots (ale_xfem.remap.remapper_2d._new_state,
    before it was compiled into swept_kernels_2d.material_slots)."""
    from ale_xfem.model.state import ranked_materials

    n_materials, n_cells = volume.shape
    present = (volume > trace * area) | (standing & (mass != 0.0))
    count = present.sum(axis=0)
    slots = 2 if np.any(count == 2) else 1
    cell_material = np.full((slots, n_cells), -1, dtype=np.int64)
    ranked = ranked_materials(np.where(present, volume, -1.0), slots)
    cell_material[0] = ranked[0]
    if slots == 2:
        cell_material[1] = np.where(count == 2, ranked[1], -1)
    slot_mass, slot_energy, slot_volume = (np.zeros((slots, n_cells)) for _ in range(3))
    for slot in range(slots):
        for m in range(n_materials):
            here = cell_material[slot] == m
            np.copyto(slot_mass[slot], mass[m], where=here)
            np.copyto(slot_volume[slot], volume[m], where=here)
            np.copyto(slot_energy[slot], energy[m], where=here)
        np.divide(slot_energy[slot], slot_mass[slot], out=slot_energy[slot], where=cell_material[slot] >= 0)
    return count, cell_material, slot_mass, slot_volume, slot_energy


def mixed_cell_cuts(problem, state, layout, mixed):
    """What PLIC needs of a state's mixed cells, as numpy computed it (ale_xfem.model.plic,
    before plic.mixed_cell_cuts compiled it): (cells, corners (n, k, 2), Youngs' normals of
    their slot-0 material, its volume fractions)."""
    from ale_xfem.geometry.shapes import polygon_area as shapes_polygon_area
    from ale_xfem.model.mesh import cells_around
    from ale_xfem.model.plic import youngs_normals

    mesh, cells = problem.mesh, mixed.cells
    around = cells_around(mesh, cells)
    area = mesh.cell_geometry(state.node_position, around)[0]
    fractions = np.zeros((len(problem.materials), mesh.n_cells))
    for slot in range(layout.cell_material.shape[0]):
        material = layout.cell_material[slot, around]
        here = material >= 0
        fractions[material[here], around[here]] += state.material_volume[slot, around[here]] / area[here]
    alpha = layout.cell_material[0, cells]
    materials = np.unique(alpha)
    normals = youngs_normals(mesh, state.node_position, fractions[materials], cells, around)
    normals = normals[np.searchsorted(materials, alpha), np.arange(cells.size)]
    vertices = np.moveaxis(state.node_position[:, mesh.cell_nodes[cells]], 0, -1)
    return cells, vertices, normals, state.material_volume[0, cells] / shapes_polygon_area(vertices)


# -- the vectorised numpy polygon geometry of ale_xfem.geometry.shapes, before its functions
# called the compiled one-polygon kernels of ale_xfem.geometry.polygon_kernels


def polygon_area(vertices: np.ndarray) -> np.ndarray:
    """Signed (shoelace) areas of polygons (n, m, 2): > 0 counter-clockwise."""
    x, y = vertices[..., 0], vertices[..., 1]
    m = vertices.shape[-2]
    total = x[..., m - 1] * y[..., 0] - x[..., 0] * y[..., m - 1]
    for i in range(m - 1):  # a loop over the polygon's vertices, vectorised over polygons
        total += x[..., i] * y[..., i + 1] - x[..., i + 1] * y[..., i]
    total *= 0.5
    return total


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


def edge_half_planes(clip: np.ndarray, i: int):
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
        result = clip_half_plane(result, *edge_half_planes(clip, i))
    return result


def eos_state(eos, rho, e):
    """(p, ∂p/∂ρ|_e, ∂p/∂e|_ρ, c²) of an equation of state of ale_xfem.eos, in numpy (the
    models' ``state`` before ale_xfem.eos.kernels.state_derivatives)."""
    from ale_xfem.eos import Linear, MieGruneisen, StiffenedGas

    if isinstance(eos, StiffenedGas):
        g1 = eos.gamma - 1.0
        p = g1 * rho * e - eos.gamma * eos.p_inf
        return p, g1 * e, g1 * rho, eos.gamma * g1 * (e - eos.p_inf / rho)
    if isinstance(eos, MieGruneisen):
        eta = 1.0 - eos.rho0 / rho
        denom = 1.0 - eos.s * eta
        p_h = eos.rho0 * eos.c0**2 * eta / denom**2
        dp_h_deta = eos.rho0 * eos.c0**2 * (1.0 + eos.s * eta) / libm_power(denom, 3.0)
        e_h = p_h * eta / (2.0 * eos.rho0)
        de_h_deta = (p_h + eta * dp_h_deta) / (2.0 * eos.rho0)
        k = eos.gamma0 * eos.rho0
        p = p_h + k * (e - e_h)
        dp_drho = (dp_h_deta - k * de_h_deta) * eos.rho0 / rho**2
        dp_de = np.full_like(np.asarray(rho, dtype=float), k)
        return p, dp_drho, dp_de, dp_drho + p / rho**2 * k
    assert isinstance(eos, Linear)
    ones = np.ones_like(np.asarray(rho, dtype=float))
    return eos.pressure(rho, e), eos.c0**2 * ones, 0.0 * ones, eos.c0**2 * ones


def _relaxed_pressure(mixed, groups, mass, volume, energy0, volume0):
    rho = mass / volume
    p0, _, dp_de, _ = groups.eos_values(mixed.materials, rho, energy0)
    coupling = dp_de * (volume0 - volume) / mass  # S
    keep = 1.0 - coupling
    admissible = keep > 0.0
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        keep = np.where(admissible, keep, 1.0)
        pi = np.where(admissible, p0 / keep, np.inf)
        work = np.where(admissible, pi, 0.0)
        dp_drho = groups.eos_values(mixed.materials, rho, energy0 - work * (volume - volume0) / mass)[1]
        slope = np.where(admissible, -(dp_drho * rho + dp_de * work / mass * volume) / (volume * keep), 0.0)
    return pi, slope, coupling


def relax(mixed, volume, state0):
    """The pressure relaxation's root over all mixed cells at once, in numpy
    (ale_xfem.mixed.equilibrium.relax_cells): (status, cell, V_α, V_β, p*), status 0
    relaxed, 1 a volume that cannot hold both materials, 2 not converged."""
    with np.errstate(invalid="ignore"):  # the tests give it NaN states too
        return _relax(mixed, volume, state0)


def _relax(mixed, volume, state0):
    m_a, m_b, va0, vb0, ea0, eb0 = state0
    total = volume
    lo = np.maximum(1e-12 * total, m_a / mixed.max_density_left * (1 + 1e-9)) - va0
    hi = vb0 - np.maximum(1e-12 * total, m_b / mixed.max_density_right * (1 + 1e-9))
    if (lo >= hi).any():
        return 1, int(np.flatnonzero(lo >= hi)[0]), None, None, None
    delta = np.minimum(np.maximum(0.0, lo), hi)
    finished = False
    for iteration in range(200):
        va, vb = va0 + delta, vb0 - delta
        pi_a, slope_a, coupling_a = _relaxed_pressure(mixed, mixed.left_groups, m_a, va, ea0, va0)
        pi_b, slope_b, coupling_b = _relaxed_pressure(mixed, mixed.right_groups, m_b, vb, eb0, vb0)
        h = pi_a - pi_b
        scale = np.maximum(np.maximum(np.abs(pi_a), np.abs(pi_b)),
                           np.minimum(np.abs(slope_a) * va, np.abs(slope_b) * vb))
        balanced = np.isfinite(h) & (np.abs(h) <= 1e-3 * mixed.tolerance * scale)
        if finished or balanced.all():
            break
        lo = np.where(h > 0, delta, lo)
        hi = np.where(h <= 0, delta, hi)
        with np.errstate(invalid="ignore", divide="ignore"):
            newton = delta - h / (slope_a + slope_b)
        # (Newton for the first 50 iterations, then bisection: equilibrium.NEWTON_ITERATIONS)
        inside = np.isfinite(newton) & (newton > lo) & (newton < hi) & (iteration < 50)
        new_delta = np.where(balanced, delta, np.where(inside, newton, 0.5 * (lo + hi)))
        resolution = 4e-16 * np.minimum(va, vb)
        finished = bool((balanced | (np.abs(new_delta - delta) <= resolution) | (hi - lo <= resolution)).all())
        delta = new_delta
    else:
        with np.errstate(invalid="ignore", divide="ignore"):
            return 2, int(np.argmax(np.abs(h) / scale)), None, None, None
    return 0, 0, va, vb, np.where(np.abs(coupling_a) >= np.abs(coupling_b), pi_a, pi_b)


def adiabat(mixed, groups, mass, volume, energy0, volume0, work_pressure):
    """p, dp/dV, e, ρ, c², ∂p/∂W of one side's materials on their trapezoidal adiabats, in
    numpy (ale_xfem.mixed.equilibrium.adiabat)."""
    specific_change = (volume - volume0) / mass
    energy = energy0 - work_pressure * specific_change
    rho = mass / volume
    p, dp_drho, dp_de, c2 = groups.eos_values(mixed.materials, rho, energy)
    dp_dv = -dp_drho * rho / volume - dp_de * work_pressure / mass
    dp_dwork = -dp_de * specific_change
    return p, dp_dv, energy, rho, c2, dp_dwork


def split(mixed, total, state0, work_pressure, guess):
    """The corrector's balance of every mixed cell at once, in numpy
    (ale_xfem.mixed.equilibrium.split_cells): (the cell that cannot hold its materials or
    −1, the iterations, V_α, and each side's p, dp/dV, e, ρ, c², ∂p/∂W)."""
    m_a, m_b, va0, vb0, ea0, eb0 = state0
    limit_a = m_a / mixed.max_density_left
    limit_b = m_b / mixed.max_density_right
    lo = np.maximum(1e-12 * total, limit_a * (1 + 1e-9))
    hi = np.minimum((1 - 1e-12) * total, total - limit_b * (1 + 1e-9))
    if (lo >= hi).any():
        return int(np.flatnonzero(lo >= hi)[0]), 0, None, None
    v = np.minimum(np.maximum(guess, lo), hi)
    with np.errstate(invalid="ignore", divide="ignore"):
        for iteration in range(1, 101):
            a = adiabat(mixed, mixed.left_groups, m_a, v, ea0, va0, work_pressure)
            b = adiabat(mixed, mixed.right_groups, m_b, total - v, eb0, vb0, work_pressure)
            h = a[0] - b[0]
            slope = a[1] + b[1]
            balanced = np.abs(h) <= 1e-3 * mixed.tolerance * np.abs(slope) * total
            if balanced.all():
                return -1, iteration, v, (a, b)
            lo = np.where(h > 0, v, lo)
            hi = np.where(h <= 0, v, hi)
            newton = v - h / slope
            inside = np.isfinite(newton) & (newton > lo) & (newton < hi)
            v_new = np.where(balanced, v, np.where(inside, newton, 0.5 * (lo + hi)))
            change = np.abs(v_new - v)
            v = v_new
            if (balanced | (change <= 8e-16 * total) | (hi - lo <= 8e-16 * total)).all():
                break
        a = adiabat(mixed, mixed.left_groups, m_a, v, ea0, va0, work_pressure)
        b = adiabat(mixed, mixed.right_groups, m_b, total - v, eb0, vb0, work_pressure)
    return -1, iteration, v, (a, b)


def interface_solve(mixed, state0, pressure0, volume_affine, work_affine):
    """The interface pressure of every mixed cell, the predictor's iteration in numpy
    (ale_xfem.mixed.equilibrium.interface_solve): (π, V_α, V_β, details, iterations), or
    ("cannot hold" | "not converged", the cell)."""
    a, b = volume_affine
    w0, w1 = work_affine
    m_a, m_b, va0, vb0, ea0, eb0 = state0
    va, vb, pi = va0.copy(), vb0.copy(), pressure0.copy()
    stalled = 64 * np.finfo(float).eps

    def coupled(p, dp_dv, dp_dpi, pi):
        coupling = np.minimum(np.maximum(dp_dpi, -0.5), 0.5)
        return (p - coupling * pi) / (1.0 - coupling), dp_dv / (1.0 - coupling)

    def state_at(va, vb, work):
        pa, _, ea, rho_a, c2a, _ = adiabat(mixed, mixed.left_groups, m_a, va, ea0, va0, work)
        pb, _, eb, rho_b, c2b, _ = adiabat(mixed, mixed.right_groups, m_b, vb, eb0, vb0, work)
        return ea, eb, pa, pb, rho_a, rho_b, c2a, c2b

    previous = None
    for iteration in range(1, mixed.max_iterations + 1):
        work = w0 + w1 * pi
        if previous is None:
            pa, da, *_, wa = adiabat(mixed, mixed.left_groups, m_a, va, ea0, va0, work)
            pb, db, *_, wb = adiabat(mixed, mixed.right_groups, m_b, vb, eb0, vb0, work)
        else:
            pa, pb, da, db, wa, wb = previous
        pa, da = coupled(pa, da, wa * w1, pi)
        pb, db = coupled(pb, db, wb * w1, pi)
        pi_new = (a - va - vb + pa / da + pb / db) / (1.0 / da + 1.0 / db - b)
        total = a + b * pi_new
        work_new = w0 + w1 * pi_new
        if not mixed.nonlinear:
            va = va + (pi_new - pa) / da
            vb = total - va
            return pi_new, va, vb, state_at(va, vb, work_new), iteration
        bad, _, va_new, sides = split(mixed, total, state0, work_new, va + (pi_new - pa) / da)
        if bad >= 0:
            return "cannot hold", bad
        side_a, side_b = sides
        details = (side_a[2], side_b[2], side_a[0], side_b[0], side_a[3], side_b[3], side_a[4], side_b[4])
        balanced = 0.5 * (side_a[0] + side_b[0])
        scale = np.maximum(np.abs(pi_new), np.minimum(details[4] * details[6], details[5] * details[7]))
        converged = np.abs(balanced - pi_new) <= mixed.tolerance * scale
        change = np.abs(pi_new - pi)
        converged |= change <= stalled * np.maximum(np.abs(pi_new), scale)
        va, vb, pi = va_new, total - va_new, pi_new
        previous = (side_a[0], side_b[0], side_a[1], side_b[1], side_a[5], side_b[5])
        if converged.all():
            return pi, va, vb, details, iteration
    stiffer = np.maximum(details[4] * details[6], details[5] * details[7])
    if (converged | (change <= stalled * np.maximum(np.abs(pi_new), stiffer))).all():
        return pi, va, vb, details, mixed.max_iterations
    return "not converged", int(np.argmax(np.abs(balanced - pi_new) / scale))


def deposit_losses(loss, corner_mass, node_mass, left_node, right_node, in_order, mixed_cells, condensed,
                   material_mass, material_energy):
    """pieces_1d.deposit_kinetic_loss's deposit of every loss (before it was compiled into
    swept_kernels.deposit_losses), in place on ``material_energy``."""
    if node_mass.min() > 0:  # every node keeps mass (always in the swept form)
        per_mass = loss / node_mass
    else:
        per_mass = np.zeros_like(loss)
        np.divide(loss, node_mass, out=per_mass, where=node_mass > 0)
    if in_order:
        left, right = per_mass[:-1] * corner_mass[0], per_mass[1:] * corner_mass[1]
    else:
        left, right = per_mass[left_node] * corner_mass[0], per_mass[right_node] * corner_mass[1]
    heat = left
    heat += right
    if mixed_cells.size:
        c = mixed_cells
        to_second = right[c] if condensed else heat[c] * material_mass[1, c] / (material_mass[0, c] + material_mass[1, c])
        heat[c] -= to_second
        material_energy[1, c] += to_second / material_mass[1, c]
    heat /= material_mass[0]
    material_energy[0] += heat


def node_velocities_and_losses(node_mass, momentum, right_corner, left_corner, kinetic, heat):
    """The end of swept_1d.remap_1d_swept (before it was compiled into
    swept_kernels.node_velocities_and_losses): left corners in place, (velocity, ½ p·u,
    loss or None)."""
    left_corner[...] = node_mass[:-1]
    left_corner[1:] -= right_corner[:-1]
    velocity = momentum / node_mass
    kinetic_new = component_dot(momentum, velocity)
    kinetic_new *= 0.5
    return velocity, kinetic_new, (kinetic - kinetic_new if heat else None)


def density_of(mass, volume):
    """model.state.density_of before it was compiled (cell_kernels.slot_densities)."""
    density = np.empty_like(mass)
    for m, v, rho in zip(mass, volume, density):
        if v.min() > 0.0:
            np.divide(m, v, out=rho)
        else:
            rho.fill(0.0)
            filled = np.flatnonzero(v > 0.0)
            rho[filled] = m[filled] / v[filled]
    return density


def finite_where_occupied(values, mass):
    """The remapper's check before it was compiled (cell_kernels.finite_where_occupied)."""
    return bool(np.all(np.isfinite(values[mass > 0])))
