"""Studies: what accuracy costs in time (`ale-xfem study accuracy`).

A study runs every variant at every resolution and writes, into its output folder:
``accuracy.csv`` (a row per run), ``accuracy.md`` (the table, the fitted convergence
rates, and which variant is cheapest for a given error), and ``accuracy.png`` (the error
against cells, and the work-precision chart: the error against wall time, a line per
variant).  The error ranked and charted is L1(ρ) unless the study names another
(``error = "velocity"`` or ``"pressure"``: where the density's does not show what the
variants differ in — a slip line moves no density).  Where a scene's exact solution is a
planar Riemann problem, the velocity's errors along its normal (u_n) and along the contact
(u_t) are reported too, with their rates.

Variants come either from ``--vary key=v1,v2`` on one scene (every combination), or from a
shipped study (``demos/studies/*.toml``): a list of labelled (scene, overrides) variants.
Every variant's scene is loaded and checked before anything runs.
"""

from __future__ import annotations

import csv
import itertools
import math
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ale_xfem.scene import SceneError, load_scene, resolve_scene_path

STUDIES_DIR = Path(__file__).resolve().parents[2] / "demos" / "studies"
DEFAULT_CELLS = (100, 200, 400, 800, 1600)
COLUMNS = ("variant", "scene", "cells", "status", "steps", "wall_seconds", "L1_density", "L1_velocity",
           "L1_pressure", "L1_normal_velocity", "L1_tangential_velocity", "ms_per_step_lagrange",
           "ms_per_step_mixed_cell_solve", "ms_per_step_remap", "mixed_iterations_mean")
ERRORS = ("density", "velocity", "pressure")  # what a study may rank its variants by
# reported besides, where the scene's exact solution is a planar Riemann problem: the
# velocity's components along its normal and along the contact (a slip line)
COMPONENTS = ("normal_velocity", "tangential_velocity")
SYMBOL = {"density": "ρ", "velocity": "u", "pressure": "p", "normal_velocity": "u_n", "tangential_velocity": "u_t"}


@dataclass
class Variant:
    label: str
    scene: str  # a shipped scene's name or a path
    overrides: list[str] = field(default_factory=list)


@dataclass
class Study:
    name: str
    description: str
    cells: list[int]
    variants: list[Variant]
    error: str = "density"  # the L1 error ranked and charted: one of ERRORS


def shipped_studies() -> list[Path]:
    return sorted(STUDIES_DIR.glob("*.toml"))


def study_path(name: str) -> Path | None:
    for candidate in (Path(name), STUDIES_DIR / name, STUDIES_DIR / f"{name}.toml"):
        if candidate.suffix == ".toml" and candidate.exists():
            try:
                if "variants" in tomllib.loads(candidate.read_text()):
                    return candidate
            except tomllib.TOMLDecodeError:
                return None
    return None


def load_study(path: Path) -> Study:
    """A shipped (or user) study file: name, description, cells, [[variants]] with label,
    scene and optional set = ["key=value", ...]; optional error = "density" | "velocity" |
    "pressure" (what the variants are ranked and charted by; density by default)."""
    data = tomllib.loads(path.read_text())
    allowed = {"name", "description", "cells", "variants", "error"}
    for key in data:
        if key not in allowed:
            raise SceneError(key, data[key], f"a study key ({', '.join(sorted(allowed))})")
    cells = data.get("cells", list(DEFAULT_CELLS))
    if not isinstance(cells, list) or not cells or not all(isinstance(c, int) and c > 0 for c in cells):
        raise SceneError("cells", cells, "a list of positive integers")
    error = _checked_error(data.get("error", "density"))
    variants = []
    for i, table in enumerate(data["variants"]):
        for key in table:
            if key not in ("label", "scene", "set"):
                raise SceneError(f"variants.{i}.{key}", table[key], "label, scene or set")
        if "label" not in table or "scene" not in table:
            raise SceneError(f"variants.{i}", table, "a table with label and scene (and optional set)")
        overrides = table.get("set", [])
        if not isinstance(overrides, list) or not all(isinstance(o, str) for o in overrides):
            raise SceneError(f"variants.{i}.set", overrides, 'a list of "key=value" strings')
        variants.append(Variant(str(table["label"]), str(table["scene"]), list(overrides)))
    return Study(str(data.get("name", path.stem)), str(data.get("description", "")), cells, variants, error)


def _checked_error(error):
    """The error a study ranks by, if it is one of ERRORS (SceneError otherwise)."""
    if error not in ERRORS:
        raise SceneError("error", error, f"the L1 error to rank by: {', '.join(ERRORS)}")
    return error


def study_from_vary(scene: str, cells: list[int], vary: list[str], overrides: list[str]) -> Study:
    """Every combination of the --vary values on one scene."""
    axes = []
    for item in vary:
        key, sep, values = item.partition("=")
        if not sep or not key.strip() or not values.strip():
            raise SceneError("--vary", item, "key=v1,v2,... (e.g. numerics.remap_order=1,2)")
        axes.append([f"{key.strip()}={v.strip()}" for v in _split_values(values)])
    variants = []
    for combination in itertools.product(*axes) if axes else [()]:
        label = ", ".join(combination) if combination else "as given"
        variants.append(Variant(label, scene, [*overrides, *combination]))
    name = Path(scene).stem
    return Study(name, f"{name}: " + ("; ".join(vary) if vary else "as given"), cells, variants)


def _split_values(values: str) -> list[str]:
    """Split on commas outside brackets (a value may be a list: velocity=[1.0],[2.0])."""
    parts, depth, current = [], 0, ""
    for char in values:
        depth += char in "[{"
        depth -= char in "]}"
        if char == "," and depth == 0:
            parts.append(current)
            current = ""
        else:
            current += char
    parts.append(current)
    return [p for p in (p.strip() for p in parts) if p]


def cells_override(path, cells: int) -> str:
    """The override that sets a scene's resolution: ``cells`` cells in 1D, ``cells`` ×
    ``cells`` in 2D."""
    if load_scene(path).dimension == 2:
        return f"mesh.cells=[{cells},{cells}]"
    return f"mesh.cells={cells}"


def check_study(study: Study) -> None:
    """Load every variant's scene at every resolution (SceneError on the first bad one), and
    check the error the study ranks by."""
    _checked_error(study.error)
    for variant in study.variants:
        path = resolve_scene_path(variant.scene)
        for cells in study.cells:
            load_scene(path, [cells_override(path, cells), *variant.overrides])


WARM_UP_STEPS = 2


def run_accuracy_study(study: Study, out: Path, echo=print) -> list[dict]:
    """Run every variant at every resolution; write the CSV, the Markdown table and the
    chart into ``out``; return the rows."""
    from ale_xfem.problem import build_problem
    from ale_xfem.run import simulate

    check_study(study)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    total = len(study.variants) * len(study.cells)
    clock = time.perf_counter()
    # each variant's first steps once on its coarsest mesh, untimed: loading the compiled
    # kernels (and forms) it needs is not charged to the first of its runs that needs them
    # (at 50 cells of Sod that made the first run 30 times as long a step as the others)
    for variant in study.variants:
        path = resolve_scene_path(variant.scene)
        simulate(build_problem(load_scene(path, [cells_override(path, min(study.cells)), *variant.overrides])),
                 stop_after_steps=WARM_UP_STEPS)
    for variant in study.variants:
        for cells in study.cells:
            path = resolve_scene_path(variant.scene)
            scene = load_scene(path, [cells_override(path, cells), *variant.overrides])
            problem = build_problem(scene)
            result = simulate(problem)
            errors = result.errors or {}
            steps = max(result.steps, 1)
            phases = result.phase_seconds
            row = {"variant": variant.label, "scene": scene.name, "cells": cells, "status": result.status,
                   "steps": result.steps, "wall_seconds": result.wall_seconds,
                   "L1_density": errors.get("L1_density", math.nan),
                   "L1_velocity": errors.get("L1_velocity", math.nan),
                   "L1_pressure": errors.get("L1_pressure", math.nan),
                   **{f"L1_{q}": errors.get(f"L1_{q}", math.nan) for q in COMPONENTS},
                   "ms_per_step_lagrange": 1e3 * phases.get("lagrange", 0.0) / steps,
                   "ms_per_step_mixed_cell_solve": 1e3 * phases.get("mixed_cell_solve", 0.0) / steps,
                   "ms_per_step_remap": 1e3 * phases.get("remap", 0.0) / steps,
                   # the mixed cells' predictor/corrector iterations per step (nan where no
                   # iteration was counted: no mixed cells, or a closure that does not iterate)
                   "mixed_iterations_mean": float((result.mixed_cells or {}).get("iterations_mean", 0.0)
                                                  or math.nan)}
            rows.append(row)
            echo(f"[{len(rows):>3}/{total}] {variant.label:<40} {cells:>6} cells  {result.status:<6} "
                 f"L1({SYMBOL[study.error]}) {row['L1_' + study.error]:.3e}  {result.wall_seconds:7.2f} s"
                 f"  ({time.perf_counter() - clock:.0f} s so far)")
    write_csv(rows, out / "accuracy.csv")
    rates = fitted_rates(rows)
    (out / "accuracy.md").write_text(markdown_report(study, rows, rates))
    work_precision_chart(study.name, rows, rates, out / "accuracy.png", study.error)
    return rows


def write_csv(rows: list[dict], path: Path) -> None:
    with path.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=COLUMNS)
        writer.writeheader()
        for row in rows:
            writer.writerow({k: (f"{v:.6e}" if isinstance(v, float) else v) for k, v in row.items()})


def _fit(x, y) -> float:
    """Rate r of y ~ x^-r fitted over all points (log-log slope); nan with < 2 points."""
    keep = np.isfinite(y) & (np.asarray(y) > 0)
    if keep.sum() < 2:
        return math.nan
    return -float(np.polyfit(np.log(np.asarray(x)[keep]), np.log(np.asarray(y)[keep]), 1)[0])


def fitted_rates(rows: list[dict]) -> dict[str, dict[str, float]]:
    """Per variant: convergence rates of the L1 errors (ERRORS, and COMPONENTS where the
    runs have them: nan otherwise) over the resolutions that finished."""
    rates = {}
    for label in dict.fromkeys(r["variant"] for r in rows):
        mine = [r for r in rows if r["variant"] == label and r["status"] == "ok"]
        cells = [r["cells"] for r in mine]
        rates[label] = {q: _fit(cells, [r.get(f"L1_{q}", math.nan) for r in mine])
                        for q in (*ERRORS, *COMPONENTS)}
    return rates


def time_to_reach(errors, seconds, target: float) -> float:
    """Wall time for a given error, interpolated log-log between runs at several
    resolutions (nan outside the errors they reached)."""
    log_e, log_t = np.log(errors), np.log(np.maximum(seconds, 1e-9))
    if not log_e.min() <= math.log(target) <= log_e.max():
        return math.nan
    order = np.argsort(log_e)
    return float(np.exp(np.interp(math.log(target), log_e[order], log_t[order])))


def cheapest_for(rows: list[dict], error: str = "density") -> tuple[float, list[tuple[str, float, bool]]] | None:
    """The L1 ``error`` (one of ERRORS) that every variant with two finished runs reaches,
    and each such variant's wall time to reach it, cheapest first: (target, [(label,
    seconds, at_most)]).  A variant reaches it at its first resolution (in increasing
    order) whose error is at or below it: the time is interpolated log-log from the
    resolution before that one, or, when its coarsest run already reaches it, that run's
    time, an upper bound (``at_most``).  The first resolution counts, not the finest: an
    error that rises again on finer meshes does not hide a cheap run."""
    key = f"L1_{error}"
    curves = {}
    for label in dict.fromkeys(r["variant"] for r in rows):
        mine = sorted((r for r in rows if r["variant"] == label and r["status"] == "ok"
                       and np.isfinite(r[key])), key=lambda r: r["cells"])
        if len(mine) >= 2:
            curves[label] = ([r[key] for r in mine], [r["wall_seconds"] for r in mine])
    if len(curves) < 2:
        return None
    target = max(min(errors) for errors, _ in curves.values())
    costs = []
    for label, (errors, seconds) in curves.items():
        k = next(i for i, e in enumerate(errors) if e <= target)
        if k == 0:
            costs.append((label, seconds[0], True))
        else:
            costs.append((label, time_to_reach(errors[k - 1:k + 1], seconds[k - 1:k + 1], target), False))
    return target, sorted(costs, key=lambda item: item[1])


def cheapest_named(costs: list[tuple[str, float, bool]]) -> list[str]:
    """The variants that are cheapest for sure: the first of ``costs`` (cheapest_for's), and
    with it every other upper bound (``at_most``) below the first time that is not one —
    between upper bounds these resolutions cannot tell which is cheaper."""
    first_known = next((seconds for _, seconds, at_most in costs if not at_most), math.inf)
    if not costs[0][2]:
        return [costs[0][0]]
    return [label for label, seconds, at_most in costs if at_most and seconds < first_known]


def markdown_report(study: Study, rows: list[dict], rates: dict) -> str:
    # the velocity's components, where some run has them (a planar Riemann problem's)
    components = [q for q in COMPONENTS if any(np.isfinite(r.get(f"L1_{q}", math.nan)) for r in rows)]
    titles = "".join(f" L1({SYMBOL[q]}) |" for q in components)
    lines = [f"# Accuracy against cost: {study.name}", "", study.description, "",
             f"| variant | cells | status | steps | L1(ρ) | L1(u) | L1(p) |{titles} wall s | ms/step explicit "
             "| ms/step mixed | ms/step remap | iterations |",
             "|---|---:|---|---:|---:|---:|---:|" + "---:|" * len(components) + "---:|---:|---:|---:|---:|"]
    for r in rows:
        values = "".join(f" {r.get(f'L1_{q}', math.nan):.3e} |" for q in components)
        lines.append(f"| {r['variant']} | {r['cells']} | {r['status']} | {r['steps']} | {r['L1_density']:.3e} "
                     f"| {r['L1_velocity']:.3e} | {r['L1_pressure']:.3e} |{values} {r['wall_seconds']:.3f} "
                     f"| {r['ms_per_step_lagrange']:.3f} | {r['ms_per_step_mixed_cell_solve']:.3f} "
                     f"| {r['ms_per_step_remap']:.3f} | {_iterations(r)} |")
    symbols = "".join(f" {SYMBOL[q]} |" for q in components)
    lines += ["", "Convergence rates (L1 ~ cells^-rate, fitted over the resolutions that finished):", "",
              f"| variant | ρ | u | p |{symbols}", "|---|---:|---:|---:|" + "---:|" * len(components)]
    for label, r in rates.items():
        values = "".join(f" {r[q]:.2f} |" for q in components)
        lines.append(f"| {label} | {r['density']:.2f} | {r['velocity']:.2f} | {r['pressure']:.2f} |{values}")
    cheapest = cheapest_for(rows, study.error)
    if cheapest is not None:
        target, costs = cheapest
        symbol = SYMBOL[study.error]
        lines += ["", f"Wall time to reach L1({symbol}) = {target:.3e} (the finest error every variant reaches; "
                      "log-log interpolation from the resolution before the first that reaches it):", ""]
        lines += [f"- {label}: " + (f"at most {seconds:.3g} s (its coarsest run reaches it)" if at_most
                                    else f"{seconds:.3g} s") for label, seconds, at_most in costs]
        leaders = cheapest_named(costs)
        if len(leaders) == 1:
            lines += ["", f"For L1({symbol}) down to {target:.3e} on this problem, **{leaders[0]}** is cheapest."]
        else:
            names = ", ".join(f"**{label}**" for label in leaders)
            lines += ["", f"For L1({symbol}) down to {target:.3e} on this problem, {names} are cheaper than the "
                          "others (their coarsest runs already reach it; which of them is cheapest, these "
                          "resolutions cannot tell)."]
    return "\n".join(lines) + "\n"


def _iterations(row: dict) -> str:
    """The mixed cells' mean iterations per step of a row, '–' without them."""
    value = row.get("mixed_iterations_mean", math.nan)
    return "–" if not np.isfinite(value) else f"{value:.2f}"


def work_precision_chart(title: str, rows: list[dict], rates: dict, path: Path, error: str = "density") -> None:
    """Convergence (the L1 ``error`` against cells) and work-precision (against wall time),
    a line per variant; ``rows`` as written by a study (variant, status, cells, L1_<error>,
    wall_seconds)."""
    import matplotlib
    import matplotlib.ticker

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, (by_cells, by_time) = plt.subplots(1, 2, figsize=(11, 4.2))
    for label in dict.fromkeys(r["variant"] for r in rows):
        mine = [r for r in rows if r["variant"] == label and r["status"] == "ok" and np.isfinite(r[f"L1_{error}"])]
        if not mine:
            continue
        cells = [r["cells"] for r in mine]
        values = [r[f"L1_{error}"] for r in mine]
        wall = [max(r["wall_seconds"], 1e-4) for r in mine]
        rate = rates[label][error]
        by_cells.loglog(cells, values, "o-", label=f"{label} (rate {rate:.2f})")
        by_time.loglog(wall, values, "o-", label=label)
    by_cells.set_xlabel("cells")
    by_cells.set_ylabel(f"L1 error of {error}")
    by_cells.set_title("convergence")
    by_time.set_xlabel("wall time of the run (s)")
    by_time.set_ylabel(f"L1 error of {error}")
    by_time.set_title("work-precision (lower left is better)")
    for axes in (by_cells, by_time):
        axes.grid(True, which="both", alpha=0.3)
        for axis in (axes.xaxis, axes.yaxis):
            low, high = sorted(axis.get_view_interval())
            # two powers of ten inside label the axis; with fewer, ticks at 2, 3 and 5 times
            # them carry plain labels too
            if math.floor(math.log10(high)) - math.ceil(math.log10(low)) >= 1:
                axis.set_minor_formatter(matplotlib.ticker.NullFormatter())
            else:
                axis.set_minor_locator(matplotlib.ticker.LogLocator(subs=(2.0, 3.0, 5.0)))
                axis.set_minor_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
                axis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
    by_cells.legend(fontsize=7)
    figure.suptitle(title)
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)
