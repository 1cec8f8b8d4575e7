"""Compiled kernels of the explicit Wilkins step (ale_xfem.lagrange.wilkins drives them).

The physics of a cell is written once, as a function of one cell (its volume rate, its
artificial viscosity, its hourglass forces, its corner forces, its time step limit); the
loops call them.  A state whose cells are all pure is evaluated in one loop with its
equation of state (:func:`evaluate_pure`; quadrilaterals of one gas in two, the second
vectorised); with mixed cells the same functions run in
stages (:func:`geometry_and_rates`, the equation of state, :func:`stress_and_corner_forces`),
between which the mixed cells' closure sets their entries.

Every formula keeps the order of operations of the numpy code it replaced: the results
are the same to the bit, which tests/test_regression.py checks on every shipped scene.
Cell types are told apart by the codes of ale_xfem.model.cell_kernels, whose shape
convention and node access (``cell_nodes``, ``runs``) these kernels follow.

Corner forces are summed onto the nodes corner by corner, in the order numpy's scatters
summed them (:func:`scatter_corners`): a node's force does not depend on the order the
cells are visited in, and a state at rest stays at rest to round-off.
"""

from __future__ import annotations

import numba
import numba.extending
import numpy as np

from ale_xfem.eos.kernels import BODY, LOOP, STIFFENED_GAS, pressure_sound_speed
from ale_xfem.model.cell_kernels import (INTERVAL, QUADRILATERAL, TRIANGLE, geometry_loop, geometry_of_cell, load_shape,
                                         nan_max, nan_min, node, node_access, quad_corner_values, store_shape)

# how corner values are summed onto the nodes (ExplicitWilkins.scatter_mode)
RUNS, PER_CORNER, FLAT = 0, 1, 2
# the stages of pure_step (a whole step: both)
PREDICTOR_STAGE, CORRECTOR_STAGE, BOTH_STAGES = 1, 2, 3


# -- one cell ---------------------------------------------------------------------------

@numba.njit(**LOOP)
def quad_gradient(s):  # pragma: no cover (compiled)
    """(g_0x, g_0y, g_1x, g_1y) of a quadrilateral's shape ``s``: ∂A/∂x_0 = ½ (r_y, −r_x)
    and ∂A/∂x_1 = ½ (−p_y, p_x)."""
    return 0.5 * s[3], -0.5 * s[2], -0.5 * s[1], 0.5 * s[0]


@numba.njit(**LOOP)
def volume_rate(cell_type, s, cell_nodes, at, k, u, combos):  # pragma: no cover (compiled)
    """dV/dt = Σ_i ∂V/∂x_i·u_i of cell k, shape ``s`` (quadrilaterals read the velocity's
    corner combinations ``combos`` instead of u)."""
    if cell_type == INTERVAL:
        return u[0, node(cell_nodes, at, k, 1)] - u[0, node(cell_nodes, at, k, 0)]
    if cell_type == TRIANGLE:
        a = node(cell_nodes, at, k, 0)
        total = s[0] * u[0, a]
        total += s[1] * u[1, a]
        a = node(cell_nodes, at, k, 1)
        total += s[2] * u[0, a]
        total += s[3] * u[1, a]
        a = node(cell_nodes, at, k, 2)
        total += s[4] * u[0, a]
        total += s[5] * u[1, a]
        return total
    return quad_volume_rate(s, combos[0, 0, k], combos[0, 1, k], combos[1, 0, k], combos[1, 1, k])


@numba.njit(**LOOP)
def quad_volume_rate(s, across02_x, across02_y, across13_x, across13_y):  # pragma: no cover (compiled)
    """dA/dt = g_0·(u_0 − u_2) + g_1·(u_1 − u_3) of a quadrilateral, shape ``s``, from its
    velocity's corner combinations."""
    g0x, g0y, g1x, g1y = quad_gradient(s)
    total = g0x * across02_x
    total += g0y * across02_y
    total += g1x * across13_x
    total += g1y * across13_y
    return total


@numba.njit(**LOOP)
def velocity_jump(cell_type, volume, rate):  # pragma: no cover (compiled)
    """Δu = L ∇·u = L (dV/dt)/V, the velocity jump across the cell that the artificial
    viscosity sees: 1D u_right − u_left exactly (L = V); 2D L = √A.

    2D choice, measured (2026-11-22, quadrilaterals): a directional length — the cell's
    width along the direction of greatest compression, the eigenvector of the least
    eigenvalue of the symmetric velocity gradient — let the cells along Noh's symmetry axes
    collapse (negative energy at t ≈ 0.45 on 100 × 100) and left Saltzman's plateau between
    3.86 and 4.30 in the mid-height cells; with L = √A Noh runs to t = 0.6 and Saltzman's
    plateau stays within 3.99–4.03 (``demos/scenes/saltzman.toml``)."""
    return rate if cell_type == INTERVAL else rate / np.sqrt(volume)


@numba.njit(**LOOP)
def artificial_viscosity(q_quadratic, q_linear, jump, density, sound_speed):  # pragma: no cover (compiled)
    """q = ρ (c2 Δu² + c1 c |Δu|) in compression (von Neumann–Richtmyer and Landshoff),
    0 in expansion."""
    compression = nan_min(jump, 0.0)
    return (q_quadratic * compression - q_linear * sound_speed) * compression * density


@numba.njit(**LOOP)
def hourglass_cell(volume, s, combos, density, sound_speed, coefficient, k):  # pragma: no cover (compiled)
    """Viscous hourglass control of quadrilateral k (Flanagan & Belytschko, IJNME 17, 1981):
    γ_i = h_i − (Σ_j h_j x_j)·(∂A/∂x_i)/A is orthogonal to every linear field; the hourglass
    velocity Σ_i γ_i u_i is resisted by f_i = γ_i Q, Q = −(κ/4) ρ c √A Σ_j γ_j u_j.  With
    ∂A/∂x_2 = −∂A/∂x_0, ∂A/∂x_3 = −∂A/∂x_1: γ = (1 − s_0, −1 − s_1, 1 + s_0, −1 + s_1),
    s_i = h·(∂A/∂x_i)/A (shape ``s``).  Returns (s_0, s_1, Q_x, Q_y)."""
    g0x, g0y, g1x, g1y = quad_gradient(s)
    hx, hy = s[4], s[5]
    inverse_area = 1.0 / volume
    a = (hx * g0x + hy * g0y) * inverse_area
    b = (hx * g1x + hy * g1y) * inverse_area
    scale = np.sqrt(volume) * density * sound_speed * (-0.25 * coefficient)
    qx = (combos[2, 0, k] - a * combos[0, 0, k] - b * combos[1, 0, k]) * scale
    qy = (combos[2, 1, k] - a * combos[0, 1, k] - b * combos[1, 1, k]) * scale
    return a, b, qx, qy


@numba.njit(**LOOP)
def quad_corner_forces(stress, g0, g1, s0, s1, q, hourglass):  # pragma: no cover (compiled)
    """One component of a quadrilateral's four corner forces F_i = P ∂A/∂x_i + γ_i Q:
    with γ = (1 − s_0, −1 − s_1, 1 + s_0, −1 + s_1), F_0 = a + Q, F_2 = Q − a with
    a = P g_0 − s_0 Q, and F_1 = b − Q, F_3 = −b − Q with b = P g_1 − s_1 Q (g_0, g_1: the
    component of ∂A/∂x_0, ∂A/∂x_1; no hourglass control: F_2 = −F_0, F_3 = −F_1)."""
    f0 = stress * g0
    f1 = stress * g1
    if not hourglass:
        return f0, f1, -f0, -f1
    f0 = f0 - s0 * q
    f1 = f1 - s1 * q
    f2 = q - f0
    f0 = f0 + q
    f3 = -f1
    f3 = f3 - q
    f1 = f1 - q
    return f0, f1, f2, f3


@numba.njit(**LOOP)
def corner_forces_cell(cell_type, s, stress, hourglass, s0, s1, qx, qy, k, rows):  # pragma: no cover (compiled)
    """Cell k's corner forces F_Ki = P_K ∂V_K/∂x_i (shape ``s``; + the hourglass forces
    γ_i Q of quadrilaterals, (s_0, s_1, Q_x, Q_y) of :func:`hourglass_cell`) into
    rows[:, :, k] (2D; 1D scatters ∓P itself)."""
    if cell_type == TRIANGLE:
        for i in range(3):
            rows[0, i, k] = s[2 * i] * stress
            rows[1, i, k] = s[2 * i + 1] * stress
    elif cell_type == QUADRILATERAL:
        g0x, g0y, g1x, g1y = quad_gradient(s)
        a = s0 if hourglass else 0.0
        b = s1 if hourglass else 0.0
        rows[0, 0, k], rows[0, 1, k], rows[0, 2, k], rows[0, 3, k] = quad_corner_forces(
            stress, g0x, g1x, a, b, qx if hourglass else 0.0, hourglass)
        rows[1, 0, k], rows[1, 1, k], rows[1, 2, k], rows[1, 3, k] = quad_corner_forces(
            stress, g0y, g1y, a, b, qy if hourglass else 0.0, hourglass)


@numba.njit(**LOOP)
def hourglass_work(s0, s1, q, k, combos_sum):  # pragma: no cover (compiled)
    """Σ_i f_i·(u^n + u)_i = Q·Σ_i γ_i (u^n + u)_i of quadrilateral k."""
    return quad_hourglass_work(s0[k], s1[k], q[0, k], q[1, k], combos_sum[0, 0, k], combos_sum[0, 1, k],
                               combos_sum[1, 0, k], combos_sum[1, 1, k], combos_sum[2, 0, k], combos_sum[2, 1, k])


@numba.njit(**LOOP)
def quad_hourglass_work(s0, s1, qx, qy, across02_x, across02_y, across13_x, across13_y, hourglass_x,
                        hourglass_y):  # pragma: no cover (compiled)
    """Q·Σ_i γ_i v_i of a quadrilateral (s_0, s_1, Q of :func:`hourglass_cell`) from a
    velocity's corner combinations."""
    gamma_x = hourglass_x - s0 * across02_x - s1 * across13_x
    gamma_y = hourglass_y - s0 * across02_y - s1 * across13_y
    total = qx * gamma_x
    total += qy * gamma_y
    return total


@numba.njit(**LOOP)
def cfl_time(c, jump, length, stiffness, q_quadratic, q_linear, artificial):  # pragma: no cover (compiled)
    """A cell's L / signal speed: with the viscosity, Q + √(Q² + c²), Q = (c1 c + 2 c2 |Δu|)
    L_q/L in compression (Benson, CMAME 99, 1992); never less than |Δu| (no cell changes its
    length by more than its own size in a step)."""
    if artificial:
        q_speed = nan_min(jump, 0.0) * (-2.0 * q_quadratic) + q_linear * c
        q_speed *= stiffness
        signal = np.sqrt(q_speed * q_speed + c * c) + q_speed
    else:
        signal = c
    signal = nan_max(signal, abs(jump))
    return length / signal


@numba.njit(**LOOP)
def sound_time(c, jump, volume, length, viscous, q_quadratic, q_linear, artificial):  # pragma: no cover (compiled)
    """A cell's :func:`cfl_time`, the viscosity's length L_q = √V (``viscous``) or L."""
    stiffness = np.sqrt(volume) / length if viscous else 1.0
    return cfl_time(c, jump, length, stiffness, q_quadratic, q_linear, artificial)


# -- evaluations of a state ----------------------------------------------------------------
#
# Each loop is written once (``_name``) for a cell type and a way of reading nodes given as
# arguments, and entered through ``name``, which passes both as constants: intervals whose
# corners run on read node k + offset (every interval mesh DOLFINx makes in serial), other
# meshes through ``cell_nodes`` (ale_xfem.model.cell_kernels).

@numba.njit(**BODY)
def _geometry_and_rates(cell_type, running, x, u, combos, cell_nodes, runs, hourglass, with_length, with_density,
                        mass, volume, shape, least_corner, length, density, jump):  # pragma: no cover (compiled)
    at = node_access(runs, running)
    for k in range(volume.size):
        v, s = geometry_of_cell(cell_type, x, cell_nodes, at, k, hourglass, volume, least_corner, with_length,
                                length)
        if with_density:
            density[k] = mass[k] / v
        jump[k] = velocity_jump(cell_type, v, volume_rate(cell_type, s, cell_nodes, at, k, u, combos))
        store_shape(cell_type, s, hourglass, shape, k)


@numba.njit(**LOOP)
def geometry_and_rates(cell_type, x, u, combos, cell_nodes, runs, hourglass, with_length, with_density, mass, volume,
                       shape, least_corner, length, density, jump):  # pragma: no cover (compiled)
    """Per cell: volume and shape (with ``hourglass`` the quadrilaterals' hourglass shape
    and, ``least_corner`` not empty, their least corner det J), CFL length
    (``with_length``), ρ = m/V (``with_density``), the velocity jump."""
    if cell_type == INTERVAL:
        if runs[4] == 1:
            _geometry_and_rates(INTERVAL, True, x, u, combos, cell_nodes, runs, hourglass, with_length, with_density,
                                mass, volume, shape, least_corner, length, density, jump)
        else:
            _geometry_and_rates(INTERVAL, False, x, u, combos, cell_nodes, runs, hourglass, with_length,
                                with_density, mass, volume, shape, least_corner, length, density, jump)
    elif cell_type == TRIANGLE:
        _geometry_and_rates(TRIANGLE, False, x, u, combos, cell_nodes, runs, hourglass, with_length, with_density,
                            mass, volume, shape, least_corner, length, density, jump)
    else:
        _geometry_and_rates(QUADRILATERAL, False, x, u, combos, cell_nodes, runs, hourglass, with_length,
                            with_density, mass, volume, shape, least_corner, length, density, jump)


@numba.njit(**LOOP)
def cell_hourglass(cell_type, compute, hourglass, v, s, combos, rho, c, coefficient, k, s0, s1,
                   q):  # pragma: no cover (compiled)
    """Quadrilateral k's hourglass control (s_0, s_1, Q_x, Q_y): computed (``compute``,
    :func:`hourglass_cell`) and written to s0, s1, q; or read from them (``hourglass``: the
    forces of an earlier evaluation act); or none."""
    if cell_type != QUADRILATERAL:
        return 0.0, 0.0, 0.0, 0.0
    if compute:
        a, b, qx, qy = hourglass_cell(v, s, combos, rho, c, coefficient, k)
        s0[k], s1[k], q[0, k], q[1, k] = a, b, qx, qy
        return a, b, qx, qy
    if hourglass:
        return s0[k], s1[k], q[0, k], q[1, k]
    return 0.0, 0.0, 0.0, 0.0


@numba.njit(**BODY)
def _stress_and_corner_forces(cell_type, volume, shape, combos, jump, density, sound_speed, pressure, q_quadratic,
                              q_linear, artificial, mixed_cells, mixed_density, mixed_sound_speed, interface_pressure,
                              hourglass, compute_hourglass, coefficient, s0, s1, q, viscosity, stress,
                              rows):  # pragma: no cover (compiled)
    for k in range(volume.size):
        qk = artificial_viscosity(q_quadratic, q_linear, jump[k], density[k], sound_speed[k]) if artificial else 0.0
        viscosity[k] = qk
        stress[k] = pressure[k] + qk if artificial else pressure[k]
    for j in range(mixed_cells.size):
        k = mixed_cells[j]
        if artificial:
            squeeze = nan_min(jump[k], 0.0)
            viscosity[k] = mixed_density[j] * squeeze * (q_quadratic * squeeze - q_linear * mixed_sound_speed[j])
        stress[k] = interface_pressure[j] + viscosity[k]
    if cell_type == INTERVAL:
        return
    for k in range(volume.size):
        s = load_shape(cell_type, shape, k)
        a, b, qx, qy = cell_hourglass(cell_type, compute_hourglass, hourglass, volume[k], s, combos, density[k],
                                      sound_speed[k], coefficient, k, s0, s1, q)
        corner_forces_cell(cell_type, s, stress[k], hourglass, a, b, qx, qy, k, rows)


@numba.njit(**LOOP)
def stress_and_corner_forces(cell_type, volume, shape, combos, jump, density, sound_speed, pressure, q_quadratic,
                             q_linear, artificial, mixed_cells, mixed_density, mixed_sound_speed, interface_pressure,
                             hourglass, compute_hourglass, coefficient, s0, s1, q, viscosity, stress,
                             rows):  # pragma: no cover (compiled)
    """Per cell: the viscosity q and the corner forces' pressure P = p + q; a mixed cell's
    q from the density and sound speed its closure gives, and its P = p_Γ + q.  Then
    (``compute_hourglass``) the quadrilaterals' hourglass forces, and the corner forces
    (2D; ``hourglass``: with hourglass forces)."""
    if cell_type == INTERVAL:
        _stress_and_corner_forces(INTERVAL, volume, shape, combos, jump, density, sound_speed, pressure, q_quadratic,
                                  q_linear, artificial, mixed_cells, mixed_density, mixed_sound_speed,
                                  interface_pressure, hourglass, compute_hourglass, coefficient, s0, s1, q, viscosity,
                                  stress, rows)
    elif cell_type == TRIANGLE:
        _stress_and_corner_forces(TRIANGLE, volume, shape, combos, jump, density, sound_speed, pressure, q_quadratic,
                                  q_linear, artificial, mixed_cells, mixed_density, mixed_sound_speed,
                                  interface_pressure, hourglass, compute_hourglass, coefficient, s0, s1, q, viscosity,
                                  stress, rows)
    else:
        _stress_and_corner_forces(QUADRILATERAL, volume, shape, combos, jump, density, sound_speed, pressure,
                                  q_quadratic, q_linear, artificial, mixed_cells, mixed_density, mixed_sound_speed,
                                  interface_pressure, hourglass, compute_hourglass, coefficient, s0, s1, q, viscosity,
                                  stress, rows)


@numba.njit(**BODY)
def _evaluate_pure(cell_type, running, kind, store, x, u, combos, cell_nodes, runs, hourglass, with_length, eos,
                   cell_material, mass, energy, viscosity_law, hourglass_control, out,
                   rows):  # pragma: no cover (compiled)
    volume, shape, least_corner, length = out[0], out[1], out[2], out[3]
    at = node_access(runs, running)
    for k in range(volume.size):
        v, s = geometry_of_cell(cell_type, x, cell_nodes, at, k, hourglass, volume, least_corner, with_length,
                                length)
        cell_state(cell_type, kind, store, k, v, s, volume_rate(cell_type, s, cell_nodes, at, k, u, combos), combos,
                   eos, cell_material, mass, energy, viscosity_law, hourglass_control, out, rows)
        store_shape(cell_type, s, hourglass, shape, k)


@numba.njit(**BODY)
def cell_state(cell_type, kind, store, k, v, s, rate, combos, eos, cell_material, mass, energy, viscosity_law,
               hourglass_control, out, rows):  # pragma: no cover (compiled)
    """Pure cell k of volume v, shape ``s`` and volume rate ``rate`` (its geometry done):
    ρ, the equation of state (``kind``: the one gas's model, or −1: the cell's material's),
    the velocity jump, the viscosity, the corner forces' pressure, the hourglass control and
    the corner forces, into :func:`evaluate_pure`'s ``out`` and ``rows`` (density, pressure
    and viscosity only with ``store``)."""
    kinds, parameters = eos
    q_quadratic, q_linear, artificial = viscosity_law
    hourglass_forces, compute_hourglass, coefficient, s0, s1, q = hourglass_control
    density, pressure, sound_speed, jump, viscosity, stress = out[4], out[5], out[6], out[7], out[8], out[9]
    rho = mass[k] / v
    material = 0 if kind >= 0 else cell_material[k]
    p, c = pressure_sound_speed(kind if kind >= 0 else kinds[material], parameters, material, rho, energy[k])
    sound_speed[k] = c
    if store:
        density[k], pressure[k] = rho, p
    du = velocity_jump(cell_type, v, rate)
    jump[k] = du
    qk = artificial_viscosity(q_quadratic, q_linear, du, rho, c) if artificial else 0.0
    if store:
        viscosity[k] = qk
    pk = p + qk if artificial else p
    stress[k] = pk
    a, b, qx, qy = cell_hourglass(cell_type, compute_hourglass, hourglass_forces, v, s, combos, rho, c, coefficient,
                                  k, s0, s1, q)
    corner_forces_cell(cell_type, s, pk, hourglass_forces, a, b, qx, qy, k, rows)


@numba.njit(**BODY)
def _quad_states(hourglass_forces, compute_hourglass, combos, eos, cell_material, mass, energy, viscosity_law,
                 hourglass_control, out, rows):  # pragma: no cover (compiled)
    # entered with both hourglass flags constants (the loop then has no branch and vectorises)
    _, _, coefficient, s0, s1, q = hourglass_control
    control = (hourglass_forces, compute_hourglass, coefficient, s0, s1, q)
    volume, shape = out[0], out[1]
    for k in range(volume.size):
        v = volume[k]
        # h is read only where the hourglass forces are computed (the shape holds it then)
        h_x, h_y = (shape[2, 0, k], shape[2, 1, k]) if compute_hourglass else (0.0, 0.0)
        s = (shape[0, 0, k], shape[0, 1, k], shape[1, 0, k], shape[1, 1, k], h_x, h_y)
        cell_state(QUADRILATERAL, STIFFENED_GAS, True, k, v, s,
                   quad_volume_rate(s, combos[0, 0, k], combos[0, 1, k], combos[1, 0, k], combos[1, 1, k]), combos,
                   eos, cell_material, mass, energy, viscosity_law, control, out, rows)


@numba.njit(**LOOP)
def evaluate_one_gas_quadrilaterals(x, combos, cell_nodes, runs, hourglass, with_length, eos, cell_material, mass,
                                    energy, viscosity_law, hourglass_control, out, rows):  # pragma: no cover (compiled)
    """:func:`evaluate_pure` of quadrilaterals of one stiffened (or ideal) gas, in two loops:
    the geometry, which gathers each cell's nodes (volume, shape, least corner det J and CFL
    length, as asked), then the rest of each cell's state from the stored geometry (density,
    pressure, sound speed, velocity jump, viscosity, hourglass control, corner forces; the
    density, pressure and viscosity always stored).  The second loop reads and writes only
    the cells' own entries and is entered with the hourglass control's two flags as
    constants: it vectorises (the runtime overlap checks it needs are allowed by the LLVM
    setting of ale_xfem/__init__.py), where one loop gathering the nodes stays scalar.  The
    same numbers."""
    volume, shape, least_corner, length = out[0], out[1], out[2], out[3]
    geometry_loop(QUADRILATERAL, False, x, cell_nodes, runs, hourglass, with_length, volume, shape, least_corner,
                  length)
    if hourglass_control[1]:
        _quad_states(True, True, combos, eos, cell_material, mass, energy, viscosity_law, hourglass_control, out,
                     rows)
    else:
        _quad_states(True, False, combos, eos, cell_material, mass, energy, viscosity_law, hourglass_control, out,
                     rows)


@numba.njit(**LOOP)
def evaluate_pure(cell_type, x, u, combos, cell_nodes, runs, hourglass, with_length, eos, cell_material, mass,
                  energy, viscosity_law, hourglass_control, out, rows, store):  # pragma: no cover (compiled)
    """A state whose cells are all pure, in one loop: what :func:`geometry_and_rates`, the
    equation of state and :func:`stress_and_corner_forces` give.  ``hourglass``: the
    positions' hourglass shape; ``eos``: (kinds, parameters) of the materials;
    ``viscosity_law``: (c2, c1, whether on); ``hourglass_control``: (whether the corner
    forces have hourglass forces, whether to compute them, κ, s_0, s_1, Q); ``out``: (volume,
    shape, least corner, length, density, pressure, sound speed, velocity jump, viscosity,
    stress).

    A 1D state of one material, a stiffened (or ideal) gas, is evaluated by a loop entered
    with that model as a constant: its formulas then sit in the loop, which the compiler
    vectorises (0.28 ms at 10⁵ cells against 0.67 ms choosing each cell's model, measured
    alone); otherwise each cell's model is chosen in the loop (ale_xfem.eos.kernels).  In 2D
    the cells' nodes are gathered through ``cell_nodes`` and a loop that gathers stays
    scalar; quadrilaterals of one stiffened gas with hourglass forces are evaluated in two
    loops instead, the second one vectorised (:func:`evaluate_one_gas_quadrilaterals`: at
    10⁵ cells a final state's evaluation and corner sums 1.4 against 1.8 ms, a predicted
    one's 1.0 against 1.4, timed alone; it costs the first 2D run's compilation about 20
    s).  Triangles, several materials and quadrilaterals without hourglass control keep the
    one scalar loop.

    ``store`` False: density, pressure and viscosity are not stored (a lean evaluation,
    :func:`pure_steps`; the two loops of one gas's quadrilaterals store them all the same,
    where their arrays hold every cell); what the step goes on with is.  The one-gas 1D
    loop has ``store`` as a constant, so that it vectorises either way.  (Lean always and the three added by a
    second pass when asked cost a step called from Python about 10 %, interleaved A/B at
    10⁵ cells; the two loops cost the first run's compilation a few seconds.)"""
    gas = one_gas_model(eos) == STIFFENED_GAS
    if cell_type == INTERVAL:
        if runs[4] == 1 and gas and store:
            _evaluate_pure(INTERVAL, True, STIFFENED_GAS, True, x, u, combos, cell_nodes, runs, hourglass,
                           with_length, eos, cell_material, mass, energy, viscosity_law, hourglass_control, out, rows)
        elif runs[4] == 1 and gas:
            _evaluate_pure(INTERVAL, True, STIFFENED_GAS, False, x, u, combos, cell_nodes, runs, hourglass,
                           with_length, eos, cell_material, mass, energy, viscosity_law, hourglass_control, out, rows)
        elif runs[4] == 1:
            _evaluate_pure(INTERVAL, True, -1, store, x, u, combos, cell_nodes, runs, hourglass, with_length, eos,
                           cell_material, mass, energy, viscosity_law, hourglass_control, out, rows)
        else:
            _evaluate_pure(INTERVAL, False, -1, store, x, u, combos, cell_nodes, runs, hourglass, with_length, eos,
                           cell_material, mass, energy, viscosity_law, hourglass_control, out, rows)
    elif cell_type == TRIANGLE:
        _evaluate_pure(TRIANGLE, False, -1, store, x, u, combos, cell_nodes, runs, hourglass, with_length, eos,
                       cell_material, mass, energy, viscosity_law, hourglass_control, out, rows)
    elif (gas and hourglass_control[0] and (hourglass or not hourglass_control[1])
          and out[4].size == out[0].size and out[5].size == out[0].size and out[8].size == out[0].size):
        # (the second loop reads h where it computes the hourglass forces: only where the
        # geometry stores it; it stores density, pressure and viscosity: only into arrays of
        # every cell; without hourglass forces: the one loop)
        evaluate_one_gas_quadrilaterals(x, combos, cell_nodes, runs, hourglass, with_length, eos, cell_material,
                                        mass, energy, viscosity_law, hourglass_control, out, rows)
    else:
        _evaluate_pure(QUADRILATERAL, False, -1, store, x, u, combos, cell_nodes, runs, hourglass, with_length, eos,
                       cell_material, mass, energy, viscosity_law, hourglass_control, out, rows)


@numba.njit(**LOOP)
def one_gas_model(eos_tables):  # pragma: no cover (compiled)
    """STIFFENED_GAS for a state of one stiffened (or ideal) gas, whose loops then have its
    model as a constant (and vectorise); −1: each cell's model chosen in the loop."""
    kinds = eos_tables[0]
    return STIFFENED_GAS if kinds.size == 1 and kinds[0] == STIFFENED_GAS else -1


@numba.njit(**LOOP)
def evaluate_intervals(kind, x, u, combos, cell_nodes, runs, eos, cell_material, mass, energy, viscosity_law,
                       hourglass_control, out, rows, mesh_scatter, nodal_force):  # pragma: no cover (compiled)
    """A state of intervals whose corners run on (cell k: nodes k + runs[0], k + runs[1]),
    evaluated in full and its nodal forces summed, as :func:`evaluate_stage` does it for a
    corrector's state: the intervals' loops of :func:`evaluate_pure` and
    :func:`scatter_corners`, compiled for ``kind`` (STIFFENED_GAS, one gas's model, or −1)
    alone (numba.literally), not for every cell type.  ``mesh_scatter``: (scatter mode,
    corner_is_run, node scratch)."""
    numba.literally(kind)
    _evaluate_pure(INTERVAL, True, kind, True, x, u, combos, cell_nodes, runs, True, False, eos, cell_material, mass,
                   energy, viscosity_law, hourglass_control, out, rows)
    mode, corner_is_run, scratch = mesh_scatter
    _scatter_corners(INTERVAL, True, out[9], rows, cell_nodes, runs, mode, corner_is_run, scratch, nodal_force)


@numba.njit(**LOOP)
def evaluate_one_gas_intervals(x, u, combos, cell_nodes, runs, eos, cell_material, mass, energy, viscosity_law,
                               hourglass_control, out, rows, mesh_scatter, nodal_force):  # pragma: no cover (compiled)
    """:func:`evaluate_intervals` of a state of one stiffened (or ideal) gas, called from
    Python (a literal argument requested from Python costs milliseconds a call)."""
    evaluate_intervals(STIFFENED_GAS, x, u, combos, cell_nodes, runs, eos, cell_material, mass, energy, viscosity_law,
                       hourglass_control, out, rows, mesh_scatter, nodal_force)


@numba.njit(**LOOP)
def evaluate_any_intervals(x, u, combos, cell_nodes, runs, eos, cell_material, mass, energy, viscosity_law,
                           hourglass_control, out, rows, mesh_scatter, nodal_force):  # pragma: no cover (compiled)
    """:func:`evaluate_intervals` of any state, called from Python."""
    evaluate_intervals(-1, x, u, combos, cell_nodes, runs, eos, cell_material, mass, energy, viscosity_law,
                       hourglass_control, out, rows, mesh_scatter, nodal_force)


@numba.njit(**BODY)
def _scatter_corner(cell_type, stress, rows, cell_nodes, at, d, c, assign, target):  # pragma: no cover (compiled)
    """Corner c's values of component d written (``assign``) or added to ``target``."""
    sign = -1.0 if c == 0 else 1.0  # an interval's corner forces ∓P
    n = cell_nodes.shape[0]
    if cell_type == INTERVAL:
        if assign:
            for k in range(n):
                target[node(cell_nodes, at, k, c)] = sign * stress[k]
        else:
            for k in range(n):
                target[node(cell_nodes, at, k, c)] += sign * stress[k]
    else:
        if assign:
            for k in range(n):
                target[node(cell_nodes, at, k, c)] = rows[d, c, k]
        else:
            for k in range(n):
                target[node(cell_nodes, at, k, c)] += rows[d, c, k]


@numba.njit(**BODY)
def _scatter_corners(cell_type, running, stress, rows, cell_nodes, runs, mode, corner_is_run, scratch,
                     out):  # pragma: no cover (compiled)
    at = node_access(runs, running)
    n = cell_nodes.shape[0]
    if (cell_type == INTERVAL and running and mode == RUNS and runs[0] == 0 and runs[1] == 1 and n > 0
            and out.shape[1] == n + 1):
        # cells numbered along the tube: node i gets −P_i + P_{i−1}, one pass (the same sums)
        target = out[0]
        target[0] = -stress[0]
        for i in range(1, n):
            target[i] = node_force(stress[i - 1], stress[i])
        target[n] = 0.0 + stress[n - 1]
        return
    for d in range(out.shape[0]):
        target = out[d]
        target[:] = 0.0
        for c in range(cell_nodes.shape[1]):
            direct = mode == RUNS or (mode == PER_CORNER and corner_is_run[c])
            if mode == FLAT or direct:
                _scatter_corner(cell_type, stress, rows, cell_nodes, at, d, c, c == 0 and direct, target)
            else:
                scratch[:] = 0.0
                _scatter_corner(cell_type, stress, rows, cell_nodes, at, d, c, False, scratch)
                target += scratch


@numba.njit(**LOOP)
def scatter_corners(cell_type, stress, rows, cell_nodes, runs, mode, corner_is_run, scratch,
                    out):  # pragma: no cover (compiled)
    """Σ over corners of the corner forces onto the nodes, component by component, into
    ``out`` (dim, n_nodes): rows (dim, k, n_cells), or for intervals ∓P from ``stress``.

    - RUNS (each corner's nodes distinct: intervals, grids of quadrilaterals): corner 0
      written, the others added, corner by corner;
    - PER_CORNER: corner by corner, each corner's sums formed apart (``scratch``: a node
      met several times as that corner) and added; a corner whose nodes run on (one each,
      ``corner_is_run``) added directly;
    - FLAT: one running sum over the corners in turn."""
    if cell_type == INTERVAL:
        if runs[4] == 1:
            _scatter_corners(INTERVAL, True, stress, rows, cell_nodes, runs, mode, corner_is_run, scratch, out)
        else:
            _scatter_corners(INTERVAL, False, stress, rows, cell_nodes, runs, mode, corner_is_run, scratch, out)
    elif cell_type == TRIANGLE:
        _scatter_corners(TRIANGLE, False, stress, rows, cell_nodes, runs, mode, corner_is_run, scratch, out)
    else:
        _scatter_corners(QUADRILATERAL, False, stress, rows, cell_nodes, runs, mode, corner_is_run, scratch, out)


# -- the step --------------------------------------------------------------------------------

@numba.njit(**LOOP)
def advanced(u0, force, dt, inverse_mass):  # pragma: no cover (compiled)
    """A node's velocity after dt under ``force``: u = u0 + dt F/M."""
    return force * (dt * inverse_mass) + u0


@numba.njit(**LOOP)
def moved(u0, u, x0, dt):  # pragma: no cover (compiled)
    """(u^n + u, x^n + dt (u^n + u)/2) of a node: the velocity sum (the ½ of ū folded into
    the scalars that use it) and the position."""
    total = u0 + u
    return total, total * (0.5 * dt) + x0


@numba.njit(**LOOP)
def node_force(left_stress, right_stress):  # pragma: no cover (compiled)
    """The force on the node between two intervals, −P_right + P_left (their corner forces
    ∓P, the right one's first, as the scatter sums them)."""
    return -right_stress + left_stress


@numba.njit(**LOOP)
def energy_after(energy, mass, dt, work, two):  # pragma: no cover (compiled)
    """The compatible energy update of a cell, e = e^n − (dt/2) work/m, ``work`` the corner
    forces' Σ_i F_Ki·(u^n + u)_i (``two``: of two evaluations' forces, whose mean acts)."""
    scale = 0.5 * dt / mass
    if two:
        scale *= 0.5
    return energy - work * scale


@numba.njit(**LOOP)
def advance_velocity(u0, force, dt, inverse_node_mass, out):  # pragma: no cover (compiled)
    """u = u0 + dt F/M for the components the forces have; transverse components (1D)
    carried unchanged (paper §3.1)."""
    for d in range(u0.shape[0]):
        if d < force.shape[0]:
            for i in range(u0.shape[1]):
                out[d, i] = advanced(u0[d, i], force[d, i], dt, inverse_node_mass[i])
        else:
            for i in range(u0.shape[1]):
                out[d, i] = u0[d, i]


@numba.njit(**LOOP)
def hold(values, kinds, offsets, nodes, normals, velocities, pistons_to_zero):  # pragma: no cover (compiled)
    """Impose the boundaries, in their order, on a nodal field (components, n_nodes):
    a wall (kind 0) removes the normal part u − n (n·u); a piston (kind 1) sets its velocity
    (``pistons_to_zero``: sets 0, for an acceleration)."""
    dim = normals.shape[1]
    for b in range(kinds.size):
        for j in range(offsets[b], offsets[b + 1]):
            i = nodes[j]
            if kinds[b] == 0:
                normal_part = normals[b, 0] * values[0, i]
                for d in range(1, dim):
                    normal_part += normals[b, d] * values[d, i]
                for d in range(dim):
                    values[d, i] = values[d, i] - normals[b, d] * normal_part
            else:
                for d in range(dim):
                    values[d, i] = 0.0 if pistons_to_zero else velocities[b, d]


@numba.njit(**LOOP)
def velocity_sum_and_position(u0, u, x0, dt, velocity_sum, x):  # pragma: no cover (compiled)
    """u^n + u (the ½ of ū folded into the scalars that use it) and x = x^n + dt (u^n + u)/2."""
    for d in range(u0.shape[0]):
        if d < x0.shape[0]:
            for i in range(u0.shape[1]):
                velocity_sum[d, i], x[d, i] = moved(u0[d, i], u[d, i], x0[d, i], dt)
        else:
            for i in range(u0.shape[1]):
                velocity_sum[d, i] = u0[d, i] + u[d, i]


@numba.njit(**BODY)
def _compatible_energy(cell_type, running, cell_nodes, runs, energy, mass, dt, shape_a, stress_a, shape_b, stress_b,
                       two, hourglass, s0, s1, q, velocity_sum, combos_sum, out):  # pragma: no cover (compiled)
    # the loop is entered with ``two`` a constant: it reads stress_b only when it exists
    if two:
        _energy_loop(cell_type, running, cell_nodes, runs, energy, mass, dt, shape_a, stress_a, shape_b, stress_b,
                     True, hourglass, s0, s1, q, velocity_sum, combos_sum, out)
    else:
        _energy_loop(cell_type, running, cell_nodes, runs, energy, mass, dt, shape_a, stress_a, shape_b, stress_b,
                     False, hourglass, s0, s1, q, velocity_sum, combos_sum, out)


@numba.njit(**BODY)
def _energy_loop(cell_type, running, cell_nodes, runs, energy, mass, dt, shape_a, stress_a, shape_b, stress_b,
                 two, hourglass, s0, s1, q, velocity_sum, combos_sum, out):  # pragma: no cover (compiled)
    at = node_access(runs, running)
    for k in range(energy.size):
        rate = volume_rate(cell_type, load_shape(cell_type, shape_a, k), cell_nodes, at, k, velocity_sum, combos_sum)
        if cell_type == INTERVAL:
            work = rate * (stress_a[k] + stress_b[k]) if two else rate * stress_a[k]
        else:
            extra = hourglass_work(s0, s1, q, k, combos_sum) if hourglass else 0.0
            rate_b = volume_rate(cell_type, load_shape(cell_type, shape_b, k), cell_nodes, at, k, velocity_sum,
                                 combos_sum) if two else 0.0
            work = compatible_work(rate, rate_b, stress_a[k], stress_b[k], extra, two, hourglass)
        out[k] = energy_after(energy[k], mass[k], dt, work, two)


@numba.njit(**LOOP)
def compatible_work(rate_a, rate_b, stress_a, stress_b, extra, two, hourglass):  # pragma: no cover (compiled)
    """Σ_i F_Ki·(u^n + u)_i of a 2D cell: its corner forces' P ∂V/∂x_i part is P times the
    volume rate of u^n + u at that evaluation's shape (``rate_a`` with ``stress_a``; with
    ``two`` also ``rate_b`` with ``stress_b``, the corrector's second evaluation), and each
    evaluation's hourglass forces add ``extra`` (:func:`hourglass_work`)."""
    work = rate_a * stress_a
    if hourglass:
        work += extra
    if two:
        term = rate_b * stress_b
        if hourglass:
            term += extra
        work += term
    return work


@numba.njit(**LOOP)
def compatible_energy(cell_type, cell_nodes, runs, energy, mass, dt, shape_a, stress_a, shape_b, stress_b, two,
                      hourglass, s0, s1, q, velocity_sum, combos_sum, out):  # pragma: no cover (compiled)
    """The compatible energy update m_K e_K = m_K e_K^n − (dt/2) Σ_i F_Ki·(u^n + u)_i, the
    corner forces F_Ki those of one evaluation (the predictor) or the mean of two (``two``:
    the corrector, F̄ = (F^n + F*)/2), hourglass forces included (the predicted state
    reuses the start's: their work counts once per evaluation).  Intervals (∂V/∂x_i = ±1)
    sum the two stresses first."""
    if cell_type == INTERVAL:
        if runs[4] == 1:
            _compatible_energy(INTERVAL, True, cell_nodes, runs, energy, mass, dt, shape_a, stress_a, shape_b,
                               stress_b, two, hourglass, s0, s1, q, velocity_sum, combos_sum, out)
        else:
            _compatible_energy(INTERVAL, False, cell_nodes, runs, energy, mass, dt, shape_a, stress_a, shape_b,
                               stress_b, two, hourglass, s0, s1, q, velocity_sum, combos_sum, out)
    elif cell_type == TRIANGLE:
        _compatible_energy(TRIANGLE, False, cell_nodes, runs, energy, mass, dt, shape_a, stress_a, shape_b, stress_b,
                           two, hourglass, s0, s1, q, velocity_sum, combos_sum, out)
    else:
        _compatible_energy(QUADRILATERAL, False, cell_nodes, runs, energy, mass, dt, shape_a, stress_a, shape_b,
                           stress_b, two, hourglass, s0, s1, q, velocity_sum, combos_sum, out)


@numba.njit(**BODY)
def _quad_combinations_and_energy(cell_nodes, u, combos0, combos, energy, mass, dt, shape_a, stress_a, shape_b,
                                  stress_b, two, hourglass, s0, s1, q, out):  # pragma: no cover (compiled)
    at = (False, (0, 0, 0, 0))  # the nodes read through cell_nodes (node_access's form)
    for k in range(energy.size):
        ax, bx, hx = quad_corner_values(u, cell_nodes, at, k, 0, True)
        ay, by, hy = quad_corner_values(u, cell_nodes, at, k, 1, True)
        combos[0, 0, k], combos[1, 0, k], combos[2, 0, k] = ax, bx, hx
        combos[0, 1, k], combos[1, 1, k], combos[2, 1, k] = ay, by, hy
        # (u^n + u)'s combinations, kept in registers
        ax, ay, bx, by = combos0[0, 0, k] + ax, combos0[0, 1, k] + ay, combos0[1, 0, k] + bx, combos0[1, 1, k] + by
        hx, hy = combos0[2, 0, k] + hx, combos0[2, 1, k] + hy
        rate = quad_volume_rate(load_shape(QUADRILATERAL, shape_a, k), ax, ay, bx, by)
        extra = quad_hourglass_work(s0[k], s1[k], q[0, k], q[1, k], ax, ay, bx, by, hx, hy) if hourglass else 0.0
        rate_b = quad_volume_rate(load_shape(QUADRILATERAL, shape_b, k), ax, ay, bx, by) if two else 0.0
        out[k] = energy_after(energy[k], mass[k], dt, compatible_work(rate, rate_b, stress_a[k], stress_b[k], extra,
                                                                      two, hourglass), two)


@numba.njit(**LOOP)
def quad_combinations_and_energy(cell_nodes, u, combos0, combos, energy, mass, dt, shape_a, stress_a, shape_b,
                                 stress_b, two, hourglass, s0, s1, q, out):  # pragma: no cover (compiled)
    """A stage's velocity combinations and compatible energy update of quadrilaterals in one
    loop: :func:`ale_xfem.model.cell_kernels.quad_combinations` of the new velocity u into
    ``combos``, then :func:`compatible_energy` with the combinations of u^n + u (``combos0``:
    u^n's) formed in registers, not stored — the same numbers, without the two passes that
    stored and read back u^n + u's combinations (six numbers a cell).  The cells' evaluation
    stays a loop of its own: fused into this one it took the same time."""
    if two:
        _quad_combinations_and_energy(cell_nodes, u, combos0, combos, energy, mass, dt, shape_a, stress_a, shape_b,
                                      stress_b, True, hourglass, s0, s1, q, out)
    else:
        _quad_combinations_and_energy(cell_nodes, u, combos0, combos, energy, mass, dt, shape_a, stress_a, shape_b,
                                      stress_b, False, hourglass, s0, s1, q, out)


def double_of_bits(bits):
    """The double whose bits are the unsigned 64-bit integer ``bits`` (a reinterpretation,
    no conversion; compiled, one instruction)."""
    return np.uint64(bits).view(np.float64)


@numba.extending.intrinsic
def _reinterpreted_as_double(typingctx, bits):
    if bits != numba.types.uint64:
        return None

    def codegen(context, builder, signature, arguments):
        return builder.bitcast(arguments[0], context.get_value_type(numba.types.float64))
    return numba.types.float64(numba.types.uint64), codegen


@numba.extending.overload(double_of_bits)
def _double_of_bits_compiled(bits):
    return lambda bits: _reinterpreted_as_double(bits)


# the bits of +∞: non-negative doubles, +0 to +∞, order as their bits do; a negative double or
# a NaN has bits above these, read unsigned
INFINITY_BITS = np.uint64(0x7FF0000000000000)


@numba.njit(**LOOP)
def least_of(values, start, stop):  # pragma: no cover (compiled)
    """The least of ``values[start:stop]`` (NaN if any is; +∞ if none), exactly.  Where
    every value lies in [+0, +∞] (time limits, lengths) it is the least of their bits read
    as unsigned integers, whose minimum and maximum vectorise; otherwise (a negative value,
    −0 or a NaN: the bits' maximum is above +∞'s) it is taken as numbers, in four
    interleaved running minima so that the comparisons do not wait on each other (the
    minimum of a set does not depend on the order it is taken in, so the least of a whole
    is the least of its parts' least)."""
    bits = values[start:stop].view(np.uint64)
    low, high = INFINITY_BITS, np.uint64(0)
    for k in range(bits.size):
        b = bits[k]
        low = b if b < low else low
        high = b if b > high else high
    if high <= INFINITY_BITS:
        return double_of_bits(low)
    m0 = m1 = m2 = m3 = np.inf
    body = start + (stop - start) // 4 * 4 if stop > start else start
    for k in range(start, body, 4):
        m0 = nan_min(m0, values[k])
        m1 = nan_min(m1, values[k + 1])
        m2 = nan_min(m2, values[k + 2])
        m3 = nan_min(m3, values[k + 3])
    for k in range(body, stop):
        m0 = nan_min(m0, values[k])
    return nan_min(nan_min(m0, m1), nan_min(m2, m3))


@numba.njit(**LOOP)
def least(values):  # pragma: no cover (compiled)
    """The least of ``values`` (NaN if any is; +∞ if empty): :func:`least_of` all of them."""
    return least_of(values, 0, values.size)


@numba.njit(**BODY)
def _time_limits(running, volume, length, sound_speed, jump, viscous, q_quadratic, q_linear, artificial, mixed_cells,
                mixed_sound_speed, acceleration, cell_nodes, runs, sound_times,
                acceleration_ratio):  # pragma: no cover (compiled)
    dim = acceleration.shape[0]
    at = node_access(runs, running)
    for k in range(volume.size):
        sound_times[k] = sound_time(sound_speed[k], jump[k], volume[k], length[k], viscous, q_quadratic, q_linear,
                                    artificial)
    for j in range(mixed_cells.size):
        k = mixed_cells[j]
        sound_times[k] = nan_min(sound_times[k], sound_time(mixed_sound_speed[j], jump[k], volume[k], length[k],
                                                            viscous, q_quadratic, q_linear, artificial))
    if running:  # intervals: two nodes, k + offsets
        _, offsets = at
        for k in range(volume.size):
            largest = nan_max(abs(acceleration[0, k + offsets[0]]), abs(acceleration[0, k + offsets[1]]))
            acceleration_ratio[k] = length[k] / largest
        return least(sound_times), least(acceleration_ratio)
    # each node's |a| (2D: its square) once, into the first row (the loops without gathers
    # vectorise); each cell's largest over its nodes; then L / |a|
    magnitude = acceleration[0]
    if dim == 1:
        for i in range(magnitude.size):
            magnitude[i] = abs(magnitude[i])
    else:
        ay = acceleration[1]
        for i in range(magnitude.size):
            square = magnitude[i] * magnitude[i]
            square += ay[i] * ay[i]
            magnitude[i] = square
    for k in range(volume.size):
        largest = magnitude[node(cell_nodes, at, k, 0)]
        for c in range(1, cell_nodes.shape[1]):
            largest = nan_max(largest, magnitude[node(cell_nodes, at, k, c)])
        acceleration_ratio[k] = largest
    if dim == 1:
        for k in range(volume.size):
            acceleration_ratio[k] = length[k] / acceleration_ratio[k]
    else:
        for k in range(volume.size):
            acceleration_ratio[k] = length[k] / np.sqrt(acceleration_ratio[k])
    return least(sound_times), least(acceleration_ratio)


@numba.njit(**LOOP)
def time_limits(volume, length, sound_speed, jump, viscous, q_quadratic, q_linear, artificial, mixed_cells,
                mixed_sound_speed, acceleration, cell_nodes, runs, sound_times,
                acceleration_ratio):  # pragma: no cover (compiled)
    """Each cell's time step limits before the CFL number: ``sound_times`` from its signal
    speed (a mixed cell also from the larger sound speed of its materials) and
    ``acceleration_ratio`` L / a, a the largest acceleration of its nodes (``acceleration``
    (dim, n_nodes), held directions removed; except on intervals whose corners run on, its
    first row is left holding each node's |a|, in 2D its square).  Returns the least of
    each (NaN if any is)."""
    if acceleration.shape[0] == 1 and runs[4] == 1:
        return _time_limits(True, volume, length, sound_speed, jump, viscous, q_quadratic, q_linear, artificial,
                            mixed_cells, mixed_sound_speed, acceleration, cell_nodes, runs, sound_times,
                            acceleration_ratio)
    return _time_limits(False, volume, length, sound_speed, jump, viscous, q_quadratic, q_linear, artificial,
                        mixed_cells, mixed_sound_speed, acceleration, cell_nodes, runs, sound_times,
                        acceleration_ratio)


@numba.njit(**LOOP)
def stable_time_step(force, inverse_node_mass, boundaries, volume, length, sound_speed, jump, viscous, viscosity_law,
                     mixed_cells, mixed_sound_speed, cell_nodes, runs, cfl, acceleration, sound_times,
                     ratios):  # pragma: no cover (compiled)
    """The CFL time step of a state (ExplicitWilkins.stable_time_step): cfl × the smaller
    of the least signal-speed limit and √(L / 2a) at the least L / a, a the nodes'
    accelerations F/M with the held directions removed (``acceleration``: scratch, see
    :func:`time_limits`); each cell's limits are left in ``sound_times`` and ``ratios``."""
    for d in range(force.shape[0]):
        for i in range(force.shape[1]):
            acceleration[d, i] = force[d, i] * inverse_node_mass[i]
    # walls take the normal part (their reaction); a piston's nodes move with it
    hold(acceleration, *boundaries, True)
    q_quadratic, q_linear, artificial = viscosity_law
    least_sound, least_ratio = time_limits(volume, length, sound_speed, jump, viscous, q_quadratic, q_linear,
                                           artificial, mixed_cells, mixed_sound_speed, acceleration, cell_nodes,
                                           runs, sound_times, ratios)
    return cfl_step(cfl, least_sound, least_ratio)


@numba.njit(**LOOP)
def cfl_step(cfl, least_sound, least_ratio):  # pragma: no cover (compiled)
    """cfl × the smaller of the least signal-speed limit and √(L / 2a) at the least L / a."""
    limit = np.sqrt(0.5 * least_ratio)
    return cfl * (limit if limit < least_sound else least_sound)


@numba.njit(**LOOP)
def healthy(volume, sound_speed, energy, stress, least_corner):  # pragma: no cover (compiled)
    """Positive volumes, finite sound speeds, energies and stresses, and (``least_corner``
    not empty) no quadrilateral corner turned inside out."""
    ok = True
    for k in range(volume.size):
        ok &= volume[k] > 0.0
        ok &= abs(sound_speed[k]) < np.inf
        ok &= abs(energy[k]) < np.inf
        ok &= abs(stress[k]) < np.inf
    for k in range(least_corner.size):
        ok &= least_corner[k] > 0.0
    return ok


@numba.njit(**LOOP)
def evaluate_stage(cell_type, mesh, eos, cell_material, viscosity_law, hourglass_coefficient, mass, hourglass,
                   state, hourglass_state, corrector, lean):  # pragma: no cover (compiled)
    """The forces of a stage's state (``state``: pure_step's arrays of it): the predicted
    state takes the start's hourglass forces (``hourglass``: whether they act) and needs no
    tangle check and no CFL length; the final state (``corrector``) has its own hourglass
    forces.  ``lean``: its density, pressure and viscosity are not stored."""
    cell_nodes, runs, mode, corner_is_run, scratch = mesh
    (u, _, x, combos, _, e, volume, shape, least_corner, length, density, pressure,
     sound_speed, jump, viscosity, stress, rows, nodal_force) = state
    compute = corrector and cell_type == QUADRILATERAL and hourglass_coefficient > 0.0
    hourglass_s0, hourglass_s1, hourglass_q = hourglass_state
    evaluate_pure(cell_type, x, u, combos, cell_nodes, runs, corrector, corrector and cell_type != INTERVAL,
                  eos, cell_material, mass, e, viscosity_law,
                  (compute if corrector else hourglass, compute, hourglass_coefficient, hourglass_s0, hourglass_s1,
                   hourglass_q),
                  (volume, shape, least_corner, length, density, pressure, sound_speed, jump, viscosity, stress), rows,
                  not lean)
    scatter_corners(cell_type, stress, rows, cell_nodes, runs, mode, corner_is_run, scratch, nodal_force)


@numba.njit(**LOOP)
def _stage(cell_type, mesh, boundaries, eos, cell_material, viscosity_law, hourglass_coefficient, dt,
           inverse_node_mass, start, force, other, state, hourglass_state, corrector, evaluate,
           lean):  # pragma: no cover
    """One stage of :func:`pure_step`: the velocity from ``force``, the positions, the
    energy (with the forces of the start, and of ``other``, the predicted state, in the
    corrector) and, ``evaluate``, the forces of the new state (:func:`evaluate_stage`)."""
    cell_nodes, runs, mode, corner_is_run, scratch = mesh
    x0, u0, mass, energy, force0, stress0, shape0, combos0, s0, s1, q, hourglass = start
    (u, velocity_sum, x, combos, _, e, volume, shape, least_corner, length, density, pressure,
     sound_speed, jump, viscosity, stress, rows, nodal_force) = state
    advance_velocity(u0, force, dt, inverse_node_mass, u)
    hold(u, *boundaries, False)
    velocity_sum_and_position(u0, u, x0, dt, velocity_sum, x)
    if cell_type == QUADRILATERAL:
        quad_combinations_and_energy(cell_nodes, u, combos0, combos, energy, mass, dt, shape0, stress0, other[7],
                                     other[15], corrector, hourglass, s0, s1, q, e)
    else:
        compatible_energy(cell_type, cell_nodes, runs, energy, mass, dt, shape0, stress0, other[7], other[15],
                          corrector, hourglass, s0, s1, q, velocity_sum, combos, e)  # (combos: empty)
    if evaluate:
        evaluate_stage(cell_type, mesh, eos, cell_material, viscosity_law, hourglass_coefficient, mass, hourglass,
                       state, hourglass_state, corrector, lean)


@numba.njit(**LOOP)
def pure_step(cell_type, mesh, boundaries, eos, cell_material, viscosity_law, hourglass_coefficient, dt,
              inverse_node_mass, start, predicted, final, final_hourglass, mean_force, evaluate_final,
              lean, stages):  # pragma: no cover (compiled)
    """One whole step of a state whose cells are all pure (ExplicitWilkins.step), from the
    start's forces to the new state and (``evaluate_final``) its forces, in one call:

        u* = u^n + dt F^n/M (held),  x* = x^n + dt (u^n + u*)/2,  e* from F^n;  F* at x*;
        F̄ = (F^n + F*)/2,  u = u^n + dt F̄/M (held),  x = x^n + dt (u^n + u)/2,  e from F̄.

    ``mesh``: (cell_nodes, runs, scatter mode, corner_is_run, node scratch);
    ``boundaries``: kernels.hold's arrays; ``start``: (x^n, u^n, m, e^n, F^n, P^n, shape,
    velocity combinations, s_0, s_1, Q, whether hourglass forces act); ``predicted`` and
    ``final``: the arrays each state's evaluation fills — (u, u^n + u, x, velocity
    combinations, an unused slot (an empty array), e, volume, shape, least corner, length, density,
    pressure, sound speed, velocity jump, viscosity, stress, corner forces, nodal forces);
    ``final_hourglass``: (s_0, s_1, Q) of the final state; ``mean_force``: F̄ is written
    there; ``lean``: the evaluations store no density, pressure and viscosity (the step
    does not need them); ``stages``: PREDICTOR_STAGE, CORRECTOR_STAGE or both (their sum):
    the corrector alone takes the predicted state's forces as ``predicted`` holds them (on
    several ranks their ghost nodes' are exchanged in between).  Returns 0, or 1 when a
    predicted volume is not positive, 2 when the final state is not healthy (the caller
    names the cause)."""
    force0 = start[4]
    if stages & PREDICTOR_STAGE:
        _stage(cell_type, mesh, boundaries, eos, cell_material, viscosity_law, hourglass_coefficient, dt,
               inverse_node_mass, start, force0, predicted, predicted, (start[8], start[9], start[10]), False, True,
               lean)
        if not least(predicted[6]) > 0.0:
            return 1
    if not stages & CORRECTOR_STAGE:
        return 0
    predicted_force = predicted[17]
    for d in range(mean_force.shape[0]):
        for i in range(mean_force.shape[1]):
            mean_force[d, i] = (force0[d, i] + predicted_force[d, i]) * 0.5
    _stage(cell_type, mesh, boundaries, eos, cell_material, viscosity_law, hourglass_coefficient, dt,
           inverse_node_mass, start, mean_force, predicted, final, final_hourglass, True, evaluate_final, lean)
    if evaluate_final and not healthy(final[6], final[12], final[5], final[15], final[8]):
        return 2
    return 0


@numba.njit(**LOOP)
def block_sum(values, start, count):  # pragma: no cover (compiled)
    """numpy's sum of at most 128 values: one by one below 8, else eight running sums
    combined pairwise, then the rest one by one."""
    if count < 8:
        total = 0.0
        for i in range(start, start + count):
            total += values[i]
        return total
    r0, r1, r2, r3 = values[start], values[start + 1], values[start + 2], values[start + 3]
    r4, r5, r6, r7 = values[start + 4], values[start + 5], values[start + 6], values[start + 7]
    whole = count - count % 8
    for i in range(start + 8, start + whole, 8):
        r0 += values[i]
        r1 += values[i + 1]
        r2 += values[i + 2]
        r3 += values[i + 3]
        r4 += values[i + 4]
        r5 += values[i + 5]
        r6 += values[i + 6]
        r7 += values[i + 7]
    total = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    for i in range(start + whole, start + count):
        total += values[i]
    return total


@numba.njit(**LOOP)
def pairwise_sum(values, start, count, stack, partial):  # pragma: no cover (compiled)
    """Σ values[start:start + count] added in numpy's pairwise order (np.sum of a
    contiguous array: the same bits): blocks of at most 128 (:func:`block_sum`), halves
    (rounded down to a multiple of 8) summed apart and added.  Without recursion (cached
    recursive kernels crashed when loaded): ``stack`` (3, 64) int and ``partial`` (64,)
    float scratch, enough for 2⁶⁴ values."""
    top, filled = 0, 0
    stack[0, 0], stack[1, 0], stack[2, 0] = start, count, 0
    while top >= 0:
        first, n, phase = stack[0, top], stack[1, top], stack[2, top]
        if n <= 128:
            partial[filled] = block_sum(values, first, n)
            filled += 1
            top -= 1
            continue
        half = n // 2
        half -= half % 8
        if phase == 0:  # the first half
            stack[2, top] = 1
            top += 1
            stack[0, top], stack[1, top], stack[2, top] = first, half, 0
        elif phase == 1:  # the second half
            stack[2, top] = 2
            top += 1
            stack[0, top], stack[1, top], stack[2, top] = first + half, n - half, 0
        else:  # both done: their sum
            partial[filled - 2] = partial[filled - 2] + partial[filled - 1]
            filled -= 1
            top -= 1
    return partial[0]


@numba.njit(**LOOP)
def boundary_reaction(node_mass, held, u0, u, velocity_sum, mean_force, dt, scratch, stack, partial,
                      impulse):  # pragma: no cover (compiled)
    """Work of the boundary reactions R = M du/dt − F̄ on the held nodes over the step,
    (dt/2) Σ R·(u^n + u), returned, and their impulse dt Σ R added to ``impulse``; each sum
    in the order numpy sums ExplicitWilkins._boundary_reaction's arrays, which (dim, m)
    indexing lays out column by column: the work pairwise over that order, the impulse of
    each component one term after the other (in 1D, pairwise).  ``scratch``: 2 dim m
    values; ``stack``, ``partial``: pairwise_sum's."""
    dim, m = mean_force.shape[0], held.size
    for j in range(m):
        i = held[j]
        for d in range(dim):
            reaction = node_mass[i] * (u[d, i] - u0[d, i]) / dt - mean_force[d, i]
            scratch[j * dim + d] = reaction
            scratch[dim * m + j * dim + d] = reaction * velocity_sum[d, i]
    for d in range(dim):
        if dim == 1:
            total = pairwise_sum(scratch, 0, m, stack, partial)
        else:
            total = scratch[d]
            for j in range(1, m):
                total += scratch[j * dim + d]
        impulse[d] = impulse[d] + dt * total
    return 0.5 * dt * pairwise_sum(scratch, dim * m, dim * m, stack, partial)


@numba.njit(**LOOP)
def clamped_step(dt, growth_limit, time_left):  # pragma: no cover (compiled)
    """A run's time step: the CFL step, at most ``growth_limit`` (growth × the previous
    step) and the time left."""
    if growth_limit < dt:
        dt = growth_limit
    if time_left < dt:
        dt = time_left
    return dt


@numba.njit(**LOOP)
def plain_step(dt, time_left, watch_stall, steps_left):  # pragma: no cover (compiled)
    """Whether a compiled loop may take a step of dt: positive and finite, and (the stall
    watch on) one that reaches the end within the steps left."""
    if not (dt > 0.0 and abs(dt) < np.inf):
        return False
    return not (watch_stall and time_left > dt * steps_left)


@numba.njit(**LOOP)
def account_step(node_mass, held, u0, u, velocity_sum, mean_force, dt, impulse, t, work, dt_min,
                 dt_max):  # pragma: no cover (compiled)
    """What a compiled run loop records of a step it took: (the boundary work so far with the
    step's boundary reactions' work added, t + dt, the least and the largest dt so far);
    their impulse is added to ``impulse``.  ``held``: as :func:`pure_steps` takes it."""
    held_nodes, held_scratch, stack, partial, _ = held
    if held_nodes.size:
        work = work + boundary_reaction(node_mass, held_nodes, u0, u, velocity_sum, mean_force, dt, held_scratch,
                                        stack, partial, impulse)
    return work, t + dt, (dt if dt < dt_min else dt_min), (dt if dt > dt_max else dt_max)


@numba.njit(**LOOP)
def pure_steps(cell_type, mesh, boundaries, eos, cell_material, viscosity_law, hourglass_coefficient,
               inverse_node_mass, mass, time_step, held, clock, first, predicted, buffers,
               impulse):  # pragma: no cover (compiled)
    """Steps of a state whose cells are all pure, on a Lagrangian mesh, as simulate() takes
    them one by one (ale_xfem.run): each step's dt = min(CFL limit, growth × the previous
    dt, t_end − t), :func:`pure_step`, the boundary reactions' work and impulse.  It stops
    before any step that is not plain: dt not positive and finite, a time step too small to
    reach t_end within the steps allowed (the stall watch), a step that breaks down, or at
    the end of ``clock``'s step budget — simulate() then takes that step itself and says what
    happened.

    ``time_step``: (node mass, CFL number, viscous time step, an acceleration array,
    kernels.time_limits' two scratch arrays, no mixed cells and their empty values);
    ``held``: (the constrained nodes, boundary_reaction's scratch arrays, an array for F̄);
    ``clock``: (t, t_end, the previous dt, growth, the step budget, the steps left before
    max_steps, whether the stall watch is on, the boundary work so far, a time to stop at
    once reached: an observer's next); ``first``: the
    current state and evaluation as (pure_step's final arrays, hourglass forces, whether
    those act); ``buffers``: two more such sets to step into, in turn.
    Returns (steps taken, t, the last dt, least dt, largest dt, the boundary work so far,
    which of first (0) or buffers (1, 2) holds the state reached); ``impulse`` accumulates
    (both sums as simulate() makes them, step by step)."""
    node_mass, cfl, viscous, acceleration, sound_times, ratios, no_cells, no_values = time_step
    mean_force = held[4]
    t, t_end, dt_previous, growth, budget, steps_left, watch_stall, work, t_stop = clock
    cell_nodes, runs = mesh[0], mesh[1]
    steps = 0
    dt_min, dt_max = np.inf, 0.0
    current = 0
    while t < t_end * (1.0 - 1e-14) and steps < budget and steps < steps_left and t < t_stop:
        state = first if current == 0 else (buffers[0] if current == 1 else buffers[1])
        target = 2 if current == 1 else 1
        new_arrays, new_hourglass, _ = buffers[0] if target == 1 else buffers[1]
        arrays, hourglass_state, hourglass = state
        force = arrays[17]
        length = arrays[9] if arrays[9].size else arrays[6]
        dt = stable_time_step(force, inverse_node_mass, boundaries, arrays[6], length, arrays[12], arrays[13],
                              viscous, viscosity_law, no_cells, no_values, cell_nodes, runs, cfl, acceleration,
                              sound_times, ratios)
        dt = clamped_step(dt, growth * dt_previous, t_end - t)
        if not plain_step(dt, t_end - t, watch_stall, steps_left - steps):
            break
        u0 = arrays[0]
        start = (arrays[2], u0, mass, arrays[5], force, arrays[15], arrays[7], arrays[3], hourglass_state[0],
                 hourglass_state[1], hourglass_state[2], hourglass)
        status = pure_step(cell_type, mesh, boundaries, eos, cell_material, viscosity_law, hourglass_coefficient,
                           dt, inverse_node_mass, start, predicted, new_arrays, new_hourglass, mean_force, True, True,
                           BOTH_STAGES)
        if status != 0:
            break
        work, t, dt_min, dt_max = account_step(node_mass, held, u0, new_arrays[0], new_arrays[1], mean_force, dt,
                                               impulse, t, work, dt_min, dt_max)
        dt_previous = dt
        steps += 1
        current = target
    if steps:  # the steps were lean: the state reached, evaluated in full (the same numbers)
        arrays, hourglass_state, _ = buffers[0] if current == 1 else buffers[1]
        evaluate_stage(cell_type, mesh, eos, cell_material, viscosity_law, hourglass_coefficient, mass, False,
                       arrays, hourglass_state, True, False)
    return steps, t, dt_previous, dt_min, dt_max, work, current
