# # x–t diagrams of the demo scenes
#
# Density as colour over x and t: shocks, rarefaction fans, contacts and the interface
# between materials are lines and fans in the plane, and one picture shows a whole run.
# On a Lagrangian mesh the strips between node paths are the cells themselves (they
# compress behind a shock); on an Eulerian mesh the strips are fixed and the material
# moves through them.
#
# Run as `python demos/xt_diagrams.py [--cells 400] [--out docs]` (the README's pictures
# are made with the defaults).

# +
import argparse
from pathlib import Path

from ale_xfem.output.plots import XTHistory, plot_xt
from ale_xfem.problem import build_problem
from ale_xfem.run import simulate
from ale_xfem.scene import load_scene, resolve_scene_path

parser = argparse.ArgumentParser(description=__doc__)
parser.add_argument("--cells", type=int, default=400)
parser.add_argument("--out", type=Path, default=Path("out/xt_diagrams"))
args = parser.parse_args()
args.out.mkdir(parents=True, exist_ok=True)
# -

# ## The scenes
#
# - `shock-interface`: Sod's shock meets an interface inside a cell (transmitted and
#   reflected waves; the paper's figure 4);
# - `plate-impact-enriched`: an aluminium flyer at 2 km/s on copper, the contact inside a
#   cell (two shocks leave the contact; the paper's figure 5);
# - `water-air`: water at 10⁹ Pa expands into air (a density ratio of 20 across Γ);
# - `transverse-eulerian`: the two-gamma tube on an Eulerian mesh (the interface crosses
#   the fixed cells).

# +
SCENES = ("shock-interface", "plate-impact-enriched", "water-air", "transverse-eulerian")
for name in SCENES:
    problem = build_problem(load_scene(resolve_scene_path(name), [f"mesh.cells={args.cells}"]))
    history = XTHistory()
    result = simulate(problem, observe=history.observe)
    path = plot_xt(history, args.out / f"xt-{name}.png", f"{name}: density over x and t")
    print(f"{name}: {result.status}, {result.steps} steps → {path}")
# -
