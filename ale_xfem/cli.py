"""Command line: `ale-xfem run | list | study | bench`.

Exit codes: 0 success; 2 bad input (scene or arguments: one line on stderr, nothing runs);
3 the simulation broke down (status "failed", diagnostic, last good state written).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

EXIT_OK, EXIT_BAD_INPUT, EXIT_BREAKDOWN = 0, 2, 3
EXIT_DEFECT = 1  # an error of the program itself (Python's own code for an uncaught exception)
ABORT_GRACE_SECONDS = 0.5  # before an error on one rank aborts them all (_run_on_every_rank)
DEFAULT_BENCH_CELLS = "1000,10000,100000,1000000"  # bench's 1D loop without --cells
DEFAULT_FRAMES = 20  # 2D runs: the VTK series's states after the initial one
COMPILE_NOTE_SECONDS = 1.0  # a run that compiled kernels for this long says so (a fresh install's first run)


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
    run.add_argument("--xt", action="store_true",
                     help="also write <name>-xt.png, the x–t diagram of density (1D)")
    run.add_argument("--frames", type=int, default=None, metavar="N",
                     help="2D: the initial state and the first state at or after each of N times evenly "
                          "spaced to the end (fewer in a run of fewer steps), written to the VTK "
                          "series <name>.pvd (ParaView, pyvista) and the VTX files <name>-cells.bp, "
                          "<name>-velocity.bp (ParaView, adios2) (default 20; 0: none)")
    run.add_argument("--interface-solve", default="replicated", metavar="HOW",
                     help="on several MPI ranks, how enriched mixed cells' interface system (2D, or the 1D "
                          "assembled predictor) is solved: "
                          "replicated (default: every rank the whole system, the serial run to the bit) or "
                          "distributed (one system shared out over the ranks, assembled and factorised by "
                          "PETSc over them: the serial run to round-off)")
    run.add_argument("--explain", action="store_true",
                     help="print which effects the scene switches on and why (which key), and exit "
                          "without running")

    commands.add_parser("list", help="list the shipped scenes and studies with their descriptions")

    study = commands.add_parser("study", help="accuracy against cost; stability of hard cases; the 2D interface "
                                                 "system on its own")
    kinds = study.add_subparsers(dest="kind", required=True)
    accuracy = kinds.add_parser(
        "accuracy", help="run variants at several resolutions: CSV, Markdown table, work-precision chart")
    accuracy.add_argument("target", help="a shipped study (see `list`), a study file, or a scene")
    accuracy.add_argument("--cells", default=None,
                          help="comma-separated resolutions (default: the study's, or 100,200,400,800,1600)")
    accuracy.add_argument("--vary", action="append", default=[], metavar="KEY=V1,V2",
                          help="with a scene: a key and its values; every combination is run (repeatable)")
    accuracy.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                          help="with a scene: override a key in every variant (repeatable)")
    accuracy.add_argument("--error", choices=("density", "velocity", "pressure"), default=None,
                          help="the L1 error the variants are ranked and charted by (default: the study's, "
                               "or density)")
    accuracy.add_argument("--out", type=Path, default=None, help="output folder (default: out/study-<name>)")
    stability = kinds.add_parser(
        "stability", help="the hard cases (Toro 1-5, LeBlanc, water-air, plate impact, slivers, long run, "
                          "random Riemann problems; in 2D Noh, Saltzman, the rotated tube, an interface "
                          "through an Eulerian mesh, the shock on a disk): a pass/fail table")
    stability.add_argument("--cells", type=int, default=200, help="resolution of the suite (default 200)")
    stability.add_argument("--random", type=int, default=10, help="random Riemann problems (default 10)")
    stability.add_argument("--seed", type=int, default=1, help="seed of the random problems (default 1)")
    stability.add_argument("--case", dest="cases", action="append", default=[], metavar="NAME",
                           help="run only this case (repeatable)")
    stability.add_argument("--out", type=Path, default=Path("out") / "study-stability",
                           help="output folder (default: out/study-stability)")

    interface = kinds.add_parser(
        "interface", help="the 2D enriched interface system on its own: bubbles, Nitsche (several penalty "
                          "factors) and the unstabilised pair under a uniform impact, triangles and "
                          "quadrilaterals, then slivers down to a cut fraction of 1e-8")
    interface.add_argument("--cells", default=None,
                           help="comma-separated cells per side (default 24,48,96)")
    interface.add_argument("--out", type=Path, default=Path("out") / "study-interface",
                           help="output folder (default: out/study-interface)")

    bench = commands.add_parser("bench", help="zone-cycles per second of the explicit loop; with an option, time by "
                                                 "phase, the 2D enriched cells, PLIC, PyClaw, several ranks")
    bench.add_argument("--cells", default=None,
                       help="comma-separated mesh sizes (default: 1000,...,1000000)")
    bench.add_argument("--dimension", type=int, choices=(1, 2), default=1,
                       help="2: the 2D loop on √n × √n quadrilaterals (scene sod-2d), n = 10^4 ... 10^6 "
                            "by default; with --phases the 2D remap against the Lagrange step on the rotated "
                            "two-material tube, 200 × 200 (or --cells N: N × N)")
    bench.add_argument("--phases", action="store_true",
                       help="time per step by phase (explicit, mixed-cell solve, remap) with and "
                            "without an enriched interface, at 1000 and 100000 cells (or --cells); the cases "
                            "run in turn in three rounds, ratios are the median of the rounds'")
    bench.add_argument("--enriched", action="store_true",
                       help="what 2D enriched mixed cells (bubbles, Nitsche; bubbles with the linearised law alone) "
                            "cost over one velocity field: the sheared tube, Eulerian, 100 × 100 and 200 × 200 "
                            "(or --cells N,M: N × N, M × M), time per step by phase")
    bench.add_argument("--cell-type", choices=("quadrilateral", "triangle"), default=None,
                       help="with --enriched, or --phases --dimension 2: the mesh's cells (default quadrilateral; "
                            "triangle: each square of the mesh split into four crossed triangles)")
    bench.add_argument("--plic", action="store_true",
                       help="one PLIC reconstruction with Youngs' and with LVIRA's normals (interface.normal): "
                            "the rotated two-material tube's mixed cells, 200 × 200 (or --cells N: N × N)")
    bench.add_argument("--peers", action="store_true",
                       help="Sod's tube: PyClaw's second-order solver against our Lagrangian and enriched "
                            "runs, 100 ... 3200 cells (`make bench-peers` installs PyClaw)")
    bench.add_argument("--ranks", default=None, metavar="N1,N2,...",
                       help="strong scaling on MPI ranks (mpiexec -n N ale-xfem run): the 2D explicit loop "
                            "(sod-2d) on 1000 × 1000 cells (or --cells N: √N × √N), and the rotated tube with "
                            "single-velocity mixed cells, Lagrangian and Eulerian (remapped), on a quarter of "
                            "them; about 50 steps, by phase with the communication, speed-up against the first "
                            "number of ranks")
    bench.add_argument("--out", type=Path, default=None,
                       help="with --peers: output folder (default: out/bench-peers)")
    # an unknown option is reported with the usage of the (sub)command it was given to
    for command_parser in (run, commands.choices["list"], accuracy, stability, interface, bench):
        command_parser.set_defaults(command_parser=command_parser)
    return parser


def _unwritable(folder: Path) -> str | None:
    """Why a run could not write its outputs into ``folder`` (made here if missing), or None."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        return f"cannot make that folder ({error.strerror.lower() if error.strerror else error})"
    if not os.access(folder, os.W_OK | os.X_OK):
        return "that folder is not writable"
    return None


def main(argv: list[str] | None = None) -> int:
    args, unknown = _parser().parse_known_args(argv)
    if unknown:
        args.command_parser.error(f"unrecognized arguments: {' '.join(unknown)}")
    if args.command == "list":
        return _list()
    if args.command == "bench":
        return _bench(args)
    if args.command == "study":
        return _study(args)
    return _run_on_every_rank(args)


def _run_on_every_rank(args) -> int:
    """``run``; launched by mpiexec among several ranks, an error that escapes one rank (a
    defect: breakdowns and bad input are agreed by all) aborts them all, its traceback
    printed, instead of leaving the others waiting for it in an exchange."""
    from ale_xfem.parallel.distribution import launched_by_mpiexec

    if not launched_by_mpiexec():
        return _run(args)
    try:
        return _run(args)
    except BaseException:  # (SystemExit and KeyboardInterrupt too: the others would wait)
        import traceback

        from ale_xfem.parallel.distribution import rank, world

        print(f"error on MPI rank {rank()}: every rank stopped\n{traceback.format_exc()}", file=sys.stderr,
              flush=True)
        # mpiexec forwards each rank's output on its own time and an abort kills the ranks at
        # once: in one fresh-clone run of the test suite the test of this path saw the exit
        # code but an empty stderr (not seen again in 24 runs of that test, 12 of them with
        # both cores busy).  A moment to forward the message first.
        time.sleep(ABORT_GRACE_SECONDS)
        world().Abort(EXIT_DEFECT)
        raise


def _list() -> int:
    from ale_xfem.scene import SceneError, load_scene, shipped_scenes
    from ale_xfem.studies.accuracy import load_study, shipped_studies

    scenes, studies = shipped_scenes(), shipped_studies()
    width = max(len(path.stem) for path in scenes + studies) + 2  # (names in one column)
    print("scenes (ale-xfem run NAME):")
    for path in scenes:
        try:
            description = load_scene(path).description
        except SceneError as error:
            description = f"(invalid: {error})"
        print(f"  {path.stem:<{width}}{description}")
    print("studies (ale-xfem study accuracy NAME):")
    for path in studies:
        try:
            description = load_study(path).description
        except (SceneError, KeyError) as error:
            description = f"(invalid: {error})"
        print(f"  {path.stem:<{width}}{description}")
    return EXIT_OK


def _cells(text: str, option: str = "--cells") -> list[int]:
    try:
        sizes = [int(v) for v in text.split(",")]
        if not sizes or any(v < 1 for v in sizes):
            raise ValueError
    except ValueError:
        raise ValueError(f"{option} = {text!r}: comma-separated positive integers") from None
    return sizes


def _study(args) -> int:
    if args.kind == "stability":
        return _stability(args)
    if args.kind == "interface":
        return _interface_study(args)
    from ale_xfem.scene import SceneError, resolve_scene_path
    from ale_xfem.studies.accuracy import (DEFAULT_CELLS, study_path, check_study, load_study,
                                  run_accuracy_study, study_from_vary)

    try:
        cells = _cells(args.cells) if args.cells is not None else None
        path = study_path(args.target)
        if path is not None:
            if args.vary or args.overrides:
                raise SceneError("--vary/--set", " ".join(args.vary + args.overrides),
                                 "only with a scene (a study lists its own variants)")
            study = load_study(path)
            if cells is not None:
                study.cells = cells
        else:
            if not resolve_scene_path(args.target).exists():
                raise SceneError("target", args.target, "a shipped study or scene (see `ale-xfem list`), "
                                                        "or a study or scene file")
            study = study_from_vary(args.target, cells or list(DEFAULT_CELLS), args.vary, args.overrides)
        if args.error is not None:
            study.error = args.error
        check_study(study)
    except (SceneError, ValueError) as error:
        print(f"error: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    out = args.out if args.out is not None else Path("out") / f"study-{study.name}"
    run_accuracy_study(study, out)
    print(f"written: {out}/accuracy.csv, accuracy.md, accuracy.png")
    return EXIT_OK


def _bench(args) -> int:
    from ale_xfem.studies.bench import run_bench, run_phase_bench

    modes = [f"--{name}" for name in ("phases", "enriched", "plic", "peers") if getattr(args, name)]
    modes += ["--ranks"] if args.ranks is not None else []
    if len(modes) > 1:
        print(f"error: {' '.join(modes)}: one of them at a time (each is a bench of its own)", file=sys.stderr)
        return EXIT_BAD_INPUT
    if args.out is not None and not args.peers:
        print(f"error: --out = {args.out}: acts with --peers only (the other benches print their tables and "
              "write nothing)", file=sys.stderr)
        return EXIT_BAD_INPUT
    if args.out is None:
        args.out = Path("out") / "bench-peers"

    if args.cell_type is not None and not (args.enriched or (args.phases and args.dimension == 2)):
        print(f"error: --cell-type = {args.cell_type!r}: acts with --enriched or --phases --dimension 2 only "
              "(the 2D benches of the rotated tube)", file=sys.stderr)
        return EXIT_BAD_INPUT
    if args.peers:
        from ale_xfem.studies.peers import SIZES, pyclaw_available, run_peer_comparison

        if not pyclaw_available():
            print("error: --peers needs PyClaw (package clawpack), which is not installed: run "
                  "`make bench-peers` (it installs clawpack into .venv; the build needs gfortran)", file=sys.stderr)
            return EXIT_BAD_INPUT
        sizes = SIZES if args.cells is None else None
        try:
            sizes = sizes or _cells(args.cells)
        except ValueError as error:
            print(f"error: {error}", file=sys.stderr)
            return EXIT_BAD_INPUT
        run_peer_comparison(args.out, sizes)
        print(f"written: {args.out}/peers.csv, peers.md, peers.png")
        return EXIT_OK

    given = args.cells is not None  # (without --cells each mode has its own sizes)
    if not given:
        args.cells = DEFAULT_BENCH_CELLS
    try:
        sizes = [int(v) for v in args.cells.split(",")]
        if any(v < 1 for v in sizes):
            raise ValueError
    except ValueError:
        print(f"error: --cells = {args.cells!r}: comma-separated positive integers", file=sys.stderr)
        return EXIT_BAD_INPUT
    if args.ranks is not None:
        from ale_xfem.studies.bench import mpi_launcher, run_rank_bench

        try:
            ranks = [int(v) for v in args.ranks.split(",")]
            if not ranks or any(v < 1 for v in ranks):
                raise ValueError
        except ValueError:
            print(f"error: --ranks = {args.ranks!r}: comma-separated positive integers (numbers of MPI ranks)",
                  file=sys.stderr)
            return EXIT_BAD_INPUT
        if max(ranks) > 1 and not mpi_launcher().exists():
            print(f"error: --ranks = {args.ranks!r}: needs the MPI launcher {mpi_launcher()}, which is not there "
                  "(the mpich wheel DOLFINx needs puts it there: `make test` or `make demo` sets .venv up)",
                  file=sys.stderr)
            return EXIT_BAD_INPUT
        if len(sizes) > 1 and given:
            print(f"error: --cells = {args.cells!r}: one size with --ranks", file=sys.stderr)
            return EXIT_BAD_INPUT
        run_rank_bench(ranks, 1_000_000 if not given else sizes[0])
        return EXIT_OK
    if args.plic:
        from ale_xfem.studies.bench import run_plic_bench

        run_plic_bench(200 if not given else sizes[0])
    elif args.enriched:
        from ale_xfem.studies.bench import run_enriched_bench

        run_enriched_bench(sizes if given else (100, 200),
                           cell_type=args.cell_type or "quadrilateral")
    elif args.phases and args.dimension == 2:
        from ale_xfem.studies.bench import run_phase_bench_2d

        run_phase_bench_2d(200 if not given else sizes[0],
                           cell_type=args.cell_type or "quadrilateral")
    elif args.phases:
        run_phase_bench(sizes if given else (1_000, 100_000))
    elif args.dimension == 2:
        run_bench(sizes if given else (10_000, 100_000, 1_000_000), "sod-2d")
    else:
        run_bench(sizes)
    return EXIT_OK


def _interface_study(args) -> int:
    try:
        cells = _cells(args.cells) if args.cells is not None else None
        if cells is not None and min(cells) < 8:
            raise ValueError(f"--cells = {args.cells!r}: at least 8 cells per side (the interface must "
                             "cross cells away from the walls)")
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    from ale_xfem.studies.interface import DEFAULT_CELLS, run_interface_study

    run_interface_study(args.out, tuple(cells) if cells else DEFAULT_CELLS)
    print(f"written: {args.out}/interface.csv, slivers.csv, interface.md, interface.png")
    return EXIT_OK


def _stability(args) -> int:
    from ale_xfem.studies.stability import random_riemann_cases, run_stability_study, suite

    if args.cells < 20 or args.random < 0:
        print(f"error: --cells = {args.cells}, --random = {args.random}: cells ≥ 20, random ≥ 0", file=sys.stderr)
        return EXIT_BAD_INPUT
    known = [c.name for c in suite(args.cells) + random_riemann_cases(args.random, args.seed, args.cells)]
    unknown = [name for name in args.cases if name not in known]
    if unknown:
        print(f"error: --case = {unknown[0]!r}: one of {', '.join(known)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    rows = run_stability_study(args.out, args.cells, args.random, args.seed, names=args.cases or None)
    passed = sum(r["verdict"] == "pass" for r in rows)
    print(f"{passed} of {len(rows)} cases pass; written: {args.out}/stability.csv, stability.md")
    return EXIT_OK if passed == len(rows) else EXIT_BREAKDOWN  # (1 is kept for the program's own errors)


def _run(args) -> int:
    from ale_xfem.parallel.distribution import (INTERFACE_SOLVES, REMAP_GHOST_RINGS, check_distributable,
                                                has_interface_system, launched_by_mpiexec, rank, ranks)
    from ale_xfem.scene import SceneError, load_scene, resolve_scene_path

    # on several MPI ranks (mpiexec) every rank runs this; rank 0 alone writes and speaks
    root = rank() == 0 if launched_by_mpiexec() else True
    try:
        scene = load_scene(resolve_scene_path(args.scene), args.overrides)
    except SceneError as error:
        if root:
            print(f"error: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT

    from ale_xfem.output.files import remove_earlier_outputs, write_outputs
    from ale_xfem.problem import build_problem
    from ale_xfem.run import Progress, compiled_so_far, simulate

    out = args.out if args.out is not None else Path("out") / scene.name
    if args.xt and scene.dimension != 1:
        if root:
            print("error: --xt: the x–t diagram is for 1D scenes", file=sys.stderr)
        return EXIT_BAD_INPUT
    if args.frames is not None and args.frames > 0 and scene.dimension != 2:  # (0 asks for none: any scene)
        if root:
            print(f"error: --frames = {args.frames}: the VTK series is for 2D scenes (1D writes profile.csv; "
                  "--xt draws the x–t diagram)", file=sys.stderr)
        return EXIT_BAD_INPUT
    if args.frames is not None and args.frames < 0:
        if root:
            print(f"error: --frames = {args.frames}: an integer >= 0", file=sys.stderr)
        return EXIT_BAD_INPUT
    frames = DEFAULT_FRAMES if args.frames is None else args.frames
    if args.interface_solve not in INTERFACE_SOLVES:
        if root:
            print(f"error: --interface-solve = {args.interface_solve}: one of {', '.join(INTERFACE_SOLVES)}",
                  file=sys.stderr)
        return EXIT_BAD_INPUT
    compiled_before = compiled_so_far()  # (kernels compile while the problem is built too)
    try:
        problem = build_problem(scene)  # 2D: region coverage is checked on the mesh
        if ranks() > 1 and not args.explain:
            check_distributable(problem)
    except SceneError as error:
        if root:
            print(f"error: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    if args.interface_solve != "replicated" and (ranks() == 1 or not has_interface_system(problem)):
        if root:  # (nothing it could act on)
            print(f"error: --interface-solve = {args.interface_solve}: acts on an assembled interface system "
                  "(interface.model = \"enriched\" in 2D, or in 1D with interface.predictor = \"assembled\") on "
                  "several MPI ranks; this run has "
                  + (f"{ranks()} rank" if ranks() == 1 else "none"), file=sys.stderr)
        return EXIT_BAD_INPUT
    if args.explain and not root:
        return EXIT_OK
    if args.explain:
        from ale_xfem.scene.effects import explain

        print(f"{scene.name}: {scene.description}" if scene.description else scene.name)
        print(explain(problem.effect_table))
        if ranks() > 1:  # launched by mpiexec: whether the run would share its cells out
            try:
                check_distributable(problem)
                remapped = any(name.startswith("remap_") for name in problem.effects)
                mixed = problem.mixed is not None or problem.scene.interface is not None
                print(f"on {ranks()} MPI ranks: each steps its share of the cells and their ghost layer"
                      + ((f" ({REMAP_GHOST_RINGS} cells deep: each remaps its share)" if problem.mesh.dimension == 2
                          else "; each remaps the whole line, gathered, and keeps its share") if remapped else "")
                      + ("; the mixed cells' solves take every rank's cells as one set" if mixed else "")
                      + ("; the enriched cells' interface system shared out over the ranks (assembled and "
                         "factorised by PETSc over them)" if args.interface_solve == "distributed" else "")
                      + " (ale_xfem.parallel)")
            except SceneError as error:
                print(f"on {ranks()} MPI ranks: refused: {error}")
        return EXIT_OK
    # the output folder, checked before the run (a long run's results are not lost at its
    # end) and cleared of an earlier run's outputs of this scene, by rank 0 for all
    unwritable = _unwritable(out) if root else None
    if root and not unwritable:
        remove_earlier_outputs(out, scene.name)
    if launched_by_mpiexec():
        from mpi4py import MPI

        unwritable = MPI.COMM_WORLD.bcast(unwritable, root=0)
    if unwritable:
        if root:
            print(f"error: --out = {out}: {unwritable}", file=sys.stderr)
        return EXIT_BAD_INPUT
    progress = Progress(scene.t_end, enabled=False if args.quiet or not root else None)
    history = None
    if args.xt and root:
        from ale_xfem.output.plots import XTHistory

        history = XTHistory()
    series = None
    if scene.dimension == 2 and frames > 0:
        from ale_xfem.output.cells_2d import Frames, VTKFiles
        from ale_xfem.output.vtx import VTXFiles

        # the VTX files written by every rank (each its share of the cells), the VTK series
        # by rank 0
        series = Frames(scene.t_end, frames, ([VTKFiles(problem, out)] if root else [])
                        + [VTXFiles(problem, out)])
    observe = history.observe if history else series.observe if series else None
    # the frames want the states at their times only: the steps between them may run in
    # compiled chunks (the x–t history wants every state)
    observe_from = series.observe_from if series and not history else None
    result = simulate(problem, progress, observe=observe, observe_from=observe_from,
                      interface_solve=args.interface_solve)
    result.compile_seconds = compiled_so_far() - compiled_before  # the run's and the build's
    if series is not None:  # (every rank: the VTX files are written together)
        series.finish(result.state, problem)
    if not root:
        return EXIT_OK if result.status == "ok" else EXIT_BREAKDOWN
    write_outputs(problem, result, out, plot=not args.no_plot)
    if history is not None:
        from ale_xfem.output.plots import plot_xt

        plot_xt(history, out / f"{scene.name}-xt.png", f"{scene.name}: density over x and t")
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
            if "L1_normal_velocity" in result.errors:  # a planar Riemann problem's slip line
                line += (f" (velocity along the normal {result.errors['L1_normal_velocity']:.3e}, along the "
                         f"contact {result.errors['L1_tangential_velocity']:.3e})")
        print(line)
        if result.compile_seconds >= COMPILE_NOTE_SECONDS:
            print(f"(and {result.compile_seconds:.3g} s compiling the kernels first, not counted above: they are "
                  "cached for the next runs)")
        print(f"outputs in {out}/")
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
