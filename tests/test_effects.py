"""Effects: a scene builds only what its keys ask for; what is off is not built and
changes nothing."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ale_xfem.problem import build_problem
from ale_xfem.run import simulate
from ale_xfem.scene import SceneError, load_scene, resolve_scene_path
from ale_xfem.scene.effects import scene_effects

STATE_ARRAYS = ("node_position", "node_velocity", "material_mass", "material_energy", "material_volume",
                "material_density", "material_pressure", "material_sound_speed")


def _scene_file(tmp_path, name, extra="", replace=()):
    text = resolve_scene_path(name).read_text()
    for old, new in replace:
        assert old in text
        text = text.replace(old, new)
    path = tmp_path / f"{name}-variant.toml"
    path.write_text(text + extra)
    return path


def _run(path, *overrides, steps=60):
    problem = build_problem(load_scene(path, ["mesh.cells=80", *overrides]))
    return problem, simulate(problem, stop_after_steps=steps)


def _assert_bit_identical(a, b):
    for name in STATE_ARRAYS:
        assert np.array_equal(getattr(a.state, name), getattr(b.state, name)), name
    assert a.steps == b.steps and a.state.time == b.state.time


@pytest.fixture
def counters(monkeypatch):
    """Count mixed-cell solvers, remappers and form compilations made during a test."""
    import dolfinx_solver  # noqa: F401  (before dolfinx: it loads MPI and PETSc)
    import dolfinx.jit

    import ale_xfem.model.mixed_cells
    import ale_xfem.remap.remapper_1d

    counts = {"mixed_cell_solvers": 0, "remappers": 0, "compiled_forms": 0}

    def counting(cls, key):
        original = cls.__init__

        def init(self, *args, **kwargs):
            counts[key] += 1
            original(self, *args, **kwargs)
        monkeypatch.setattr(cls, "__init__", init)

    counting(ale_xfem.model.mixed_cells.MixedCells, "mixed_cell_solvers")
    counting(ale_xfem.remap.remapper_1d.Remapper, "remappers")
    jit = dolfinx.jit.ffcx_jit

    def counting_jit(*args, **kwargs):
        counts["compiled_forms"] += 1
        return jit(*args, **kwargs)
    monkeypatch.setattr(dolfinx.jit, "ffcx_jit", counting_jit)
    return counts


def test_a_scene_without_interface_builds_no_mixed_cell_solver_and_compiles_no_form(counters):
    problem, result = _run(resolve_scene_path("sod-two-gamma"))
    assert result.status == "ok" and result.steps == 60
    assert counters == {"mixed_cell_solvers": 0, "remappers": 0, "compiled_forms": 0}
    assert problem.effects == ["lagrange_explicit", "artificial_viscosity"]


def test_the_counters_do_count(counters):
    """The same counters see the solver, the remapper and the forms when the scene asks."""
    problem, result = _run(resolve_scene_path("sod-two-gamma-enriched"), "mesh.motion=eulerian",
                           "interface.predictor=assembled", steps=3)
    assert result.status == "ok"
    assert counters["mixed_cell_solvers"] >= 1 and counters["remappers"] == 1
    assert counters["compiled_forms"] >= 1


def test_an_interface_table_with_the_interface_on_a_node_changes_nothing(tmp_path, counters):
    """[interface] asks for mixed cells, but a node-aligned interface makes none: nothing is
    built (not even the forms of the assembled predictor) and the run is bit-identical."""
    plain = _run(resolve_scene_path("sod-two-gamma"))[1]
    path = _scene_file(tmp_path, "sod-two-gamma",
                       '\n[interface]\nmodel = "enriched"\npredictor = "assembled"\nrelaxation = true\n')
    problem, with_table = _run(path)
    _assert_bit_identical(plain, with_table)
    assert counters == {"mixed_cell_solvers": 0, "remappers": 0, "compiled_forms": 0}
    off = {e.name: e for e in problem.effect_table}
    assert not off["mixed_cells_enriched"].on and "on a node" in off["mixed_cells_enriched"].why


def test_remap_keys_of_a_lagrangian_scene_are_errors_and_left_out_of_its_resolved_scene(tmp_path, counters):
    """mesh.motion = "lagrangian" with a remap order written out: the key cannot act (nothing
    is remapped), so the scene is refused, naming it, before anything runs; without it no
    remapper is built, and the resolved scene holds no remap key (it runs as is)."""
    path = _scene_file(tmp_path, "sod", "\n[numerics]\nremap_order = 1\n")
    with pytest.raises(SceneError) as error:
        load_scene(path, ["mesh.motion=lagrangian"])
    assert error.value.key == "numerics.remap_order" and "mesh.motion" in str(error.value)
    problem, _ = _run(resolve_scene_path("sod"), "mesh.motion=lagrangian")
    assert counters["remappers"] == 0 and not any(name.startswith("remap") for name in problem.effects)
    assert not {"remap_order", "remap_energy"} & set(problem.scene.resolved["numerics"])
    eulerian = load_scene(resolve_scene_path("sod"), ["mesh.motion=eulerian"]).resolved["numerics"]
    assert (eulerian["remap_order"], eulerian["remap_energy"]) == (2, "total")


@pytest.mark.parametrize("override, key", [
    ("numerics.hourglass=0.2", "numerics.hourglass"),  # intervals have no hourglass modes
    ("numerics.viscous_time_step=false", "numerics.viscous_time_step"),  # 2D only
    ("numerics.interface_tolerance=1e-8", "numerics.interface_tolerance"),  # no [interface]
    ("numerics.remap_energy=internal", "numerics.remap_energy"),  # nothing remapped
])
def test_numerics_keys_that_cannot_act_in_a_1d_tube_are_errors(override, key):
    with pytest.raises(SceneError) as error:
        load_scene(resolve_scene_path("sod"), [override])
    assert error.value.key == key


@pytest.mark.parametrize("scene, overrides, why", [
    ("sod-two-gamma-enriched", ["mesh.motion=eulerian"], "a 1D mesh"),  # the 1D remap leaves no traces
    ("sod-2d", ["mesh.motion=eulerian"], "no [interface] table"),  # one material
    ("rotated-tube", ["mesh.motion=lagrangian", "interface.model=single_velocity"], "nothing is remapped"),
])
def test_the_trace_fraction_acts_only_in_a_2d_remap_with_an_interface(scene, overrides, why):
    """numerics.trace_fraction: where a 2D remap leaves a material below it in a cell (the
    remapper's traces) — an error elsewhere, naming why; left out of the resolved scene where
    it cannot act, and the remapper takes the scene's value where it can."""
    from ale_xfem.remap.remapper_2d import Remapper2D

    with pytest.raises(SceneError) as error:
        load_scene(resolve_scene_path(scene), [*overrides, "numerics.trace_fraction=1e-6"])
    assert error.value.key == "numerics.trace_fraction" and why in str(error.value)
    assert "trace_fraction" not in load_scene(resolve_scene_path(scene), overrides).resolved["numerics"]
    for overrides, fraction in (([], 1e-4), (["numerics.trace_fraction=1e-7"], 1e-7)):
        problem = build_problem(load_scene(resolve_scene_path("rotated-tube"), ["mesh.cells=[4,4]",
                                                                                 "mesh.motion=eulerian", *overrides]))
        assert Remapper2D(problem, "eulerian", 2).trace == fraction


def test_the_hourglass_key_on_triangles_is_an_error_and_acts_on_quadrilaterals():
    with pytest.raises(SceneError) as error:
        load_scene(resolve_scene_path("noh"), ["mesh.cell_type=triangle", "numerics.hourglass=0.1"])
    assert error.value.key == "numerics.hourglass" and "triangle" in str(error.value)
    assert "hourglass" not in load_scene(resolve_scene_path("noh"), ["mesh.cell_type=triangle"]).resolved["numerics"]
    assert load_scene(resolve_scene_path("noh"), ["numerics.hourglass=0.1"]).numerics.hourglass == 0.1


def test_a_zero_transverse_velocity_leaves_the_dynamics_bit_identical(tmp_path):
    """Transverse-velocity transport is an effect of its own: switched on by a second
    velocity component, it adds that component and nothing else."""
    plain_problem, plain = _run(resolve_scene_path("sod"))
    path = _scene_file(tmp_path, "sod", replace=[("velocity = [0.0]", "velocity = [0.0, 0.0]")])
    problem, transverse = _run(path)
    assert "transverse_velocity" in problem.effects and "transverse_velocity" not in plain_problem.effects
    assert transverse.state.node_velocity.shape[0] == 2
    for name in STATE_ARRAYS:
        a, b = getattr(plain.state, name), getattr(transverse.state, name)
        assert np.array_equal(a, b[:1] if name == "node_velocity" else b), name
    assert np.all(transverse.state.node_velocity[1] == 0.0)


def test_zero_viscosity_coefficients_switch_the_viscosity_off():
    problem = build_problem(load_scene(resolve_scene_path("sod"),
                                       ["numerics.q_quadratic=0", "numerics.q_linear=0"]))
    assert "artificial_viscosity" not in problem.effects
    from ale_xfem.run import make_stepper

    stepper = make_stepper(problem)
    evaluation = stepper.evaluate_state(problem.state)
    assert not stepper.artificial_viscosity and np.all(evaluation.viscosity == 0.0)


def test_the_viscous_time_step_is_an_effect_of_2d_scenes_with_a_viscosity():
    """On by default in 2D; off with its key or without a viscosity; on a mesh of squares
    (√A equal to the least width) the first step is the same to round-off."""
    def effects(*overrides):
        return build_problem(load_scene(resolve_scene_path("sod-2d"), ["mesh.cells=[20,20]", *overrides])).effects
    assert "viscous_time_step" in effects()
    assert "viscous_time_step" not in effects("numerics.viscous_time_step=false")
    assert "viscous_time_step" not in effects("numerics.q_quadratic=0", "numerics.q_linear=0")
    assert "viscous_time_step" not in build_problem(load_scene(resolve_scene_path("sod"))).effects
    runs = [simulate(build_problem(load_scene(resolve_scene_path("sod-2d"),
                                              ["mesh.cells=[20,20]", f"numerics.viscous_time_step={flag}"])),
                     stop_after_steps=1) for flag in ("true", "false")]
    assert runs[0].state.time == pytest.approx(runs[1].state.time, rel=1e-13)
    for name in ("node_position", "node_velocity", "material_energy"):
        np.testing.assert_allclose(getattr(runs[0].state, name), getattr(runs[1].state, name),
                                   rtol=1e-12, atol=1e-13, err_msg=name)


def test_explain_prints_the_effects_and_their_keys_and_runs_nothing(tmp_path):
    out = tmp_path / "out"
    done = subprocess.run([sys.executable, "-m", "ale_xfem.cli", "run", "--explain", "sod-two-gamma-enriched",
                           "--set", "mesh.motion=eulerian", "--out", str(out)],
                          capture_output=True, text=True, check=True)
    text = done.stdout
    on, off = text.split("switched off")
    for name, key in (("mixed_cells_enriched", "interface.model"), ("remap_eulerian", "mesh.motion"),
                      ("pressure_relaxation", "interface.relaxation"), ("remap_order_2", "numerics.remap_order")):
        line = next(line for line in on.splitlines() if line.strip().startswith(name))
        assert key in line
    assert "transverse_velocity" in off and "mixed_cells_single_velocity" in off
    assert not Path(out).exists()


def test_explain_gives_the_ghost_viscosity_that_holds_2d_enriched_cells():
    """The 2D enriched cells' stabilisation says which weight holds each material's
    velocity beyond its part: its default by cell type (0.3 on quadrilaterals, 1 on
    triangles), or the scene's."""
    for overrides, weight in ((["mesh.cell_type=quadrilateral"], "0.3"), (["mesh.cell_type=triangle"], "1"),
                              (["interface.ghost_viscosity=2.5"], "2.5")):
        scene = load_scene(resolve_scene_path("slip-line"), ["mesh.cells=[8,8]", *overrides])
        line = next(e.why for e in scene_effects(scene, 10, []) if e.name == "interface_stabilisation_bubble")
        assert line.endswith(f"held by interface.ghost_viscosity = {weight})"), line


def test_explain_names_no_interface_key_in_a_scene_without_an_interface_table():
    """A scene without [interface] has no interface.normal to name: PLIC's normals are off
    because it has no mixed cells (a scene with the table says which normal it would take)."""
    why = {scene: next(e.why for e in scene_effects(load_scene(resolve_scene_path(scene), ["mesh.cells=[8,8]"]),
                                                    10, []) if e.name == "interface_normal_lvira")
           for scene in ("sod-2d", "slip-line")}
    assert why["sod-2d"] == "needs mixed cells"
    assert why["slip-line"] == 'interface.normal = "youngs"'
