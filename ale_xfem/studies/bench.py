"""Zone-cycles per second of the explicit loop (`ale-xfem bench`, `--dimension 2`).

A zone-cycle is one cell advanced by one time step (both stages of the predictor–corrector
included).  The Sod tube (1D; in 2D across a square of quadrilaterals, ``sod-2d``) is run
for a fixed number of steps at each size, after one warm-up step, on one core (numpy's
element-wise kernels are single-threaded)."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ale_xfem.problem import build_problem
from ale_xfem.run import make_stepper
from ale_xfem.scene import load_scene, resolve_scene_path

DEFAULT_SIZES = (1_000, 10_000, 100_000, 1_000_000)


def explicit_loop_rate(cells: int, steps: int, scene: str = "sod", rounds: int = 3) -> dict:
    """``cells``: 1D cells, or in 2D the zones of a square mesh of √cells × √cells.  Times
    ``steps`` steps three ways, in turn within each of ``rounds`` rounds: called one by one
    from Python at a fixed dt (``ExplicitWilkins.step``); as a run takes them (the compiled
    chunks of ``ExplicitWilkins.pure_steps``, each step's dt from the CFL condition); and the
    plain numpy loop of ``benchmarks/`` (:func:`plain_numpy_step`).  Each time is the fastest
    round's, the ratio numpy / run the median of the rounds' own (a ratio of timings taken
    minutes apart would carry the machine's drift), with its range."""
    path = resolve_scene_path(scene)
    size = f"mesh.cells={cells}"
    dimension = load_scene(path).dimension
    if dimension == 2:
        side = int(round(np.sqrt(cells)))
        cells, size = side * side, f"mesh.cells=[{side},{side}]"
    problem = build_problem(load_scene(path, [size]))
    stepper = make_stepper(problem)
    state = problem.state
    evaluation = stepper.evaluate_state(state)
    dt = 0.5 * stepper.stable_time_step(evaluation)
    # a fixed step: the run must stay within the scene's time (the waves then keep within
    # the CFL limit of the start)
    steps = int(max(1, min(steps, problem.scene.t_end / dt - 1)))
    state, evaluation, _, _ = stepper.step(state, dt, evaluation)  # warm-up
    # as a run takes them (ale_xfem.run.simulate): the same number of steps from the same state
    clock_state = {"t_end": problem.scene.t_end, "dt_previous": dt, "growth": problem.scene.numerics.dt_growth,
                   "budget": steps, "steps_left": steps, "watch_stall": False, "boundary_work": 0.0}
    stepper.pure_steps(state, evaluation, dict(clock_state, budget=1), np.zeros(problem.mesh.dimension))  # warm-up
    plain = plain_numpy_loop(dimension)
    called, run, numpy_step, ratios, run_steps = np.inf, np.inf, np.inf, [], 0
    for _ in range(rounds):
        current, current_eval = state, evaluation
        clock = time.perf_counter()
        for _ in range(steps):
            current, current_eval, _, _ = stepper.step(current, dt, current_eval)
        called = min(called, (time.perf_counter() - clock) / steps)
        clock = time.perf_counter()
        taken = stepper.pure_steps(state, evaluation, dict(clock_state), np.zeros(problem.mesh.dimension))[0]
        this_run = (time.perf_counter() - clock) / max(taken, 1)
        if taken and this_run < run:
            run, run_steps = this_run, taken
        if plain is not None:
            this_numpy = plain(cells, min(steps, 50))
            numpy_step = min(numpy_step, this_numpy)
            ratios.append(this_numpy / this_run)
    return {"cells": cells, "steps": steps, "seconds_per_step": called, "zone_cycles_per_second": cells / called,
            "run_steps": run_steps, "run_seconds_per_step": run, "run_zone_cycles_per_second": cells / run,
            "numpy_seconds_per_step": numpy_step if plain is not None else None,
            "numpy_over_run": (float(np.median(ratios)), min(ratios), max(ratios)) if ratios else None}


def steps_for(cells: int, dimension: int = 1) -> int:
    if dimension == 2:  # a 2D zone costs several times a 1D cell
        return int(max(5, min(500, 5e6 // cells)))
    return int(max(10, min(2000, 2e7 // cells)))


BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"


def plain_numpy_loop(dimension: int):
    """The plain numpy loop of the repository's ``benchmarks/`` (the scheme's arithmetic as
    whole-array numpy expressions: 1D plain_1d_remap.py, 2D plain_quad_step.py) as a
    function (cells, steps) → seconds a step (one timing after a warm-up); None outside a
    source checkout."""
    script = BENCHMARKS / ("plain_1d_remap.py" if dimension == 1 else "plain_quad_step.py")
    if not script.is_file():
        return None
    spec = importlib.util.spec_from_file_location(f"plain_{dimension}d", script)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    if dimension == 1:
        return lambda cells, steps: module.cycle_seconds("numpy", cells, steps, repeats=1, eulerian=False)["pure"]
    return lambda cells, steps: module.step_seconds("numpy", cells, steps, repeats=1)[0]


def run_bench(sizes=DEFAULT_SIZES, scene: str = "sod", out=print) -> list[dict]:
    out(f"explicit Wilkins loop, scene '{scene}', one core, fastest of 3 interleaved rounds: steps called from "
        f"Python (fixed dt), steps as a run takes them (compiled chunks, CFL dt), and the plain numpy loop of "
        f"benchmarks/ (the same scheme's arithmetic as whole-array numpy expressions) in the same process; "
        f"numpy/run: median of the rounds' (range)")
    out(f"{'cells':>10} {'steps':>6} {'called us/step':>15} {'run us/step':>12} {'run zone-cycles/s':>18} "
        f"{'numpy us/step':>14} {'numpy/run':>10} {'range':>12}")
    rows = []
    for cells in sizes:
        dimension = load_scene(resolve_scene_path(scene)).dimension
        row = explicit_loop_rate(cells, steps_for(cells, dimension), scene)
        rows.append(row)
        line = (f"{row['cells']:>10d} {row['steps']:>6d} {1e6 * row['seconds_per_step']:>15.1f} "
                f"{1e6 * row['run_seconds_per_step']:>12.1f} {row['run_zone_cycles_per_second']:>18.3e} ")
        if row["numpy_over_run"] is None:
            out(line + f"{'(no benchmarks/)':>27}")
        else:
            median, low, high = row["numpy_over_run"]
            out(line + f"{1e6 * row['numpy_seconds_per_step']:>14.1f} {median:>10.2f} {low:>5.2f}–{high:<6.2f}")
    return rows


PHASE_CASES = (
    ("pure Lagrangian (node-aligned interface)", "sod-two-gamma", []),
    ("one enriched interface, interface-following", "sod-two-gamma-enriched",
     ["regions.0.interval=[0.0, 0.500037]", "regions.1.interval=[0.500037, 1.0]",
      "mesh.motion=interface"]),
    ("one enriched interface, Eulerian remap", "sod-two-gamma-enriched",
     ["regions.0.interval=[0.0, 0.500037]", "regions.1.interval=[0.500037, 1.0]", "mesh.motion=eulerian"]),
)


def phase_times(cells: int, steps: int, overrides=(), scene: str = "sod-two-gamma",
                repeats: int = 3) -> dict:
    """Seconds per step in each phase over `steps` steps of a scene (after 5 warm-up steps),
    from the fastest of `repeats` runs."""
    from ale_xfem.run import simulate

    best = None
    for _ in range(repeats):  # best of `repeats` runs: this machine's timings are noisy
        problem = build_problem(load_scene(resolve_scene_path(scene), [f"mesh.cells={cells}", "t_end=1e9",
                                                                       *overrides]))
        warm = simulate(problem, stop_after_steps=5)
        problem.state = warm.state
        result = simulate(problem, stop_after_steps=steps)
        per_step = {k: v / steps for k, v in result.phase_seconds.items()
                    if k in ("lagrange", "mixed_cell_solve", "remap")}
        per_step["total"] = result.wall_seconds / steps
        if best is None or per_step["total"] < best["total"]:
            best = per_step
    return best


def _interleaved(cases, rounds: int):
    """Time each case once per round, the cases one after the other within a round, so
    that a ratio is taken between runs made under the same conditions (this machine's speed
    drifts by ±10 % over minutes).  ``cases``: callables returning phase_times dicts.
    Returns, per case, its rounds' dicts."""
    runs = [[] for _ in cases]
    for _ in range(rounds):
        for k, case in enumerate(cases):
            runs[k].append(case())
    return runs


def _fastest(runs):
    return min(runs, key=lambda t: t["total"])


def _ratios(runs, reference_runs, key="total", less_runs=None):
    """Median and range of the round-by-round ratios of runs[key] to the reference's total;
    ``less_runs``: of runs[key] less their total (what runs add to them)."""
    less = [0.0] * len(runs) if less_runs is None else [t["total"] for t in less_runs]
    ratios = sorted((t[key] - b) / r["total"] for t, b, r in zip(runs, less, reference_runs))
    return ratios[len(ratios) // 2], ratios[0], ratios[-1]


def run_phase_bench(sizes=(1_000, 100_000), out=print, rounds: int = 3) -> list[dict]:
    out(f"time per step by phase (ms, fastest of {rounds} rounds), 1D two-gamma tube, the interface strictly "
        "inside a cell; ratio to the pure run: median of the rounds' (range)")
    out(f"{'cells':>8} {'case':<42} {'lagrange':>9} {'mixed':>9} {'remap':>9} {'total':>9} {'ratio':>7} "
        f"{'range':>11}")
    rows = []
    for cells in sizes:
        steps = steps_for(cells) // 4 if cells <= 10_000 else 50
        cases = [lambda overrides=overrides, scene=scene: phase_times(cells, steps, overrides, scene, repeats=1)
                 for _, scene, overrides in PHASE_CASES]
        runs = _interleaved(cases, rounds)
        for (label, _, _), case_runs in zip(PHASE_CASES, runs):
            t = _fastest(case_runs)
            ratio, low, high = _ratios(case_runs, runs[0])
            rows.append({"cells": cells, "case": label, **t, "ratio": ratio, "ratio_range": (low, high)})
            out(f"{cells:>8d} {label:<42} {1e3 * t['lagrange']:>9.3f} {1e3 * t['mixed_cell_solve']:>9.3f} "
                f"{1e3 * t['remap']:>9.3f} {1e3 * t['total']:>9.3f} {ratio:>7.2f} {low:>5.2f}–{high:<5.2f}")
        # What the remap costs a step: the Eulerian run less the same interface without a
        # remap (its remap column also holds the remapped state's force evaluation, which
        # the step then leaves out), against the pure Lagrange step (issue 3: ≤ 2×).
        pure, following, eulerian = runs
        ratio, low, high = _ratios(eulerian, pure, less_runs=following)
        added = _fastest(eulerian)["total"] - _fastest(following)["total"]
        rows.append({"cells": cells, "case": "what an Eulerian remap adds", "total": added, "ratio": ratio,
                     "ratio_range": (low, high)})
        out(f"{cells:>8d} {'an Eulerian remap adds to a step':<42} {'':>9} {'':>9} {'':>9} {1e3 * added:>9.3f} "
            f"{ratio:>7.2f} {low:>5.2f}–{high:<5.2f}")
    return rows


PHASE_CASES_2D = (
    ("rotated two-material tube, Lagrangian", ["mesh.motion=lagrangian"]),
    ("rotated two-material tube, Eulerian remap", ["mesh.motion=eulerian"]),
    ("rotated two-material tube, smoothed mesh", ["mesh.motion=smoothed"]),
)


def run_phase_bench_2d(side: int = 200, steps: int = 10, out=print, rounds: int = 3,
                       cell_type: str = "quadrilateral") -> list[dict]:
    """The 2D remap against the Lagrange step: the rotated two-material tube (its interface
    crossing the domain, single-velocity mixed cells) on side × side quadrilaterals (or,
    ``cell_type`` = "triangle", side × side squares of four crossed triangles).  Two ratios
    to the Lagrangian run's step: the remap column's (which holds the relaxation and the
    force evaluation of the remapped state, which the step then skips) and what the remap
    adds to a step, the remapped run's step less the Lagrangian one (as the 1D bench
    measures it)."""
    mesh = {"quadrilateral": "quadrilaterals", "triangle": "squares of four crossed triangles"}[cell_type]
    out(f"time per step by phase (ms, fastest of {rounds} rounds of {steps} steps), 2D rotated two-material "
        f"tube, {side} × {side} {mesh}; ratios to the Lagrangian run's step: median of the rounds' (range)")
    out(f"{'case':<44} {'lagrange':>9} {'remap':>9} {'total':>9} {'remap column':>13} {'range':>11} "
        f"{'the remap adds':>15} {'range':>11}")
    mesh_overrides = [f"mesh.cells=[{side},{side}]", f"mesh.cell_type={cell_type}"]
    cases = [lambda overrides=overrides: phase_times(side, steps, [*mesh_overrides, *overrides], "rotated-tube",
                                                     repeats=1)
             for _, overrides in PHASE_CASES_2D]
    runs = _interleaved(cases, rounds)
    rows = []
    for (label, _), case_runs in zip(PHASE_CASES_2D, runs):
        t = _fastest(case_runs)
        ratio, low, high = _ratios(case_runs, runs[0], key="remap")
        added, added_low, added_high = _ratios(case_runs, runs[0], less_runs=runs[0])
        rows.append({"case": label, **t, "remap_ratio": ratio, "remap_ratio_range": (low, high),
                     "added_ratio": added, "added_ratio_range": (added_low, added_high)})
        out(f"{label:<44} {1e3 * t['lagrange']:>9.2f} {1e3 * t['remap']:>9.2f} {1e3 * t['total']:>9.2f} "
            f"{ratio:>13.2f} {low:>5.2f}–{high:<5.2f} {added:>15.2f} {added_low:>5.2f}–{added_high:<5.2f}")
    return rows


ENRICHED_CASES = (
    ("one velocity field", []),
    ("enriched, bubbles", ["interface.model=enriched", "interface.stabilisation=bubble"]),
    ("enriched, Nitsche", ["interface.model=enriched", "interface.stabilisation=nitsche"]),
    # the linearised law alone: one solve a step, no corrector
    ("bubbles, linearised", ["interface.model=enriched", "interface.stabilisation=bubble",
                             "interface.solver=linearised"]),
)


def run_enriched_bench(sides=(100, 200), steps: int = 10, out=print, rounds: int = 3,
                       cell_type: str = "quadrilateral") -> list[dict]:
    """What the paper's 2D enriched mixed cells cost over one velocity field: the sheared
    two-material tube (``rotated-tube-shear``, Eulerian) on side × side quadrilaterals (or,
    ``cell_type`` = "triangle", side × side squares of four crossed triangles), time per step
    by phase (the mixed-cell column: the interface solve with its cut geometry; the remap
    column includes the per-material momentum remap and the next step's evaluation), and
    the whole step's ratio to the single-velocity run's; bubbles with the nonlinear
    corrector (the default) and with the linearised law alone."""
    mesh = {"quadrilateral": "quadrilaterals", "triangle": "squares of four crossed triangles"}[cell_type]
    out(f"time per step by phase (ms, fastest of {rounds} rounds of {steps} steps), the sheared two-material "
        f"tube (rotated-tube-shear, Eulerian) on side × side {mesh}; ratio to one velocity field: median of the "
        "rounds' (range)")
    out(f"{'side':>5} {'mixed':>6} {'closure':<20} {'lagrange':>9} {'mixed':>9} {'remap':>9} {'total':>9} "
        f"{'ratio':>7} {'range':>11}")
    rows = []
    for side in sides:
        mesh_overrides = [f"mesh.cells=[{side},{side}]", f"mesh.cell_type={cell_type}"]
        cases = [lambda overrides=overrides: phase_times(side, steps, [*mesh_overrides, *overrides],
                                                         "rotated-tube-shear", repeats=1)
                 for _, overrides in ENRICHED_CASES]
        runs = _interleaved(cases, rounds)
        mixed = _mixed_cells("rotated-tube-shear", mesh_overrides)
        for (label, _), case_runs in zip(ENRICHED_CASES, runs):
            t = _fastest(case_runs)
            ratio, low, high = _ratios(case_runs, runs[0])
            rows.append({"side": side, "cell_type": cell_type, "mixed_cells": mixed, "case": label, **t,
                         "ratio": ratio, "ratio_range": (low, high)})
            out(f"{side:>5d} {mixed:>6d} {label:<20} {1e3 * t['lagrange']:>9.2f} {1e3 * t['mixed_cell_solve']:>9.2f} "
                f"{1e3 * t['remap']:>9.2f} {1e3 * t['total']:>9.2f} {ratio:>7.2f} {low:>5.2f}–{high:<5.2f}")
    return rows


def run_plic_bench(side: int = 200, out=print, repeats: int = 20) -> list[dict]:
    """What PLIC's normals cost (``[interface] normal``): the rotated two-material tube
    (Eulerian) on side × side quadrilaterals five steps in, one reconstruction of its mixed
    cells with Youngs' normals and with LVIRA's, fastest of ``repeats``, and the mean change
    of angle LVIRA makes."""
    from ale_xfem.model.plic import reconstruct_state
    from ale_xfem.run import simulate

    problem = build_problem(load_scene(resolve_scene_path("rotated-tube"), [f"mesh.cells=[{side},{side}]",
                                                                           "mesh.motion=eulerian"]))
    result = simulate(problem, stop_after_steps=5)
    n = int(problem.mixed.cells.size) if problem.mixed is not None else 0
    out(f"one PLIC reconstruction (ms, fastest of {repeats}) of the rotated two-material tube's {n} mixed cells, "
        f"{side} × {side} quadrilaterals, five steps in")
    out(f"{'normal':<8} {'ms':>8} {'µs a cell':>10} {'angle change (°, mean)':>23}")
    rows, normals = [], {}
    for normal in ("youngs", "lvira"):
        best = np.inf
        for _ in range(repeats + 1):  # (the first call compiles or loads the kernels)
            clock = time.perf_counter()
            normals[normal] = reconstruct_state(problem, result.state, normal=normal).normal
            best = min(best, time.perf_counter() - clock)
        change = np.degrees(np.mean(np.arccos(np.clip(np.sum(normals[normal] * normals["youngs"], axis=1), -1, 1))))
        rows.append({"normal": normal, "mixed_cells": n, "seconds": best, "angle_change_degrees": float(change)})
        out(f"{normal:<8} {1e3 * best:>8.3f} {1e6 * best / max(n, 1):>10.2f} {change:>23.3f}")
    return rows


def _mixed_cells(scene: str, overrides) -> int:
    """The scene's mixed cells at the start, with its ``overrides`` (its mesh)."""
    problem = build_problem(load_scene(resolve_scene_path(scene), list(overrides)))
    return 0 if problem.mixed is None else int(problem.mixed.cells.size)


# Strong scaling on several MPI ranks (`bench --ranks`): (label, scene, overrides on side ×
# side cells, the side's share of the bench's), each run for about 50 steps (its t_end
# scaled with the cell size); the runs with mixed cells and a remap on a quarter of the cells
RANK_CASES = (
    ("2D explicit loop (sod-2d)", "sod-2d", lambda side: [f"mesh.cells=[{side},{side}]", f"t_end={4.0 / side!r}"],
     1.0),
    ("mixed cells (rotated tube, Lagrangian)", "rotated-tube",
     lambda side: [f"mesh.cells=[{side},{side}]", "mesh.motion=lagrangian", f"t_end={3.4 / side!r}"], 0.5),
    ("remapped (rotated tube, Eulerian)", "rotated-tube",
     lambda side: [f"mesh.cells=[{side},{side}]", "mesh.motion=eulerian", f"t_end={6.9 / side!r}"], 0.5),
)


def mpi_launcher() -> Path:
    """The launcher of the MPI that DOLFINx's wheels install beside this Python."""
    return Path(sys.executable).parent / "mpiexec"


def run_on_ranks(ranks: int, scene: str, overrides, folder: Path) -> dict:
    """`ale-xfem run` of ``scene`` on ``ranks`` MPI ranks (1: without the launcher), in a
    process of its own; its summary.json."""
    command = [sys.executable, "-m", "ale_xfem.cli", "run", scene, "--quiet", "--no-plot", "--frames", "0",
               "--out", str(folder), *[a for o in overrides for a in ("--set", o)]]
    if ranks > 1:
        command = [str(mpi_launcher()), "-n", str(ranks), *command]
    done = subprocess.run(command, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(command)} failed (exit {done.returncode}): {done.stderr.strip()[-500:]}")
    return json.loads((folder / "summary.json").read_text())


def run_rank_bench(ranks=(1, 2), cells: int = 1_000_000, out=print, rounds: int = 3,
                   cases=RANK_CASES) -> list[dict]:
    """Strong scaling of whole runs on several MPI ranks (ale_xfem.parallel): each of
    ``cases`` (by default :data:`RANK_CASES`) on its share of √cells × √cells, run on each number of ``ranks`` in
    turn within each of ``rounds`` rounds (separate processes: `mpiexec -n N ale-xfem run`).
    Per number of ranks: ms a step (range over the rounds), zone-cycles/s (the fastest
    round), speed-up and parallel efficiency against the first number of ranks (median of
    the rounds' own, with the range), and the step by phase (ms, medians of the rounds): the
    Lagrange step, the remap, and within them the exchanges and reductions between the
    ranks (the rank that spent most; waiting for the others included)."""
    side = int(round(np.sqrt(cells)))
    out(f"strong scaling on MPI ranks ({mpi_launcher()}), {rounds} rounds, each number of ranks in turn within a "
        f"round; speed-up and efficiency: median of the rounds' own (range), against {ranks[0]} "
        f"rank{'s' if ranks[0] > 1 else ''}; phases: ms a step, medians")
    out(f"{'case':<40} {'cells':>9} {'ranks':>5} {'steps':>5} {'ms/step':>15} {'zone-cycles/s':>13} "
        f"{'speed-up':>16} {'efficiency':>16} {'lagrange':>8} {'remap':>8} {'comm.':>8}")
    rows = []
    with tempfile.TemporaryDirectory() as scratch:
        for label, scene, overrides, share in cases:
            case_side = max(4, int(round(share * side)))
            runs = {n: [] for n in ranks}
            for round_ in range(rounds):
                for n in ranks:
                    runs[n].append(run_on_ranks(n, scene, overrides(case_side),
                                                Path(scratch) / f"{scene}-{n}-{round_}"))
            reference = [s["wall_seconds"] for s in runs[ranks[0]]]
            for n in ranks:
                summaries = runs[n]
                steps = summaries[0]["steps"]
                per_step = [s["wall_seconds"] / steps for s in summaries]
                speed_up = sorted(r / s["wall_seconds"] for r, s in zip(reference, summaries))
                efficiency = [v * ranks[0] / n for v in speed_up]
                phases = {key: float(np.median([s["phase_seconds"].get(key, 0.0) for s in summaries])) / steps
                          for key in ("lagrange", "mixed_cell_solve", "remap", "communication")}
                row = {"case": label, "ranks": n, "steps": steps, "cells": summaries[0]["cells"],
                       "seconds_per_step": (min(per_step), max(per_step)),
                       "zone_cycles_per_second": summaries[0]["cells"] / min(per_step),
                       "speed_up": (speed_up[len(speed_up) // 2], speed_up[0], speed_up[-1]),
                       "efficiency": (efficiency[len(efficiency) // 2], efficiency[0], efficiency[-1]),
                       "phases": phases}
                rows.append(row)
                out(f"{label:<40} {row['cells']:>9d} {n:>5d} {steps:>5d} "
                    f"{1e3 * min(per_step):>7.1f}–{1e3 * max(per_step):<7.1f} {row['zone_cycles_per_second']:>13.3e} "
                    f"{row['speed_up'][0]:>5.2f} ({speed_up[0]:.2f}–{speed_up[-1]:.2f}) {row['efficiency'][0]:>5.2f} "
                    f"({efficiency[0]:.2f}–{efficiency[-1]:.2f}) "
                    f"{1e3 * (phases['lagrange'] + phases['mixed_cell_solve']):>8.1f} {1e3 * phases['remap']:>8.1f} "
                    f"{1e3 * phases['communication']:>8.1f}")
    return rows
