"""Run outputs: summary.json, profile.csv (1D) or cells.csv (2D, see ale_xfem.io2d), the
resolved scene, and the PNG plot."""

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
    """Per cell per material present, sorted by position (1D).  A row's velocity is the
    mean of its part's end velocities (nodes, and Γ in a mixed cell)."""
    mesh = problem.mesh
    x = state.node_position[0][mesh.cell_nodes]
    u = state.node_velocity[0][mesh.cell_nodes]
    swap = x[:, 0] > x[:, 1]
    x[swap], u[swap] = x[swap, ::-1], u[swap, ::-1]
    names = np.array([m.name for m in problem.materials])
    rows = {
        "x_left": x[:, 0], "x_right": x[:, 1],
        "material": names[problem.layout.cell_material[0]],
        "volume_fraction": state.material_volume[0] / (x[:, 1] - x[:, 0]),
        "density": state.material_density[0],
        "velocity": u.mean(axis=1),
        "pressure": state.material_pressure[0],
        "internal_energy": state.material_energy[0],
    }
    transverse = state.node_velocity.shape[0] > 1
    if transverse:
        w = state.node_velocity[1][mesh.cell_nodes]
        w[swap] = w[swap, ::-1]
        rows["velocity_transverse"] = w.mean(axis=1)
    if problem.mixed is not None:
        cells = problem.mixed.cells
        xg = x[cells, 0] + state.material_volume[0, cells]
        ug = state.interface_velocity
        rows = {k: v.copy() for k, v in rows.items()}
        rows["x_right"][cells] = xg
        rows["velocity"][cells] = 0.5 * (u[cells, 0] + ug)
        extra = {
            "x_left": xg, "x_right": x[cells, 1],
            "material": names[problem.layout.cell_material[1, cells]],
            "volume_fraction": state.material_volume[1, cells] / (x[cells, 1] - x[cells, 0]),
            "density": state.material_density[1, cells],
            "velocity": 0.5 * (ug + u[cells, 1]),
            "pressure": state.material_pressure[1, cells],
            "internal_energy": state.material_energy[1, cells],
        }
        if transverse:
            # each material's own transverse velocity: that of its internal node
            rows["velocity_transverse"][cells] = w[cells, 0]
            extra["velocity_transverse"] = w[cells, 1]
        rows = {k: np.concatenate([rows[k], extra[k]]) for k in rows}
    order = np.argsort(rows["x_left"], kind="stable")
    return {k: v[order] for k, v in rows.items()}


def write_profile(problem: Problem, state, folder: Path) -> Path:
    rows = profile_rows(problem, state)
    names = PROFILE_COLUMNS + (("velocity_transverse",) if "velocity_transverse" in rows else ())
    path = folder / "profile.csv"
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(names)
        columns = [rows[c] for c in names]
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
    if result.mixed_cells is not None:
        data["mixed_cells"] = result.mixed_cells
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
    }
    if problem.mesh.dimension == 2:
        from ale_xfem.io2d import plot_density_2d, write_cells

        written["cells"] = write_cells(problem, result.state, folder)
        if plot:
            written["plot"] = plot_density_2d(problem, result, folder / f"{problem.scene.name}.png")
        return written
    written["profile"] = write_profile(problem, result.state, folder)
    if plot:
        from ale_xfem.plot import plot_profile

        written["plot"] = plot_profile(problem, result, folder / f"{problem.scene.name}.png")
    return written
