# # Materials that slide: enriched 2D mixed cells against one velocity field
#
# Two steady or exact flows with a slip line inside mesh cells of an Eulerian mesh, run
# with single-velocity mixed cells (both materials of a cut cell move alike) and with the
# paper's enriched cells (one velocity per material on the cut cells' nodes, an implicit
# interface pressure), stabilised by bubbles or by Nitsche's method:
#
# - a light disk spinning inside a heavier fluid at rest (scene `spinning-disk`): the disk
#   should keep its angular momentum and the fluid gain none;
# - the two-material Riemann problem at 30° to the mesh with each side sliding along the
#   contact (scene `rotated-tube-shear`): the exact solution keeps the tangential velocity
#   jump sharp; stick (the whole velocity continuous) should do what one velocity field does;
# - a dense block sliding along its length through a light gas at rest (scene
#   `sliding-block`): its ends push and pull the gas, its long sides should slide freely.
#
# Run as `python demos/sliding_interfaces.py [--cells 80] [--out out/sliding_interfaces]`
# (the runs use a quarter of --cells along each side: the enriched cells' implicit solve
# makes them slower).

# +
import argparse
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ale_xfem.model.state import material_angular_momenta, material_momenta  # noqa: E402
from ale_xfem.problem import build_problem  # noqa: E402
from ale_xfem.run import simulate  # noqa: E402
from ale_xfem.scene import load_scene, resolve_scene_path  # noqa: E402

parser = argparse.ArgumentParser(description="enriched 2D mixed cells against one velocity field")
parser.add_argument("--cells", type=int, default=80, help="four times the cells along each side of the runs")
parser.add_argument("--out", type=Path, default=Path("out/sliding_interfaces"))
args = parser.parse_args()
if args.cells < 48:
    parser.error(f"--cells = {args.cells}: at least 48 (the runs take a quarter of it along each side)")
args.out.mkdir(parents=True, exist_ok=True)
n = args.cells // 4
CLOSURES = {"one velocity field": {"model": "single_velocity"},
            "enriched, bubbles": {"model": "enriched", "stabilisation": "bubble"},
            "enriched, Nitsche": {"model": "enriched", "stabilisation": "nitsche"},
            "enriched, bubbles, stick": {"model": "enriched", "stabilisation": "bubble", "slip": "stick"}}


def run(scene, closure, cells):
    overrides = [f"mesh.cells=[{cells},{cells}]"] + [f'interface.{k}="{v}"' for k, v in closure.items()]
    problem = build_problem(load_scene(resolve_scene_path(scene), overrides))
    clock = time.perf_counter()
    result = simulate(problem)
    return problem, result, time.perf_counter() - clock
# -

# ## The spinning disk to t = 1
#
# Each material's angular momentum about the centre over the disk's exact ½πρωR⁴ (with
# one velocity per material: Σ_i M_α,i (x_i − c) × u_α,i over its own nodal masses).

# +
disks = {}
for name in ("one velocity field", "enriched, bubbles", "enriched, Nitsche"):
    problem, result, seconds = run("spinning-disk", CLOSURES[name], n)
    mesh, exact = problem.mesh, problem.exact.solution
    disk = list(problem.scene.materials).index("disk")
    end = material_angular_momenta(result.state, problem.layout, mesh.cell_nodes,
                                   mesh.cell_centroids(result.state.node_position), exact.center) / exact.angular_momentum
    disks[name] = (problem, result)
    print(f"spinning disk, {n}², {name:20s}: {result.status}, the disk holds {end[disk]:5.1%} and the fluid "
          f"{end[1 - disk]:+6.1%} at t = {result.state.time:.2f}; {result.steps} steps, {seconds:.1f} s")
# -

# ## The sheared tube
#
# L1 errors over the disk around the centre at t = 0.1, against the exact solution.

# +
tubes = {}
for name, closure in CLOSURES.items():
    problem, result, seconds = run("rotated-tube-shear", closure, n)
    tubes[name] = (problem, result)
    errors = result.errors
    print(f"sheared tube, {n}², {name:26s}: L1 density {errors['L1_density']:.2e}, velocity "
          f"{errors['L1_velocity']:.2e}, pressure {errors['L1_pressure']:.2e}; {result.steps} steps, {seconds:.1f} s")
# -

# ## The sliding block
#
# The block's momentum along its length at t = 0.25 over its start (each material's
# momentum: with one velocity per material, its nodal masses times its own velocities;
# with one velocity field, its cells' masses times their nodes' mean velocity).

# +
for name in ("one velocity field", "enriched, bubbles"):
    overrides = [f"mesh.cells=[{2 * n},{n}]"] + [f'interface.{k}="{v}"' for k, v in CLOSURES[name].items()]
    problem = build_problem(load_scene(resolve_scene_path("sliding-block"), overrides))
    block = list(problem.scene.materials).index("block")
    # the start before the run: the run changes problem.layout as the mixed cells change
    start = material_momenta(problem.state, problem.layout, problem.mesh.cell_nodes)[block]
    clock = time.perf_counter()
    result = simulate(problem)
    seconds = time.perf_counter() - clock
    end = material_momenta(result.state, problem.layout, problem.mesh.cell_nodes)[block]
    print(f"sliding block, {2 * n} × {n}, {name:20s}: {result.status}, it keeps {end @ start / (start @ start):6.2%} "
          f"of its momentum at t = {result.state.time:.2f}; {result.steps} steps, {seconds:.1f} s")
# -

# ## Pictures
#
# Left: each node's azimuthal velocity against its distance to the disk's centre (the
# velocity of the material the node lies in), with the steady state.  Right: the sheared
# tube's tangential velocity against the distance along the normal, at the nodes within a
# band around the tube's axis, with the exact solution.

# +
figure, (left, right) = plt.subplots(1, 2, figsize=(12, 4.5))
for (name, (problem, result)), colour in zip(disks.items(), ("tab:red", "tab:blue", "tab:green")):
    exact = problem.exact.solution
    offset = result.state.node_position.T - np.array(exact.center)
    r = np.linalg.norm(offset, axis=1)
    u = result.state.node_velocity
    left.plot(r, (offset[:, 0] * u[1] - offset[:, 1] * u[0]) / np.where(r > 0, r, 1.0), ".", markersize=2,
              color=colour, label=name)
line = np.linspace(0.0, 0.7, 400)
left.plot(line, np.where(line < exact.radius, exact.angular_velocity * line, 0.0), "k-", linewidth=1,
          label="steady state")
left.set(xlabel="r", ylabel="v_θ", title=f"spinning disk, {n}², t = 1")
left.legend(markerscale=4)
for (name, (problem, result)), colour in zip(tubes.items(), ("tab:red", "tab:blue", "tab:green", "tab:orange")):
    exact = problem.exact.solution
    normal = np.array(exact.normal)
    tangent = np.array([-normal[1], normal[0]])
    points = result.state.node_position.T
    s = exact.coordinate(points)
    along = (points - np.array(exact.point)) @ tangent
    band = np.abs(along) < 0.15
    right.plot(s[band], (result.state.node_velocity.T @ tangent)[band], ".", markersize=3, color=colour, label=name)
line = np.linspace(-0.4, 0.4, 800)
points = np.array(exact.point) + line[:, None] * normal
right.plot(line, exact.sample(points, result.state.time)["velocity"] @ tangent, "k-", linewidth=1, label="exact")
right.set(xlim=(-0.45, 0.45), xlabel="distance along the normal", ylabel="tangential velocity",
          title=f"sheared tube, {n}², t = {result.state.time:.2f}")
right.legend(markerscale=3, fontsize=8)
figure.savefig(args.out / "sliding-interfaces.png", dpi=120, bbox_inches="tight")
print("plot:", args.out / "sliding-interfaces.png")
# -
