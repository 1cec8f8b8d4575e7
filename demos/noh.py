# # Noh's implosion in 2D
#
# Cold gas (γ = 5/3, ρ = 1, p ≈ 0) flows towards the origin at unit speed.  A cylindrical
# shock leaves the centre at speed 1/3; behind it the gas is at rest with ρ = 16 and
# p = 16/3, ahead of it ρ = 1 + t/r (W. F. Noh, JCP 72, 1987).  A quarter of the domain is
# computed: the axes are walls (symmetry planes), the outer sides free (the inflowing gas
# has no pressure, so a free side is exact).  The explicit Wilkins scheme runs on a
# Lagrangian mesh of quadrilaterals with viscous hourglass control.
#
# Run as `python demos/noh.py [--cells 100] [--cell-type triangle] [--out out/noh]`.

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

parser = argparse.ArgumentParser(description="Noh's cylindrical implosion")
parser.add_argument("--cells", type=int, default=100, help="cells along each side")
parser.add_argument("--cell-type", default="quadrilateral", choices=("quadrilateral", "triangle"))
parser.add_argument("--out", type=Path, default=Path("out/noh"))
args = parser.parse_args()
# -

# ## The run

# +
overrides = [f"mesh.cells=[{args.cells},{args.cells}]", f"mesh.cell_type={args.cell_type}"]
problem = build_problem(load_scene(resolve_scene_path("noh"), overrides))
result = simulate(problem)
files = write_outputs(problem, result, args.out)
print(f"status {result.status} after {result.steps} steps")
print("L1 errors:", {k: f"{v:.3e}" for k, v in result.errors.items() if k.startswith("L1")})
print("conservation:", {k: f"{v:.1e}" for k, v in result.conservation.items()})
# -

# ## Density against radius
#
# Every cell's density at its centroid's radius, with the exact profile.  Look for the
# shock at r = 0.2, the plateau at 16, and the low densities at the origin: the
# classical "wall heating" of Lagrangian schemes (the start-up error of the shock at the
# centre is frozen into the material there).

# +
centre = problem.mesh.cell_centroids(result.state.node_position)
radius = np.hypot(*centre.T)
r = np.linspace(1e-3, radius.max(), 600)
exact = problem.exact.sample(np.stack([r, np.zeros_like(r)], axis=1), result.state.time)["density"]
figure, axis = plt.subplots(figsize=(7, 4.5))
axis.plot(radius, result.state.material_density[0], ".", markersize=2, label=f"{problem.mesh.n_cells} cells")
axis.plot(r, exact, "k-", linewidth=1, label="exact")
axis.set(xlabel="r", ylabel="density", title=f"Noh, t = {result.state.time:.2f}", ylim=(0, 20))
axis.legend()
figure.savefig(args.out / "noh-radius.png", dpi=120, bbox_inches="tight")
print("plots:", files["plot"], args.out / "noh-radius.png")
# -
