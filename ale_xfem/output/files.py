"""Run outputs: summary.json, profile.csv (1D) or cells.csv (2D, see ale_xfem.output.cells_2d), the
resolved scene, and the PNG plot."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import tomli_w

from ale_xfem.output.profile import write_profile
from ale_xfem.problem.build import Problem
from ale_xfem.run import RunResult


# what a run of a scene named <name> writes into its output folder (ale_xfem.output.cells_2d,
# ale_xfem.output.vtx, the plots): an earlier run's are removed before a run, so that the
# folder holds one run's outputs (a coarser rerun with fewer frames left the finer run's
# last frames beside its own)
RUN_FILES = ("summary.json", "scene.toml", "profile.csv", "cells.csv")
SCENE_FILES = ("{name}.png", "{name}-xt.png", "{name}.pvd", "{name}_[0-9][0-9][0-9][0-9].vtu")
SCENE_FOLDERS = ("{name}-cells.bp", "{name}-velocity.bp")


def remove_earlier_outputs(folder: Path, name: str) -> list[Path]:
    """Remove from ``folder`` the outputs an earlier run of the scene ``name`` wrote there
    (RUN_FILES, SCENE_FILES, SCENE_FOLDERS; nothing else is touched).  Returns what was
    removed."""
    import shutil

    folder = Path(folder)
    removed = [folder / file for file in RUN_FILES if (folder / file).is_file()]
    for pattern in SCENE_FILES:
        removed += [path for path in folder.glob(pattern.format(name=name)) if path.is_file()]
    for path in removed:
        path.unlink()
    for pattern in SCENE_FOLDERS:
        path = folder / pattern.format(name=name)
        if path.is_dir():
            shutil.rmtree(path)
            removed.append(path)
    return removed


def write_resolved_scene(problem: Problem, folder: Path) -> Path:
    path = folder / "scene.toml"
    path.write_bytes(tomli_w.dumps(problem.scene.resolved).encode())
    return path


def summary(problem: Problem, result: RunResult) -> dict:
    scene = problem.scene
    data = {
        "scene": scene.name,
        "status": result.status,
        "t_end": scene.t_end,
        "t_reached": result.state.time,
        "steps": result.steps,
        "cells": problem.mesh.n_cells,
        "ranks": result.ranks,
        "wall_seconds": result.wall_seconds,
        "compile_seconds": result.compile_seconds,
        "zone_cycles_per_second": result.zone_cycles_per_second,
        "effects": list(problem.effects),
        "conservation": result.conservation,
        "dt": {"min": result.dt_min, "max": result.dt_max},
        "phase_seconds": result.phase_seconds,
    }
    if result.interface_solve is not None:  # (several MPI ranks, an assembled interface system)
        data["interface_solve"] = result.interface_solve
    if result.remaps is not None:
        data["remaps"] = result.remaps
    if result.mixed_cells is not None:
        data["mixed_cells"] = result.mixed_cells
    if result.diagnostic:
        data["diagnostic"] = result.diagnostic
    if result.errors is not None:
        data["errors"] = result.errors
    if problem.exact is not None:  # what the reference is, how long it holds, and why
        data["exact_reference"] = exact_reference_note(problem, result)
    return data


def exact_reference_note(problem: Problem, result: RunResult) -> dict:
    """The exact reference of the scene: its kind, until when it is the solution of the scene
    as run (``valid_until``), whether the errors were taken against it, and the phrase that
    says what limits it."""
    exact = problem.exact
    return {"kind": exact.kind, "valid_until": _finite_or_none(exact.valid_until),
            "errors": result.errors is not None, "limit": exact.limit}


def _finite_or_none(value: float):
    """JSON has no infinity: a reference that holds for ever is written null."""
    return value if np.isfinite(value) else None


def write_summary(problem: Problem, result: RunResult, folder: Path) -> Path:
    path = folder / "summary.json"
    path.write_text(json.dumps(summary(problem, result), indent=2) + "\n")
    return path


def write_outputs(problem: Problem, result: RunResult, folder: Path, plot: bool = True) -> dict:
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = {
        "scene": write_resolved_scene(problem, folder),
        "summary": write_summary(problem, result, folder),
    }
    if problem.mesh.dimension == 2:
        from ale_xfem.output.cells_2d import plot_density_2d, write_cells

        written["cells"] = write_cells(problem, result.state, folder)
        if plot:
            written["plot"] = plot_density_2d(problem, result, folder / f"{problem.scene.name}.png")
        return written
    written["profile"] = write_profile(problem, result.state, folder)
    if plot:
        from ale_xfem.output.plots import plot_profile

        written["plot"] = plot_profile(problem, result, folder / f"{problem.scene.name}.png")
    return written
