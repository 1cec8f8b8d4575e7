"""The 1D Lagrangian run loop of one gas in three stages a step (compiled; the loop
:meth:`ale_xfem.lagrange.wilkins.ExplicitWilkins.pure_steps` runs on intervals numbered
along the tube, the usual 1D mesh).

:func:`ale_xfem.lagrange.kernels.pure_step` takes a step in stages, each a pass over the
nodes or the cells that stores what the next one reads: the new velocities, then the
positions, the energies, the evaluation, the nodal forces, their mean, the accelerations,
the time-step limits; about seventy arrays are read or written a step.  Here a step is
three stages, four loops over the cells and nodes and about thirty arrays, and what a cell
needs of its nodes is computed in the loop that needs it, from the values of the step's
start:

- the predictor: per cell, its two nodes' velocities and positions under the start's
  forces F^n (each node's −P_right + P_left from the cells beside it, as the scatter sums
  them), the cell's energy e* and its evaluation at x*.  Only the stress P* is stored
  (and the end nodes' values);
- the corrector: the same under F̄ = (F^n + F*)/2, the energy from both; it stores the
  energies, volumes, stresses and each cell's sound-speed time limit and checks the
  state's health, then the nodes' new velocities and positions in a loop of their own
  (one more store in the cells' loop kept the compiler from vectorising it);
- the next time step: the accelerations from the new stresses, and the least limits.

A node's values are computed by each of its two cells, by the same formulas
(:func:`ale_xfem.lagrange.kernels.advanced`, ``moved``, ``energy_after``, the cell
functions): the results are the bits the staged step gives (tests/test_wilkins.py, and
the regression captures).  The two end nodes, the only ones the boundaries may hold, are
computed first and held (:func:`ale_xfem.lagrange.kernels.hold`); the cells beside them
are taken apart from the loop, which then has no branch and vectorises.

On a mesh of more than BLOCK_CELLS cells the three stages go block by block
(:func:`_blocked_step`): the ends first, then for each block of inner cells the
predictor's cells, the corrector's cells and nodes whose predicted stresses are all known
(a cell reads its neighbours'), and the time-step limits of the cells whose new stresses
are; each loop reads what the loop before it has just written, from a core's L2 cache
rather than from memory.  The values are the same numbers, computed in another order of
cells; the least limits are the least of the blocks' least.  Each loop runs over views that
begin a cell before its first cell, from index 1: from a first index it could not bound
below, the compiler guarded each ``k − 1`` against a negative index, and the loops did not
vectorise.

The chunk's last state is evaluated in full at its end (density, pressure, viscosity,
nodal forces), as :func:`ale_xfem.lagrange.kernels.pure_steps` does.
"""

from __future__ import annotations

import numba
import numpy as np

from ale_xfem.eos.kernels import BODY, LOOP, STIFFENED_GAS, pressure_sound_speed
from ale_xfem.lagrange.kernels import (RUNS, account_step, advanced, artificial_viscosity, cfl_step, clamped_step,
                                       energy_after, evaluate_intervals, hold, least, least_of, moved, node_force,
                                       plain_step, sound_time, velocity_jump)
from ale_xfem.model.cell_kernels import INTERVAL, nan_max, nan_min


def runs_in_passes(cell_code: int, runs, scatter_mode: int, held_nodes, n_cells: int, n_nodes: int,
                   components: int, gas_model: int) -> bool:
    """Whether a run's steps are taken by :func:`one_gas_steps`: intervals whose cell k is
    nodes k and k + 1 (n_cells + 1 nodes), their corner forces summed along the tube, the
    held nodes among the two ends, one velocity component (no transverse one), one
    stiffened (or ideal) gas (``gas_model``: kernels.one_gas_model).  With several materials
    each cell chooses its model in the loop, which then does not vectorise, and the stages
    were slower than the staged step (measured on the two-gamma tube, best of 7 interleaved
    runs: 3.5 against 3.2 ms a step at 10⁵ cells, 35 against 25 µs at 10³)."""
    return bool(cell_code == INTERVAL and runs[4] == 1 and runs[0] == 0 and runs[1] == 1 and scatter_mode == RUNS
                and n_nodes == n_cells + 1 and components == 1 and gas_model == STIFFENED_GAS
                and np.isin(held_nodes, (0, n_nodes - 1)).all())


# the inner cells a step takes in one block (_blocked_step): its arrays' values for them,
# about twenty arrays of 32 kB, stay in a core's L2 cache from one loop to the next.  (On
# the Intel Xeon machine of BENCHMARKS.md, 10⁵ cells: 2048, 4096 and 8192 within the
# machine's drift of each other; a mesh of at most BLOCK_CELLS cells takes the stages whole.)
BLOCK_CELLS = 4096


@numba.njit(**LOOP)
def stage_force(two, stress0, stress1, i):  # pragma: no cover (compiled)
    """The force a stage moves node i (not an end) with: F^n, or (``two``) F̄ = (F^n + F*)/2."""
    force = node_force(stress0[i - 1], stress0[i])
    if two:
        force = (force + node_force(stress1[i - 1], stress1[i])) * 0.5
    return force


@numba.njit(**LOOP)
def end_forces(two, stress0, stress1):  # pragma: no cover (compiled)
    """The forces on the two end nodes: −P_0 and P_{n−1} (as the scatter writes them)."""
    n = stress0.size
    first, last = -stress0[0], 0.0 + stress0[n - 1]
    if two:
        first = (first + -stress1[0]) * 0.5
        last = (last + (0.0 + stress1[n - 1])) * 0.5
    return first, last


@numba.njit(**LOOP)
def stage_cell(kind, two, parameters, law, dt, k, mass, energy, stress0, stress1, ua, sa, xa, ub, sb,
               xb):  # pragma: no cover (compiled)
    """Cell k at the end of a stage, from its nodes' new velocities u, velocity sums s and
    positions x: (e, V, c, Δu, P) — its compatible energy (from P^n, or ``two`` P^n and P*)
    and its evaluation (``kind``: the gas's model, its parameters row 0)."""
    q_quadratic, q_linear, artificial = law
    rate = sb - sa
    work = rate * (stress0[k] + stress1[k]) if two else rate * stress0[k]
    e = energy_after(energy[k], mass[k], dt, work, two)
    v = xb - xa
    rho = mass[k] / v
    p, c = pressure_sound_speed(kind, parameters, 0, rho, e)
    du = velocity_jump(INTERVAL, v, ub - ua)
    q = artificial_viscosity(q_quadratic, q_linear, du, rho, c) if artificial else 0.0
    return e, v, c, du, p + q if artificial else p


@numba.njit(**LOOP)
def interval_sound_time(c, du, v, law):  # pragma: no cover (compiled)
    """An interval's sound-speed time limit (kernels.time_limits'): its length is its volume,
    and 1D has no viscous length (ExplicitWilkins.viscous_time_step is for 2D cells)."""
    q_quadratic, q_linear, artificial = law
    return sound_time(c, du, v, v, False, q_quadratic, q_linear, artificial)


@numba.njit(**LOOP)
def keep_cell(two, k, e, v, c, du, stress, law, out):  # pragma: no cover (compiled)
    """Store what a stage keeps of cell k and return whether it is sound: the predictor its
    stress (sound: V > 0); the corrector its energy, volume, stress and sound-speed time
    limit (sound: V > 0, c, e and P finite)."""
    energy, volume, stress_out, sound_times = out
    stress_out[k] = stress
    if not two:
        return v > 0.0
    energy[k], volume[k] = e, v
    sound_times[k] = interval_sound_time(c, du, v, law)
    return (v > 0.0) & (abs(c) < np.inf) & (abs(e) < np.inf) & (abs(stress) < np.inf)


@numba.njit(**BODY)
def _stage_ends(two, boundaries, dt, inverse_node_mass, x0, u0, stress0, stress1, u, x, velocity_sum,
                mean_force):  # pragma: no cover (compiled)
    """A stage's two end nodes (module docstring): their new velocities (held), velocity
    sums, positions and forces stored; returns (s, x) of the first and of the last."""
    n = stress0.size
    first, last = end_forces(two, stress0, stress1)
    u[0, 0] = advanced(u0[0, 0], first, dt, inverse_node_mass[0])
    u[0, n] = advanced(u0[0, n], last, dt, inverse_node_mass[n])
    hold(u, *boundaries, False)
    s_first, x_first = moved(u0[0, 0], u[0, 0], x0[0, 0], dt)
    s_last, x_last = moved(u0[0, n], u[0, n], x0[0, n], dt)
    x[0, 0], x[0, n] = x_first, x_last
    velocity_sum[0, 0], velocity_sum[0, n] = s_first, s_last
    mean_force[0, 0], mean_force[0, n] = first, last
    return s_first, x_first, s_last, x_last


@numba.njit(**BODY)
def _first_cell(kind, two, parameters, law, dt, inverse_node_mass, x0, u0, mass, energy, stress0, stress1, u,
                s_first, x_first, out):  # pragma: no cover (compiled)
    """Cell 0 of a mesh of two cells or more: the first end and node 1."""
    ub = advanced(u0[0, 1], stage_force(two, stress0, stress1, 1), dt, inverse_node_mass[1])
    sb, xb = moved(u0[0, 1], ub, x0[0, 1], dt)
    e, v, c, du, p = stage_cell(kind, two, parameters, law, dt, 0, mass, energy, stress0, stress1,
                                u[0, 0], s_first, x_first, ub, sb, xb)
    return keep_cell(two, 0, e, v, c, du, p, law, out)


@numba.njit(**BODY)
def _last_cell(kind, two, parameters, law, dt, inverse_node_mass, x0, u0, mass, energy, stress0, stress1, u,
               s_last, x_last, out):  # pragma: no cover (compiled)
    """Cell n − 1 of a mesh of two cells or more: node n − 1 and the last end."""
    n = mass.size
    ua = advanced(u0[0, n - 1], stage_force(two, stress0, stress1, n - 1), dt, inverse_node_mass[n - 1])
    sa, xa = moved(u0[0, n - 1], ua, x0[0, n - 1], dt)
    e, v, c, du, p = stage_cell(kind, two, parameters, law, dt, n - 1, mass, energy, stress0, stress1,
                                ua, sa, xa, u[0, n], s_last, x_last)
    return keep_cell(two, n - 1, e, v, c, du, p, law, out)


@numba.njit(**BODY)
def _stage_cells(kind, two, parameters, law, dt, inverse_node_mass, x0, u0, mass, energy, stress0, stress1, out,
                 start, stop):  # pragma: no cover (compiled)
    """Cells start … stop − 1 of a stage, none of them an end cell: each computes its two
    nodes' values itself.  Returns whether they are sound.  (The loop runs over views that
    begin a cell before ``start``, from index 1: the compiler then knows that no index is
    negative, and the corrector's loop vectorises, which it did not from a ``start`` it
    could not bound.)"""
    before, end = start - 1, stop + 1
    x, u, inverse = x0[0, before:end], u0[0, before:end], inverse_node_mass[before:end]
    m, e0, s0, s1 = mass[before:end], energy[before:end], stress0[before:end], stress1[before:end]
    kept = (out[0][before:end], out[1][before:end], out[2][before:end], out[3][before:end])
    sound = True
    for k in range(1, stop - before):
        ua = advanced(u[k], stage_force(two, s0, s1, k), dt, inverse[k])
        sa, xa = moved(u[k], ua, x[k], dt)
        ub = advanced(u[k + 1], stage_force(two, s0, s1, k + 1), dt, inverse[k + 1])
        sb, xb = moved(u[k + 1], ub, x[k + 1], dt)
        e, v, c, du, p = stage_cell(kind, two, parameters, law, dt, k, m, e0, s0, s1, ua, sa, xa, ub, sb, xb)
        sound &= keep_cell(two, k, e, v, c, du, p, law, kept)
    return sound


@numba.njit(**BODY)
def _corrector_nodes(dt, inverse_node_mass, x0, u0, stress0, stress1, u, x, start, stop):  # pragma: no cover (compiled)
    """The corrector's new velocities and positions of nodes start … stop − 1 (not the
    ends), in a loop of their own (module docstring); over views from index 1, as in
    :func:`_stage_cells`."""
    before = start - 1
    inverse, s0, s1 = inverse_node_mass[before:stop], stress0[before:stop], stress1[before:stop]
    u_start, x_start, u_new, x_new = u0[0, before:stop], x0[0, before:stop], u[0, before:stop], x[0, before:stop]
    for i in range(1, stop - before):
        ui = advanced(u_start[i], stage_force(True, s0, s1, i), dt, inverse[i])
        u_new[i] = ui
        x_new[i] = moved(u_start[i], ui, x_start[i], dt)[1]


@numba.njit(**BODY)
def _stage(kind, two, parameters, law, boundaries, dt, inverse_node_mass, x0, u0, mass, energy,
           stress0, stress1, u, x, velocity_sum, mean_force, out):  # pragma: no cover (compiled)
    """One stage over every cell (module docstring); ``u``, ``x``: the new node values
    (the predictor's only at the ends), ``velocity_sum`` and ``mean_force`` at the ends
    (the boundary reactions').  Returns whether every cell is sound."""
    n = mass.size
    s_first, x_first, s_last, x_last = _stage_ends(two, boundaries, dt, inverse_node_mass, x0, u0, stress0, stress1,
                                                   u, x, velocity_sum, mean_force)
    if n == 1:
        e, v, c, du, p = stage_cell(kind, two, parameters, law, dt, 0, mass, energy, stress0, stress1,
                                    u[0, 0], s_first, x_first, u[0, 1], s_last, x_last)
        return keep_cell(two, 0, e, v, c, du, p, law, out)
    sound = _first_cell(kind, two, parameters, law, dt, inverse_node_mass, x0, u0, mass, energy, stress0, stress1,
                        u, s_first, x_first, out)
    sound &= _stage_cells(kind, two, parameters, law, dt, inverse_node_mass, x0, u0, mass, energy, stress0,
                          stress1, out, 1, n - 1)
    sound &= _last_cell(kind, two, parameters, law, dt, inverse_node_mass, x0, u0, mass, energy, stress0, stress1,
                        u, s_last, x_last, out)
    if two:
        _corrector_nodes(dt, inverse_node_mass, x0, u0, stress0, stress1, u, x, 1, n)
    return sound


@numba.njit(**LOOP)
def stage(kind, two, parameters, law, boundaries, dt, inverse_node_mass, x0, u0, mass, energy, stress0,
          stress1, u, x, velocity_sum, mean_force, out):  # pragma: no cover (compiled)
    """A stage (:func:`_stage`), compiled for each ``kind`` (the gas's model) and ``two`` (the
    corrector) apart, both constants of its loop (numba.literally; it is called from
    compiled code with constants).  A function of its own: inlined into the run loop, its
    loops did not vectorise (measured on the EPYC machine of BENCHMARKS.md: the 1D step took
    3.2 ms at 10⁵ cells, against about 1.5 ms as a function of its own, before the blocks of
    :func:`_blocked_step`)."""
    numba.literally(kind)
    numba.literally(two)
    return _stage(kind, two, parameters, law, boundaries, dt, inverse_node_mass, x0, u0, mass, energy,
                  stress0, stress1, u, x, velocity_sum, mean_force, out)


@numba.njit(**LOOP)
def end_accelerations(stress, inverse_node_mass, boundaries, acceleration):  # pragma: no cover (compiled)
    """The end nodes' accelerations F/M, held as kernels.stable_time_step holds them."""
    n = stress.size
    first, last = end_forces(False, stress, stress)
    acceleration[0, 0] = first * inverse_node_mass[0]
    acceleration[0, n] = last * inverse_node_mass[n]
    hold(acceleration, *boundaries, True)
    return acceleration[0, 0], acceleration[0, n]


@numba.njit(**LOOP)
def acceleration_ratio(volume, a, b):  # pragma: no cover (compiled)
    """L / a of an interval, a the larger of its nodes' |accelerations| (kernels.time_limits)."""
    return volume / nan_max(abs(a), abs(b))


@numba.njit(**BODY)
def _end_ratios(stress, volume, inverse_node_mass, boundaries, acceleration, ratios):  # pragma: no cover (compiled)
    """The time step's L / a of the two end cells (of the one cell), from the end nodes'
    held accelerations."""
    n = volume.size
    first, last = end_accelerations(stress, inverse_node_mass, boundaries, acceleration)
    if n == 1:
        ratios[0] = acceleration_ratio(volume[0], first, last)
    else:
        ratios[0] = acceleration_ratio(volume[0], first, node_force(stress[0], stress[1]) * inverse_node_mass[1])
        ratios[n - 1] = acceleration_ratio(volume[n - 1], node_force(stress[n - 2], stress[n - 1])
                                           * inverse_node_mass[n - 1], last)


@numba.njit(**BODY)
def _ratio_cells(stress, volume, inverse_node_mass, ratios, start, stop):  # pragma: no cover (compiled)
    """The time step's L / a of cells start … stop − 1, none of them an end cell; over views
    from index 1, as in :func:`_stage_cells`."""
    before = start - 1
    p, inverse = stress[before:stop + 1], inverse_node_mass[before:stop + 1]
    v, r = volume[before:stop], ratios[before:stop]
    for k in range(1, stop - before):
        r[k] = acceleration_ratio(v[k], node_force(p[k - 1], p[k]) * inverse[k],
                                  node_force(p[k], p[k + 1]) * inverse[k + 1])


@numba.njit(**LOOP)
def next_time_step(stress, volume, sound_times, inverse_node_mass, boundaries, cfl, acceleration,
                   ratios):  # pragma: no cover (compiled)
    """The CFL time step of the state a corrector made (kernels.stable_time_step's)."""
    n = volume.size
    _end_ratios(stress, volume, inverse_node_mass, boundaries, acceleration, ratios)
    _ratio_cells(stress, volume, inverse_node_mass, ratios, 1, n - 1)
    return cfl_step(cfl, least(sound_times), least(ratios))


@numba.njit(**LOOP)
def stage_cells(kind, two, parameters, law, dt, inverse_node_mass, x0, u0, mass, energy, stress0, stress1, out,
                start, stop):  # pragma: no cover (compiled)
    """:func:`_stage_cells` compiled for each ``kind`` and ``two`` apart, both constants of
    its loop (as :func:`stage`), so that it vectorises."""
    numba.literally(kind)
    numba.literally(two)
    return _stage_cells(kind, two, parameters, law, dt, inverse_node_mass, x0, u0, mass, energy, stress0, stress1,
                        out, start, stop)


@numba.njit(**LOOP)
def corrector_nodes(dt, inverse_node_mass, x0, u0, stress0, stress1, u, x, start, stop):  # pragma: no cover (compiled)
    """:func:`_corrector_nodes` in a loop of its own."""
    _corrector_nodes(dt, inverse_node_mass, x0, u0, stress0, stress1, u, x, start, stop)


@numba.njit(**LOOP)
def ratio_cells(stress, volume, inverse_node_mass, ratios, start, stop):  # pragma: no cover (compiled)
    """:func:`_ratio_cells` in a loop of its own."""
    _ratio_cells(stress, volume, inverse_node_mass, ratios, start, stop)


@numba.njit(**BODY)
def _blocked_step(kind, parameters, law, boundaries, dt, inverse_node_mass, x0, u0, mass, energy, stress0,
                  predicted, u, x, velocity_sum, mean_force, corrected, cfl, acceleration, ratios,
                  block):  # pragma: no cover (compiled)
    """A whole step of a mesh of three cells or more, block by block (module docstring):
    the predictor's and the corrector's ends first, then for each ``block`` of inner cells
    the predictor's cells, the corrector's cells and nodes whose predicted stresses are all
    known, and the time step's limits of the cells whose new stresses are, each loop
    reading what the loop before it has just written.  Returns (whether every cell is
    sound, the next CFL time step).  ``corrected``: the corrector's (energy, volume,
    stress, sound-speed time limits); ``predicted``: the predictor's arrays (its u, s, x at
    the ends, its stress)."""
    n = mass.size
    e, volume, stress, sound_times = corrected
    predicted_stress = predicted[15]
    kept = (predicted[5], predicted[6], predicted_stress, sound_times)  # (the predictor stores the stress only)
    # the predictor's ends and end cells, then the corrector's ends, which read their stresses
    s_first, x_first, s_last, x_last = _stage_ends(False, boundaries, dt, inverse_node_mass, x0, u0, stress0, stress0,
                                                   predicted[0], predicted[2], predicted[1], mean_force)
    sound = _first_cell(kind, False, parameters, law, dt, inverse_node_mass, x0, u0, mass, energy, stress0, stress0,
                        predicted[0], s_first, x_first, kept)
    sound &= _last_cell(kind, False, parameters, law, dt, inverse_node_mass, x0, u0, mass, energy, stress0, stress0,
                        predicted[0], s_last, x_last, kept)
    s_first, x_first, s_last, x_last = _stage_ends(True, boundaries, dt, inverse_node_mass, x0, u0, stress0,
                                                   predicted_stress, u, x, velocity_sum, mean_force)
    # (where each inner range has reached; not literal constants, which would compile the
    # loops once more for them, unvectorised)
    corrected_to = nodes_to = ratios_to = np.int64(1)
    least_sound, least_ratio = np.inf, np.inf
    for start in range(1, n - 1, block):
        stop = min(start + block, n - 1)
        sound &= stage_cells(kind, False, parameters, law, dt, inverse_node_mass, x0, u0, mass, energy, stress0,
                             stress0, kept, start, stop)
        if start == 1:  # cell 0 reads the predicted stresses of cells 0 and 1
            sound &= _first_cell(kind, True, parameters, law, dt, inverse_node_mass, x0, u0, mass, energy, stress0,
                                 predicted_stress, u, s_first, x_first, corrected)
            least_sound = nan_min(least_sound, sound_times[0])
        # a cell reads the predicted stresses of its neighbours, a node those of its two cells
        last_block = stop == n - 1
        cells_to = n - 1 if last_block else stop - 1
        sound &= stage_cells(kind, True, parameters, law, dt, inverse_node_mass, x0, u0, mass, energy, stress0,
                             predicted_stress, corrected, corrected_to, cells_to)
        corrector_nodes(dt, inverse_node_mass, x0, u0, stress0, predicted_stress, u, x, nodes_to,
                        n if last_block else stop)
        least_sound = nan_min(least_sound, least_of(sound_times, corrected_to, cells_to))
        # the limits of the cells whose neighbours' new stresses are known
        if cells_to - 1 > ratios_to:
            ratio_cells(stress, volume, inverse_node_mass, ratios, ratios_to, cells_to - 1)
            least_ratio = nan_min(least_ratio, least_of(ratios, ratios_to, cells_to - 1))
            ratios_to = cells_to - 1
        corrected_to, nodes_to = cells_to, stop
    sound &= _last_cell(kind, True, parameters, law, dt, inverse_node_mass, x0, u0, mass, energy, stress0,
                        predicted_stress, u, s_last, x_last, corrected)
    least_sound = nan_min(least_sound, sound_times[n - 1])
    _ratio_cells(stress, volume, inverse_node_mass, ratios, ratios_to, n - 1)
    _end_ratios(stress, volume, inverse_node_mass, boundaries, acceleration, ratios)
    least_ratio = nan_min(least_ratio, least_of(ratios, ratios_to, n - 1))
    least_ratio = nan_min(least_ratio, nan_min(ratios[0], ratios[n - 1]))
    return sound, cfl_step(cfl, least_sound, least_ratio)


@numba.njit(**BODY)
def _interval_steps(kind, blocked, mesh, boundaries, eos, cell_material, law, hourglass_coefficient,
                    inverse_node_mass, mass, time_step, held, clock, first, predicted, buffers,
                    impulse):  # pragma: no cover (compiled)
    """The run loop of :func:`one_gas_steps` (``blocked`` a constant: False, the stages
    whole; True, :func:`_blocked_step`, which needs more than two cells)."""
    node_mass, cfl, _, acceleration, sound_times, ratios, _, _ = time_step
    mean_force = held[4]
    t, t_end, dt_previous, growth, budget, steps_left, watch_stall, work, t_stop = clock
    steps = 0
    dt_min, dt_max = np.inf, 0.0
    current = 0
    arrays = first[0]
    volume, sound_speed, jump = arrays[6], arrays[12], arrays[13]
    for k in range(volume.size):  # the start's limits, as the corrector leaves them
        sound_times[k] = interval_sound_time(sound_speed[k], jump[k], volume[k], law)
    dt = next_time_step(arrays[15], volume, sound_times, inverse_node_mass, boundaries, cfl, acceleration, ratios)
    while t < t_end * (1.0 - 1e-14) and steps < budget and steps < steps_left and t < t_stop:
        arrays = first[0] if current == 0 else (buffers[0][0] if current == 1 else buffers[1][0])
        target = 2 if current == 1 else 1
        new = buffers[0][0] if target == 1 else buffers[1][0]
        dt = clamped_step(dt, growth * dt_previous, t_end - t)
        if not plain_step(dt, t_end - t, watch_stall, steps_left - steps):
            break
        u0, x0, energy, stress = arrays[0], arrays[2], arrays[5], arrays[15]
        u, velocity_sum, x, e, volume, new_stress = new[0], new[1], new[2], new[5], new[6], new[15]
        if not blocked:
            if not stage(kind, False, eos[1], law, boundaries, dt, inverse_node_mass, x0, u0, mass,
                         energy, stress, stress, predicted[0], predicted[2], predicted[1], mean_force,
                         (predicted[5], predicted[6], predicted[15], sound_times)):
                break
            if not stage(kind, True, eos[1], law, boundaries, dt, inverse_node_mass, x0, u0, mass,
                         energy, stress, predicted[15], u, x, velocity_sum, mean_force,
                         (e, volume, new_stress, sound_times)):
                break
            dt_next = next_time_step(new_stress, volume, sound_times, inverse_node_mass, boundaries, cfl,
                                     acceleration, ratios)
        else:
            sound, dt_next = _blocked_step(kind, eos[1], law, boundaries, dt, inverse_node_mass, x0, u0, mass, energy,
                                           stress, predicted, u, x, velocity_sum, mean_force,
                                           (e, volume, new_stress, sound_times), cfl, acceleration, ratios,
                                           BLOCK_CELLS)
            if not sound:
                break
        work, t, dt_min, dt_max = account_step(node_mass, held, u0, u, velocity_sum, mean_force, dt, impulse, t,
                                               work, dt_min, dt_max)
        dt_previous = dt
        steps += 1
        current = target
        dt = dt_next
    if steps:  # the state reached, evaluated in full
        arrays, (s0, s1, q), _ = buffers[0] if current == 1 else buffers[1]
        evaluate_intervals(kind, arrays[2], arrays[0], arrays[3], mesh[0], mesh[1], eos, cell_material, mass, arrays[5],
                           law, (False, False, hourglass_coefficient, s0, s1, q), arrays[6:16], arrays[16],
                           mesh[2:], arrays[17])
    return steps, t, dt_previous, dt_min, dt_max, work, current


@numba.njit(**LOOP)
def one_gas_steps(cell_type, mesh, boundaries, eos, cell_material, law, hourglass_coefficient, inverse_node_mass,
                  mass, time_step, held, clock, first, predicted, buffers, impulse):  # pragma: no cover (compiled)
    """:func:`ale_xfem.lagrange.kernels.pure_steps` (the same arguments and results) where
    :func:`runs_in_passes` admits it: a step in three stages (module docstring), the same
    numbers to the bit.  The start's forces are formed again from its stresses: ``first``
    must be an evaluation whose nodal forces are the scatter of its stresses (every pure
    state's is)."""
    # (cell_type: pure_steps' signature; always intervals here)
    return _interval_steps(STIFFENED_GAS, False, mesh, boundaries, eos, cell_material, law, hourglass_coefficient,
                           inverse_node_mass, mass, time_step, held, clock, first, predicted, buffers, impulse)


@numba.njit(**LOOP)
def one_gas_steps_in_blocks(cell_type, mesh, boundaries, eos, cell_material, law, hourglass_coefficient,
                            inverse_node_mass, mass, time_step, held, clock, first, predicted, buffers,
                            impulse):  # pragma: no cover (compiled)
    """:func:`one_gas_steps` on a mesh of more than BLOCK_CELLS cells: each step block by
    block (:func:`_blocked_step`), the same numbers to the bit.  An entry point of its own,
    so that a run on a smaller mesh does not compile the blocked step's loops."""
    return _interval_steps(STIFFENED_GAS, True, mesh, boundaries, eos, cell_material, law, hourglass_coefficient,
                           inverse_node_mass, mass, time_step, held, clock, first, predicted, buffers, impulse)
