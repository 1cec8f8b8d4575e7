"""2D run outputs: ``cells.csv`` for scripts, a VTX time series for ParaView, and a pyvista
PNG snapshot of the density with the boundaries between materials drawn.

``cells.csv`` has a row per cell per material present, columns
``x,y,volume,material,volume_fraction,density,velocity_x,velocity_y,pressure,internal_energy``
(x, y: centroid of that material's part of the cell; volume: its area; the velocity is the
mean of the cell's corner velocities, one field for both materials of a single-velocity
mixed cell).  A mixed cell's parts are those of its PLIC reconstruction (``ale_xfem.model.plic``):
their areas are the materials' volumes exactly; rows come cell by cell.

The VTX folder ``<name>.bp`` holds, at each written time, the moving mesh, the nodal
velocity, and per material m the cell fields ``volume_fraction_m``, ``density_m``,
``pressure_m``, ``internal_energy_m`` (0 where m is absent), with ``material`` (the index of
the cell's main material — slot 0 — in the scene's order) and the cell's mean ``density``.
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
    plic = reconstruct_state(problem, state)
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


class VTXSeries:
    """Writes the state at chosen times to ``<folder>/<name>.bp`` (ADIOS2 VTX, read by
    ParaView), the mesh moving with the nodes.  ``observe(state, problem)`` fits
    :func:`ale_xfem.run.simulate`'s observer: it writes the first state at or after each of
    ``frames`` + 1 evenly spaced times from 0 to t_end."""

    def __init__(self, problem, folder: Path, frames: int = 20):
        import dolfinx_solver  # noqa: F401
        import dolfinx
        import dolfinx.io

        Path(folder).mkdir(parents=True, exist_ok=True)
        self.path = Path(folder) / f"{problem.scene.name}.bp"
        mesh = problem.mesh.dolfinx_mesh
        self.mesh = mesh
        velocity_space = dolfinx.fem.functionspace(mesh, ("Lagrange", 1, (2,)))
        cell_space = dolfinx.fem.functionspace(mesh, ("DG", 0))
        self.velocity = dolfinx.fem.Function(velocity_space, name="velocity")
        # the project's node and cell numbers may differ from DOLFINx's (a rectangle is
        # numbered row by row: MeshArrays.dolfinx_node / dolfinx_cell)
        arrays = problem.mesh
        self.geometry_node = (np.arange(arrays.n_nodes) if arrays.dolfinx_node is None
                              else arrays.dolfinx_node)
        node_of_geometry = np.empty_like(self.geometry_node)
        node_of_geometry[self.geometry_node] = np.arange(arrays.n_nodes)
        node_of_dof = np.empty(velocity_space.dofmap.index_map.size_local, dtype=np.int64)
        node_of_dof[velocity_space.dofmap.list] = node_of_geometry[mesh.geometry.dofmaps[0]]
        self.node_of_dof = node_of_dof
        cell_dof = cell_space.dofmap.list[:, 0]
        self.cell_dof = (cell_dof if arrays.dolfinx_cell is None else cell_dof[arrays.dolfinx_cell]).copy()
        names = [m.name for m in problem.materials]
        self.fields = {"material": dolfinx.fem.Function(cell_space, name="material"),
                       "density": dolfinx.fem.Function(cell_space, name="density")}
        for name in names:
            for quantity in ("volume_fraction", "density", "pressure", "internal_energy"):
                key = f"{quantity}_{name}"
                self.fields[key] = dolfinx.fem.Function(cell_space, name=key)
        self.names = names
        self.writer = dolfinx.io.VTXWriter(mesh.comm, str(self.path), [self.velocity, *self.fields.values()],
                                           engine="BP4", mesh_policy=dolfinx.io.VTXMeshPolicy.update)
        self.times = np.linspace(0.0, problem.scene.t_end, frames + 1)
        self.next = 0
        self.written = 0

    def observe(self, state, problem) -> None:
        if self.next < self.times.size and state.time >= self.times[self.next] * (1 - 1e-12):
            self.write(state, problem)
            while self.next < self.times.size and self.times[self.next] <= state.time * (1 + 1e-12):
                self.next += 1

    def write(self, state, problem) -> None:
        mesh = problem.mesh
        self.mesh.geometry.x[self.geometry_node, :2] = state.node_position.T
        self.velocity.x.array[:] = state.node_velocity[:2, self.node_of_dof].T.ravel()
        material = problem.layout.cell_material[0]
        area = mesh.cell_volumes(state.node_position)

        def put(key, values):
            self.fields[key].x.array[self.cell_dof] = values

        put("material", material.astype(float))
        put("density", state.material_mass.sum(axis=0) / area)
        for index, name in enumerate(self.names):
            fraction, density, pressure, energy = (np.zeros(area.size) for _ in range(4))
            for slot in range(problem.layout.cell_material.shape[0]):
                here = problem.layout.cell_material[slot] == index
                fraction[here] = state.material_volume[slot, here] / area[here]
                density[here] = state.material_density[slot, here]
                pressure[here] = state.material_pressure[slot, here]
                energy[here] = state.material_energy[slot, here]
            put(f"volume_fraction_{name}", fraction)
            put(f"density_{name}", density)
            put(f"pressure_{name}", pressure)
            put(f"internal_energy_{name}", energy)
        self.writer.write(float(state.time))
        self.written += 1

    def close(self) -> None:
        self.writer.close()


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


def plot_density_2d(problem, result, path: Path) -> Path:
    """PNG of the density (a mixed cell's mean) on the deformed mesh, boundaries between
    materials in black: mesh lines between pure cells, PLIC segments in mixed cells."""
    import os

    if not os.environ.get("DISPLAY"):  # headless: render through EGL, not a missing X server
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    pv.OFF_SCREEN = True
    mesh, state = problem.mesh, result.state
    points = np.zeros((mesh.n_nodes, 3))
    points[:, :2] = state.node_position.T
    corners = mesh.cell_type.nodes_per_cell
    cell_kind = pv.CellType.QUAD if corners == 4 else pv.CellType.TRIANGLE
    connectivity = np.hstack([np.full((mesh.n_cells, 1), corners), mesh.cell_nodes]).ravel()
    grid = pv.UnstructuredGrid(connectivity, np.full(mesh.n_cells, cell_kind), points)
    grid.cell_data["density"] = state.material_mass.sum(axis=0) / mesh.cell_volumes(state.node_position)
    grid.cell_data["material"] = problem.layout.cell_material[0]
    plotter = pv.Plotter(off_screen=True, window_size=(900, 800))
    plotter.add_mesh(grid, scalars="density", cmap="viridis", show_edges=mesh.n_cells <= 2500,
                     edge_color="grey", scalar_bar_args={"title": "density"})
    first, second = material_edges(problem)
    if first.size:
        ends = np.zeros((2 * first.size, 3))
        ends[0::2, :2], ends[1::2, :2] = state.node_position[:, first].T, state.node_position[:, second].T
        plotter.add_mesh(pv.line_segments_from_points(ends), color="black", line_width=2)
    if problem.mixed is not None:  # the reconstructed interface
        plic = reconstruct_state(problem, state)
        ends = np.zeros((2 * plic.cells.size, 3))
        ends[0::2, :2], ends[1::2, :2] = plic.start, plic.end
        plotter.add_mesh(pv.line_segments_from_points(ends), color="black", line_width=2)
    plotter.add_text(f"{problem.scene.name}, t = {state.time:.4g}", font_size=12)
    plotter.view_xy()
    plotter.screenshot(str(path))
    plotter.close()
    return Path(path)
