"""The command line end to end: outputs, exit codes, breakdown, list and bench."""

import csv
import json
import os
import subprocess
import sys
import tomllib

import numpy as np
import pytest

from ale_xfem.lagrange.interval_steps import BLOCK_CELLS
from ale_xfem.cli import main
from ale_xfem.scene import load_scene, resolve_scene_path

CAVITATION = """
name = "cavitation"
dimension = 1
t_end = 1e-3
[mesh]
extent = [0.0, 1.0]
cells = 50
[materials.water]
eos = "stiffened_gas"
gamma = 4.4
p_inf = 6.0e8
[[regions]]
material = "water"
interval = [0.0, 0.5]
density = 1000.0
pressure = 1.0e5
velocity = [-2000.0]
[[regions]]
material = "water"
interval = [0.5, 1.0]
density = 1000.0
pressure = 1.0e5
velocity = [2000.0]
[boundaries]
left = "free"
right = "free"
"""


def cli(*args):
    return subprocess.run([sys.executable, "-m", "ale_xfem.cli", *args], capture_output=True, text=True)


def test_run_writes_summary_profile_plot_and_resolved_scene(tmp_path):
    out = tmp_path / "run"
    done = cli("run", "sod-two-gamma", "--out", str(out), "--set", "mesh.cells=100")
    assert done.returncode == 0, done.stderr
    summary = json.loads((out / "summary.json").read_text())
    for key in ("scene", "status", "t_end", "steps", "wall_seconds", "zone_cycles_per_second",
                "effects", "conservation", "errors"):
        assert key in summary
    assert summary["status"] == "ok" and summary["t_end"] == 0.2 and summary["steps"] > 50
    assert set(summary["conservation"]) >= {"mass", "momentum", "total_energy"}
    assert summary["errors"]["L1_density"] < 0.01
    assert "artificial_viscosity" in summary["effects"]
    with (out / "profile.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert list(rows[0]) == ["x_left", "x_right", "material", "volume_fraction", "density",
                             "velocity", "pressure", "internal_energy"]
    assert len(rows) == 100
    x_left = [float(r["x_left"]) for r in rows]
    assert x_left == sorted(x_left)
    assert {r["material"] for r in rows} == {"left", "right"}
    # Mass from the profile equals the initial mass: 1·0.5 + 0.125·0.5.
    mass = sum(float(r["density"]) * (float(r["x_right"]) - float(r["x_left"])) for r in rows)
    assert mass == pytest.approx(0.5625, rel=1e-13)
    assert (out / "sod-two-gamma.png").stat().st_size > 10_000
    resolved = tomllib.loads((out / "scene.toml").read_text())
    assert resolved["mesh"]["cells"] == 100 and resolved["numerics"]["cfl"] == 0.5
    assert load_scene(out / "scene.toml").mesh.cells == 100  # the resolved scene runs as is


@pytest.mark.parametrize("cells", [50, 2 * BLOCK_CELLS + 3])  # (one gas: a step's stages whole, or in blocks)
def test_breakdown_stops_with_exit_code_3_and_writes_the_last_good_state(tmp_path, cells):
    scene = tmp_path / "cavitation.toml"
    scene.write_text(CAVITATION.replace("cells = 50", f"cells = {cells}"))
    out = tmp_path / "run"
    done = cli("run", str(scene), "--out", str(out))
    assert done.returncode == 3
    message = done.stderr.strip().splitlines()
    assert len(message) == 1
    assert "step 1" in message[0] and "cell" in message[0] and "sound speed" in message[0]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed" and "sound speed" in summary["diagnostic"]
    assert summary["t_reached"] < summary["t_end"]
    with (out / "profile.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == cells and all(float(r["density"]) > 0 for r in rows)


def test_run_reports_a_slip_lines_velocity_errors_along_the_normal_and_the_contact(tmp_path, capsys):
    assert main(["run", "slip-line", "--set", "mesh.cells=[8,8]", "--no-plot", "--frames", "0",
                 "--out", str(tmp_path)]) == 0
    line = next(row for row in capsys.readouterr().out.splitlines() if row.startswith("slip-line:"))
    errors = json.loads((tmp_path / "summary.json").read_text())["errors"]
    assert f"along the normal {errors['L1_normal_velocity']:.3e}" in line
    assert f"along the contact {errors['L1_tangential_velocity']:.3e}" in line


def test_list_shows_every_shipped_scene_with_its_description(capsys):
    assert main(["list"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    names = {line.split()[0] for line in lines}
    assert {"sod", "sod-two-gamma", "plate-impact", "water-air", "piston", "blast-symmetric"} <= names
    assert all(len(line.split(maxsplit=1)) == 2 for line in lines)
    # the descriptions start in one column, after the longest name and two spaces
    entries = [line for line in lines if line.startswith("  ")]
    starts = {len(line) - len(line[2:].split(maxsplit=1)[1]) for line in entries}
    assert len(starts) == 1 and starts.pop() == 2 + max(len(line.split()[0]) for line in entries) + 2


def test_bench_prints_zone_cycles_per_second(capsys):
    assert main(["bench", "--cells", "1000,2000"]) == 0
    rows = [line.split() for line in capsys.readouterr().out.splitlines() if line.strip()[:1].isdigit()]
    assert [int(r[0]) for r in rows] == [1000, 2000]
    for cells, _, called, run, rate, numpy_step, ratio, spread in rows:
        assert float(called) > 0 and float(run) > 0 and float(numpy_step) > 0
        # the run's rate is its cells over its time a step (printed to 0.1 µs: at 10³ cells a
        # step of 6 µs carries 0.8 % of rounding; the rate 4 digits); the ratio numpy / run is
        # the median of the rounds', within its range
        assert float(rate) == pytest.approx(int(cells) / (float(run) * 1e-6), rel=0.05 / float(run) + 1e-3)
        low, high = (float(v) for v in spread.split("–"))
        assert 0 < low <= float(ratio) <= high


@pytest.mark.parametrize("cell_type, mesh", [(None, "quadrilaterals"),
                                             ("triangle", "squares of four crossed triangles")])
def test_bench_enriched_prints_each_closure_by_phase(cell_type, mesh, capsys):
    """`bench --enriched --cells N [--cell-type triangle]`: the sheared tube on N × N cells
    (quadrilaterals, or squares of crossed triangles), one velocity field and the enriched
    cells with bubbles, with Nitsche and with bubbles and the linearised law, a row each
    with the mixed cells' column zero only for one velocity field and the ratio 1 for it;
    the mixed cells counted on that mesh."""
    from ale_xfem.problem import build_problem

    assert main(["bench", "--enriched", "--cells", "10", *(["--cell-type", cell_type] if cell_type else [])]) == 0
    out = capsys.readouterr().out
    assert f"on side × side {mesh};" in out
    rows = [line.split() for line in out.splitlines() if line.strip()[:1].isdigit()]
    assert len(rows) == 4 and all(r[0] == "10" for r in rows)
    problem = build_problem(load_scene(resolve_scene_path("rotated-tube-shear"),
                                       ["mesh.cells=[10,10]", f"mesh.cell_type={cell_type or 'quadrilateral'}"]))
    assert all(int(r[1]) == problem.mixed.cells.size for r in rows)
    reference, bubbles, nitsche, linearised = rows  # ... lagrange, mixed, remap, total, ratio, range
    assert " ".join(reference[2:-6]) == "one velocity field" and float(reference[-5]) == 0.0
    assert float(reference[-2]) == 1.0
    assert " ".join(bubbles[2:-6]) == "enriched, bubbles" and " ".join(nitsche[2:-6]) == "enriched, Nitsche"
    assert " ".join(linearised[2:-6]) == "bubbles, linearised"
    assert float(bubbles[-5]) > 0.0 and float(nitsche[-5]) > 0.0 and float(linearised[-5]) > 0.0


@pytest.mark.parametrize("cell_type, mesh", [(None, "quadrilaterals"),
                                             ("triangle", "squares of four crossed triangles")])
def test_bench_phases_2d_prints_what_the_remap_adds_on_either_cell_type(cell_type, mesh, capsys):
    """`bench --phases --dimension 2 --cells N [--cell-type triangle]`: the rotated tube on N
    × N cells, Lagrangian, Eulerian and smoothed, a row each; the Lagrangian run has no
    remap (its ratios 0), the remapped runs a remap column and what the remap adds above 0,
    each median within its rounds' range."""
    assert main(["bench", "--phases", "--dimension", "2", "--cells", "10",
                 *(["--cell-type", cell_type] if cell_type else [])]) == 0
    out = capsys.readouterr().out
    assert f"10 × 10 {mesh};" in out
    rows = [line.split() for line in out.splitlines() if line.startswith("rotated two-material tube")]
    assert len(rows) == 3
    (_, _, _, _, lagrangian_remap, _, lagrangian_column, _, lagrangian_added, _), *remapped = (r[-10:] for r in rows)
    assert float(lagrangian_remap) == 0.0 and float(lagrangian_column) == 0.0 and float(lagrangian_added) == 0.0
    for _, _, _, remap, total, column, column_range, added, added_range in (r[-9:] for r in remapped):
        assert float(remap) > 0.0 and float(total) > float(remap)
        for value, spread in ((column, column_range), (added, added_range)):
            low, high = (float(v) for v in spread.split("–"))
            assert 0.0 < low <= float(value) <= high


def test_phase_ratios_pair_runs_of_the_same_round():
    """A machine that slows down between rounds must not bias the ratios: each round's case
    is divided by the same round's reference (here the true ratio is 1.5 in every round)."""
    from ale_xfem.studies.bench import _fastest, _interleaved, _ratios

    clock = iter(range(100))
    speed = [1.0, 1.0, 1.6, 1.6, 1.2, 1.2]  # the machine's pace, one entry per timed run
    cases = [lambda: {"total": 1.0 * speed[next(clock)]}, lambda: {"total": 1.5 * speed[next(clock)]}]
    runs = _interleaved(cases, rounds=3)
    assert [t["total"] for t in runs[0]] == [1.0, 1.6, 1.2]
    assert _ratios(runs[1], runs[0]) == pytest.approx((1.5, 1.5, 1.5))
    assert _fastest(runs[1])["total"] == 1.5
    # what the second case adds to the first, per round: 0.5 × the first
    assert _ratios(runs[1], runs[0], less_runs=runs[0]) == pytest.approx((0.5, 0.5, 0.5))


def test_bench_plic_prints_both_normals(capsys):
    """`bench --plic --cells N`: one reconstruction of the rotated tube's mixed cells on N ×
    N cells with each normal; LVIRA's turn Youngs' (by a little: their mean change of angle
    is below 5°, and not zero on quadrilaterals)."""
    assert main(["bench", "--plic", "--cells", "24"]) == 0
    lines = capsys.readouterr().out.splitlines()
    rows = {line.split()[0]: line.split()[1:] for line in lines if line.split()[:1] in (["youngs"], ["lvira"])}
    assert set(rows) == {"youngs", "lvira"} and all(float(v) >= 0 for r in rows.values() for v in r)
    assert float(rows["youngs"][2]) == 0.0 and 0.0 < float(rows["lvira"][2]) < 5.0


def test_compile_seconds_count_what_compiles_while_the_problem_is_built(tmp_path, monkeypatch):
    """summary.json's compile_seconds is the compiling the whole command did, building the
    problem included (its kernels compile there too: 38.5 s of a first 2D run's 41 s, where
    the run alone counted 1.8 s), read from the process's compile clock before the build
    and after the run."""
    import ale_xfem.lagrange.compile_clock as compile_clock
    import ale_xfem.problem as problem_package

    # a build that compiles for 1000 s, as far as the compile clock can tell
    extra, clock, build = [0.0], compile_clock.compile_seconds, problem_package.build_problem
    monkeypatch.setattr(compile_clock, "compile_seconds", lambda: clock() + extra[0])

    def compiling_build(scene):
        built = build(scene)
        extra[0] = 1000.0
        return built

    monkeypatch.setattr(problem_package, "build_problem", compiling_build)
    out = tmp_path / "out"
    assert main(["run", "sod", "--set", "mesh.cells=20", "--quiet", "--no-plot", "--out", str(out)]) == 0
    assert 1000.0 <= json.loads((out / "summary.json").read_text())["compile_seconds"] < 1300.0


def test_bench_runs_the_sizes_given_even_when_they_are_the_1d_default(monkeypatch):
    """``--cells`` given is what runs; without it each mode has its own sizes (the 2D loop
    10⁴ to 10⁶ zones), also when the sizes given are written as the 1D default."""
    import ale_xfem.studies.bench as bench

    runs = []
    monkeypatch.setattr(bench, "run_bench", lambda sizes, scene="sod": runs.append((list(sizes), scene)))
    assert main(["bench", "--dimension", "2", "--cells", "1000,10000,100000,1000000"]) == 0
    assert main(["bench", "--dimension", "2"]) == 0
    assert main(["bench"]) == 0
    assert runs == [([1000, 10000, 100000, 1000000], "sod-2d"), ([10000, 100000, 1000000], "sod-2d"),
                    ([1000, 10000, 100000, 1000000], "sod")]


def test_bench_rejects_bad_sizes(capsys):
    assert main(["bench", "--cells", "10,x"]) == 2


@pytest.mark.parametrize("argv, message", [
    (["--plic", "--enriched"], "error: --enriched --plic: one of them at a time"),
    (["--phases", "--ranks", "1,2"], "error: --phases --ranks: one of them at a time"),
    (["--cells", "1000", "--out", "{out}"], "error: --out = {out}: acts with --peers only"),
])
def test_bench_rejects_options_that_cannot_act_together(argv, message, capsys, tmp_path):
    """Two benches at once, or an output folder for a bench that writes none: one line,
    exit 2, nothing run or made (they were silently one of them, or ignored)."""
    out = tmp_path / "never"
    assert main(["bench", *[a.format(out=out) for a in argv]]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.startswith(message.format(out=out)), captured.err
    assert captured.err.count("\n") == 1 and not out.exists()


@pytest.mark.parametrize("argv", [["--cell-type", "triangle"], ["--plic", "--cell-type", "triangle"],
                                  ["--peers", "--cell-type", "quadrilateral"], ["--phases", "--cell-type", "triangle"]])
def test_bench_rejects_a_cell_type_without_the_enriched_bench(argv, capsys):
    """--cell-type acts on `bench --enriched` and `bench --phases --dimension 2` only:
    elsewhere (the 1D phases among them) one line, exit 2, nothing run."""
    assert main(["bench", *argv]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.startswith(f"error: --cell-type = {argv[-1]!r}: acts with --enriched or --phases "
                                   "--dimension 2 only")
    assert captured.err.count("\n") == 1


def test_xt_writes_the_diagram_with_one_row_per_recorded_step(tmp_path):
    from ale_xfem.output.plots import XTHistory
    from ale_xfem.problem import build_problem
    from ale_xfem.run import simulate
    from ale_xfem.scene import resolve_scene_path

    assert main(["run", "sod", "--set", "mesh.cells=60", "--xt", "--no-plot", "--quiet", "--out",
                 str(tmp_path)]) == 0
    assert (tmp_path / "sod-xt.png").stat().st_size > 10_000
    history = XTHistory(max_rows=50)
    result = simulate(build_problem(load_scene(resolve_scene_path("sod"), ["mesh.cells=60"])),
                      observe=history.observe)
    assert len(history.times) <= 51 and history.times[0] == 0.0  # thinned, from t = 0
    assert history.edges[0].size == 61 and history.densities[0].size == 60
    assert result.steps + 1 > len(history.times)  # every step observed, rows thinned


@pytest.mark.parametrize("argv, message", [
    (["run", "sod", "--frames", "3"], "error: --frames = 3: the VTK series is for 2D scenes"),
    (["run", "noh", "--xt"], "error: --xt: the x–t diagram is for 1D scenes"),
    (["run", "noh", "--frames", "-1"], "error: --frames = -1: an integer >= 0"),
])
def test_a_run_option_that_cannot_act_in_the_scene_is_an_error(argv, message, capsys, tmp_path):
    """An option for the other dimension's outputs exits 2 with one line and writes nothing
    (``--frames 0``, which asks for none, is accepted by any scene)."""
    assert main([*argv, "--quiet", "--no-plot", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(message) and err.count("\n") == 1, err
    assert not (tmp_path / "out").exists()


def test_an_output_folder_that_cannot_be_written_is_an_error_before_the_run(capsys, tmp_path):
    """``--out`` naming a file, or a folder that cannot be made, exits 2 with one line before
    anything runs (after the run its results would be lost)."""
    in_the_way = tmp_path / "a-file"
    in_the_way.write_text("kept\n")
    for out in (in_the_way, in_the_way / "below"):
        assert main(["run", "sod", "--set", "mesh.cells=20", "--quiet", "--no-plot", "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"error: --out = {out}: cannot make that folder") and err.count("\n") == 1, err
    assert in_the_way.read_text() == "kept\n"


def test_a_run_replaces_an_earlier_runs_outputs_of_its_scene_and_nothing_else(tmp_path):
    """The output folder holds one run's outputs: what an earlier run of the scene wrote
    there and this one does not (its plot under ``--no-plot``, its x–t diagram, frames) is
    removed before the run; other files, other scenes' outputs included, are kept."""
    out = tmp_path / "out"
    (out / "sod-cells.bp").mkdir(parents=True)
    earlier = ["sod.png", "sod-xt.png", "sod_0003.vtu", "sod.pvd", "summary.json"]
    kept = ["notes.txt", "noh.png", "sod_3.vtu", "sod.png.bak"]
    for name in earlier + kept:
        (out / name).write_text("earlier\n")
    assert main(["run", "sod", "--set", "mesh.cells=20", "--quiet", "--no-plot", "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == sorted(kept + ["profile.csv", "scene.toml", "summary.json"])
    assert json.loads((out / "summary.json").read_text())["cells"] == 20


@pytest.mark.parametrize("argv, command", [
    (["run", "sod", "--bogus"], "ale-xfem run"),
    (["study", "stability", "--output", "x"], "ale-xfem study stability"),
    (["study", "accuracy", "sod", "--zz"], "ale-xfem study accuracy"),
    (["bench", "--foo", "1"], "ale-xfem bench"),
])
def test_an_unknown_option_is_reported_with_the_usage_of_its_command(argv, command, capsys, tmp_path,
                                                                      monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as stop:
        main(argv)
    err = capsys.readouterr().err
    assert stop.value.code == 2
    assert f"usage: {command} " in err
    assert err.strip().splitlines()[-1].startswith(f"{command}: error: unrecognized arguments:")
    assert not any(tmp_path.iterdir())  # nothing ran, nothing written


def test_the_progress_bar_reports_simulated_time_and_steps_and_is_silent_when_redirected(capsys):
    """A tqdm bar in simulated time (it was written by hand): on when asked, off when stderr
    is not a terminal and nobody asked."""
    from ale_xfem.problem import build_problem
    from ale_xfem.run import Progress, simulate

    problem = build_problem(load_scene(resolve_scene_path("sod"), ["mesh.cells=50"]))
    result = simulate(problem, Progress(problem.scene.t_end, enabled=True))
    shown = capsys.readouterr().err
    assert "t = 0.2 / 0.2" in shown and f"step {result.steps}" in shown and "100%" in shown
    simulate(build_problem(problem.scene), Progress(problem.scene.t_end))  # stderr is captured: not a terminal
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("scene, overrides, output", [
    ("sod", ["mesh.cells=20"], "profile.csv"),
    ("sod-two-gamma-enriched", ["mesh.cells=40", "mesh.motion=eulerian"], "profile.csv"),
    ("sod-2d", ["mesh.cells=[6,6]"], "cells.csv"),
    ("noh", ["mesh.cells=[6,6]", "mesh.cell_type=triangle"], "cells.csv"),
    ("rotated-tube-shear", ["mesh.cells=[8,8]", "interface.model=enriched", "t_end=0.2"], "cells.csv"),
    ("rotated-tube-shear", ["mesh.cells=[6,6]", "mesh.cell_type=triangle", "interface.model=enriched",
                            "interface.stabilisation=nitsche", "t_end=0.2"], "cells.csv"),
])
def test_the_kernels_run_as_plain_python_with_the_compiled_results(tmp_path, scene, overrides, output):
    """NUMBA_DISABLE_JIT=1 (the way to step through a kernel in a debugger, README) runs
    every compiled kernel as plain Python: the runs it makes — 1D, an enriched interface
    through the swept remap, quadrilaterals with hourglass control, triangles, 2D enriched
    cells (their cut geometry, cut weights, interface solve and per-material remap) — write
    the same bytes as the compiled kernels'."""
    files = {}
    for label, environment in (("compiled", {}), ("python", {"NUMBA_DISABLE_JIT": "1"})):
        out = tmp_path / label
        args = ["run", scene, *(a for o in overrides for a in ("--set", o)), "--quiet", "--no-plot", "--out", str(out)]
        if load_scene(resolve_scene_path(scene)).dimension == 2:
            args += ["--frames", "0"]
        done = subprocess.run([sys.executable, "-m", "ale_xfem.cli", *args], capture_output=True, text=True,
                              env={**os.environ, **environment})
        assert done.returncode == 0, done.stderr
        files[label] = (out / output).read_bytes()
    assert files["python"] == files["compiled"]


def test_a_runs_timings_leave_out_compiling_kernels(tmp_path, monkeypatch):
    """A kernel compiled during a run (here a fresh one, at the first step) is no part of the
    run's time: summary.json's wall_seconds and phases leave it out and compile_seconds
    holds it (on a fresh install the first run of Sod compiled its kernels for 9.9 s, where
    the run itself, its kernels' loading included, took 0.03 s)."""
    import numba

    import ale_xfem.run as run
    from ale_xfem.lagrange.compile_clock import compile_seconds

    @numba.njit
    def fresh(x):  # compiled at its first call
        return np.sqrt(np.abs(x)) + np.sum(np.cumsum(np.arange(3.0)))

    step = run._step

    def compiling_step(*args):
        fresh(1.0)
        return step(*args)

    command = ["run", "sod-two-gamma-enriched", "--set", "mesh.cells=40", "--set", "t_end=0.01", "--set",
               "mesh.motion=eulerian", "--no-plot", "--quiet", "--out"]
    # once first: what the set-up compiles (before the run's clock starts) compiled or loaded,
    # whatever ran in this process before (with a cold cache it added 0.66 s to the delta)
    assert main(command + [str(tmp_path / "first")]) == 0
    monkeypatch.setattr(run, "_step", compiling_step)
    before = compile_seconds()
    assert main(command + [str(tmp_path)]) == 0
    compiled = compile_seconds() - before
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert compiled > 0.02 and summary["compile_seconds"] == pytest.approx(compiled, rel=1e-9)
    assert summary["wall_seconds"] < compiled
    assert sum(summary["phase_seconds"].values()) == pytest.approx(summary["wall_seconds"], rel=1e-9)
