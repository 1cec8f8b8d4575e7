"""A peer, side by side: PyClaw's second-order finite-volume Euler solver against our
Lagrangian Wilkins run and our enriched run on Sod's tube (`ale-xfem bench --peers`,
`make bench-peers` installs PyClaw first).

All three run here, in one process, one after the other, at each resolution; the L1 error
of density is measured the same way for all (our exact Riemann solver, on the same
sub-samples per cell as our runs' own L1 errors, against each method's cell values) and
the wall time is that of the time loop.  PyClaw: classic Clawpack solver (Lax–Wendroff with wave limiters, MC), Roe
solver with entropy fix (Fortran), transmissive ends (the waves do not reach them by
t = 0.2), CFL 0.9 (its default target).  Ours: the shipped `sod` scene (walls, CFL 0.5),
and the same tube with the contact between two identical gases as an enriched interface
inside a cell.
"""

from __future__ import annotations

import csv
import math
import time
from pathlib import Path

import numpy as np

from ale_xfem.exact.riemann import GasState, RiemannSolution
from ale_xfem.studies.accuracy import fitted_rates, time_to_reach, work_precision_chart

SIZES = (100, 200, 400, 800, 1600, 3200)
GAMMA, T_END = 1.4, 0.2
LEFT, RIGHT = (1.0, 0.0, 1.0), (0.125, 0.0, 0.1)


def pyclaw_available() -> bool:
    try:
        import clawpack.pyclaw  # noqa: F401
        from clawpack import riemann  # noqa: F401
    except ImportError:
        return False
    return True


def _l1_of_cells(edges, values, exact: RiemannSolution) -> float:
    """∫|f_h − f| over the cells, f_h constant per cell: the midpoint rule on the same
    sub-samples per cell as our own runs' L1 errors (:func:`ale_xfem.run.l1_errors`)."""
    from ale_xfem.run import SUBSAMPLES_PER_CELL as samples

    s = (np.arange(samples) + 0.5) / samples
    points = edges[:-1, None] + (edges[1:] - edges[:-1])[:, None] * s
    reference = exact.sample(points, T_END)["density"]
    weights = (edges[1:] - edges[:-1])[:, None] / samples
    return float(np.sum(np.abs(values[:, None] - reference) * weights))


def run_pyclaw(cells: int, x0: float = 0.5) -> dict:
    from clawpack import pyclaw, riemann

    solver = pyclaw.ClawSolver1D(riemann.euler_with_efix_1D)
    solver.kernel_language = "Fortran"
    solver.limiters = pyclaw.limiters.tvd.MC
    solver.bc_lower[0] = solver.bc_upper[0] = pyclaw.BC.extrap
    solver.cfl_desired, solver.cfl_max = 0.9, 1.0
    dimension = pyclaw.Dimension(0.0, 1.0, cells, name="x")
    domain = pyclaw.Domain([dimension])
    state = pyclaw.State(domain, 3)
    state.problem_data["gamma"] = GAMMA
    state.problem_data["gamma1"] = GAMMA - 1.0
    state.problem_data["efix"] = True
    x = state.grid.x.centers
    left = x < x0
    rho = np.where(left, LEFT[0], RIGHT[0])
    p = np.where(left, LEFT[2], RIGHT[2])
    state.q[0, :] = rho
    state.q[1, :] = 0.0
    state.q[2, :] = p / (GAMMA - 1.0)
    controller = pyclaw.Controller()
    controller.solution = pyclaw.Solution(state, domain)
    controller.solver = solver
    controller.tfinal = T_END
    controller.num_output_times = 1
    controller.output_format = None
    controller.keep_copy = True
    controller.verbosity = 0
    clock = time.perf_counter()
    controller.run()
    wall = time.perf_counter() - clock
    final = controller.frames[-1].state
    exact = RiemannSolution.solve(GasState(*LEFT, GAMMA), GasState(*RIGHT, GAMMA), x0)
    edges = np.linspace(0.0, 1.0, cells + 1)
    return {"method": "PyClaw (classic, Roe, MC)", "cells": cells, "wall_seconds": wall,
            "L1_density": _l1_of_cells(edges, final.q[0], exact), "steps": solver.status.get("numsteps", math.nan)}


def run_ours(cells: int, enriched: bool) -> dict:
    from ale_xfem.problem import build_problem
    from ale_xfem.run import simulate
    from ale_xfem.scene import load_scene, resolve_scene_path

    if not enriched:
        scene = load_scene(resolve_scene_path("sod"), [f"mesh.cells={cells}"])
        label = "ale_xfem, Lagrangian"
    else:
        # the contact between two identical gases, inside a cell: an enriched mixed cell
        xi = 0.5 + 0.37 / cells
        scene = load_scene(resolve_scene_path("sod-two-gamma-enriched"), [
            f"mesh.cells={cells}", "materials.right.gamma=1.4", f"regions.0.interval=[0.0, {xi}]",
            f"regions.1.interval=[{xi}, 1.0]"])
        label = "ale_xfem, enriched interface in a cell"
    problem = build_problem(scene)
    result = simulate(problem)
    return {"method": label, "cells": cells, "wall_seconds": result.wall_seconds,
            "L1_density": result.errors["L1_density"], "steps": result.steps}


def run_peer_comparison(out: Path, sizes=SIZES, echo=print) -> list[dict]:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    # one untimed run of each method first: what a process pays once (loading compiled
    # kernels from their cache, PyClaw's Fortran modules) is not charged to the first size
    run_pyclaw(min(sizes)), run_ours(min(sizes), False), run_ours(min(sizes), True)
    for cells in sizes:
        for run in (lambda: run_pyclaw(cells), lambda: run_ours(cells, False), lambda: run_ours(cells, True)):
            row = run()
            rows.append(row)
            echo(f"{row['method']:<40} {cells:>6} cells  L1(ρ) {row['L1_density']:.3e}  {row['wall_seconds']:.4f} s")
    with (out / "peers.csv").open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=("method", "cells", "steps", "L1_density", "wall_seconds"))
        writer.writeheader()
        writer.writerows(rows)
    methods = list(dict.fromkeys(r["method"] for r in rows))
    lines = ["| method | " + " | ".join(f"{n} cells" for n in sizes) + " |",
             "|---|" + "---:|" * len(sizes)]
    for method in methods:
        cells_rows = {r["cells"]: r for r in rows if r["method"] == method}
        lines.append(f"| {method} | " + " | ".join(
            f"{cells_rows[n]['L1_density']:.2e} / {cells_rows[n]['wall_seconds']:.3f} s" for n in sizes) + " |")
    lines += ["", "Wall time at equal L1(ρ) (log-log interpolation), and the ratio to PyClaw's:", "",
              "| L1(ρ) | " + " | ".join(methods) + " |", "|---:|" + "---:|" * len(methods)]
    all_errors = [r["L1_density"] for r in rows]
    for error in (3e-3, 1e-3, 5e-4):
        if not (min(all_errors) <= error <= max(all_errors)):
            continue
        times = []
        for method in methods:
            mine = [r for r in rows if r["method"] == method]
            times.append(time_to_reach([r["L1_density"] for r in mine], [r["wall_seconds"] for r in mine], error))
        cells = []
        for t in times:
            cells.append("–" if math.isnan(t) or math.isnan(times[0]) else f"{t:.3g} s ({t / times[0]:.2f}×)")
        lines.append(f"| {error:.0e} | " + " | ".join(cells) + " |")
    (out / "peers.md").write_text("\n".join(lines) + "\n")
    work_precision_chart("Sod's tube, t = 0.2: PyClaw and ale_xfem",
                         [{**r, "variant": r["method"], "status": "ok"} for r in rows],
                         fitted_rates([{**r, "variant": r["method"], "status": "ok"} for r in rows]),
                         out / "peers.png")
    echo("\n".join(lines))
    return rows
