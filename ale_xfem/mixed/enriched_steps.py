"""A 1D Lagrangian run with enriched mixed cells, its steps in compiled chunks.

The steps :class:`ale_xfem.lagrange.wilkins.ExplicitWilkins` takes with the enriched
closure (:mod:`ale_xfem.mixed.enriched`), each through a dozen Python calls, taken here in
one compiled loop (:func:`enriched_steps`), as :func:`ale_xfem.lagrange.kernels.pure_steps`
takes those of pure cells: the same kernels of the explicit step, the mixed cells'
viscosity medium, their interface solve (:func:`ale_xfem.mixed.equilibrium.interface_solve`)
and the pressure relaxation that ends a step (:func:`ale_xfem.mixed.equilibrium.relax_cells`),
each formula in the order of operations of the staged step, so that the numbers are the
same to the bit (tests/test_mixed_cells.py runs both).

The loop stops before any step that is not plain — a time step that is not positive and
finite or too small to reach t_end, a start state whose mixed cells need relaxing, a mixed
cell whose solve or relaxation fails, a state that is not healthy, the end of the chunk's
budget — and the run loop (ale_xfem.run) takes that step itself with the staged step,
which says what happened (and halves the time step where a mixed cell breaks down).
"""

from __future__ import annotations

import numba
import numpy as np

from ale_xfem.eos.kernels import pressure_sound_speed
from ale_xfem.geometry.polygon_kernels import KERNEL, maximum
from ale_xfem.lagrange.kernels import (account_step, advance_velocity, clamped_step, compatible_energy,
                                       geometry_and_rates, healthy, hold, least, plain_step, scatter_corners,
                                       stable_time_step, stress_and_corner_forces, velocity_sum_and_position)
from ale_xfem.lagrange.wilkins import ForceEvaluation
from ale_xfem.mixed.closure_kernels import cap_by_internal_nodes, interface_affine, viscosity_media
from ale_xfem.mixed.equilibrium import RELAXED, SOLVED, balanced_cells, interface_solve, relaxed_states
from ale_xfem.model.cell_kernels import INTERVAL

# the arrays of one state and its force evaluation, in the order the kernels take them
STATE_ARRAYS = ("node_position", "node_velocity", "material_energy", "material_volume", "material_density",
                "material_pressure", "material_sound_speed", "interface_pressure", "interface_velocity",
                "volume", "sound_speed", "velocity_jump", "viscosity", "stress", "nodal_force",
                "mixed_sound_speed", "mixed_viscosity", "mixed_density")


@numba.njit(**KERNEL)
def evaluate_enriched(x, u, mesh, eos, cell_material, mass, energy, mixed, node_mass, viscosity_law, view, empty,
                      tangle_check, out):  # pragma: no cover (compiled)
    """The forces of a 1D state with enriched mixed cells, as ExplicitWilkins.evaluate
    makes them in stages: volumes, velocity jumps and ρ = m/V (a mixed cell's slot 0 its
    α part: ρ_α = m_α/V_α), slot 0's pressure and sound speed, each mixed cell's
    viscosity medium (EnrichedClosure.viscosity_medium), the viscosity and stresses (a
    mixed cell's P = p_Γ + q), the nodal forces.  ``view``: the mixed cells' (V_α, V_β,
    slot 1's energies (n_cells,), p_Γ); ``out``: (volume, density, pressure, sound speed,
    velocity jump, viscosity, stress, nodal force, mixed cells' viscosity density, sound
    speed and viscosity) of slot 0."""
    cell_nodes, runs, mode, corner_is_run, scratch = mesh
    kinds, parameters = eos
    cells, node_a, node_b, _, right, _, _ = mixed
    volume_left, volume_right, energy_right, interface_pressure = view
    no_shape, no_values, no_hourglass = empty
    (volume, density, pressure, sound_speed, jump, viscosity, stress, nodal_force, mixed_density, mixed_sound_speed,
     mixed_viscosity) = out
    geometry_and_rates(INTERVAL, x, u, no_shape, cell_nodes, runs, tangle_check, False, True, mass[0], volume,
                       no_shape, no_values, no_values, density, jump)
    for j in range(cells.size):
        k = cells[j]
        density[k] = mass[0, k] / volume_left[j]
    for k in range(volume.size):  # as ale_xfem.eos.kernels.fill_pressure_sound_speed
        material = cell_material[k]
        if material < 0:
            pressure[k], sound_speed[k] = 0.0, 0.0
        else:
            pressure[k], sound_speed[k] = pressure_sound_speed(kinds[material], parameters, material, density[k],
                                                               energy[k])
    # the medium of the mixed cells' viscosity (EnrichedClosure.viscosity_medium)
    mass_right, energy_of_right = np.empty(cells.size), np.empty(cells.size)
    for j in range(cells.size):
        mass_right[j], energy_of_right[j] = mass[1, cells[j]], energy_right[cells[j]]
    viscosity_media(kinds, parameters, right, cells, volume, density, sound_speed, volume_left, volume_right,
                    mass_right, energy_of_right, mixed_density, mixed_sound_speed)
    cap_by_internal_nodes(cells, volume, node_mass, node_a, node_b, mixed_density)
    q_quadratic, q_linear, artificial = viscosity_law
    stress_and_corner_forces(INTERVAL, volume, no_shape, no_shape, jump, density, sound_speed, pressure, q_quadratic,
                             q_linear, artificial, cells, mixed_density, mixed_sound_speed, interface_pressure, False,
                             False, 0.0, no_values, no_values, no_hourglass, viscosity, stress, no_shape)
    for j in range(cells.size):
        mixed_viscosity[j] = viscosity[cells[j]]
    scatter_corners(INTERVAL, stress, no_shape, cell_nodes, runs, mode, corner_is_run, scratch, nodal_force)


@numba.njit(**KERNEL)
def enriched_step(mesh, boundaries, eos, cell_material, viscosity_law, inverse_node_mass, node_mass, free_nodes,
                  mass, mixed, settings, empty, dt, state, predicted, new, mean_force):  # pragma: no cover
    """One step of a state with enriched 1D mixed cells (ExplicitWilkins.step with
    EnrichedClosure), into the arrays of ``new``.  Returns (0, the interface solve's
    iterations, whether the end state was relaxed), or (1, 0, False) where the staged step
    would stop or say more: a predicted volume not positive, a mixed cell's failure, a
    final state not healthy."""
    cell_nodes, runs = mesh[0], mesh[1]
    cells, node_a, node_b, left, right, max_density_left, max_density_right = mixed
    tolerance, max_iterations, nonlinear, relaxation = settings
    no_shape, no_values, no_hourglass = empty
    (x0, u0, energy, material_volume, _, _, _, interface_pressure, _, volume, _, _, _, stress, force, _,
     mixed_viscosity, _) = state
    (u_pred, velocity_sum, x_pred, e_pred, volume_left, volume_right, p_volume, p_density, p_pressure, p_sound_speed,
     p_jump, p_viscosity, p_stress, p_force, p_mixed_density, p_mixed_sound_speed, p_mixed_viscosity) = predicted
    (x, u, e, v, density, pressure, sound_speed, new_interface_pressure, interface_velocity, new_volume, _, jump,
     viscosity, new_stress, new_force, mixed_sound_speed, new_mixed_viscosity, mixed_density) = new
    m = cells.size
    # Predictor: u* = u^n + dt F^n/M (held), x*, e* from F^n; the mixed cells keep their
    # energies and are strained alike (SharedClosure.predicted_view), for their q*.
    advance_velocity(u0, force, dt, inverse_node_mass, u_pred)
    hold(u_pred, *boundaries, False)
    velocity_sum_and_position(u0, u_pred, x0, dt, velocity_sum, x_pred)
    compatible_energy(INTERVAL, cell_nodes, runs, energy[0], mass[0], dt, no_shape, stress, no_shape, stress, False,
                      False, no_values, no_values, no_hourglass, velocity_sum, no_shape, e_pred)
    for j in range(m):
        k = cells[j]
        e_pred[k] = energy[0, k]
        strain = (x_pred[0, node_b[j]] - x_pred[0, node_a[j]]) / volume[k]
        volume_left[j], volume_right[j] = material_volume[0, k] * strain, material_volume[1, k] * strain
    evaluate_enriched(x_pred, u_pred, mesh, eos, cell_material, mass, e_pred, mixed, node_mass, viscosity_law,
                      (volume_left, volume_right, energy[1], interface_pressure), empty, False,
                      (p_volume, p_density, p_pressure, p_sound_speed, p_jump, p_viscosity, p_stress, p_force,
                       p_mixed_density, p_mixed_sound_speed, p_mixed_viscosity))
    if not least(p_volume) > 0.0:
        return 1, 0, False
    for i in range(mean_force.shape[1]):
        mean_force[0, i] = (force[0, i] + p_force[0, i]) * 0.5
    # The interface solve (EnrichedClosure.implicit_solve): V(π) = A + Bπ of each mixed cell
    # from its internal nodes' trapezoidal motion, the work pressure ½(π^n + q^n + q*) + ½π.
    m_a, m_b, va0, vb0, ea0, eb0 = np.empty(m), np.empty(m), np.empty(m), np.empty(m), np.empty(m), np.empty(m)
    offset, slope, work_offset, work_slope = np.empty(m), np.empty(m), np.empty(m), np.full(m, 0.5)
    interface_affine(dt, inverse_node_mass, free_nodes, cells, node_a, node_b, u0, mean_force, volume,
                     interface_pressure, mixed_viscosity, p_mixed_viscosity, np.empty((2, m)), offset, slope,
                     work_offset)
    for j in range(m):
        k = cells[j]
        m_a[j], m_b[j], va0[j], vb0[j] = mass[0, k], mass[1, k], material_volume[0, k], material_volume[1, k]
        ea0[j], eb0[j] = energy[0, k], energy[1, k]
    status, _, iterations, pi, va, _, details, _ = interface_solve(
        eos[0], eos[1], left, right, m_a, m_b, va0, vb0, ea0, eb0, interface_pressure, offset, slope, work_offset,
        work_slope, max_iterations, nonlinear, tolerance, max_density_left, max_density_right)
    if status != SOLVED:
        return 1, 0, False
    for j in range(m):
        change = 0.5 * (pi[j] - interface_pressure[j])
        mean_force[0, node_a[j]] -= change
        mean_force[0, node_b[j]] += change
    # Corrector: F̄ = (F^n + F*)/2 with the mixed cells' trapezoidal stresses.
    advance_velocity(u0, mean_force, dt, inverse_node_mass, u)
    hold(u, *boundaries, False)
    velocity_sum_and_position(u0, u, x0, dt, velocity_sum, x)
    compatible_energy(INTERVAL, cell_nodes, runs, energy[0], mass[0], dt, no_shape, stress, no_shape, p_stress, True,
                      False, no_values, no_values, no_hourglass, velocity_sum, no_shape, e[0])
    # The mixed cells' new state (SharedClosure.finish): V_β takes the cell's round-off,
    # then the relaxation that starts the next step (PressureRelaxation.relax_end).
    vb = np.empty(m)
    for j in range(m):
        k, a = cells[j], node_a[j]
        vb[j] = (x[0, node_b[j]] - x[0, a]) - va[j]
        interface_velocity[j] = (x[0, a] + va[j] - (x0[0, a] + material_volume[0, k])) / dt
    relaxed = False
    if relaxation and not balanced_cells(details[2], details[3], details[4] * details[6], details[5] * details[7],
                                         tolerance):
        status, _, va, vb, _, details, _, _ = relaxed_states(eos[0], eos[1], left, right, m_a, m_b, va, vb,
                                                            details[0].copy(), details[1].copy(), va + vb,
                                                            max_density_left, max_density_right, 1e-3 * tolerance)
        if status != RELAXED:
            return 1, 0, False
        relaxed = True
    for j in range(m):
        k = cells[j]
        e[0, k], e[1, k] = details[0, j], details[1, j]
        new_interface_pressure[j] = 0.5 * (details[2, j] + details[3, j])
    evaluate_enriched(x, u, mesh, eos, cell_material, mass, e[0], mixed, node_mass, viscosity_law,
                      (va, vb, e[1], new_interface_pressure), empty, True,
                      (new_volume, density[0], pressure[0], sound_speed[0], jump, viscosity, new_stress, new_force,
                       mixed_density, mixed_sound_speed, new_mixed_viscosity))
    v[0, :] = new_volume
    for j in range(m):
        k = cells[j]
        v[0, k], v[1, k] = va[j], vb[j]
        density[1, k], pressure[1, k] = details[5, j], details[3, j]
        sound_speed[1, k] = np.sqrt(maximum(details[7, j], 0.0))
    if not healthy(new_volume, sound_speed[0], e[0], new_stress, no_values):
        return 1, 0, False
    return 0, iterations, relaxed


@numba.njit(**KERNEL)
def enriched_steps(mesh, boundaries, eos, cell_material, viscosity_law, inverse_node_mass, node_mass, free_nodes,
                   mass, mixed, settings, empty, time_step, held, clock, first, buffers, predicted, impulse,
                   counts):  # pragma: no cover (compiled)
    """Steps of a 1D state with enriched mixed cells on a Lagrangian mesh, as simulate()
    takes them one by one (:func:`enriched_step`; dt and the stops as
    ale_xfem.lagrange.kernels.pure_steps makes them, a mixed cell's sound speed in its CFL
    limit), stopping before a step that is not plain (module docstring).  ``first``: the
    current state and evaluation (:data:`STATE_ARRAYS`, not written); ``buffers``: two
    more such sets to step into, in turn; ``counts`` accumulates the solves, their
    iterations, the most iterations of one, and the relaxations.  Returns (steps taken, t,
    the last dt, least dt, largest dt, the boundary work so far, which of first (0) or
    buffers (1, 2) holds the state reached)."""
    cfl, viscous, acceleration, sound_times, ratios = time_step
    mean_force = held[4]
    t, t_end, dt_previous, growth, budget, steps_left, watch_stall, work, t_stop = clock
    cell_nodes, runs = mesh[0], mesh[1]
    cells = mixed[0]
    tolerance, relaxation = settings[0], settings[3]
    steps, current = 0, 0
    dt_min, dt_max = np.inf, 0.0
    while t < t_end * (1.0 - 1e-14) and steps < budget and steps < steps_left and t < t_stop:
        state = first if current == 0 else (buffers[0] if current == 1 else buffers[1])
        target = 2 if current == 1 else 1
        new = buffers[0] if target == 1 else buffers[1]
        (_, u0, _, _, density, pressure, sound_speed, _, _, volume, evaluated_sound_speed, jump, _, _, force,
         mixed_sound_speed, _, _) = state
        if relaxation:  # a start state out of balance is relaxed by the staged step
            start = np.empty((4, cells.size))
            for j in range(cells.size):
                k = cells[j]
                start[0, j], start[1, j] = pressure[0, k], pressure[1, k]
                start[2, j] = density[0, k] * (sound_speed[0, k] * sound_speed[0, k])
                start[3, j] = density[1, k] * (sound_speed[1, k] * sound_speed[1, k])
            if not balanced_cells(start[0], start[1], start[2], start[3], tolerance):
                break
        dt = stable_time_step(force, inverse_node_mass, boundaries, volume, volume, evaluated_sound_speed, jump,
                              viscous, viscosity_law, cells, mixed_sound_speed, cell_nodes, runs, cfl, acceleration,
                              sound_times, ratios)
        dt = clamped_step(dt, growth * dt_previous, t_end - t)
        if not plain_step(dt, t_end - t, watch_stall, steps_left - steps):
            break
        status, iterations, relaxed = enriched_step(mesh, boundaries, eos, cell_material, viscosity_law,
                                                    inverse_node_mass, node_mass, free_nodes, mass, mixed, settings,
                                                    empty, dt, state, predicted, new, mean_force)
        if status != 0:
            break
        work, t, dt_min, dt_max = account_step(node_mass, held, u0, new[1], predicted[1], mean_force, dt, impulse,
                                               t, work, dt_min, dt_max)
        counts[0] += 1
        counts[1] += iterations
        counts[2] = max(counts[2], iterations)
        counts[3] += 1 if relaxed else 0
        dt_previous = dt
        steps += 1
        current = target
    return steps, t, dt_previous, dt_min, dt_max, work, current


def take_steps(step, closure, state, evaluation, clock: dict, boundary_impulse):
    """The steps of ``state`` (1D, enriched mixed cells, Lagrangian mesh) that
    :func:`enriched_steps` can take, as ExplicitWilkins.pure_steps takes those of pure
    cells (the same ``clock`` and results): (steps taken, state, evaluation, last dt,
    least dt, largest dt, boundary work, boundary impulse).  The mixed cells' statistics
    and the stepper's count of interface solves follow the steps; their time counts in
    the step's (one compiled call)."""
    mixed = closure.mixed
    n, n_nodes, m = step.mesh.n_cells, step.mesh.n_nodes, mixed.cells.size
    floats = np.ascontiguousarray
    interface_velocity = np.zeros(m) if state.interface_velocity is None else state.interface_velocity
    first = [floats(a, dtype=float) for a in (
        state.node_position, state.node_velocity, state.material_energy, state.material_volume,
        state.material_density, state.material_pressure, state.material_sound_speed, state.interface_pressure,
        interface_velocity, evaluation.volume, evaluation.sound_speed[0], evaluation.velocity_jump,
        evaluation.viscosity, evaluation.stress, evaluation.nodal_force, evaluation.mixed_sound_speed,
        evaluation.mixed_viscosity, np.empty(m))]

    # the nodal velocities may have more components than the mesh's one (a transverse
    # velocity, carried along: paper §3.1)
    velocity_shape = state.node_velocity.shape

    def state_set():
        arrays = [np.empty((1, n_nodes)), np.empty(velocity_shape)] + [np.zeros((2, n)) for _ in range(5)] + [
            np.empty(m), np.empty(m), np.empty(n), None, np.empty(n), np.empty(n), np.empty(n),
            np.empty((1, n_nodes)), np.empty(m), np.empty(m), np.empty(m)]
        arrays[10] = arrays[6][0]  # the evaluation's sound speeds are the state's slot 0
        return tuple(arrays)
    buffers = (state_set(), state_set())
    predicted = tuple([np.empty(velocity_shape), np.empty(velocity_shape), np.empty((1, n_nodes)), np.empty(n),
                       np.empty(m), np.empty(m)]
                      + [np.empty(n) for _ in range(7)] + [np.empty((1, n_nodes)), np.empty(m), np.empty(m),
                                                            np.empty(m)])
    index = lambda values: np.ascontiguousarray(values, dtype=np.int64)  # noqa: E731
    mixed_arrays = (index(mixed.cells), index(mixed.node_left), index(mixed.node_right),
                    *closure.equilibrium.sides, floats(mixed.max_density_left, dtype=float),
                    floats(mixed.max_density_right, dtype=float))
    settings = (float(mixed.tolerance), int(mixed.max_iterations), bool(mixed.nonlinear), bool(mixed.relaxation))
    empty = (step.no_shape, step.no_values, np.empty((2, 0)))
    held = step.held_nodes
    impulse = np.array(boundary_impulse, dtype=float)
    counts = np.zeros(4, dtype=np.int64)
    steps, t, dt_previous, dt_min, dt_max, work, current = enriched_steps(
        (step.cell_nodes, step.runs, step.scatter_mode, step.corner_is_run, step.scratch), step.held,
        step.eos_tables, step.pure_layout.cell_material[0], step.viscosity_law, step.inverse_node_mass,
        step.node_mass, step.free_nodes, floats(state.material_mass, dtype=float), mixed_arrays, settings, empty,
        (float(step.numerics.cfl), step.viscous_time_step, np.empty((1, n_nodes)), np.empty(n), np.empty(n)),
        (held, np.empty(2 * held.size), step.sum_stack, step.sum_partial, np.empty((1, n_nodes))),
        (float(state.time), float(clock["t_end"]), float(clock["dt_previous"]), float(clock["growth"]),
         int(clock["budget"]), int(clock["steps_left"]), bool(clock["watch_stall"]), float(clock["boundary_work"]),
         float(clock.get("t_stop", np.inf))),
        tuple(first), buffers, predicted, impulse, counts)
    stats = mixed.stats
    stats["steps"] += int(counts[0])
    stats["iterations"] += int(counts[1])
    stats["max_iterations"] = max(stats["max_iterations"], int(counts[2]))
    stats["relaxations"] += int(counts[3])
    step.mixed_calls += int(counts[0])
    if steps == 0:
        return 0, state, evaluation, dt_previous, dt_min, dt_max, work, impulse
    (x, u, energy, volumes, density, pressure, sound_speed, interface_pressure, interface_velocity, volume, _, jump,
     viscosity, stress, nodal_force, mixed_sound_speed, mixed_viscosity, _) = buffers[current - 1]
    new_state = state.evolved(
        time=t, node_position=x, node_velocity=u, material_energy=energy, material_volume=volumes,
        material_density=density, material_pressure=pressure, material_sound_speed=sound_speed,
        interface_pressure=interface_pressure, interface_velocity=interface_velocity)
    new_evaluation = ForceEvaluation(volume, step.no_shape, density, pressure, sound_speed, viscosity, jump, stress,
                                     None, nodal_force, mixed_sound_speed, mixed_viscosity, volume)
    return steps, new_state, new_evaluation, dt_previous, dt_min, dt_max, work, impulse
