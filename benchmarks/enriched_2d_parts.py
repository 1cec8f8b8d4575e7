"""Where a step with 2D enriched mixed cells spends its time, part by part.

Evidence for BENCHMARKS.md ("2D enriched runs against one velocity field"), not part of
the package.  The sheared two-material tube (``rotated-tube-shear``, Eulerian) on side ×
side cells: wall-clock timers (``time.perf_counter``) around the parts of the step named
below, over ``--steps`` steps after three, printed in ms a step beside the run's own
phases.  The timers nest (the solves inside the implicit solve, the remap's parts inside
its ``apply``) and add a little to what they time.

    python benchmarks/enriched_2d_parts.py --stabilisation bubble --cell-type quadrilateral
    python benchmarks/enriched_2d_parts.py --stabilisation nitsche --cells 100
    python benchmarks/enriched_2d_parts.py --cell-type triangle   # squares of four crossed triangles
"""

from __future__ import annotations

import argparse
import collections
import functools
import time

import ale_xfem.mixed.cut_cells_2d as cut_cells_2d
import ale_xfem.mixed.enriched_2d as enriched_2d
import ale_xfem.remap.remapper_2d as remapper_2d
import ale_xfem.remap.swept_kernels_2d as swept_kernels_2d
import forms.enriched_interface as enriched_interface
from ale_xfem.problem import build_problem
from ale_xfem.run import simulate
from ale_xfem.scene import load_scene, resolve_scene_path

# (where the function is looked up, its name, what the row says)
PARTS = (
    (enriched_2d.EnrichedClosure2D, "implicit_solve", "mixed cells: the implicit solve"),
    (enriched_interface.InterfaceSystem, "solve", "  the interface system: the predictor's solve"),
    (enriched_interface.InterfaceSystem, "resolve", "  the interface system: the corrector's solves"),
    (enriched_2d, "interface_geometry", "  the step's cut geometry"),
    (enriched_interface.InterfaceSystem, "set_geometry", "  filling the cut weights"),
    (enriched_2d.EnrichedClosure2D, "end_of_step", "mixed cells: the end of the step"),
    (enriched_2d.EnrichedClosure2D, "_crossings", "  the materials' crossings"),
    (remapper_2d.Remapper2D, "apply", "remap: apply"),
    (cut_cells_2d, "enriched_geometry", "  the cut geometry and corner masses"),
    (swept_kernels_2d, "material_momentum_fluxes", "  material_momentum_fluxes"),
    (swept_kernels_2d, "material_node_velocities", "  material_node_velocities"),
    (remapper_2d.Remapper2D, "_mixed_donor_volumes", "  the mixed donors' parts"),
)


def timed(owner, name: str, label: str, spent: collections.Counter) -> None:
    """Replace ``owner.name`` by the same function adding its wall time to spent[label]."""
    function = getattr(owner, name)

    @functools.wraps(function)
    def wrapper(*args, **kwargs):
        start = time.perf_counter()
        try:
            return function(*args, **kwargs)
        finally:
            spent[label] += time.perf_counter() - start

    setattr(owner, name, wrapper)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stabilisation", choices=("bubble", "nitsche"), default="bubble")
    parser.add_argument("--cell-type", choices=("quadrilateral", "triangle"), default="quadrilateral")
    parser.add_argument("--cells", type=int, default=200, help="cells a side (default 200)")
    parser.add_argument("--steps", type=int, default=20, help="steps timed, after three (default 20)")
    args = parser.parse_args()
    spent = collections.Counter()
    for owner, name, label in PARTS:
        timed(owner, name, label, spent)
    problem = build_problem(load_scene(resolve_scene_path("rotated-tube-shear"), [
        f"mesh.cells=[{args.cells},{args.cells}]", f"mesh.cell_type={args.cell_type}", "t_end=1e9",
        "interface.model=enriched", f"interface.stabilisation={args.stabilisation}"]))
    problem.state = simulate(problem, stop_after_steps=3).state  # (kernels loaded, band bound)
    spent.clear()
    result = simulate(problem, stop_after_steps=args.steps)
    mixed = 0 if problem.mixed is None else problem.mixed.cells.size
    phases = ", ".join(f"{k} {1e3 * v / args.steps:.2f}" for k, v in result.phase_seconds.items())
    print(f"{args.stabilisation}, {args.cells} × {args.cells} {args.cell_type} cells, {mixed} mixed cells: "
          f"{1e3 * result.wall_seconds / args.steps:.1f} ms a step ({phases})")
    for _, _, label in PARTS:
        print(f"{label:<50s} {1e3 * spent[label] / args.steps:8.2f} ms")


if __name__ == "__main__":
    main()
