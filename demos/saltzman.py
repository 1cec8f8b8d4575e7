# # Saltzman's piston
#
# A piston moving at unit speed drives a planar shock into cold gas (γ = 5/3): density 4
# behind a shock of speed 4/3.  The mesh is skewed — nodes shifted by
# (0.1 − y) sin(πx) along x — so the shock crosses cells at an angle to their faces, the
# classical test of a 2D Lagrangian scheme's viscosity and hourglass control
# (J. Saltzman's problem, as in Dukowicz & Meltz, JCP 99, 1992).
#
# Run as `python demos/saltzman.py [--cells 100] [--out out/saltzman]` (cells along x;
# a tenth of that along y).

# +
import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ale_xfem.output.files import write_outputs  # noqa: E402
from ale_xfem.problem import build_problem  # noqa: E402
from ale_xfem.run import simulate  # noqa: E402
from ale_xfem.scene import load_scene, resolve_scene_path  # noqa: E402

parser = argparse.ArgumentParser(description="Saltzman's piston")
parser.add_argument("--cells", type=int, default=100, help="cells along x")
parser.add_argument("--out", type=Path, default=Path("out/saltzman"))
args = parser.parse_args()
# -

# ## The run

# +
problem = build_problem(load_scene(resolve_scene_path("saltzman"),
                                   [f"mesh.cells=[{args.cells},{max(2, args.cells // 10)}]"]))
result = simulate(problem)
files = write_outputs(problem, result, args.out)
print(f"status {result.status} after {result.steps} steps")
print("L1 errors:", {k: f"{v:.3e}" for k, v in result.errors.items() if k.startswith("L1")})
print("conservation:", {k: f"{v:.1e}" for k, v in result.conservation.items()})
# -

# ## Density along x
#
# Each cell's density at its centroid's x; cells next to the walls (y < 0.02 or y > 0.08)
# in grey.  The plateau should sit at 4 between the piston (x = t) and the shock (x = 4t/3).

# +
centre = problem.mesh.cell_centroids(result.state.node_position)
rho = result.state.material_density[0]
wall = (centre[:, 1] < 0.02) | (centre[:, 1] > 0.08)
x = np.linspace(0, 1, 800)
exact = problem.exact.sample(np.stack([x, np.full_like(x, 0.05)], axis=1), result.state.time)["density"]
figure, axis = plt.subplots(figsize=(7, 4.5))
axis.plot(centre[wall, 0], rho[wall], ".", color="0.6", markersize=3, label="cells next to a wall")
axis.plot(centre[~wall, 0], rho[~wall], ".", markersize=3, label="other cells")
axis.plot(x, exact, "k-", linewidth=1, label="exact")
axis.set(xlabel="x", ylabel="density", title=f"Saltzman, t = {result.state.time:.2f}")
axis.legend()
figure.savefig(args.out / "saltzman-density.png", dpi=120, bbox_inches="tight")
print("plots:", files["plot"], args.out / "saltzman-density.png")
# -
