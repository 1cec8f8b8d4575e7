import numpy as np
import pytest

from ale_xfem.problem import build_problem
from ale_xfem.run import simulate
from ale_xfem.scene import load_scene, resolve_scene_path


def run_scene(name: str, *overrides: str):
    """Build and run a shipped scene with --set style overrides; returns (problem, result)."""
    problem = build_problem(load_scene(resolve_scene_path(name), list(overrides)))
    return problem, simulate(problem)


def fitted_rate(sizes, errors) -> float:
    """Convergence rate r of error ~ h^r, fitted over all resolutions (log-log slope)."""
    return -float(np.polyfit(np.log(sizes), np.log(errors), 1)[0])


@pytest.fixture
def run():
    return run_scene
