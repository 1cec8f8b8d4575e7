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
# slip against stick.  (`ale-xfem study interface` measures the same over resolutions and
# penalty factors; docs/design.md §4 has the method.)
#
# Run as `python demos/bubble_vs_nitsche.py [--cells 48] [--out out/bubble_vs_nitsche]`.

# +
import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402

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
