"""profile.csv (1D): a row per cell per material present, sorted by position; a mixed cell's
rows give each material's own sub-interval."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ale_xfem.problem.build import Problem


PROFILE_COLUMNS = ("x_left", "x_right", "material", "volume_fraction", "density", "velocity",
                   "pressure", "internal_energy")


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
