"""`ale-xfem study accuracy`: every variant at every resolution, the files it promises, and
errors that fall with resolution."""

import csv
import subprocess
import sys

import pytest

from ale_xfem.studies.accuracy import (check_study, load_study, run_accuracy_study, shipped_studies,
                              study_from_vary)


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "ale_xfem.cli", *args], capture_output=True, text=True)


def test_vary_runs_every_combination_and_writes_the_table_and_chart(tmp_path):
    out = tmp_path / "study"
    done = _cli("study", "accuracy", "sod", "--cells", "50,100,200", "--vary", "numerics.remap_order=1,2",
                "--vary", "numerics.cfl=0.3,0.5", "--set", "mesh.motion=eulerian", "--out", str(out))
    assert done.returncode == 0, done.stderr
    rows = list(csv.DictReader((out / "accuracy.csv").open()))
    assert len(rows) == 12  # 2 × 2 variants × 3 resolutions
    assert {r["variant"] for r in rows} == {f"numerics.remap_order={o}, numerics.cfl={c}"
                                            for o in (1, 2) for c in (0.3, 0.5)}
    for variant in {r["variant"] for r in rows}:
        errors = [float(r["L1_density"]) for r in rows if r["variant"] == variant]
        assert all(r["status"] == "ok" for r in rows)
        assert errors[0] > errors[1] > errors[2]  # errors fall with resolution
        remap_ms = [float(r["ms_per_step_remap"]) for r in rows if r["variant"] == variant]
        assert all(ms > 0 for ms in remap_ms)  # the Eulerian remap's time is measured
    report = (out / "accuracy.md").read_text()
    assert "Convergence rates" in report and "is cheapest" in report
    assert (out / "accuracy.png").stat().st_size > 10_000


def test_second_order_remap_beats_first_order_at_equal_resolution(tmp_path):
    study = study_from_vary("sod", [100, 200], ["numerics.remap_order=1,2"], ["mesh.motion=eulerian"])
    rows = run_accuracy_study(study, tmp_path, echo=lambda line: None)
    first = {r["cells"]: r["L1_density"] for r in rows if r["variant"].endswith("=1")}
    second = {r["cells"]: r["L1_density"] for r in rows if r["variant"].endswith("=2")}
    assert all(second[n] < first[n] for n in (100, 200))


@pytest.mark.parametrize("path", shipped_studies(), ids=lambda p: p.stem)
def test_shipped_studies_are_valid_and_run_at_small_size(path, tmp_path):
    study = load_study(path)
    check_study(study)
    assert len(study.variants) >= 2
    study.cells = [40, 80]
    rows = run_accuracy_study(study, tmp_path, echo=lambda line: None)
    assert all(r["status"] == "ok" for r in rows), [r for r in rows if r["status"] != "ok"]
    for variant in study.variants:
        errors = [r["L1_density"] for r in rows if r["variant"] == variant.label]
        assert errors[1] < errors[0], variant.label


def test_a_bad_vary_key_is_one_line_and_runs_nothing(tmp_path):
    out = tmp_path / "never"
    done = _cli("study", "accuracy", "sod", "--vary", "numerics.cfll=0.3,0.5", "--out", str(out))
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and "numerics.cfll" in done.stderr
    assert not out.exists()
    done = _cli("study", "accuracy", "sod", "--vary", "numerics.cfl=0.3,-1", "--out", str(out))
    assert done.returncode == 2 and "numerics.cfl" in done.stderr and not out.exists()
    done = _cli("study", "accuracy", "no-such-thing", "--out", str(out))
    assert done.returncode == 2 and "target" in done.stderr and not out.exists()
