import os

import numpy as np
import pytest

from ale_xfem.problem import build_problem
from ale_xfem.run import simulate
from ale_xfem.scene import load_scene, resolve_scene_path

# The tests' MPI runs start more processes than the machine has cores (two test workers, one
# of them launching two or three ranks); MPICH's waiting ranks then poll and take the cores
# from the ranks they wait for.  Its progress throttle lets a rank that polls in vain sleep:
# the 1D enriched tube's distributed solve on 3 ranks beside nothing else, 16.6 s without it,
# 1.9 s with it, the same results.  (The runs' subprocesses inherit the environment.)
os.environ.setdefault("MPIR_CVAR_CH4_PROGRESS_THROTTLE", "1")
os.environ.setdefault("MPIR_CVAR_CH4_PROGRESS_THROTTLE_NO_PROGRESS_COUNT", "256")


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
