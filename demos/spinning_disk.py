# # A disk spinning inside a fluid at rest
#
# A light disk (ρ = 1) spins at ω = 2 about its centre inside a heavier fluid (ρ = 10) at
# rest, its pressure in radial equilibrium, p = p₀ − ½ρω²(R² − r²): a steady state of the
# Euler equations, with a slip line at the rim.  It holds for ever where the interface lets
# the disk slide.  With one velocity field (single-velocity mixed cells, Eulerian mesh) the
# rim's cells move both materials alike: the disk drags the outer fluid and hands it its
# angular momentum.  This demo measures how much, and how that changes with the mesh.
#
# Run as `python demos/spinning_disk.py [--cells 80] [--out out/spinning_disk]`.

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
from ale_xfem.model.state import material_angular_momenta  # noqa: E402

parser = argparse.ArgumentParser(description="a disk spinning inside a fluid at rest")
parser.add_argument("--cells", type=int, default=80, help="cells along each side (finest run)")
parser.add_argument("--out", type=Path, default=Path("out/spinning_disk"))
args = parser.parse_args()
if args.cells < 40:  # the coarsest of the three runs takes a quarter of it
    parser.error(f"--cells = {args.cells}: at least 40 (the runs take a quarter, a half and all of it)")
# -

# ## The angular momentum the disk keeps
#
# Each material's angular momentum about the centre, Σ_K m_α,K (x_K − c) × ū_K (ū_K the
# mean velocity of the cell's nodes), over the exact ½πρωR⁴ of the disk, at t = 0 and at
# t = 1 (a third of a turn), at three resolutions; and L1 of the velocity against the
# steady state.  Already at t = 0 one velocity field cannot hold the disk's rotation: the
# nodes of the rim's cells carry the mass-weighted mean of both materials' velocities, and
# the outer fluid is ten times denser.  (The walls of the box exert a torque too: angular
# momentum is not conserved in it.)

# +
def angular_momenta(problem, state):
    mesh = problem.mesh
    return material_angular_momenta(state, problem.layout, mesh.cell_nodes, mesh.cell_centroids(state.node_position),
                                    problem.exact.solution.center)


sizes = [args.cells // 4, args.cells // 2, args.cells]
for n in sizes:
    problem = build_problem(load_scene(resolve_scene_path("spinning-disk"), [f"mesh.cells=[{n},{n}]"]))
    start = angular_momenta(problem, problem.state)
    result = simulate(problem)
    end = angular_momenta(problem, result.state)
    exact = problem.exact.solution.angular_momentum
    disk = list(problem.scene.materials).index("disk")
    print(f"{n:4d}² cells, as fractions of ½πρωR⁴: the disk holds {start[disk] / exact:5.1%} at t = 0 and "
          f"{end[disk] / exact:5.1%} at t = 1, the outer fluid gained {(end[1 - disk] - start[1 - disk]) / exact:5.1%}; "
          f"L1(u) {result.errors['L1_velocity']:.3e}, {result.steps} steps")
files = write_outputs(problem, result, args.out)
# -

# ## Azimuthal velocity against r
#
# Every node's v_θ against its distance to the centre, with the steady state: ωr inside,
# 0 outside.  The drag shows as the band where v_θ falls from ωR to 0 across the rim.

# +
solution = problem.exact.solution
offset = result.state.node_position.T - np.array(solution.center)
r = np.linalg.norm(offset, axis=1)
v_theta = (offset[:, 0] * result.state.node_velocity[1] - offset[:, 1] * result.state.node_velocity[0]) / np.where(
    r > 0, r, 1.0)
line = np.linspace(0.0, r.max(), 400)
figure, axis = plt.subplots(figsize=(7, 4.5))
axis.plot(r, v_theta, ".", markersize=2, label=f"nodes, {args.cells}²")
axis.plot(line, np.where(line < solution.radius, solution.angular_velocity * line, 0.0), "k-", linewidth=1,
          label="steady state")
axis.set(xlabel="r (distance from the centre)", ylabel="azimuthal velocity v_θ",
         title=f"spinning disk, single-velocity mixed cells, t = {result.state.time:.2f}")
axis.legend()
figure.savefig(args.out / "spinning-disk-velocity.png", dpi=120, bbox_inches="tight")
print("plots:", files["plot"], args.out / "spinning-disk-velocity.png")
# -
