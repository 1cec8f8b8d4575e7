# # An interface between identical materials changes nothing
#
# The same gas on both sides of an enriched interface placed inside a cell must give the
# single-material result: the mass condensation and the interface solve are then only a
# different bookkeeping of the same physics.  We run Sod's tube with such an interface at
# x = 0.7037 (the shock crosses it) on a Lagrangian and on an Eulerian mesh, and measure
# the difference against the run without an interface, next to that run's own error.
#
# Run as `python demos/identical_materials.py [--cells 200] [--out out/identical_materials]`.

# +
import argparse
from pathlib import Path

import numpy as np

from ale_xfem.output.plots import plot_comparison
from ale_xfem.problem import build_problem
from ale_xfem.run import simulate
from ale_xfem.scene import load_scene, resolve_scene_path, validate

parser = argparse.ArgumentParser(description=__doc__)
parser.add_argument("--cells", type=int, default=200)
parser.add_argument("--out", type=Path, default=Path("out/identical_materials"))
args = parser.parse_args()
args.out.mkdir(parents=True, exist_ok=True)
# -

# The scene with the interface is Sod's, plus a second material identical to the first
# that fills [0.7037, 1].

# +
def with_interface(motion):
    data = load_scene(resolve_scene_path("sod"), [f"mesh.cells={args.cells}", f"mesh.motion={motion}"]).resolved
    data["materials"]["same"] = dict(data["materials"]["gas"])
    data["regions"].append(dict(data["regions"][1], material="same", interval=[0.7037, 1.0]))
    data["interface"] = {"model": "enriched"}
    return validate(data)


for motion in ("lagrangian", "eulerian"):
    single_problem = build_problem(load_scene(resolve_scene_path("sod"),
                                              [f"mesh.cells={args.cells}", f"mesh.motion={motion}"]))
    single = simulate(single_problem)
    problem = build_problem(with_interface(motion))
    run = simulate(problem)
    rho = run.state.material_mass.sum(axis=0) / run.state.material_volume.sum(axis=0)
    rho_single = single.state.material_density[0]
    h = single_problem.mesh.cell_volumes(single.state.node_position)
    difference = float(np.sum(np.abs(rho - rho_single) * h))
    print(f"{motion:>10}: ∫|ρ − ρ_single| = {difference:.2e}, "
          f"single run's own L1(ρ) = {single.errors['L1_density']:.2e} "
          f"(ratio {difference / single.errors['L1_density']:.3f})")
    plot_comparison([("interface between identical gases", problem, run), ("single gas", single_problem, single)],
                    args.out / f"{motion}.png", f"Identical materials across Γ ({motion} mesh)",
                    exact=single_problem.exact, time=single.state.time)
# -
