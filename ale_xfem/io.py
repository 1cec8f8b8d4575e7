"""Run outputs: summary.json, profile.csv (1D), the resolved scene, and the PNG plot."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import tomli_w

from ale_xfem.problem import Problem
from ale_xfem.run import RunResult

PROFILE_COLUMNS = ("x_left", "x_right", "material", "volume_fraction", "density", "velocity",
                   "pressure", "internal_energy")


def write_resolved_scene(problem: Problem, folder: Path) -> Path:
    path = folder / "scene.toml"
    path.write_bytes(tomli_w.dumps(problem.scene.resolved).encode())
    return path


def profile_rows(problem: Problem, state) -> dict[str, np.ndarray]:
    """Per cell per material present, sorted by position (1D).  The velocity of a row is
    the mean of its cell's nodal velocities (the cell average of the P1 field)."""
    mesh = problem.mesh
    x = state.node_position[0][mesh.cell_nodes]
    u = state.node_velocity[0][mesh.cell_nodes]
    order = np.argsort(x.mean(axis=1), kind="stable")
    names = np.array([m.name for m in problem.materials])
    slot = 0
    return {
        "x_left": x.min(axis=1)[order],
        "x_right": x.max(axis=1)[order],
        "material": names[problem.layout.cell_material[slot]][order],
        "volume_fraction": (state.material_volume[slot] / (x.max(axis=1) - x.min(axis=1)))[order],
        "density": state.material_density[slot][order],
        "velocity": u.mean(axis=1)[order],
        "pressure": state.material_pressure[slot][order],
        "internal_energy": state.material_energy[slot][order],
    }


def write_profile(problem: Problem, state, folder: Path) -> Path:
    rows = profile_rows(problem, state)
    path = folder / "profile.csv"
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(PROFILE_COLUMNS)
        columns = [rows[c] for c in PROFILE_COLUMNS]
        for values in zip(*columns):
            writer.writerow([v if isinstance(v, str) else repr(float(v)) for v in values])
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
        "wall_seconds": result.wall_seconds,
        "zone_cycles_per_second": result.zone_cycles_per_second,
        "effects": list(problem.effects),
        "conservation": result.conservation,
        "dt": {"min": result.dt_min, "max": result.dt_max},
        "phase_seconds": result.phase_seconds,
    }
    if result.diagnostic:
        data["diagnostic"] = result.diagnostic
    if result.errors is not None:
        data["errors"] = result.errors
    return data


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
        "profile": write_profile(problem, result.state, folder),
    }
    if plot:
        from ale_xfem.plot import plot_profile

        written["plot"] = plot_profile(problem, result, folder / f"{problem.scene.name}.png")
    return written
