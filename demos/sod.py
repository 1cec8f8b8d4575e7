# # Sod's shock tube
#
# The standard test of a compressible-flow scheme: a diaphragm at x = 0.5 separates gas at
# rest at (ρ, p) = (1, 1) from gas at (0.125, 0.1), γ = 1.4.  A rarefaction runs left, a
# contact and a shock run right.  Here it is computed with the explicit Wilkins scheme on
# a Lagrangian mesh (nodes move with the gas) and compared with the exact solution.
#
# Run as `python demos/sod.py [--cells 400] [--out out/sod]`.

# +
import argparse
from pathlib import Path

from ale_xfem.output.files import write_outputs
from ale_xfem.problem import build_problem
from ale_xfem.run import simulate
from ale_xfem.scene import load_scene, resolve_scene_path

parser = argparse.ArgumentParser(description=__doc__)
parser.add_argument("--cells", type=int, default=400)
parser.add_argument("--out", type=Path, default=Path("out/sod"))
args = parser.parse_args()
# -

# ## The run
#
# The scene `demos/scenes/sod.toml` holds the initial data; the artificial viscosity
# coefficients and the CFL number come from its `[numerics]` table (defaults here).

# +
problem = build_problem(load_scene(resolve_scene_path("sod"), [f"mesh.cells={args.cells}"]))
result = simulate(problem)
files = write_outputs(problem, result, args.out)
# -

# ## What to look at
#
# Mass is exact and total energy conserved to round-off (the internal energy update is
# compatible with the nodal work).  The small bump of internal energy at the contact is
# the classical "wall heating" of Lagrangian schemes: the start-up error of the contact is
# frozen into the material, since nothing moves across a Lagrangian cell face.

# +
print(f"status {result.status} after {result.steps} steps")
print("L1 errors:", {k: f"{v:.3e}" for k, v in result.errors.items() if k.startswith("L1")})
print("conservation:", {k: f"{v:.1e}" for k, v in result.conservation.items()})
print("plot:", files["plot"])
# -
