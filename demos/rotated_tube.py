# # A two-material shock tube at an angle to the mesh
#
# The two-gamma Sod tube (γ = 1.4 on the left, 1.667 on the right) with its diaphragm at 30°
# to a Cartesian mesh: the interface cuts cells, which hold both materials as
# single-velocity mixed cells (equal strain, pressure relaxation; `[interface] model =
# "single_velocity"`), their interface rebuilt by PLIC.  The exact solution is the 1D one
# laid along the normal; the walls reflect the waves, so the errors are taken over the
# disk around the centre that no signal from a wall reaches before t_end.
#
# Run as `python demos/rotated_tube.py [--cells 100] [--out out/rotated_tube]`.

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

parser = argparse.ArgumentParser(description="a rotated two-material shock tube")
parser.add_argument("--cells", type=int, default=100, help="cells along each side")
parser.add_argument("--out", type=Path, default=Path("out/rotated_tube"))
args = parser.parse_args()
if args.cells < 40:  # the coarsest of the three runs takes a quarter of it
    parser.error(f"--cells = {args.cells}: at least 40 (the runs take a quarter, a half and all of it)")
# -

# ## Convergence
#
# L1(ρ) over the window at three resolutions, and the fitted rate (first order is what a
# shock-capturing scheme gets on problems with discontinuities).

# +
sizes = [args.cells // 4, args.cells // 2, args.cells]
errors = []
for n in sizes:
    problem = build_problem(load_scene(resolve_scene_path("rotated-tube"), [f"mesh.cells=[{n},{n}]"]))
    result = simulate(problem)
    errors.append(result.errors["L1_density"])
    print(f"{n:4d}² cells: L1(ρ) {result.errors['L1_density']:.3e}, mixed cells {problem.mixed.cells.size}, "
          f"energy drift {result.conservation['total_energy']:.1e}")
rate = -np.polyfit(np.log(sizes), np.log(errors), 1)[0]
print(f"fitted rate {rate:.2f}")
files = write_outputs(problem, result, args.out)
# -

# ## Density along the normal
#
# Every material part of every cell (a mixed cell's two parts at their own densities),
# against its signed distance to the initial interface, with the exact solution.  The
# cells inside the error window in colour.

# +
from ale_xfem.output.cells_2d import cells_rows  # noqa: E402

rows = cells_rows(problem, result.state)
solution = problem.exact.solution
normal, point = np.array(solution.normal), np.array(solution.point)
s = (np.stack([rows["x"], rows["y"]], axis=1) - point) @ normal
centre, radius = problem.exact.window
inside = np.hypot(rows["x"] - centre[0], rows["y"] - centre[1]) <= radius
line = np.linspace(s.min(), s.max(), 800)
exact = solution.solution.sample(line, result.state.time)["density"]
figure, axis = plt.subplots(figsize=(7, 4.5))
axis.plot(s[~inside], rows["density"][~inside], ".", color="0.7", markersize=2, label="outside the window")
axis.plot(s[inside], rows["density"][inside], ".", markersize=3, label="inside the window")
axis.plot(line, exact, "k-", linewidth=1, label="exact (1D along the normal)")
axis.set(xlabel="distance along the normal", ylabel="density",
         title=f"rotated two-material tube, {args.cells}², t = {result.state.time:.2f}")
axis.legend()
figure.savefig(args.out / "rotated-tube-normal.png", dpi=120, bbox_inches="tight")
print("plots:", files["plot"], args.out / "rotated-tube-normal.png")
# -
