"""1D profile plots: density, velocity, pressure, internal energy against x, with the exact
solution overlaid when the scene has one."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ale_xfem.io import profile_rows  # noqa: E402

PANELS = (("density", "density"), ("velocity", "velocity"), ("pressure", "pressure"),
          ("internal_energy", "specific internal energy"))


def plot_profile(problem, result, path: Path, title: str | None = None) -> Path:
    state = result.state
    rows = profile_rows(problem, state)
    centres = 0.5 * (rows["x_left"] + rows["x_right"])
    fig, axes = plt.subplots(2, 2, figsize=(10, 7), sharex=True)
    reference = None
    if problem.exact is not None and state.time > 0:
        a, b = problem.scene.mesh.extent
        fine = np.linspace(min(a, rows["x_left"].min()), max(b, rows["x_right"].max()), 4001)
        reference = problem.exact.sample(fine, state.time)
    materials = list(dict.fromkeys(rows["material"]))
    for ax, (key, label) in zip(axes.ravel(), PANELS):
        if reference is not None:
            ax.plot(fine, reference[key], "k-", lw=1.0, label="exact")
        for index, material in enumerate(materials):
            mask = rows["material"] == material
            ax.plot(centres[mask], rows[key][mask], ".", ms=3, color=f"C{index}",
                    label=f"{material}")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    for ax in axes[1]:
        ax.set_xlabel("x")
    axes[0, 0].legend(loc="best", fontsize=8)
    status = "" if result.status == "ok" else f"  [{result.status}]"
    fig.suptitle(title or f"{problem.scene.name}: t = {state.time:.4g}, "
                 f"{problem.mesh.n_cells} cells{status}")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
