# # Sedov's cylindrical blast
#
# An energy of 1 per unit length released at the origin in cold gas (ρ = 1, γ = 1.4) drives
# a cylindrical shock to R(t) = ξ0 (E t²/ρ)^{1/4}, ξ0 = 1.004, with a density of 6 behind
# it and an evacuated core.  The similarity solution is integrated from the Euler equations
# (`ale_xfem/exact/sedov.py`); a quarter of the plane is computed, the energy (0.25)
# spread over a small box at the corner.  The mesh is smoothed (ALE): on a Lagrangian mesh the
# quadrilateral at the blast's diagonal node turns a corner inside out within 15 steps, and the
# run stops with that diagnostic.
#
# Run as `python demos/sedov.py [--cells 120] [--out out/sedov]`.

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

parser = argparse.ArgumentParser(description="Sedov's cylindrical blast")
parser.add_argument("--cells", type=int, default=120, help="cells along each side")
parser.add_argument("--out", type=Path, default=Path("out/sedov"))
args = parser.parse_args()
# -

# ## The run

# +
problem = build_problem(load_scene(resolve_scene_path("sedov"), [f"mesh.cells=[{args.cells},{args.cells}]"]))
result = simulate(problem)
files = write_outputs(problem, result, args.out)
radius_exact = problem.exact.solution.shock_radius(result.state.time)
print(f"status {result.status} after {result.steps} steps; exact shock radius {radius_exact:.4f}")
print("L1 errors:", {k: f"{v:.3e}" for k, v in result.errors.items() if k.startswith("L1")})
print("conservation:", {k: f"{v:.1e}" for k, v in result.conservation.items()})
# -

# ## Density and pressure against radius

# +
centre = problem.mesh.cell_centroids(result.state.node_position)
r = np.hypot(*centre.T)
line = np.linspace(0, 1.2, 600)
exact = problem.exact.sample(np.stack([line, np.zeros_like(line)], axis=1), result.state.time)
figure, axes = plt.subplots(1, 2, figsize=(11, 4))
for axis, key in zip(axes, ("density", "pressure")):
    axis.plot(r, getattr(result.state, f"material_{key}")[0], ".", markersize=2, label=f"{problem.mesh.n_cells} cells")
    axis.plot(line, exact[key], "k-", linewidth=1, label="similarity solution")
    axis.set(xlabel="r", ylabel=key)
    axis.legend()
figure.suptitle(f"Sedov, t = {result.state.time:.2f}")
figure.savefig(args.out / "sedov-radius.png", dpi=120, bbox_inches="tight")
print("plots:", files["plot"], args.out / "sedov-radius.png")
# -
