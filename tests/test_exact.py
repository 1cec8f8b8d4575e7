"""Exact references: Toro's star states, the stiffened-gas shift, impedance matching."""

import numpy as np
import pytest

from ale_xfem.exact import GasState, Plate, PlateImpactSolution, RiemannSolution, VacuumError, star_state

# Toro, Riemann Solvers and Numerical Methods for Fluid Dynamics, tables 4.1–4.3 (γ = 1.4):
# (ρ, u, p) left, right → p*, u*, ρ*L, ρ*R.
TORO = [
    ((1.0, 0.0, 1.0), (0.125, 0.0, 0.1), (0.30313, 0.92745, 0.42632, 0.26557)),
    ((1.0, -2.0, 0.4), (1.0, 2.0, 0.4), (0.00189, 0.00000, 0.02185, 0.02185)),
    ((1.0, 0.0, 1000.0), (1.0, 0.0, 0.01), (460.894, 19.5975, 0.57506, 5.99924)),
    ((1.0, 0.0, 0.01), (1.0, 0.0, 100.0), (46.0950, -6.19633, 5.99242, 0.57511)),
    ((5.99924, 19.5975, 460.894), (5.99242, -6.19633, 46.0950), (1691.64, 8.68975, 14.2823, 31.0426)),
]


@pytest.mark.parametrize("test", range(1, 6))
def test_toro_star_states(test):
    left, right, expected = TORO[test - 1]
    star = star_state(GasState(*left, 1.4), GasState(*right, 1.4))
    got = (star.pressure, star.velocity, star.density_left, star.density_right)
    for value, reference in zip(got, expected):
        # the table gives 5–6 significant digits
        assert value == pytest.approx(reference, rel=5e-5, abs=1e-5)


def test_stiffened_gas_is_an_ideal_gas_in_shifted_pressure():
    p_inf = 2.0
    ideal = RiemannSolution.solve(GasState(1.0, 0.0, 1.0, 1.4), GasState(0.125, 0.0, 0.1, 1.4), 0.5)
    stiff = RiemannSolution.solve(GasState(1.0, 0.0, 1.0 - p_inf, 1.4, p_inf),
                                  GasState(0.125, 0.0, 0.1 - p_inf, 1.4, p_inf), 0.5)
    x = np.linspace(0.0, 1.0, 201)
    a, b = ideal.sample(x, 0.2), stiff.sample(x, 0.2)
    np.testing.assert_allclose(b["density"], a["density"], rtol=1e-10)
    np.testing.assert_allclose(b["velocity"], a["velocity"], rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(b["pressure"] + p_inf, a["pressure"], rtol=1e-10)


def test_sampled_shock_satisfies_rankine_hugoniot():
    """Water–air: mass and momentum fluxes balance across the shock running into air."""
    sol = RiemannSolution.solve(GasState(1000.0, 0.0, 1e9, 4.4, 6e8), GasState(50.0, 0.0, 1e5, 1.4), 0.7)
    shock = sol.wave_speeds()[1]
    t = 1e-4
    ahead, behind = sol.sample(0.7 + (shock + 1.0) * t, t), sol.sample(0.7 + (shock - 1.0) * t, t)
    mass = lambda s: s["density"] * (s["velocity"] - shock)  # noqa: E731
    momentum = lambda s: mass(s) * s["velocity"] + s["pressure"]  # noqa: E731
    assert mass(behind) == pytest.approx(mass(ahead), rel=1e-9)
    assert momentum(behind) == pytest.approx(momentum(ahead), rel=1e-9)


def test_a_riemann_solution_at_t_0_is_its_initial_data():
    """Sampled at t = 0 (an initial state's errors) the solution is the two states, the
    left one on x < x0, without dividing by the zero time."""
    import warnings

    solution = RiemannSolution.solve(GasState(1.0, 0.0, 1.0, 1.4), GasState(0.125, 0.0, 0.1, 1.4), 0.5)
    x = np.array([0.0, 0.49, 0.5, 0.51, 1.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        values = solution.sample(x, 0.0)
    np.testing.assert_array_equal(values["density"], [1.0, 1.0, 0.125, 0.125, 0.125])
    np.testing.assert_array_equal(values["pressure"], [1.0, 1.0, 0.1, 0.1, 0.1])
    np.testing.assert_array_equal(values["velocity"], 0.0)
    with pytest.raises(ValueError, match="t ≥ 0"):
        solution.sample(x, -1e-3)


def test_vacuum_is_reported():
    with pytest.raises(VacuumError):
        star_state(GasState(1.0, -20.0, 0.4, 1.4), GasState(1.0, 20.0, 0.4, 1.4))


def test_symmetric_plate_impact_halves_the_velocity():
    copper = dict(rho0=8930.0, c0=3940.0, s=1.49)
    sol = PlateImpactSolution.solve(Plate(**copper, velocity=500.0), Plate(**copper, velocity=0.0))
    assert sol.contact_velocity == pytest.approx(250.0, rel=1e-12)
    assert sol.contact_pressure == pytest.approx(8930.0 * (3940.0 + 1.49 * 250.0) * 250.0, rel=1e-12)


def test_impedance_matching_balances_both_hugoniots():
    al, cu = Plate(2785.0, 5328.0, 1.338, 2000.0), Plate(8930.0, 3940.0, 1.49, 0.0)
    sol = PlateImpactSolution.solve(al, cu)
    w_al, w_cu = al.velocity - sol.contact_velocity, sol.contact_velocity - cu.velocity
    p_al = al.rho0 * (al.c0 + al.s * w_al) * w_al
    p_cu = cu.rho0 * (cu.c0 + cu.s * w_cu) * w_cu
    assert p_al == pytest.approx(p_cu, rel=1e-12)
    assert 0.0 < sol.contact_velocity < 2000.0


# -- the exact reference is used only while it is the solution of the scene as run ----------

def _summary(tmp_path, scene, *overrides):
    import json

    from ale_xfem.cli import main

    out = tmp_path / "run"
    argv = ["run", scene, "--out", str(out), "--quiet"]
    for override in ("mesh.cells=100", *overrides):
        argv += ["--set", override]
    assert main(argv) == 0
    return json.loads((out / "summary.json").read_text())


@pytest.mark.parametrize("overrides, boundary, phrase", [
    # a free end at p = 0.1 launches a rarefaction at t = 0 (L1(u) read 1.31 against the
    # Riemann solution, 'valid until' 0.285)
    (["boundaries.right=free"], "boundaries.right = free", "rarefaction starts there at t = 0"),
    (["boundaries.left={velocity=[0.5]}"], "boundaries.left = {velocity = [0.5]}", "a wave starts there"),
])
def test_a_boundary_outside_the_exact_problem_leaves_no_errors_and_says_why(tmp_path, overrides, boundary, phrase):
    summary = _summary(tmp_path, "sod", *overrides)
    assert "errors" not in summary
    reference = summary["exact_reference"]
    assert reference["valid_until"] == 0.0 and reference["errors"] is False
    assert reference["limit"].startswith(boundary) and phrase in reference["limit"]


def test_the_exact_reference_holds_until_a_wave_reaches_a_wall_and_then_gives_no_errors(tmp_path):
    within = _summary(tmp_path, "sod")
    assert within["errors"]["L1_density"] < 0.02
    assert within["exact_reference"]["limit"].startswith("the fastest wave reaches the right end (wall) at t = 0.28")
    beyond = _summary(tmp_path, "sod", "t_end=0.3")
    assert "errors" not in beyond and beyond["exact_reference"]["errors"] is False


def test_a_plate_impact_at_an_ambient_pressure_says_why_it_has_no_exact_reference(tmp_path):
    at_rest = _summary(tmp_path, "plate-impact", "mesh.cells=60")
    assert at_rest["errors"]["L1_velocity"] > 0
    ambient = _summary(tmp_path, "plate-impact", "mesh.cells=60", "regions.0.pressure=1e5", "regions.1.pressure=1e5")
    assert "errors" not in ambient
    assert ambient["exact_reference"]["limit"].startswith("the plates are at p = 100000 | 100000, not at their "
                                                          "reference state")
