"""The stability suite at small resolution: every hard case must finish with positive
densities, volumes and energies, volume fractions in [0, 1], mass (of each material) and
momentum conserved to round-off, and L1(ρ) falling from n to 4n cells (2D: twice the cells along each side)
where an exact solution exists; no inverted cell in 2D."""

import subprocess
import sys

import pytest
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st

from ale_xfem.problem import build_problem
from ale_xfem.studies.stability import extreme_case, random_case, run_case, suite, vacuum_forms

SMALL = 50


@pytest.mark.parametrize("case", suite(SMALL), ids=lambda case: case.name)
def test_every_hard_case_passes(case):
    row = run_case(case)
    assert row["verdict"] == "pass", f"{case.name}: {row['verdict']} {row['diagnostic']}"
    assert row["steps"] > 0
    if case.name == "long-run-1e5-steps":
        assert row["steps"] == 100_000
    if case.name == "eulerian-crossing-100":
        assert row["t_reached"] > 0


def test_the_checks_can_fail():
    """A case pushed past what the scheme takes (Toro's test 3 without artificial
    viscosity, at CFL 1) is reported as failing."""
    case = next(case for case in suite(SMALL) if case.name == "toro-3")
    case.data = {**case.data, "numerics": {"cfl": 1.0, "q_quadratic": 0.0, "q_linear": 0.0}}
    row = run_case(case, check_convergence=False)
    assert row["verdict"] != "pass"


def test_a_material_losing_mass_fails_even_when_the_total_is_kept(monkeypatch):
    """Each material's mass counts: traces merged into their cell's other material (what the
    2D remap once did) keep the total exact but fail the interface moving through an
    Eulerian mesh."""
    from ale_xfem.remap import remapper_2d as remap2d

    # no pass moving traces to neighbours: every trace is a fleck merged into its own cell
    monkeypatch.setattr(remap2d, "MAX_TRACE_PASSES", 0)
    case = next(case for case in suite(SMALL) if case.name == "interface-eulerian-2d")
    row = run_case(case, check_convergence=False)
    assert row["status"] == "ok" and "mass drift" in row["verdict"], row["verdict"]


magnitude = st.floats(min_value=-2.0, max_value=2.0)


# The convergence check compares n with 4n cells and is asymptotic: at 50 cells a heavy gas
# (ρ = 10, u = 1) entering a light one (ρ = 0.01) at equal pressure, γ = 2, had L1(ρ) rise
# from 0.0030 to 0.0061 at 200 cells (it falls from 100 to 400 and from 200 to 800): drawn
# problems run at 100 cells.  Draws are derandomized so that CI runs the same ones;
# `ale-xfem study stability --random N --seed S` explores further.
DRAWN_CELLS = 100


@settings(max_examples=8, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@example(rho=(1.0, 0.0), pressure=(0.0, 0.0), velocity=(0.0, 0.0), gamma=(2.0, 2.0))  # a lone contact
@example(rho=(1.0, -2.0), pressure=(0.0, 0.0), velocity=(1.0, 0.0), gamma=(2.0, 2.0))  # the case above
@given(rho=st.tuples(magnitude, magnitude), pressure=st.tuples(magnitude, st.floats(-2.0, 3.0)),
       velocity=st.tuples(st.floats(-5.0, 5.0), st.floats(-5.0, 5.0)),
       gamma=st.tuples(st.floats(1.2, 3.0), st.floats(1.2, 3.0)))
def test_random_riemann_problems_stay_stable_and_converge(rho, pressure, velocity, gamma):
    left = (10 ** rho[0], velocity[0], 10 ** pressure[0])
    right = (10 ** rho[1], velocity[1], 10 ** pressure[1])
    assume(not vacuum_forms(left, right, gamma))
    row = run_case(random_case(0, left, right, gamma, cells=DRAWN_CELLS))
    assert row["verdict"] == "pass", f"{left} | {right}, γ {gamma}: {row['verdict']} {row['diagnostic']}"


def test_cli_writes_the_table_and_rejects_an_unknown_case(tmp_path):
    out = tmp_path / "stability"
    done = subprocess.run([sys.executable, "-m", "ale_xfem.cli", "study", "stability", "--cells", "40",
                           "--random", "1", "--case", "toro-3", "--case", "random-1", "--out", str(out)],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert "2 of 2 cases pass" in done.stdout
    table = (out / "stability.md").read_text()
    assert "| toro-3 | pass |" in table and "| random-1 | pass |" in table
    assert (out / "stability.csv").read_text().count("\n") == 3
    done = subprocess.run([sys.executable, "-m", "ale_xfem.cli", "study", "stability", "--case", "toro-9",
                           "--out", str(tmp_path / "never")], capture_output=True, text=True)
    assert done.returncode == 2 and "toro-9" in done.stderr and not (tmp_path / "never").exists()


def test_cli_exits_3_when_a_case_fails(tmp_path, monkeypatch, capsys):
    """A failing case is the suite's breakdown: exit 3, as a run that breaks down (1 is kept
    for an error of the program itself)."""
    from ale_xfem import cli
    from ale_xfem.studies import stability

    monkeypatch.setattr(stability, "verdict", lambda row, case: "volume ≤ 0")
    assert cli.main(["study", "stability", "--cells", "40", "--random", "0", "--case", "toro-1",
                     "--out", str(tmp_path / "stability")]) == 3
    assert "0 of 1 cases pass" in capsys.readouterr().out


# -- extreme interfaces: air against water ---------------------------------------------------

@settings(max_examples=10, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@example(air_left=True, fraction=0.04, motion="eulerian", air_pressure=8.0, water_pressure=5.0, air_density=0.08)
@given(air_left=st.booleans(), fraction=st.sampled_from([0.002, 0.04, 0.3, 0.5, 0.7, 0.96, 0.998]),
       motion=st.sampled_from(["eulerian", "smoothed", "interface", "lagrangian"]),
       air_pressure=st.floats(5.0, 8.0), water_pressure=st.floats(5.0, 9.0), air_density=st.floats(-1.0, 0.5))
def test_drawn_air_water_interfaces_survive(air_left, fraction, motion, air_pressure, water_pressure, air_density):
    """Air (ρ 0.1 to 3) against water (ρ 1000): pressures 1e5 to 1e9 Pa on either side
    (ratios up to 1e4 with the high pressure in the water, 1e3 in the air), the interface at
    any of these fractions of its cell, in both orders, on every mesh motion.  The air at 1e8
    Pa against water, 4 % of a cell on an Eulerian mesh (the explicit example), broke down at
    step 5 ('interface solve = nan')."""
    air, water = (10 ** air_density, 10 ** air_pressure), (1000.0, 10 ** water_pressure)
    row = run_case(extreme_case("drawn", air_left, fraction, motion, air, water, cells=60))
    assert row["verdict"] == "pass", f"{row['case']}: {row['verdict']} {row['diagnostic']}"


@pytest.mark.parametrize("motion", ["smoothed", "lagrangian"])
def test_a_sliver_of_air_struck_by_water_at_1e4_its_pressure(motion):
    """Air at 1e5 Pa, 0.2 % of its cell, against water at 1e9 Pa: the initial relaxation
    leaves a hot sliver of air at the water's pressure, which expands faster than the
    step the pure cells allow can follow — the interface solve's root then left the air's
    EOS domain (Lagrangian: step 3; smoothed, where Γ hops between the cells of a node:
    step 15).  Such a step is now taken again with half the time step (2 halvings
    Lagrangian, 1 smoothed), and without the retries it still fails."""
    from ale_xfem import run

    case = extreme_case("sliver", True, 0.002, motion, (1.2, 1e5), (1000.0, 1e9), cells=100)
    row = run_case(case)
    assert row["verdict"] == "pass", row["diagnostic"]
    result = run.simulate(build_problem(case.scene(100)))
    assert result.status == "ok" and result.mixed_cells["halved_steps"] >= 1
    saved = run.MIXED_CELL_RETRIES
    try:
        run.MIXED_CELL_RETRIES = 0
        assert run.simulate(build_problem(case.scene(100))).status == "failed"
    finally:
        run.MIXED_CELL_RETRIES = saved


def test_the_single_velocity_closure_with_water_against_light_air():
    """Water at 1e9 Pa against air at 1e5 Pa and ρ 0.1 on an Eulerian mesh, single-velocity
    mixed cells: the remapped air left its EOS domain while the relaxation could converge
    to compressed air at a negative energy."""
    row = run_case(extreme_case("single", False, 0.04, "eulerian", (0.1, 1e5), (1000.0, 1e9), cells=200,
                                model="single_velocity"))
    assert row["verdict"] == "pass", row["diagnostic"]
