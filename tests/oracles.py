"""Readable numpy references of compiled kernels, kept as oracles for the tests: each is
the code the kernel replaced, and the kernel must give its results to the bit."""

from __future__ import annotations

import numpy as np

from ale_xfem.remap.pieces_1d import component_dot, lump_kinetic, minmod, piece_slopes


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
