"""`ale-xfem study accuracy`: every variant at every resolution, the files it promises, and
errors that fall with resolution."""

import csv
import subprocess
import sys

import pytest

from ale_xfem.scene import SceneError, load_scene, resolve_scene_path
from ale_xfem.studies.accuracy import (SYMBOL, check_study, cheapest_for, cheapest_named, load_study,
                                       run_accuracy_study, shipped_studies, study_from_vary)


# the shipped 2D studies run in the tests at these sides (their own resolutions are studies' sizes)
SMALL_2D_CELLS = [16, 32]
SMALL_2D_T_END = 0.25  # and run to this time at most


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


def test_each_variant_is_warmed_up_untimed_before_the_timed_runs(tmp_path, monkeypatch):
    """Loading a variant's compiled kernels is not charged to its first timed run: each
    variant first takes a few steps on the coarsest mesh, and only then do the timed runs,
    to the end, begin."""
    import ale_xfem.run as run

    calls, simulate = [], run.simulate

    def recorded(problem, **kwargs):
        calls.append((problem.scene.mesh.cells, kwargs.get("stop_after_steps")))
        return simulate(problem, **kwargs)

    monkeypatch.setattr(run, "simulate", recorded)
    study = study_from_vary("sod", [60, 30], ["numerics.cfl=0.3,0.5"], [])
    run_accuracy_study(study, tmp_path, echo=lambda line: None)
    assert calls == [(30, 2), (30, 2), (60, None), (30, None), (60, None), (30, None)]


@pytest.mark.parametrize("path", shipped_studies(), ids=lambda p: p.stem)
def test_shipped_studies_are_valid_and_run_at_small_size(path, tmp_path):
    study = load_study(path)
    check_study(study)
    assert len(study.variants) >= 2
    # the error the study ranks by falls from the smaller resolution to the larger
    scene = load_scene(resolve_scene_path(study.variants[0].scene))
    study.cells = SMALL_2D_CELLS if scene.dimension == 2 else [40, 80]
    if scene.dimension == 2 and scene.t_end > SMALL_2D_T_END:
        for variant in study.variants:
            variant.overrides.append(f"t_end={SMALL_2D_T_END}")
    rows = run_accuracy_study(study, tmp_path, echo=lambda line: None)
    assert all(r["status"] == "ok" for r in rows), [r for r in rows if r["status"] != "ok"]
    for variant in study.variants:
        errors = [r[f"L1_{study.error}"] for r in rows if r["variant"] == variant.label]
        assert errors[1] < errors[0], variant.label
        if "interface.model=enriched" in variant.overrides:  # the predictor/corrector's iterations
            assert all(r["mixed_iterations_mean"] >= 1.0 for r in rows if r["variant"] == variant.label)
    assert f"L1({SYMBOL[study.error]}) down to" in (tmp_path / "accuracy.md").read_text()


def test_a_planar_riemann_studys_report_gives_the_velocity_along_the_normal_and_the_contact(tmp_path):
    """On a scene whose exact solution is a planar Riemann problem the CSV and the report
    carry L1(u_n) and L1(u_t) and their rates (the sheared tube's one velocity field smears
    the tangential jump: its u_t error falls more slowly than its u_n error); on a 1D tube
    the report has no such columns."""
    study = study_from_vary("rotated-tube-shear", [16, 32], ["interface.model=single_velocity"], [])
    rows = run_accuracy_study(study, tmp_path / "shear", echo=lambda line: None)
    assert all(r["L1_normal_velocity"] > 0 and r["L1_tangential_velocity"] > 0 for r in rows)
    saved = list(csv.DictReader((tmp_path / "shear" / "accuracy.csv").open()))
    assert [float(r["L1_tangential_velocity"]) for r in saved] == pytest.approx(
        [r["L1_tangential_velocity"] for r in rows], rel=1e-6)
    report = (tmp_path / "shear" / "accuracy.md").read_text()
    assert "| L1(u_n) | L1(u_t) |" in report and "| variant | ρ | u | p | u_n | u_t |" in report
    ratio = [rows[1][f"L1_{q}"] / rows[0][f"L1_{q}"] for q in ("normal_velocity", "tangential_velocity")]
    assert ratio[0] < ratio[1] < 1.0
    tube = study_from_vary("sod", [50, 100], ["numerics.cfl=0.5"], [])
    run_accuracy_study(tube, tmp_path / "sod", echo=lambda line: None)
    assert "u_n" not in (tmp_path / "sod" / "accuracy.md").read_text()


def test_a_study_ranks_by_the_error_it_names():
    # one variant cheaper for the density, the other for the velocity
    rows = [dict(variant=v, status="ok", cells=n, wall_seconds=t, L1_density=d, L1_velocity=u, L1_pressure=1.0)
            for v, n, t, d, u in (("a", 10, 1.0, 1e-2, 1e-1), ("a", 20, 4.0, 5e-3, 5e-2),
                                  ("b", 10, 2.0, 2e-2, 4e-2), ("b", 20, 8.0, 1e-2, 2e-2))]
    assert cheapest_for(rows)[1][0][0] == "a"
    assert cheapest_for(rows, "velocity")[1][0][0] == "b"


def test_the_cheapest_run_counts_when_a_variant_starts_below_the_target_or_rises_again():
    # b's coarsest run already beats a's finest, and b's error rises on its finest mesh
    rows = [dict(variant=v, status="ok", cells=n, wall_seconds=t, L1_density=d)
            for v, n, t, d in (("a", 10, 1.0, 4e-2), ("a", 20, 3.0, 3e-2), ("a", 40, 7.0, 2.4e-2),
                               ("b", 10, 4.0, 2.2e-2), ("b", 20, 12.0, 1.5e-2), ("b", 40, 40.0, 2.2e-2))]
    target, costs = cheapest_for(rows)
    assert target == 2.4e-2
    assert costs[0] == ("b", 4.0, True) and costs[1][0] == "a" and costs[1][1] == pytest.approx(7.0)


def test_upper_bounds_that_cannot_be_told_apart_are_named_together():
    # a and b reach the target with their coarsest runs (upper bounds); c needs more
    rows = [dict(variant=v, status="ok", cells=n, wall_seconds=t, L1_density=d)
            for v, n, t, d in (("a", 10, 3.0, 1e-2), ("a", 20, 9.0, 5e-3), ("b", 10, 4.0, 1.2e-2),
                               ("b", 20, 12.0, 6e-3), ("c", 10, 1.0, 4e-2), ("c", 20, 5.0, 1.2e-2))]
    target, costs = cheapest_for(rows)
    assert target == 1.2e-2 and [label for label, _, _ in costs] == ["a", "b", "c"]
    assert cheapest_named(costs) == ["a", "b"]
    assert cheapest_named([("c", 5.0, False), ("a", 6.0, True)]) == ["c"]
    assert cheapest_named([("a", 3.0, True), ("c", 5.0, False), ("b", 6.0, True)]) == ["a"]


def test_the_command_line_ranks_by_the_error_it_is_asked_for(tmp_path):
    out = tmp_path / "study"
    done = _cli("study", "accuracy", "sod", "--cells", "50,100", "--vary", "numerics.cfl=0.3,0.5",
                "--error", "velocity", "--out", str(out))
    assert done.returncode == 0, done.stderr
    assert "L1(u) down to" in (out / "accuracy.md").read_text()
    done = _cli("study", "accuracy", "sod", "--error", "speed", "--out", str(tmp_path / "never"))
    assert done.returncode == 2 and "--error" in done.stderr and not (tmp_path / "never").exists()


def test_a_bad_study_error_is_named(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('error = "velocty"\ncells = [10, 20]\n[[variants]]\nlabel = "a"\nscene = "sod"\n')
    with pytest.raises(SceneError, match="error.*velocty.*density, velocity, pressure"):
        load_study(path)


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
