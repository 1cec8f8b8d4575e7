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
from ale_xfem.remap.pieces_1d import RemapResult, deposit_kinetic_loss


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
    mixed_j = mixed_cells if in_order else _rank(cells, cell_left_node.size)[mixed_cells]
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
    ranges = swept_kernels.window_ranges(np.asarray(mixed_j, dtype=np.int64), boundaries, far_nodes, n,
                                         TAKEN_MARGIN, WINDOW_MARGIN)
    slots = 1
    taken_cells = []
    if ranges.shape[0]:
        if mixed_cells.size:
            mixed_data = (material_volume[0, mixed_cells], cell_material[1, mixed_cells],
                          material_mass[1, mixed_cells], material_energy[1, mixed_cells], interface_velocity)
        else:  # one slot: no mixed cell yet
            mixed_data = (np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0), np.zeros(0))
        slot_material, new_volume = swept_kernels.two_slots(np.ascontiguousarray(m0), X)
        if new_mass.shape[0] == 1:  # far-moving nodes only: the kernel gave one slot
            new_mass = np.vstack([new_mass, np.zeros(n)])
            new_energy = np.vstack([new_energy, np.zeros(n)])
        mixed_in_windows = []
        for taken_first, taken_last, window_first, window_last in ranges.tolist():
            taken, window = (taken_first, taken_last), (window_first, window_last)
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
            in_window = result["new_mixed_j"]
            mixed_in_windows.append(window[0] + in_window[(in_window >= t.start) & (in_window < t.stop)])
        # (slot 1 is empty outside the windows' taken cells)
        new_mixed_j = np.concatenate(mixed_in_windows)
        if new_mixed_j.size > 1 and np.any(np.abs(new_mixed_j[1:] - new_mixed_j[:-1]) <= 1):
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
    if in_order and heat is True:  # the common case: its end in one compiled call
        velocity, kinetic_new, specific, density = swept_kernels.end_of_swept_remap(
            node_mass, momentum, corner_new, kinetic, new_mass, new_energy, new_volume,
            np.concatenate(taken_cells) if taken_cells else np.zeros(0, dtype=np.int64), cells[new_mixed_j])
        return RemapResult(np.ascontiguousarray(slot_material), new_mass, specific, new_volume, corner_new, node_mass,
                           velocity, cells[new_mixed_j], float(np.sum(kinetic_new)) - kinetic_before, momentum,
                           density)
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
    swept_kernels.second_slot_specific_energies(specific, mass, energy, np.concatenate(taken_cells))
    return specific


# Cells around an interface taken from its window, and the window's margin on each side:
# a new cell's content depends on the old cells up to two away (donor and its slope), a
# node's momentum on the parts and velocity slopes up to three away.
TAKEN_MARGIN, WINDOW_MARGIN = 3, 4


def _swept_sorted(x, X, m0, mass0, specific0, corner_sorted, u, mixed_j, volume0_mixed, m1, mass1,
                  specific1, mixed_velocity, n_materials, order, cut=(False, False)):
    """The swept remap of a run of sorted cells (all of them, or a window of them: ``cut``
    says which ends are inside the mesh, whose end nodes move and whose results near that
    end the caller discards).  Mixed cells hold two materials; returns the new contents
    in sorted order, or None when a step is beyond the swept form's reach.  Compiled:
    :func:`ale_xfem.remap.swept_kernels.window_contents` (the cells) and
    :func:`ale_xfem.remap.swept_kernels.window_momentum` (the nodes)."""
    status, bad, slot_material, mass, energy, volume, gamma, rho0, srho0, centre0, rho1, srho1, centre1 = \
        swept_kernels.window_contents(x, X, m0, mass0, specific0, mixed_j, volume0_mixed, m1, mass1, specific1,
                                      n_materials, order, bool(cut[0]), bool(cut[1]))
    if status == 3:
        raise RemapFailure(f"sorted cell {bad}: {swept_kernels.CONTENT_FAILURES[2]}")
    if status:
        return _too_far(swept_kernels.CONTENT_FAILURES[status - 1])
    new_mixed_j = np.flatnonzero(slot_material[1] >= 0)
    result = _momentum(x, X, x[:-1], x[1:], mixed_j, gamma, new_mixed_j, X[:-1] + volume[0],
                       rho0, srho0, centre0, rho1, srho1, centre1, corner_sorted, u, order,
                       mixed_velocity, m0, m1, cut)
    if result is None:
        return None
    node_mass, momentum, corner_new, kinetic = result
    return {"slot_material": slot_material, "mass": mass, "energy": energy, "volume": volume,
            "corner": corner_new, "node_mass": node_mass, "node_momentum": momentum, "new_mixed_j": new_mixed_j,
            "kinetic": kinetic}


def _momentum(x, X, xl, xr, mixed_j, gamma, new_mixed_j, new_gamma, rho0, srho0, centre0,
              rho1, srho1, centre1, corner_sorted, u, order, mixed_velocity, m0, m1_of_mixed, cut):
    """Nodal momentum and lumped masses through the dual faces (compiled:
    :func:`ale_xfem.remap.swept_kernels.window_momentum`): (new node masses, momenta, corner
    masses, kinetic energies), or None when a face or a corner moves beyond the parts the
    swept form reads."""
    face = 0.5 * (xl + xr)
    face[mixed_j] = gamma
    # the parts' L³ as numpy's power gives them (the C library's pow differs in the last bit)
    left = np.empty(face.size + 1)  # the last node's part: x_n − x_n
    np.subtract(face, xl, out=left[:-1])
    left[-1] = x[-1] - x[-1]
    left_cube = left ** 3
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


