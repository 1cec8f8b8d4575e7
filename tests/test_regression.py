"""Regression captures: every shipped scene (and the variants that reach the code paths the
scenes do not: the assembled predictor, the linearised solver, each mesh motion, triangles)
run at a small size through the CLI, its final state compared with the capture stored in
``tests/regression/<case>/`` — ``summary.json`` (every figure except wall-clock timings),
``profile.csv`` (1D) or ``cells.csv`` (2D).

A refactor must leave these unchanged (it is bit-identical: run ``python
tests/test_regression.py --compare-bytes`` to see whether every byte is the same).  The test
allows a relative difference of 1e-12 of each column's scale, so that a change of summation
order (compiled kernels, MPI reductions) passes while any change of the physics fails.

Recapture only when a change of results is intended and explained in its commit, or when
the packages of ``constraints.txt`` change (their round-off moves the last digits):
``python tests/test_regression.py --capture [CASE ...]`` (every case, or those named).
"""

from __future__ import annotations

import csv
import json
import math
import shutil
import sys
import tempfile
from pathlib import Path

import pytest

CAPTURES = Path(__file__).resolve().parent / "regression"
RTOL = 1e-12
# summary.json figures that are gaps relative to one, whose round-off is 1e-16 on the scale
# of 1, not of their own: the conservation drifts, and the 2D enriched cells' largest
# relative gap between a cut cell's parts and its area (|Σ parts / area − 1|); the other
# figures are compared on their own scale
RELATIVE_TO_ONE = ("conservation", "volume_mismatch")

# case name → (shipped scene, --set overrides); small sizes, each runs in about a second
CASES = {
    "sod": ("sod", ["mesh.cells=41"]),
    "sod-two-gamma": ("sod-two-gamma", ["mesh.cells=40"]),
    "sod-two-gamma-enriched": ("sod-two-gamma-enriched", ["mesh.cells=41"]),
    "sod-two-gamma-enriched-assembled": ("sod-two-gamma-enriched",
                                         ["mesh.cells=41", "interface.predictor=assembled"]),
    "sod-two-gamma-enriched-linearised": ("sod-two-gamma-enriched",
                                          ["mesh.cells=41", "interface.solver=linearised"]),
    "sod-two-gamma-enriched-interface-motion": ("sod-two-gamma-enriched",
                                                ["mesh.cells=41", "mesh.motion=interface"]),
    "sod-two-gamma-enriched-smoothed": ("sod-two-gamma-enriched",
                                        ["mesh.cells=41", "mesh.motion=smoothed", "numerics.remap_order=1"]),
    "sod-two-gamma-single-velocity-eulerian": ("sod-two-gamma-enriched",
                                               ["mesh.cells=41", "interface.model=single_velocity",
                                                "mesh.motion=eulerian"]),
    "water-air": ("water-air", ["mesh.cells=40"]),
    "plate-impact": ("plate-impact", ["mesh.cells=60"]),
    "plate-impact-enriched": ("plate-impact-enriched", ["mesh.cells=41"]),
    "flyer-target-backing": ("flyer-target-backing", ["mesh.cells=41"]),
    "blast-symmetric": ("blast-symmetric", ["mesh.cells=41"]),
    "piston": ("piston", ["mesh.cells=41"]),
    "shock-interface": ("shock-interface", ["mesh.cells=41"]),
    "transverse-eulerian": ("transverse-eulerian", ["mesh.cells=41"]),
    "noh": ("noh", ["mesh.cells=[16,16]"]),
    "noh-triangles": ("noh", ["mesh.cells=[12,12]", "mesh.cell_type=triangle"]),
    "rotated-tube": ("rotated-tube", ["mesh.cells=[16,16]"]),
    "rotated-tube-eulerian-triangles": ("rotated-tube", ["mesh.cells=[14,14]", "mesh.motion=eulerian",
                                                         "mesh.cell_type=triangle"]),
    "rotated-tube-shear": ("rotated-tube-shear", ["mesh.cells=[16,16]"]),
    "spinning-disk": ("spinning-disk", ["mesh.cells=[16,16]", "t_end=0.2"]),
    "spinning-disk-enriched": ("spinning-disk", ["mesh.cells=[16,16]", "t_end=0.2", "interface.model=enriched"]),
    "rotated-tube-shear-enriched": ("rotated-tube-shear", ["mesh.cells=[16,16]", "interface.model=enriched"]),
    "rotated-tube-shear-enriched-nitsche-stick-triangles": (
        "rotated-tube-shear", ["mesh.cells=[12,12]", "interface.model=enriched", "interface.stabilisation=nitsche",
                               "interface.slip=stick", "mesh.cell_type=triangle"]),
    "saltzman": ("saltzman", ["mesh.cells=[16,16]"]),
    "sedov": ("sedov", ["mesh.cells=[16,16]"]),
    "sod-2d": ("sod-2d", ["mesh.cells=[16,16]"]),
    "shock-disk": ("shock-disk", ["mesh.cells=[24,12]"]),
    "shock-disk-enriched": ("shock-disk", ["mesh.cells=[24,12]", "interface.model=enriched"]),
    "shock-disk-enriched-linearised": ("shock-disk", ["mesh.cells=[24,12]", "interface.model=enriched",
                                                      "interface.solver=linearised"]),
    "slip-line": ("slip-line", ["mesh.cells=[16,16]"]),
    "slip-line-single-velocity": ("slip-line", ["mesh.cells=[16,16]", "interface.model=single_velocity"]),
    "sliding-block": ("sliding-block", ["mesh.cells=[24,12]", "t_end=0.1"]),
    "sliding-block-single-velocity": ("sliding-block", ["mesh.cells=[24,12]", "t_end=0.1",
                                                        "interface.model=single_velocity"]),
}

# figures of the summary that measure the machine, not the physics
TIMINGS = {"wall_seconds", "compile_seconds", "zone_cycles_per_second", "phase_seconds"}


def run_case(name: str, out: Path) -> Path:
    """Run one case through the CLI (in this process) into out/<name>; returns the folder."""
    from ale_xfem.cli import main

    scene, overrides = CASES[name]
    folder = out / name
    argv = ["run", scene, "--out", str(folder), "--no-plot", "--quiet", "--frames", "0"]
    for override in overrides:
        argv += ["--set", override]
    code = main(argv)
    assert code == 0, f"{name}: exit code {code}"
    return folder


def captured_files(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name in ("summary.json", "profile.csv", "cells.csv"))


def _without_timings(summary: dict) -> dict:
    return {k: v for k, v in summary.items() if k not in TIMINGS}


def _close(a, b, path: str, scale: float = 0.0) -> list[str]:
    """Differences between two JSON values beyond RTOL (numbers) or at all (the rest)."""
    if isinstance(a, dict) and isinstance(b, dict):
        if set(a) != set(b):
            return [f"{path}: keys {sorted(set(a) ^ set(b))} differ"]
        return [d for k in a for d in _close(a[k], b[k], f"{path}.{k}", 1.0 if k in RELATIVE_TO_ONE else scale)]
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{path}: lengths {len(a)} and {len(b)}"]
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in _close(x, y, f"{path}[{i}]", scale)]
    if isinstance(a, float) or isinstance(b, float):
        # a relative drift at round-off (1e-16) is compared on the scale of 1, not its own
        if not math.isclose(a, b, rel_tol=RTOL, abs_tol=RTOL * max(scale, 1e-300)):
            return [f"{path}: {b!r} captured, {a!r} now"]
        return []
    return [] if a == b else [f"{path}: {b!r} captured, {a!r} now"]


def _read_csv(path: Path) -> tuple[list[str], list[list[str]]]:
    with path.open() as handle:
        rows = list(csv.reader(handle))
    return rows[0], rows[1:]


def compare(folder: Path, captured: Path) -> list[str]:
    """Every difference between a run's files and the capture, beyond RTOL of each column's
    (or figure's) scale."""
    differences = []
    if captured_files(folder) != captured_files(captured):
        return [f"files {captured_files(folder)} against {captured_files(captured)} captured"]
    now = _without_timings(json.loads((folder / "summary.json").read_text()))
    then = _without_timings(json.loads((captured / "summary.json").read_text()))
    for key in now.keys() | then.keys():
        differences += _close(now.get(key), then.get(key), key, 1.0 if key in RELATIVE_TO_ONE else 0.0)
    for name in captured_files(captured):
        if not name.endswith(".csv"):
            continue
        header, rows = _read_csv(folder / name)
        header_then, rows_then = _read_csv(captured / name)
        if header != header_then or len(rows) != len(rows_then):
            differences.append(f"{name}: columns {header} ({len(rows)} rows) against {header_then} "
                               f"({len(rows_then)} rows) captured")
            continue
        for column, label in enumerate(header):
            values = [row[column] for row in rows]
            values_then = [row[column] for row in rows_then]
            try:
                numbers = [float(v) for v in values]
                numbers_then = [float(v) for v in values_then]
            except ValueError:  # a text column (material names)
                if values != values_then:
                    differences.append(f"{name}.{label}: text differs")
                continue
            scale = max((abs(v) for v in numbers_then), default=0.0)
            bad = [i for i, (x, y) in enumerate(zip(numbers, numbers_then))
                   if not abs(x - y) <= RTOL * scale]
            if bad:
                i = bad[0]
                differences.append(f"{name}.{label}: {len(bad)} rows differ beyond {RTOL:g} of "
                                   f"{scale:.3g}, first row {i}: {numbers_then[i]!r} captured, {numbers[i]!r} now")
    return differences


@pytest.mark.parametrize("name", sorted(CASES))
def test_final_state_matches_its_capture(name, tmp_path):
    folder = run_case(name, tmp_path)
    differences = compare(folder, CAPTURES / name)
    assert not differences, f"{name}: " + "; ".join(differences[:5])


def test_the_comparison_sees_a_change_at_the_tolerance(tmp_path):
    """The comparison is not blind: a perturbation of 1e-10 of one density is caught, and
    one of 1e-14 passes (the capture compared with a copy of itself)."""
    name = "sod-two-gamma-enriched"
    for relative, caught in ((1e-10, True), (1e-14, False)):
        copy = tmp_path / f"copy-{relative:g}"
        shutil.copytree(CAPTURES / name, copy)
        header, rows = _read_csv(copy / "profile.csv")
        column = header.index("density")
        rows[len(rows) // 2][column] = repr(float(rows[len(rows) // 2][column]) * (1 + relative))
        with (copy / "profile.csv").open("w", newline="") as handle:
            csv.writer(handle).writerows([header, *rows])
        assert bool(compare(copy, CAPTURES / name)) == caught, relative


def _main(argv: list[str]) -> int:
    """--capture: (re)write the captures; --compare-bytes: run the cases and report which
    files differ from their capture in any byte (timings aside).  Every case, or the cases
    named after the option."""
    options = [a for a in argv if a.startswith("-")]
    if options != ["--capture"] and options != ["--compare-bytes"]:
        print("usage: python tests/test_regression.py --capture | --compare-bytes [CASE ...]\n"
              f"{_main.__doc__}\n\n{__doc__.strip()}")
        return 0 if options in (["-h"], ["--help"]) else 2
    names = [a for a in argv if not a.startswith("-")] or sorted(CASES)
    unknown = [name for name in names if name not in CASES]
    if unknown:
        print(f"error: no regression case {unknown[0]!r}; the cases are {', '.join(sorted(CASES))}")
        return 2
    with tempfile.TemporaryDirectory() as scratch:
        scratch = Path(scratch)
        same = True
        for name in names:
            folder = run_case(name, scratch)
            target = CAPTURES / name
            if "--capture" in argv:
                target.mkdir(parents=True, exist_ok=True)
                for file in captured_files(folder):
                    shutil.copy(folder / file, target / file)
                print(f"captured {name}: {', '.join(captured_files(folder))}")
                continue
            for file in captured_files(folder):
                if file == "summary.json":
                    equal = (_without_timings(json.loads((folder / file).read_text()))
                             == _without_timings(json.loads((target / file).read_text())))
                else:
                    equal = (folder / file).read_bytes() == (target / file).read_bytes()
                same &= equal
                print(f"{name}/{file}: {'identical' if equal else 'DIFFERS'}")
        return 0 if same else 1


if __name__ == "__main__":
    sys.exit(_main(sys.argv[1:]))
