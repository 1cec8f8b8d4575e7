# # Bubbles or Nitsche: stabilising the interface of 2D enriched mixed cells
#
# In an enriched mixed cell each material has its own velocity on every node of the cell,
# and an interface condition ties them: the normal velocity is continuous across the
# interface Γ, and the interface pressure p_Γ is what enforces it.  Written with P1 (or
# Q1) velocities and one p_Γ per cut cell — the natural choice — the pair is not stable:
# p_Γ checkerboards along Γ (the paper's §3.2).  Two cures: one massless *bubble* per
# material per cut cell (zero on the cell's edges, so it touches no neighbour), or
# *Nitsche's method*, no multiplier at all but a weighted average of the two materials'
# pressures plus a penalty on the normal velocity jump.
#
# This demo solves one implicit step of the mixed cells of a unit square where a light
# material α strikes a stiffer one β across a straight interface at 17° to the mesh, and
# shows p_Γ along Γ with each choice; then two materials sliding past each other, free
# slip against stick; then a whole run of one scene, the sheared two-material tube, with
# each stabilisation side by side: its density and interface, each material's tangential
# velocity across Γ, and p_Γ along Γ.  (`ale-xfem study interface` measures the same over
# resolutions and penalty factors; docs/design.md §4 has the method.)
#
# Run as `.venv/bin/python demos/bubble_vs_nitsche.py [--cells 48] [--out out/bubble_vs_nitsche]`
# (the scene runs on half of --cells along each side).

# +
import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402

from ale_xfem.model.plic import reconstruct_state  # noqa: E402
from ale_xfem.output.cells_2d import vtk_grid  # noqa: E402
from ale_xfem.problem import build_problem  # noqa: E402
from ale_xfem.run import simulate  # noqa: E402
from ale_xfem.scene import load_scene, resolve_scene_path  # noqa: E402
from ale_xfem.studies.interface import PRESSURE, InterfaceCase  # noqa: E402

parser = argparse.ArgumentParser(description="bubble against Nitsche stabilisation of the interface")
parser.add_argument("--cells", type=int, default=48, help="cells along each side")
parser.add_argument("--out", type=Path, default=Path("out/bubble_vs_nitsche"))
args = parser.parse_args()
args.out.mkdir(parents=True, exist_ok=True)
# -

# ## The impact: p_Γ along the interface
#
# α moves at 0.1 towards β; everything else is at rest at pressure 1.  One step later the
# interface pressure has risen; it should have risen alike all along Γ (the walls aside).
# We plot its rise in every cut cell against the position along Γ, on triangles and on
# quadrilaterals.

# +
methods = [("none", 1.0, "unstabilised P1–P0"), ("bubble", 1.0, "bubbles"), ("nitsche", 1.0, "Nitsche, penalty 1")]
figure, axes = plt.subplots(2, 3, figsize=(13, 7), sharex=True)
for row, cell in enumerate(("triangle", "quadrilateral")):
    case = InterfaceCase(args.cells, "line", cell=cell)
    tangent = np.array([-case.normal_line[1], case.normal_line[0]])
    velocity = [0.1 * case.normal_line[:, None] * np.ones((2, case.mesh.n_nodes)),
                np.zeros((2, case.mesh.n_nodes))]
    along = case.cut.reconstruction.centroid @ tangent
    order = np.argsort(along)
    centroid = case.cut.reconstruction.centroid
    interior = np.all((centroid > 0.15) & (centroid < 0.85), axis=1)  # as the study reads it
    for column, (stabilisation, penalty, title) in enumerate(methods):
        _, interface = case.solve(stabilisation, velocity=velocity, penalty=penalty)
        rise = interface - PRESSURE
        mean = rise[interior].mean()
        spread = rise[interior].std() / abs(mean)
        axis = axes[row, column]
        axis.plot(along[order], rise[order], ".-", lw=0.8)
        axis.axhline(mean, color="k", lw=0.5)
        axis.set_title(f"{cell}s: {title}\nspread {spread:.2g}", fontsize=9)
        if column == 0:
            axis.set_ylabel("rise of p_Γ")
        if row == 1:
            axis.set_xlabel("position along Γ")
        print(f"{cell:13s} {title:20s} spread of p_Γ's rise {spread:6.3g} (mean {mean:.3g})")
figure.tight_layout()
figure.savefig(args.out / "interface_pressure.png", dpi=110)
# -

# The unstabilised pair's p_Γ jumps from cell to cell, by more than its mean on triangles;
# bubbles and Nitsche keep it smooth.  Nitsche's penalty factor matters: the larger it is,
# the closer Nitsche comes to the unstabilised constraint (`ale-xfem study interface`).
#
# ## The cut cells, coloured by p_Γ
#
# The same three solutions on triangles, each cut cell coloured by the rise of its interface
# pressure, the reconstructed interface drawn through it.

# +
case = InterfaceCase(args.cells, "line", cell="triangle")
velocity = [0.1 * case.normal_line[:, None] * np.ones((2, case.mesh.n_nodes)), np.zeros((2, case.mesh.n_nodes))]
figure, axes = plt.subplots(1, 3, figsize=(13, 4.5))
reconstruction = case.cut.reconstruction
for axis, (stabilisation, penalty, title) in zip(axes, methods):
    _, interface = case.solve(stabilisation, velocity=velocity, penalty=penalty)
    rise = interface - PRESSURE
    scale = np.percentile(np.abs(rise), 95)
    cells = PolyCollection(case.cut.vertices, array=rise, cmap="coolwarm", clim=(-scale, scale),
                           edgecolors="0.6", linewidths=0.3)
    axis.add_collection(cells)
    for start, end in zip(reconstruction.start, reconstruction.end):
        axis.plot([start[0], end[0]], [start[1], end[1]], "k-", lw=0.6)
    axis.set_xlim(0, 1)
    axis.set_ylim(0, 1)
    axis.set_aspect("equal")
    axis.set_title(title, fontsize=9)
    figure.colorbar(cells, ax=axis, shrink=0.7, label="rise of p_Γ")
figure.tight_layout()
figure.savefig(args.out / "cut_cells.png", dpi=110)
# -

# ## Sliding: free slip against stick
#
# Now α slides along Γ at +0.1 and β at −0.1, at rest pressure.  With free slip this is a
# steady state: each material keeps its own tangential velocity at every node it has,
# including the nodes of the cut cells that lie in the other material (its *external*
# nodes: the doubled velocities).  With stick the mean tangential jump on each cut cell's
# segment of Γ vanishes.  The plot shows each material's tangential velocity at the nodes
# of the cut cells against the signed distance to Γ.

# +
case = InterfaceCase(args.cells, "line", cell="triangle")
reconstruction = case.cut.reconstruction
tangent = np.array([-case.normal_line[1], case.normal_line[0]])
shape = (2, case.mesh.n_nodes)
sliding = [np.broadcast_to(0.1 * tangent[:, None], shape).copy(), np.broadcast_to(-0.1 * tangent[:, None], shape).copy()]
nodes = np.unique(case.mesh.cell_nodes[case.mixed])
x = case.mesh.node_position[:, nodes]
away_from_walls = np.all((x > 0.1) & (x < 0.9), axis=0)
distance = case.normal_line @ x - 0.55
figure, axes = plt.subplots(1, 2, figsize=(11, 4), sharey=True)
for axis, slip in zip(axes, ("free", "stick")):
    out, _ = case.solve("bubble", slip, sliding, walls=False)
    for k, (label, colour) in enumerate((("α", "tab:blue"), ("β", "tab:red"))):
        mean_velocity = out["velocity"][k][:, nodes]
        axis.plot(distance[away_from_walls], (tangent @ mean_velocity)[away_from_walls], "o", ms=3,
                  color=colour, label=f"{label}'s velocity along Γ")
    turned = [np.stack([u[1], -u[0]]) for u in out["velocity"]]
    cell_nodes = case.mesh.cell_nodes[case.mixed]
    jump = sum(case.cut.normal_flux(k, turned[k], cell_nodes) for k in range(2)) / reconstruction.length
    axis.axvline(0.0, color="k", lw=0.5)
    axis.set_title(f"{slip}: mean tangential jump on Γ_K up to {np.abs(jump).max():.2g}", fontsize=9)
    axis.set_xlabel("signed distance to Γ (α < 0)")
    print(f"{slip:5s} slip: largest mean tangential jump on a cut cell's Γ_K {np.abs(jump).max():.3g}")
axes[0].set_ylabel("tangential velocity (mean over the step)")
axes[0].legend(fontsize=8)
figure.tight_layout()
figure.savefig(args.out / "sliding.png", dpi=110)
print(f"written: {args.out}/interface_pressure.png, cut_cells.png, sliding.png")
# -

# With free slip every node keeps its material's velocity: a sharp slip line inside the cut
# cells, which one velocity field per node cannot hold (it would carry the mass-weighted
# mean of the two).  With stick the materials' velocities meet on Γ on average over each
# cut cell, as a single-velocity closure's would.

# ## One scene run with each stabilisation
#
# The sheared tube (scene `rotated-tube-shear`): Sod's two gases at 30° to an Eulerian mesh,
# each side also sliding along the contact (±0.25), run to t = 0.1 with enriched cells and
# free slip, once with bubbles and once with Nitsche's method (penalty factor 1).  The
# contact lies inside cells all along; the exact solution is the 1D Riemann problem along
# the normal, each side keeping its own tangential velocity.

# +
side = max(args.cells // 2, 12)
runs = {}
for stabilisation, title in (("bubble", "bubbles"), ("nitsche", "Nitsche, penalty 1")):
    problem = build_problem(load_scene(resolve_scene_path("rotated-tube-shear"), [
        f"mesh.cells=[{side},{side}]", 'interface.model="enriched"', f'interface.stabilisation="{stabilisation}"']))
    result = simulate(problem)
    runs[title] = (problem, result)
    errors = result.errors
    print(f"sheared tube, {side}², {title:18s}: {result.status}, {result.steps} steps, {result.wall_seconds:.2f} s; "
          f"L1 density {errors['L1_density']:.3g}, normal velocity {errors['L1_normal_velocity']:.3g}, "
          f"tangential velocity {errors['L1_tangential_velocity']:.3g}")
# -

# ### Density and interface
#
# Each cell's density (a cut cell's: its two materials' mass over its area), the PLIC
# segments of the cut cells in black (pyvista, drawn off-screen).

# +
import pyvista as pv  # noqa: E402

plotter = pv.Plotter(off_screen=True, shape=(1, 2), window_size=(1400, 700), border=False)
for column, (title, (problem, result)) in enumerate(runs.items()):
    state, mesh = result.state, problem.mesh
    grid = vtk_grid(mesh, state.node_position)
    grid.cell_data["density"] = state.material_mass.sum(axis=0) / mesh.cell_volumes(state.node_position)
    plic = reconstruct_state(problem, state, normal=problem.scene.interface.normal)
    ends = np.zeros((2 * plic.cells.size, 3))
    ends[0::2, :2], ends[1::2, :2] = plic.start, plic.end
    plotter.subplot(0, column)
    plotter.add_mesh(grid, scalars="density", cmap="viridis", clim=(0.1, 1.0), show_edges=side <= 40,
                     edge_color="grey", scalar_bar_args={"title": f"density ({title})"})
    plotter.add_mesh(pv.line_segments_from_points(ends), color="black", line_width=2)
    plotter.add_text(f"{title}, t = {state.time:.2g}", font_size=10)
    plotter.view_xy()
plotter.screenshot(args.out / "tube_density.png")
plotter.close()
# -

# ### Each material's tangential velocity across Γ, and p_Γ along Γ
#
# Left and middle: each material's velocity along the contact at the nodes it has near the
# tube's axis — its own nodes, and the external nodes of the cut cells where its velocity is
# the extension of its field — against the distance along the normal from where the contact
# started; the exact solution in black (the contact has moved to the jump).  Right: the
# interface pressure of each cut cell against its position along Γ, with the exact contact
# pressure; its spread (standard deviation over mean) is taken over the cut cells at least
# 0.1 from the walls, where the 1D solution does not hold.

# +
figure, axes = plt.subplots(1, 3, figsize=(16, 4.5))
for axis, (title, (problem, result)) in zip(axes[:2], runs.items()):
    state, exact = result.state, problem.exact.solution
    normal = np.array(exact.normal)
    tangent = np.array([-normal[1], normal[0]])
    points = state.node_position.T
    distance = exact.coordinate(points)
    near_axis = np.abs((points - np.array(exact.point)) @ tangent) < 0.15
    cut_nodes = np.zeros(problem.mesh.n_nodes, dtype=bool)
    cut_nodes[problem.mesh.cell_nodes[problem.mixed.cells].ravel()] = True
    for m, (name, colour) in enumerate(zip(problem.scene.materials, ("tab:blue", "tab:red"))):
        has = near_axis & (state.material_node_internal[m] | cut_nodes)
        axis.plot(distance[has], state.material_node_velocity[m].T[has] @ tangent, ".", ms=3, color=colour,
                  label=f"{name}'s velocity")
    line = np.linspace(-0.45, 0.45, 900)
    exact_velocity = exact.sample(np.array(exact.point) + line[:, None] * normal, state.time)["velocity"]
    axis.plot(line, exact_velocity @ tangent, "k-", lw=1, label="exact")
    axis.set(xlim=(-0.45, 0.45), xlabel="distance along the normal from the initial contact",
             ylabel="velocity along the contact",
             title=f"{title}: each material along Γ")
    axis.legend(fontsize=8, markerscale=3)
pressure_axis = axes[2]
for (title, (problem, result)), marker in zip(runs.items(), ("o", "s")):
    state, exact = result.state, problem.exact.solution
    plic = reconstruct_state(problem, state, normal=problem.scene.interface.normal)
    by_cell = np.argsort(problem.mixed.cells)  # each PLIC cell's place among the mixed cells
    slot = by_cell[np.searchsorted(problem.mixed.cells, plic.cells, sorter=by_cell)]
    assert np.array_equal(problem.mixed.cells[slot], plic.cells)
    tangent = np.array([-exact.normal[1], exact.normal[0]])
    along = (plic.centroid - np.array(exact.point)) @ tangent
    order = np.argsort(along)
    pressure = state.interface_pressure[slot]
    inside = np.all((plic.centroid > 0.1) & (plic.centroid < 0.9), axis=1)
    spread = np.std(pressure[inside]) / np.mean(pressure[inside])
    pressure_axis.plot(along[order], pressure[order], marker + "-", ms=3, lw=0.6, label=f"{title}: spread {spread:.2g}")
    print(f"sheared tube, {title:18s}: p_Γ over the cut cells away from the walls {np.mean(pressure[inside]):.4g} "
          f"± {np.std(pressure[inside]):.2g}")
    contact = exact.sample(plic.centroid, state.time)["pressure"]  # (the same for both runs)
pressure_axis.axhline(float(np.median(contact)), color="k", lw=1, label="exact contact pressure")
pressure_axis.set(xlabel="position along Γ", ylabel="p_Γ", title="interface pressure of each cut cell")
pressure_axis.legend(fontsize=8)
figure.tight_layout()
figure.savefig(args.out / "tube_along_interface.png", dpi=110)
print(f"written: {args.out}/tube_density.png, tube_along_interface.png")
# -

# Both stabilisations keep each material's tangential velocity up to Γ (free slip: the
# jump stays inside one cut cell) and give a p_Γ that follows the exact contact pressure
# without a checkerboard; their errors differ by a few per cent (`ale-xfem study accuracy
# sliding-2d` compares them with one velocity field over resolutions, in time and error).
