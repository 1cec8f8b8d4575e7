"""Command line: `ale-xfem run | list | bench`.

Exit codes: 0 success; 2 bad input (scene or arguments: one line on stderr, nothing runs);
3 the simulation broke down (status "failed", diagnostic, last good state written).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

EXIT_OK, EXIT_BAD_INPUT, EXIT_BREAKDOWN = 0, 2, 3


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ale-xfem",
        description="Multi-material ALE with enriched mixed cells (Folzan, Le Tallec & Perlat 2011).")
    commands = parser.add_subparsers(dest="command", required=True)

    run = commands.add_parser("run", help="run a scene and write its outputs")
    run.add_argument("scene", help="a scene file, or the name of a shipped scene (see `list`)")
    run.add_argument("--out", type=Path, default=None,
                     help="output folder (default: out/<scene name>)")
    run.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                     help="override a scene key, e.g. --set mesh.cells=400 (repeatable)")
    run.add_argument("--no-plot", action="store_true", help="skip the PNG plot")
    run.add_argument("--quiet", action="store_true", help="no progress bar, no summary line")
    run.add_argument("--explain", action="store_true",
                     help="print which effects the scene switches on and why (which key), and exit "
                          "without running")

    commands.add_parser("list", help="list the shipped scenes with their descriptions")

    bench = commands.add_parser("bench", help="zone-cycles per second of the explicit loop")
    bench.add_argument("--cells", default="1000,10000,100000,1000000",
                       help="comma-separated mesh sizes (default: 1000,...,1000000)")
    bench.add_argument("--phases", action="store_true",
                       help="time per step by phase (explicit, mixed-cell solve, remap) with and "
                            "without an enriched interface, at 1000 and 100000 cells (or --cells)")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    if args.command == "list":
        return _list()
    if args.command == "bench":
        return _bench(args)
    return _run(args)


def _list() -> int:
    from ale_xfem.scene import SceneError, load_scene, shipped_scenes

    for path in shipped_scenes():
        try:
            description = load_scene(path).description
        except SceneError as error:
            description = f"(invalid: {error})"
        print(f"{path.stem:<24} {description}")
    return EXIT_OK


def _bench(args) -> int:
    from ale_xfem.bench import run_bench, run_phase_bench

    try:
        sizes = [int(v) for v in args.cells.split(",")]
        if any(v < 1 for v in sizes):
            raise ValueError
    except ValueError:
        print(f"error: --cells = {args.cells!r}: comma-separated positive integers", file=sys.stderr)
        return EXIT_BAD_INPUT
    if args.phases:
        run_phase_bench(sizes if args.cells != "1000,10000,100000,1000000" else (1_000, 100_000))
    else:
        run_bench(sizes)
    return EXIT_OK


def _run(args) -> int:
    from ale_xfem.scene import SceneError, load_scene, resolve_scene_path

    try:
        scene = load_scene(resolve_scene_path(args.scene), args.overrides)
    except SceneError as error:
        print(f"error: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT

    from ale_xfem.io import write_outputs
    from ale_xfem.problem import build_problem
    from ale_xfem.run import Progress, simulate

    out = args.out if args.out is not None else Path("out") / scene.name
    problem = build_problem(scene)
    if args.explain:
        from ale_xfem.effects import explain

        print(f"{scene.name}: {scene.description}" if scene.description else scene.name)
        print(explain(problem.effect_table))
        return EXIT_OK
    progress = Progress(scene.t_end, enabled=False if args.quiet else None)
    result = simulate(problem, progress)
    write_outputs(problem, result, out, plot=not args.no_plot)
    if result.status != "ok":
        print(f"error: simulation failed: {result.diagnostic}; last good state (t = "
              f"{result.state.time:.6g}) written to {out}", file=sys.stderr)
        return EXIT_BREAKDOWN
    if not args.quiet:
        line = (f"{scene.name}: t = {result.state.time:.6g} in {result.steps} steps, "
                f"{result.wall_seconds:.3g} s ({result.zone_cycles_per_second:.3g} zone-cycles/s)")
        if result.errors:
            line += (f"; L1 density {result.errors['L1_density']:.3e}, velocity "
                     f"{result.errors['L1_velocity']:.3e}, pressure {result.errors['L1_pressure']:.3e}")
        print(line)
        print(f"outputs in {out}/")
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
