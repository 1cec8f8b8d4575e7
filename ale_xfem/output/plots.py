"""1D profile plots: density, velocity, pressure, internal energy against x, with the exact
solution overlaid when the scene has one."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ale_xfem.output.profile import profile_rows  # noqa: E402

PANELS = (("density", "density"), ("velocity", "velocity"), ("pressure", "pressure"),
          ("internal_energy", "specific internal energy"))


def plot_profile(problem, result, path: Path, title: str | None = None) -> Path:
    state = result.state
    rows = profile_rows(problem, state)
    centres = 0.5 * (rows["x_left"] + rows["x_right"])
    fig, axes = plt.subplots(2, 2, figsize=(10, 7), sharex=True)
    reference = None
    if problem.exact is not None and state.time > 0 and problem.exact.holds_at(state.time):
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
    if problem.exact is not None and reference is None and state.time > 0:  # say why it is not drawn
        fig.text(0.5, 0.005, f"no exact overlay: {problem.exact.limit}", ha="center", va="bottom", fontsize=8)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_comparison(runs, path: Path, title: str, fields=("density", "velocity", "pressure",
                                                            "internal_energy"), exact=None, time=None):
    """Overlay the profiles of several runs (a list of (label, problem, result)) and, when
    given, an exact reference (an object with ``sample(x, t)``)."""
    labels = dict(PANELS)
    labels["velocity_transverse"] = "transverse velocity"
    columns = 2 if len(fields) > 1 else 1
    rows_ = (len(fields) + 1) // 2
    fig, axes = plt.subplots(rows_, columns, figsize=(5 * columns, 3.4 * rows_), sharex=True, squeeze=False)
    axes = axes.ravel()
    reference = None
    if exact is not None and time:
        lo = min(profile_rows(p, r.state)["x_left"].min() for _, p, r in runs)
        hi = max(profile_rows(p, r.state)["x_right"].max() for _, p, r in runs)
        fine = np.linspace(lo, hi, 4001)
        reference = exact.sample(fine, time)
    markers = ("o", "s", "^", "v")
    for index, (label, problem, result) in enumerate(runs):
        rows = profile_rows(problem, result.state)
        centres = 0.5 * (rows["x_left"] + rows["x_right"])
        for ax, key in zip(axes, fields):
            ax.plot(centres, rows[key], markers[index % 4], ms=2.5, mfc="none", color=f"C{index}",
                    label=label, lw=0.6, ls="-" if index == 0 else "none")
    for ax, key in zip(axes, fields):
        if reference is not None and key in reference:
            ax.plot(fine, reference[key], "k-", lw=1.0, label="exact")
        ax.set_ylabel(labels.get(key, key))
        ax.grid(alpha=0.3)
        ax.set_xlabel("x")
    for ax in axes[len(fields):]:
        ax.set_visible(False)
    axes[0].legend(fontsize=8, loc="best")
    fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


class XTHistory:
    """Density over x and t, recorded as a run goes (pass :meth:`observe` to simulate):
    the sorted node positions and the cell-average densities, every ``stride`` steps; past
    ``max_rows`` rows every other row is dropped and the stride doubles."""

    def __init__(self, max_rows: int = 600):
        self.max_rows, self.stride, self.count = max_rows, 1, 0
        self.times, self.edges, self.densities = [], [], []

    def observe(self, state, problem) -> None:
        self.count += 1
        if (self.count - 1) % self.stride:
            return
        nodes = problem.mesh.cell_nodes
        x = state.node_position[0][nodes]
        left, right = x.min(axis=1), x.max(axis=1)
        order = np.argsort(left + right)
        mass = state.material_mass.sum(axis=0)
        self.times.append(state.time)
        self.edges.append(np.concatenate([left[order[:1]], right[order]]))
        self.densities.append(mass[order] / (right - left)[order])
        if len(self.times) > self.max_rows:
            for rows in (self.times, self.edges, self.densities):
                del rows[1::2]
            self.stride *= 2


def plot_xt(history: XTHistory, path: Path, title: str = "") -> Path:
    """x–t diagram: density as colour over the mesh's own positions (a Lagrangian mesh's
    cells are the strips between the node paths); logarithmic colours when the density
    spans more than a factor 50."""
    from matplotlib.colors import LogNorm, Normalize

    x = np.array(history.edges)  # (rows, n + 1)
    t = np.repeat(np.array(history.times)[:, None], x.shape[1], axis=1)
    density = np.array(history.densities)[:-1]  # the colour of the strip above each row
    low, high = float(density.min()), float(density.max())
    norm = LogNorm(low, high) if low > 0 and high / low > 50 else Normalize(low, high)
    fig, ax = plt.subplots(figsize=(8, 5))
    mesh = ax.pcolormesh(x, t, density, norm=norm, cmap="viridis", shading="flat")
    fig.colorbar(mesh, ax=ax, label="density")
    ax.set_xlabel("x")
    ax.set_ylabel("t")
    ax.set_title(title or "density over x and t")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path)
