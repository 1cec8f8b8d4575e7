"""2D run outputs: ``cells.csv`` for scripts, a VTK time series for ParaView and pyvista
(the frames of a run, :class:`Frames`, which also go to the VTX files of
:mod:`ale_xfem.output.vtx`), and a PNG picture: the density on the deformed mesh with the boundaries between materials,
and, where the scene has an exact solution that still holds, a cut against it.

``cells.csv`` has a row per cell per material present, columns
``x,y,volume,material,volume_fraction,density,velocity_x,velocity_y,pressure,internal_energy``
(x, y: centroid of that material's part of the cell; volume: its area; the velocity is the
mean of the cell's corner velocities, one field for both materials of a single-velocity
mixed cell).  A mixed cell's parts are those of its PLIC reconstruction (``ale_xfem.model.plic``):
their areas are the materials' volumes exactly; rows come cell by cell.

The series ``<name>.pvd`` (a VTK collection: ParaView opens it, ``pyvista.read`` reads it)
lists one ``<name>_NNNN.vtu`` per written time: the moving mesh, the nodal ``velocity``,
and per material m the cell fields ``volume_fraction_m``, ``density_m``, ``pressure_m``,
``internal_energy_m`` (0 where m is absent), with ``material`` (the index of the cell's
main material — slot 0 — in the scene's order) and the cell's mean ``density``.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ale_xfem.geometry.shapes import polygon_area, polygon_centroid
from ale_xfem.model.mesh import mesh_edges
from ale_xfem.model.plic import part_centroids, reconstruct_state

CELLS_COLUMNS = ("x", "y", "volume", "material", "volume_fraction", "density", "velocity_x",
                 "velocity_y", "pressure", "internal_energy")


def cells_rows(problem, state) -> dict[str, np.ndarray]:
    """Rows of ``cells.csv``: pure cells whole; a mixed cell as its two PLIC parts."""
    mesh = problem.mesh
    vertices = mesh.cell_vertex_positions(state.node_position)
    centroid = polygon_centroid(vertices)
    area = polygon_area(vertices)
    velocity = state.node_velocity[:, mesh.cell_nodes].mean(axis=2)
    names = np.array([m.name for m in problem.materials])
    material = problem.layout.cell_material[0]
    rows = {
        "x": centroid[:, 0], "y": centroid[:, 1], "volume": state.material_volume[0].copy(),
        "material": names[material],
        "volume_fraction": state.material_volume[0] / area,
        "density": state.material_density[0],
        "velocity_x": velocity[0], "velocity_y": velocity[1],
        "pressure": state.material_pressure[0],
        "internal_energy": state.material_energy[0],
        "cell": np.arange(mesh.n_cells),
    }
    if problem.mixed is None:
        return rows
    plic = reconstruct_state(problem, state, normal=problem.scene.interface.normal)
    c = plic.cells
    alpha_centre, beta_centre = part_centroids(plic)
    rows = {k: v.copy() for k, v in rows.items()}
    rows["x"][c], rows["y"][c] = alpha_centre[:, 0], alpha_centre[:, 1]
    extra = {
        "x": beta_centre[:, 0], "y": beta_centre[:, 1], "volume": state.material_volume[1, c],
        "material": names[problem.layout.cell_material[1, c]],
        "volume_fraction": state.material_volume[1, c] / area[c],
        "density": state.material_density[1, c],
        "velocity_x": velocity[0, c], "velocity_y": velocity[1, c],
        "pressure": state.material_pressure[1, c],
        "internal_energy": state.material_energy[1, c],
        "cell": c,
    }
    rows = {k: np.concatenate([rows[k], extra[k]]) for k in rows}
    order = np.argsort(rows["cell"], kind="stable")
    return {k: v[order] for k, v in rows.items()}


def write_cells(problem, state, folder: Path) -> Path:
    rows = cells_rows(problem, state)
    path = Path(folder) / "cells.csv"
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(CELLS_COLUMNS)
        for values in zip(*(rows[c] for c in CELLS_COLUMNS)):
            writer.writerow([v if isinstance(v, str) else repr(float(v)) for v in values])
    return path


def vtk_grid(mesh, node_position):
    """The mesh as a pyvista UnstructuredGrid at these positions (our node and cell order)."""
    import pyvista as pv

    points = np.zeros((mesh.n_nodes, 3))
    points[:, :2] = node_position.T
    corners = mesh.cell_type.nodes_per_cell
    cell_kind = pv.CellType.QUAD if corners == 4 else pv.CellType.TRIANGLE
    connectivity = np.hstack([np.full((mesh.n_cells, 1), corners), mesh.cell_nodes]).ravel()
    return pv.UnstructuredGrid(connectivity, np.full(mesh.n_cells, cell_kind), points)


def cell_fields(problem, state) -> dict[str, np.ndarray]:
    """The cell fields of the series (module docstring), (n_cells,) each."""
    mesh, layout = problem.mesh, problem.layout
    area = mesh.cell_volumes(state.node_position)
    fields = {"material": layout.cell_material[0].astype(float),
              "density": state.material_mass.sum(axis=0) / area}
    for index, material in enumerate(problem.materials):
        values = {q: np.zeros(area.size) for q in ("volume_fraction", "density", "pressure", "internal_energy")}
        for slot in range(layout.cell_material.shape[0]):
            here = layout.cell_material[slot] == index
            values["volume_fraction"][here] = state.material_volume[slot, here] / area[here]
            values["density"][here] = state.material_density[slot, here]
            values["pressure"][here] = state.material_pressure[slot, here]
            values["internal_energy"][here] = state.material_energy[slot, here]
        fields.update({f"{q}_{material.name}": v for q, v in values.items()})
    return fields


class Frames:
    """The states a series of frames keeps — the first state at or after each of ``frames``
    + 1 evenly spaced times from 0 to ``t_end`` — handed to each of ``writers`` (objects
    with ``write(state, problem)`` and ``close()``).  ``observe(state, problem)`` fits
    :func:`ale_xfem.run.simulate`'s observer; ``observe_from()`` says from which time it
    wants a state again (so that the steps before may run without it)."""

    def __init__(self, t_end: float, frames: int, writers):
        self.times = np.linspace(0.0, t_end, frames + 1)
        self.writers = list(writers)
        self.next = 0
        self.written = 0

    def observe_from(self) -> float:
        """The time from which :meth:`observe` writes a state again (inf: never)."""
        return self.times[self.next] * (1 - 1e-12) if self.next < self.times.size else np.inf

    def observe(self, state, problem) -> None:
        if self.next < self.times.size and state.time >= self.times[self.next] * (1 - 1e-12):
            self.write(state, problem)
            while self.next < self.times.size and self.times[self.next] <= state.time * (1 + 1e-12):
                self.next += 1

    def write(self, state, problem) -> None:
        for writer in self.writers:
            writer.write(state, problem)
        self.written += 1

    def finish(self, state, problem) -> None:
        """Write the run's last state (a failed run's last good one) unless it was written,
        and close the writers."""
        if self.written == 0 or self.times[min(self.next, self.times.size - 1)] > state.time:
            self.write(state, problem)
        self.close()

    def close(self) -> None:
        for writer in self.writers:
            writer.close()


class VTKFiles:
    """Writes states to ``<folder>/<name>.pvd`` and its ``.vtu`` files (module docstring),
    the mesh moving with the nodes; the collection is rewritten with each frame, so a run
    that breaks down leaves a readable series."""

    def __init__(self, problem, folder: Path):
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.name = problem.scene.name
        self.path = self.folder / f"{self.name}.pvd"
        self.grid = vtk_grid(problem.mesh, problem.state.node_position)
        self.entries = []  # (time, file name)

    def write(self, state, problem) -> None:
        grid = self.grid
        grid.points[:, :2] = state.node_position.T
        grid.point_data["velocity"] = np.column_stack([state.node_velocity[0], state.node_velocity[1],
                                                       np.zeros(problem.mesh.n_nodes)])
        for key, values in cell_fields(problem, state).items():
            grid.cell_data[key] = values
        file = f"{self.name}_{len(self.entries):04d}.vtu"
        grid.save(str(self.folder / file))
        self.entries.append((float(state.time), file))
        datasets = "\n".join(f'    <DataSet timestep="{time!r}" part="0" file="{name}"/>'
                             for time, name in self.entries)
        self.path.write_text('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n'
                             f"  <Collection>\n{datasets}\n  </Collection>\n</VTKFile>\n")

    def close(self) -> None:
        """Nothing is held open: each frame is complete on disk."""


class VTKSeries(Frames):
    """The VTK series alone (:class:`VTKFiles`) at ``frames`` + 1 times (:class:`Frames`)."""

    def __init__(self, problem, folder: Path, frames: int = 20):
        self.files = VTKFiles(problem, folder)
        super().__init__(problem.scene.t_end, frames, [self.files])

    @property
    def entries(self) -> list:
        """(time, file name) of each frame written."""
        return self.files.entries

    @property
    def path(self) -> Path:
        return self.files.path


def material_edges(problem) -> tuple[np.ndarray, np.ndarray]:
    """The mesh edges between two pure cells of different materials: (first node, second
    node) arrays."""
    a, b, plus, minus = mesh_edges(problem.mesh.cell_nodes)
    material = problem.layout.cell_material[0].copy()
    if problem.mixed is not None:
        material[problem.mixed.cells] = -1  # drawn by their PLIC segments
    other = np.where(minus >= 0, material[np.maximum(minus, 0)], -1)  # −1: the domain's boundary
    differ = (material[plus] != other) & (material[plus] >= 0) & (other >= 0)
    return a[differ], b[differ]


def exact_cut(problem, state):
    """Where the scene's exact solution still holds: the coordinate along which it varies
    for each cell centroid (r from Noh's or Sedov's centre, the distance along the piston's
    direction or the planar Riemann problem's normal), the exact density at the centroids,
    a mask of the cells to compare (the planar problem's window) and the axis label; or None."""
    exact = problem.exact
    if exact is None or state.time <= 0 or not exact.holds_at(state.time):
        return None
    labels = {"noh": "r (distance from the centre)", "sedov": "r (distance from the centre)",
              "piston": "distance from the piston's start, along its motion",
              "planar_riemann": "distance from the initial interface, along its normal",
              "spinning_disk": "r (distance from the centre)"}
    if exact.kind not in labels:
        return None
    centroid = problem.mesh.cell_centroids(state.node_position)
    coordinate, label = exact.solution.coordinate(centroid), labels[exact.kind]
    keep = np.ones(coordinate.size, dtype=bool)
    if exact.window is not None:
        centre, radius = exact.window
        keep = np.linalg.norm(centroid - np.asarray(centre), axis=1) <= radius
    density = exact.sample(centroid, state.time)["density"]
    return coordinate, density, keep, label


def plot_density_2d(problem, result, path: Path) -> Path:
    """PNG of the density (a mixed cell's mean) on the deformed mesh, with axes and a colour
    bar, the boundaries between materials in black (mesh lines between pure cells, PLIC
    segments in mixed cells); beside it, where the exact solution holds, the cells' density
    along the coordinate the solution varies with, the exact curve overlaid."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection, PolyCollection

    mesh, state = problem.mesh, result.state
    density = state.material_mass.sum(axis=0) / mesh.cell_volumes(state.node_position)
    cut = exact_cut(problem, state)
    figure, axes = plt.subplots(1, 2 if cut is not None else 1, figsize=(13 if cut is not None else 7, 5.6),
                                squeeze=False)
    field = axes[0, 0]
    polygons = PolyCollection(mesh.cell_vertex_positions(state.node_position), array=density, cmap="viridis",
                              edgecolors="grey" if mesh.n_cells <= 2500 else "face", linewidths=0.2)
    field.add_collection(polygons)
    segments = []
    first, second = material_edges(problem)
    if first.size:
        segments += list(np.stack([state.node_position[:, first].T, state.node_position[:, second].T], axis=1))
    if problem.mixed is not None:  # the reconstructed interface
        plic = reconstruct_state(problem, state, normal=problem.scene.interface.normal)
        segments += list(np.stack([plic.start, plic.end], axis=1))
    if segments:
        field.add_collection(LineCollection(segments, colors="black", linewidths=1.2))
    field.autoscale_view()
    field.set_aspect("equal")
    field.set_xlabel("x")
    field.set_ylabel("y")
    figure.colorbar(polygons, ax=field, label="density", shrink=0.9)
    status = "" if result.status == "ok" else f"  [{result.status}]"
    field.set_title(f"{problem.scene.name}, t = {state.time:.4g}{status}")
    if cut is not None:
        coordinate, exact, keep, label = cut
        order = np.argsort(coordinate[keep])
        profile = axes[0, 1]
        profile.plot(coordinate[keep], density[keep], ".", ms=2.5, color="C0", label="cells")
        profile.plot(coordinate[keep][order], exact[keep][order], "k-", lw=1.0, label=f"exact ({problem.exact.kind})")
        profile.set_xlabel(label)
        profile.set_ylabel("density")
        profile.grid(alpha=0.3)
        profile.legend(loc="best", fontsize=8)
        profile.set_title("every cell's density at its centroid" + (" (inside the window)" if not keep.all() else ""))
    elif problem.exact is not None and state.time > 0:
        figure.text(0.5, 0.01, f"no exact comparison: {problem.exact.limit}", ha="center", fontsize=8)
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)
    return Path(path)
