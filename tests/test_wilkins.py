"""The explicit Wilkins loop in 1D: exact solutions, rates, conservation, symmetry."""

import numpy as np
import pytest

from conftest import fitted_rate, run_scene
from ale_xfem.lagrange.interval_steps import BLOCK_CELLS

SIZES = (100, 200, 400)


class ConvergenceOnRiemannProblem:
    """scikit-fem style: subclasses set the scene; L1(ρ) is fitted over SIZES."""

    scene: str
    expected_rate = 0.8
    l1_density_at_400 = 2.5e-3

    def test_density_converges(self):
        errors = [run_scene(self.scene, f"mesh.cells={n}")[1].errors["L1_density"] for n in SIZES]
        assert fitted_rate(SIZES, errors) >= self.expected_rate, errors
        assert errors[SIZES.index(400)] <= self.l1_density_at_400, errors


class TestSod(ConvergenceOnRiemannProblem):
    scene = "sod"


class TestTwoMaterialTube(ConvergenceOnRiemannProblem):
    scene = "sod-two-gamma"


@pytest.mark.parametrize("scene", ["sod", "sod-two-gamma", "water-air", "blast-symmetric"])
def test_mass_exact_and_total_energy_to_round_off_between_walls(scene):
    problem, result = run_scene(scene, "mesh.cells=200")
    assert result.status == "ok"
    assert result.steps > 100
    assert result.conservation["mass"] == 0.0
    assert abs(result.conservation["total_energy"]) < 1e-12
    assert result.conservation["boundary_work"] == pytest.approx(0.0, abs=1e-12 * abs(
        result.state.material_mass @ result.state.material_energy.T).item())


def test_piston_energy_balance_includes_the_work_of_the_piston():
    problem, result = run_scene("piston")
    assert result.status == "ok"
    # The piston pushes at u = 1 against p ≈ 4/3 behind the shock: it does work.
    assert result.conservation["boundary_work"] > 0.5
    assert abs(result.conservation["total_energy"]) < 1e-12
    # Strong-shock limit (γ = 5/3): density 4 behind a shock of speed 4/3; check the plateau
    # away from the piston (wall heating) and from the shock.
    x = problem.mesh.cell_centroids(result.state.node_position)[:, 0]
    t = result.state.time
    plateau = (x > t + 0.1) & (x < 4.0 / 3.0 * t - 0.05)
    np.testing.assert_allclose(result.state.material_density[0][plateau], 4.0, rtol=0.02)


def test_a_symmetric_problem_stays_symmetric():
    problem, result = run_scene("blast-symmetric")
    x = problem.mesh.cell_centroids(result.state.node_position)[:, 0]
    order = np.argsort(x)
    rho = result.state.material_density[0][order]
    np.testing.assert_allclose(x[order] + x[order][::-1], 1.0, atol=1e-12)
    np.testing.assert_allclose(rho, rho[::-1], rtol=1e-11)
    node_x = result.state.node_position[0]
    node_order = np.argsort(node_x)
    u = result.state.node_velocity[0][node_order]
    np.testing.assert_allclose(u, -u[::-1], atol=1e-11 * np.abs(u).max())
    assert np.abs(u).max() > 0.1  # something happened


def test_plate_impact_contact_matches_impedance_matching():
    problem, result = run_scene("plate-impact", "mesh.cells=600")
    assert result.state.time < problem.exact.valid_until
    solution = problem.exact.solution
    x = problem.mesh.cell_centroids(result.state.node_position)[:, 0]
    left_shock, right_shock = (x0 := solution.x0) + np.array(solution.wave_speeds()) * result.state.time
    width = 10 * (problem.scene.mesh.extent[1] - problem.scene.mesh.extent[0]) / problem.scene.mesh.cells
    shocked = (x > left_shock + width) & (x < right_shock - width)
    assert shocked.sum() > 50
    p = result.state.material_pressure[0][shocked]
    np.testing.assert_allclose(p, solution.contact_pressure, rtol=0.02)
    node_x = result.state.node_position[0]
    interface_node = np.argmin(np.abs(node_x - (x0 + solution.contact_velocity * result.state.time)))
    assert result.state.node_velocity[0][interface_node] == pytest.approx(solution.contact_velocity, rel=0.02)


def test_water_air_tube_stays_positive_and_converges():
    errors = []
    for cells in (100, 200, 400):
        problem, result = run_scene("water-air", f"mesh.cells={cells}")
        assert result.status == "ok"
        assert result.state.material_density.min() > 0
        assert (result.state.material_pressure[0] + 6e8 * (problem.layout.cell_material[0] == 0)).min() > 0
        errors.append(result.errors["L1_density"])
    assert fitted_rate((100, 200, 400), errors) > 0.6, errors


@pytest.mark.parametrize("scene, overrides", [
    ("sod", ["mesh.cells=200"]),
    ("sod-2d", ["mesh.cells=[12,12]"]),
    ("noh", ["mesh.cells=[8,8]", "mesh.cell_type=triangle", "t_end=0.1"]),
    ("saltzman", ["mesh.cells=[20,2]", "t_end=0.05"]),
    ("sedov", ["mesh.cells=[10,10]", "mesh.motion=lagrangian", "t_end=0.08"]),
], ids=["sod", "sod-2d", "noh-triangles", "saltzman", "sedov"])
def test_the_compiled_steps_are_the_step_by_step_loop_to_the_bit(scene, overrides):
    """A run of pure cells on a Lagrangian mesh takes its steps in compiled chunks
    (ExplicitWilkins.pure_steps); watched step by step (an observer makes simulate() take
    each step itself) it must give the same steps, states, time steps and conservation
    sums, bit for bit."""
    from ale_xfem.problem import build_problem
    from ale_xfem.run import simulate
    from ale_xfem.scene import load_scene, resolve_scene_path

    runs = []
    for observe in (None, lambda state, problem: None):
        problem = build_problem(load_scene(resolve_scene_path(scene), overrides))
        runs.append(simulate(problem, observe=observe))
    chunked, stepwise = runs
    assert chunked.status == stepwise.status == "ok" and chunked.steps == stepwise.steps > 5
    for name in ("node_position", "node_velocity", "material_energy", "material_density"):
        np.testing.assert_array_equal(getattr(chunked.state, name), getattr(stepwise.state, name))
    assert (chunked.dt_min, chunked.dt_max) == (stepwise.dt_min, stepwise.dt_max)
    assert chunked.conservation == stepwise.conservation


@pytest.mark.parametrize("overrides, steps, diagnostic", [
    (["numerics.max_steps=344"], 344, "numerics.max_steps = 344 reached"),
    (["t_end=20", "numerics.max_steps=5000"], 999, "the time step collapsed"),
], ids=["max-steps", "stalled"])
def test_a_run_too_short_for_t_end_stops_alike_in_compiled_chunks_and_step_by_step(overrides, steps, diagnostic):
    """numerics.max_steps too few to reach t_end: the compiled chunks (one gas: the
    three-stage steps) give back each step the stall watch flags, and the loop stops the
    run as a run watched step by step does — same steps, diagnostic and last state.  Sod on
    200 cells takes 374 steps to t = 0.2: with 344 allowed the watch flags the fifth step
    (the time step still grows from its first value), so a chunk stops in its middle and
    the run ends at max_steps; to t = 20 with 5000 allowed every step is flagged, and the
    run stops when 1000 steps in a row were too small (run.STALLED_STEPS), which only the
    loop counts."""
    from ale_xfem.problem import build_problem
    from ale_xfem.run import simulate
    from ale_xfem.scene import load_scene, resolve_scene_path

    runs = [simulate(build_problem(load_scene(resolve_scene_path("sod"), ["mesh.cells=200", *overrides])),
                     observe=observe) for observe in (None, lambda state, problem: None)]
    chunked, stepwise = runs
    assert chunked.status == stepwise.status == "failed"
    assert chunked.steps == stepwise.steps == steps
    assert chunked.diagnostic == stepwise.diagnostic and diagnostic in chunked.diagnostic
    for name in ("node_position", "node_velocity", "material_energy", "material_density", "time"):
        np.testing.assert_array_equal(getattr(chunked.state, name), getattr(stepwise.state, name))


@pytest.mark.parametrize("scene, overrides", [
    ("sod", ["mesh.cells=150"]),  # one ideal gas between walls
    ("sod", [f"mesh.cells={3 * BLOCK_CELLS + 7}", "t_end=0.01"]),  # blocks of inner cells, the last one short
    ("piston", [f"mesh.cells={2 * BLOCK_CELLS + 2}", "t_end=0.01"]),  # the last block full
    ("sod", [f"mesh.cells={BLOCK_CELLS + 3}", "t_end=0.01"]),  # a last block of one cell
    ("sod", ["mesh.cells=2", "t_end=20.0"]),  # each end's cell is the other's
    ("piston", ["mesh.cells=1", "t_end=20.0"]),  # both ends in one cell
    ("piston", ["mesh.cells=40"]),  # a piston drives one end
    ("sod", ["mesh.cells=80", "materials.gas.eos=stiffened_gas", "materials.gas.p_inf=0.05"]),  # p∞ ≠ 0
    ("sod", ["mesh.cells=80", "boundaries.left=free", "boundaries.right=free"]),  # free ends
    ("blast-symmetric", ["mesh.cells=40", "numerics.q_linear=0.0", "numerics.q_quadratic=0.0"]),
], ids=["sod", "blocks", "full-blocks", "one-cell-block", "two-cells", "one-cell", "piston", "stiffened-gas", "free-ends", "no-viscosity"])
def test_interval_steps_in_three_passes_are_the_staged_steps_to_the_bit(scene, overrides):
    """One gas on intervals numbered along the tube takes its compiled steps in three stages
    over the cells (ale_xfem.lagrange.interval_steps) instead of the staged step's dozen:
    the same steps, time steps, boundary work and impulse, states and evaluations, bit for
    bit.  (Several materials take the staged steps: there they are faster.)"""
    from ale_xfem.lagrange.interval_steps import runs_in_passes
    from ale_xfem.problem import build_problem
    from ale_xfem.run import make_stepper
    from ale_xfem.scene import load_scene, resolve_scene_path

    problem = build_problem(load_scene(resolve_scene_path(scene), overrides))
    stepper = make_stepper(problem)
    assert runs_in_passes(stepper.cell_code, stepper.runs, stepper.scatter_mode, stepper.held_nodes,
                          problem.mesh.n_cells, problem.mesh.n_nodes, 1, stepper.gas_model)
    state = problem.state
    evaluation = stepper.evaluate_state(state)
    clock = {"t_end": problem.scene.t_end, "dt_previous": np.inf, "growth": problem.scene.numerics.dt_growth,
             "budget": 60, "steps_left": 60, "watch_stall": False, "boundary_work": 0.25}
    passes, staged = (stepper.pure_steps(state, evaluation, dict(clock), np.full(1, 0.5), in_passes=flag)
                      for flag in (True, False))
    assert passes[0] == staged[0] > 10
    for a, b in zip(passes[3:], staged[3:]):  # the time steps, the boundary work and impulse
        np.testing.assert_array_equal(a, b)
    for name in ("node_position", "node_velocity", "material_energy", "material_density", "material_pressure",
                 "material_sound_speed", "time"):
        np.testing.assert_array_equal(getattr(passes[1], name), getattr(staged[1], name))
    for name in ("volume", "stress", "viscosity", "velocity_jump", "nodal_force"):
        np.testing.assert_array_equal(getattr(passes[2], name), getattr(staged[2], name))


def test_the_least_of_values_is_the_running_minimum_of_numbers_to_the_bit():
    """kernels.least_of takes the least of values in [+0, +∞] from their bits (read as
    unsigned integers, they order as the numbers do), and of any others as numbers in four
    running minima: both give what the running minima alone give, −0, NaN and +∞ included,
    over any part of an array (+∞ over none)."""
    from ale_xfem.lagrange.kernels import least, least_of

    def running_minima(values):  # the four interleaved running minima, as numbers
        def smaller(a, b):
            return a if a <= b or a != a else b
        minima = [np.inf] * 4
        body = len(values) // 4 * 4
        for k in range(body):
            minima[k % 4] = smaller(minima[k % 4], values[k])
        for k in range(body, len(values)):
            minima[0] = smaller(minima[0], values[k])
        return smaller(smaller(minima[0], minima[1]), smaller(minima[2], minima[3]))

    rng = np.random.default_rng(7)
    specials = [0.0, -0.0, np.inf, -np.inf, np.nan, -1.5, 5e-324, -5e-324, 1.7976931348623157e308]
    for _ in range(2000):
        n = int(rng.integers(0, 30))
        values = rng.random(n) * 10.0 ** rng.integers(-300, 300)
        for special in rng.choice(specials, size=rng.integers(0, 3)):
            if n:
                values[rng.integers(0, n)] = special
        start = int(rng.integers(0, n + 1))
        stop = int(rng.integers(start, n + 1))
        got, expected = least_of(values, start, stop), running_minima(values[start:stop])
        assert np.array_equal(got, expected, equal_nan=True) and np.signbit(got) == np.signbit(expected), (
            values[start:stop], got, expected)
    limits = rng.random(1000) + 1e-3
    assert least(limits) == limits.min() and least(np.zeros(0)) == np.inf


def test_only_one_gas_on_a_plain_tube_takes_its_steps_in_three_stages():
    """The three-stage steps assume one gas, one velocity component, intervals numbered along
    the tube and held nodes at the ends only; anything else takes the staged steps."""
    from ale_xfem.lagrange.interval_steps import runs_in_passes
    from ale_xfem.problem import build_problem
    from ale_xfem.run import make_stepper
    from ale_xfem.scene import load_scene, resolve_scene_path

    def admitted(scene, held=None, components=1, cells=None):
        problem = build_problem(load_scene(resolve_scene_path(scene), ["mesh.cells=20"]))
        stepper = make_stepper(problem)
        mesh = problem.mesh
        return runs_in_passes(stepper.cell_code, stepper.runs, stepper.scatter_mode,
                              stepper.held_nodes if held is None else held,
                              mesh.n_cells if cells is None else cells, mesh.n_nodes, components, stepper.gas_model)

    assert admitted("sod") and admitted("piston")
    assert not admitted("water-air")  # two materials: each cell chooses its model
    assert not admitted("sod-two-gamma")
    assert not admitted("sod", components=2)  # a transverse velocity
    assert not admitted("sod", held=np.array([0, 7], dtype=np.int64))  # a node held inside the tube
    assert not admitted("sod", cells=19)  # nodes the loops would not write
    assert not admitted("sod-2d")


@pytest.mark.parametrize("case", ["sound speed not real", "mesh tangles"])
def test_the_compiled_steps_hand_a_failing_step_to_the_loop_that_names_it(case):
    """A step the compiled steps cannot take stops them before it; the loop then takes it
    and reports it as the step-by-step loop does, with the same last good state: a cell
    whose sound speed is not real (the time step is not a number), and Sedov's blast on a
    Lagrangian quadrilateral mesh, which tangles at its diagonal."""
    from ale_xfem.problem import build_problem
    from ale_xfem.run import simulate
    from ale_xfem.scene import load_scene, resolve_scene_path

    results = []
    for observe in (None, lambda state, problem: None):
        if case == "mesh tangles":
            problem = build_problem(load_scene(resolve_scene_path("sedov"), [
                "mesh.cells=[10,10]", "mesh.motion=lagrangian", "t_end=0.1"]))
        else:
            problem = build_problem(load_scene(resolve_scene_path("sod"), ["mesh.cells=50"]))
            problem.state.material_energy[0, 20] = -1.0  # c² < 0
        results.append(simulate(problem, observe=observe))
    chunked, stepwise = results
    assert chunked.status == stepwise.status == "failed"
    assert chunked.diagnostic == stepwise.diagnostic
    assert ("dt" if case == "sound speed not real" else "tangled") in chunked.diagnostic
    assert chunked.steps == stepwise.steps
    np.testing.assert_array_equal(chunked.state.node_position, stepwise.state.node_position)


def test_frames_written_between_compiled_chunks_are_those_of_the_step_by_step_loop(tmp_path):
    """The VTK series says from which time it wants a state again (observe_from): the steps
    before it run in compiled chunks, each stopping at the first state from that time; the
    frames written (their times) and the run are those of the step-by-step loop."""
    from ale_xfem.output.cells_2d import VTKSeries
    from ale_xfem.problem import build_problem
    from ale_xfem.run import simulate
    from ale_xfem.scene import load_scene, resolve_scene_path

    entries, states = [], []
    for chunked in (True, False):
        problem = build_problem(load_scene(resolve_scene_path("sod-2d"), ["mesh.cells=[12,12]"]))
        series = VTKSeries(problem, tmp_path / str(chunked), frames=7)
        result = simulate(problem, observe=series.observe, observe_from=series.observe_from if chunked else None)
        series.close()
        assert result.status == "ok"
        entries.append([time for time, _ in series.entries])
        states.append(result.state)
    assert entries[0] == entries[1] and len(entries[0]) == 8
    np.testing.assert_array_equal(states[0].node_velocity, states[1].node_velocity)
