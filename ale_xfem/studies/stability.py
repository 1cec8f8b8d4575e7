"""Hard cases stay stable (`ale-xfem study stability`).

A suite of 1D cases (and 2D ones: Noh on quadrilaterals and triangles, Saltzman, the
rotated two-material tube on a Lagrangian and on an Eulerian mesh, a shock reaching a heavy
disk, water against air at 30° to an Eulerian mesh; and, with the paper's enriched mixed
cells, bubbles and Nitsche each: water against air, the heavy disk, a column of sliver cut
cells, Noh through a circular interface), each 1D case run with an enriched interface
inside a cell (unless the case is about something else), checked for: finished, positive densities, volumes and (ideal-gas)
energies, admissible states (real sound speeds), volume fractions in [0, 1], mass (in all
and of each material) and momentum conserved to round-off, and — where an exact solution exists — the L1 error of
density falling from n to 4n cells (4n rather than 2n: on the coarsest meshes a slow wave
in a heavy material may be resolved by a few cells only, and the error can rise before it
falls — seen on drawn problems at 60 → 120 cells).  It reports the extremes seen during the run, the
conservation drifts, the worst new extremum of density against the exact solution, the
mixed-cell solver's iterations and the steps.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from ale_xfem.exact.riemann import GasState, RiemannSolution
from ale_xfem.model.mesh import corner_jacobians
from ale_xfem.scene import Scene, validate

MASS_TOLERANCE = 1e-13
REFINEMENT = 4  # the convergence check compares n and REFINEMENT × n cells
MOMENTUM_TOLERANCE = 1e-12


@dataclass
class Case:
    name: str
    description: str
    data: dict  # the scene's tables, as in its TOML file (mesh.cells is set per run)
    cells: int = 200  # resolution of the suite's run (the test suite halves it)
    max_steps: int | None = None  # stop after this many steps (the long run)
    exact: bool = True  # has an exact solution: check that L1(ρ) falls from n to 4n cells
    refinement: int = REFINEMENT  # 2D: cells along x doubled (4× the zones)

    def scene(self, cells: int, t_end: float | None = None) -> Scene:
        data = {**self.data, "mesh": {**self.data["mesh"], "cells": cells}}
        if t_end is not None:
            data["t_end"] = t_end
        return validate(data, source=f"stability case {self.name}")


def _gas(name, gamma, p_inf=0.0):
    table = {"eos": "ideal_gas" if p_inf == 0.0 else "stiffened_gas", "gamma": gamma}
    if p_inf:
        table["p_inf"] = p_inf
    return name, table


def riemann_case(name, description, left, right, x0, t_end, extent=(0.0, 1.0), cells=200,
                 gammas=(1.4, 1.667), p_infs=(0.0, 0.0), offset=0.37, pistons=True, motion="lagrangian",
                 cell_for_offset=None) -> Case:
    """A two-material Riemann problem (ρ, u, p) | (ρ, u, p) with the interface ``offset`` of
    a cell right of x0 (at the suite's resolution), inside a cell; the ends move with
    their gas (pistons at the end velocities: transmissive until a wave arrives) or are
    walls."""
    length = extent[1] - extent[0]
    xi = x0 + offset * length / (cell_for_offset or cells)
    materials = dict([_gas("left", gammas[0], p_infs[0]), _gas("right", gammas[1], p_infs[1])])
    boundaries = ({"left": {"velocity": [left[1]]}, "right": {"velocity": [right[1]]}} if pistons
                  else {"left": "wall", "right": "wall"})
    data = {
        "name": name, "description": description, "dimension": 1, "t_end": t_end,
        "mesh": {"extent": list(extent), "cells": cells, "motion": motion},
        "materials": materials,
        "regions": [
            {"material": "left", "interval": [extent[0], xi], "density": left[0], "velocity": [left[1]],
             "pressure": left[2]},
            {"material": "right", "interval": [xi, extent[1]], "density": right[0], "velocity": [right[1]],
             "pressure": right[2]},
        ],
        "interface": {"model": "enriched"},
        "boundaries": boundaries,
    }
    return Case(name, description, data, cells)


def vacuum_forms(left, right, gammas, p_infs=(0.0, 0.0), margin: float = 0.95) -> bool:
    """Whether the exact solution of (ρ, u, p) | (ρ, u, p) holds (or nearly holds) a vacuum:
    u_R − u_L ≥ margin · (2 c_L/(γ_L − 1) + 2 c_R/(γ_R − 1))."""
    c_left = GasState(*left, gammas[0], p_infs[0]).sound_speed
    c_right = GasState(*right, gammas[1], p_infs[1]).sound_speed
    return right[1] - left[1] >= margin * (2 * c_left / (gammas[0] - 1) + 2 * c_right / (gammas[1] - 1))


# Toro, Riemann Solvers and Numerical Methods for Fluid Dynamics, 3rd ed., table 4.1
TORO = {
    1: ((1.0, 0.75, 1.0), (0.125, 0.0, 0.1), 0.3, 0.2, "modified Sod (sonic rarefaction)"),
    2: ((1.0, -2.0, 0.4), (1.0, 2.0, 0.4), 0.5, 0.15, "123 problem (two strong rarefactions, near vacuum)"),
    3: ((1.0, 0.0, 1000.0), (1.0, 0.0, 0.01), 0.5, 0.012, "left half of the blast wave (pressure ratio 10^5)"),
    4: ((5.99924, 19.5975, 460.894), (5.99242, -6.19633, 46.0950), 0.4, 0.035, "two colliding shocks"),
    5: ((1.0, -19.59745, 1000.0), (1.0, -19.59745, 0.01), 0.8, 0.012, "stationary contact, fast flow"),
}


def suite(cells: int = 200) -> list[Case]:
    """The stability cases at ``cells`` (the long run and the sliver keep their own sizes)."""
    cases = []
    for number, (left, right, x0, t_end, what) in TORO.items():
        cases.append(riemann_case(f"toro-{number}", f"Toro's test {number}, {what}; γ 1.4 | 1.667 at the contact",
                                  left, right, x0, t_end, cells=cells))
    gamma = 5.0 / 3.0
    cases.append(riemann_case("leblanc", "LeBlanc's tube: pressure ratio 10^9, density ratio 1000 (γ = 5/3)",
                              (1.0, 0.0, (gamma - 1) * 1e-1), (1e-3, 0.0, (gamma - 1) * 1e-10), 3.0, 6.0,
                              extent=(0.0, 9.0), cells=cells, gammas=(gamma, gamma), pistons=False))
    cases.append(riemann_case("water-air", "water at 1e9 Pa (stiffened gas) against air at 1e5 Pa",
                              (1000.0, 0.0, 1e9), (50.0, 0.0, 1e5), 0.7, 2.2e-4, cells=cells,
                              gammas=(4.4, 1.4), p_infs=(6e8, 0.0), pistons=False))
    air_water = riemann_case("air-water", "a shock in air reaching water (density ratio ~ 800), then reflected",
                             (1.2, 0.0, 1e5), (1000.0, 0.0, 1e5), 0.7, 6e-4, cells=cells,
                             gammas=(1.4, 4.4), p_infs=(0.0, 6e8), pistons=False)
    air_water.data["regions"].insert(1, {"material": "left", "interval": [0.0, 0.3], "density": 12.0,
                                         "velocity": [0.0], "pressure": 1e7})
    air_water.exact = False
    cases.append(air_water)
    plate = {
        "name": "plate-impact-2kms", "description": "aluminium on copper at 2 km/s (Mie–Grüneisen)",
        "dimension": 1, "t_end": 6.0e-7,
        "mesh": {"extent": [0.0, 0.015], "cells": cells, "motion": "lagrangian"},
        "materials": {"aluminium": {"eos": "mie_gruneisen", "rho0": 2785.0, "c0": 5328.0, "s": 1.338, "gamma0": 2.0},
                      "copper": {"eos": "mie_gruneisen", "rho0": 8930.0, "c0": 3940.0, "s": 1.49, "gamma0": 2.0}},
        "regions": [{"material": "aluminium", "interval": [0.0, 0.005 + 0.37 * 0.015 / cells], "density": 2785.0,
                     "pressure": 0.0, "velocity": [2000.0]},
                    {"material": "copper", "interval": [0.005 + 0.37 * 0.015 / cells, 0.015], "density": 8930.0,
                     "pressure": 0.0, "velocity": [0.0]}],
        "interface": {"model": "enriched"},
        "boundaries": {"left": "free", "right": "free"},
    }
    cases.append(Case("plate-impact-2kms", plate["description"], plate, cells))
    sliver = riemann_case("sliver-1e-6", "the interface at volume fraction 1e-6 of its cell (two-gamma Sod tube)",
                          (1.0, 0.0, 1.0), (0.125, 0.0, 0.1), 0.5, 0.2, cells=cells, offset=1e-6, pistons=False)
    cases.append(sliver)
    on_node = riemann_case("on-node-eulerian", "the interface exactly on a node, on an Eulerian mesh (it enters "
                           "the cells as it moves)", (1.0, 0.0, 1.0), (0.125, 0.0, 0.1), 0.5, 0.2, cells=cells,
                           offset=0.0, pistons=False, motion="eulerian")
    cases.append(on_node)
    # The contact of Toro's test 3 (γ 1.4 | 1.667) moves at about 20: 100 cells of travel
    # on 500 cells (at any suite resolution: the waves must not reach the walls first).
    u_contact = _contact_speed(TORO[3][0], TORO[3][1], (1.4, 1.667))
    crossing = riemann_case("eulerian-crossing-100", "an interface carried across 100 of 500 cells of an "
                            "Eulerian mesh (Toro 3, walls)", TORO[3][0], TORO[3][1], 0.42, 100.0 / 500 / u_contact,
                            cells=500, pistons=False, motion="eulerian")
    cases.append(crossing)
    long_run = riemann_case("long-run-1e5-steps", "10^5 steps of a two-gamma Sod tube between walls (waves "
                            "reflected back and forth across the interface)", (1.0, 0.0, 1.0), (0.125, 0.0, 0.1),
                            0.5, 1e9, cells=40, pistons=False)
    long_run.max_steps, long_run.exact, long_run.cells = 100_000, False, 40
    cases.append(long_run)
    cases += extreme_interface_cases(cells)
    cases += cases_2d(cells)
    return cases


AIR, WATER = ("air", 1.4, 0.0), ("water", 4.4, 6e8)  # ideal gas; stiffened gas (γ, p∞)


def extreme_case(name: str, air_left: bool, fraction: float, motion: str, air: tuple, water: tuple,
                 cells: int = 200, model: str = "enriched") -> Case:
    """Air (ideal gas) against water (stiffened gas) at rest, walls at both ends, the
    interface inside the middle cell with the left material at ``fraction`` of it; ``air``
    and ``water``: (density, pressure).  Run until the fastest wave has crossed a fifth of
    the tube.  A stability check (the exact solution is not compared)."""
    left, right = (AIR, WATER) if air_left else (WATER, AIR)
    states = {"air": air, "water": water}
    gas = [GasState(states[m][0], 0.0, states[m][1], g, p_inf) for m, g, p_inf in (left, right)]
    fastest = max(np.abs(RiemannSolution.solve(*gas).wave_speeds()))
    case = riemann_case(name, "", (states[left[0]][0], 0.0, states[left[0]][1]),
                        (states[right[0]][0], 0.0, states[right[0]][1]), 0.5, 0.2 / fastest,
                        cells=cells, gammas=(left[1], right[1]), p_infs=(left[2], right[2]), offset=fraction,
                        pistons=False, motion=motion)
    case.data["materials"] = {left[0]: case.data["materials"]["left"], right[0]: case.data["materials"]["right"]}
    case.data["regions"][0]["material"], case.data["regions"][1]["material"] = left[0], right[0]
    case.data["interface"]["model"] = model
    ratio = max(air[1], water[1]) / min(air[1], water[1])
    case.description = (f"{'air | water' if air_left else 'water | air'}: p {air[1]:.0e} | {water[1]:.0e} Pa in "
                        f"{'air | water' if air_left else 'water | air'} order, density ratio "
                        f"{water[0] / air[0]:.0e}, left material {fraction:g} of its cell, {motion} mesh"
                        + ("" if ratio == 1 else f" (pressure ratio {ratio:.0e})"))
    if not air_left:
        case.description = case.description.replace(
            f"p {air[1]:.0e} | {water[1]:.0e} Pa in water | air order", f"p {water[1]:.0e} | {air[1]:.0e} Pa")
    else:
        case.description = case.description.replace(" in air | water order", "")
    case.exact = False
    return case


def extreme_interface_cases(cells: int = 200) -> list[Case]:
    """Interfaces between air and water at pressure ratios up to 1e9 and density ratios up
    to 1e4, at small and large volume fractions, in both orders, on every 1D mesh motion."""
    return [
        extreme_case("air-water-1e8-eulerian", True, 0.04, "eulerian", (1.2, 1e8), (1000.0, 1e5), cells),
        extreme_case("air-water-1e8-interface", True, 0.96, "interface", (1.2, 1e8), (1000.0, 1e5), cells),
        extreme_case("water-air-1e8-smoothed", False, 0.998, "smoothed", (1.2, 1e8), (1000.0, 1e5), cells),
        extreme_case("water-air-1e9-sliver-eulerian", False, 0.998, "eulerian", (0.1, 1e5), (1000.0, 1e9), cells),
        extreme_case("water-air-1e9-lagrangian", False, 0.5, "lagrangian", (0.1, 1e5), (1000.0, 1e9), cells),
        extreme_case("air-water-1e9-eulerian", True, 0.5, "eulerian", (0.1, 1e5), (1000.0, 1e9), cells),
        extreme_case("air-water-rest-1e4-smoothed", True, 0.002, "smoothed", (0.1, 1e5), (1000.0, 1e5), cells),
    ]


def cases_2d(cells: int = 200) -> list[Case]:
    """2D cases, their resolution tied to the suite's (``cells`` / 4 along x for Noh,
    ``cells`` / 5 for Noh on triangles, ``cells`` / 2 for Saltzman: 50 × 50, 40 × 40 and
    100 × 10 at the default 200; the water–air tube ``cells`` × 0.3), refined by 2 along each
    side for the convergence check
    (triangles: 80 × 80, where a time step blind to the viscosity's stiffness broke down)."""
    gas = {"gas": {"eos": "ideal_gas", "gamma": 5.0 / 3.0}}
    noh = {
        "name": "noh-2d", "description": "Noh's cylindrical implosion on a quarter domain (quadrilaterals)",
        "dimension": 2, "t_end": 0.6,
        "mesh": {"extent": [[0.0, 1.0], [0.0, 1.0]], "cells": max(8, cells // 4)},
        "materials": gas,
        "regions": [{"material": "gas", "box": [[0.0, 1.0], [0.0, 1.0]], "density": 1.0, "pressure": 1e-6,
                     "radial_velocity": {"center": [0.0, 0.0], "speed": -1.0}}],
        "boundaries": {"left": "wall", "bottom": "wall", "right": "free", "top": "free"},
    }
    noh_triangles = {**noh, "name": "noh-2d-triangles", "description": "Noh on crossed triangles",
                     "mesh": {**noh["mesh"], "cell_type": "triangle", "cells": max(4, cells // 5)}}
    saltzman = {
        "name": "saltzman-2d", "description": "Saltzman's piston: a planar shock through a skewed mesh",
        "dimension": 2, "t_end": 0.6,
        "mesh": {"extent": [[0.0, 1.0], [0.0, 0.1]], "cells": max(20, cells // 2), "kind": "saltzman"},
        "materials": gas,
        "regions": [{"material": "gas", "box": [[0.0, 1.0], [0.0, 0.1]], "density": 1.0, "pressure": 1e-6}],
        "boundaries": {"left": {"velocity": [1.0, 0.0]}, "right": "wall", "bottom": "wall", "top": "wall"},
    }
    tube = {
        "name": "rotated-tube-2d", "description": "the two-gamma tube at 30° to the mesh: the interface "
        "cuts cells (single-velocity mixed cells)",
        "dimension": 2, "t_end": 0.1,
        "mesh": {"extent": [[0.0, 1.0], [0.0, 1.0]], "cells": max(10, cells // 4)},
        "materials": {"left": {"eos": "ideal_gas", "gamma": 1.4}, "right": {"eos": "ideal_gas", "gamma": 1.667}},
        "regions": [{"material": "right", "box": [[0.0, 1.0], [0.0, 1.0]], "density": 0.125, "pressure": 0.1},
                    {"material": "left", "half_plane": {"point": [0.5, 0.5], "normal": [0.8660254037844387, 0.5]},
                     "density": 1.0, "pressure": 1.0}],
        "interface": {"model": "single_velocity"},
    }
    u_shock = 1.4790199457749041  # Mach 2 into air at rest
    disk = {
        "name": "shock-disk-2d", "description": "a Mach 2 shock reaching a disk five times denser "
        "(single-velocity mixed cells on its edge) on a smoothed mesh (on a Lagrangian one cells turn "
        "inside out)",
        "dimension": 2, "t_end": 0.35,
        "mesh": {"extent": [[0.0, 2.0], [0.0, 1.0]], "cells": max(20, cells // 2), "motion": "smoothed"},
        "materials": {"air": {"eos": "ideal_gas", "gamma": 1.4},
                      "heavy": {"eos": "stiffened_gas", "gamma": 3.0, "p_inf": 5.0}},
        "regions": [{"material": "air", "box": [[0.0, 2.0], [0.0, 1.0]], "density": 1.0, "pressure": 1.0},
                    {"material": "air", "box": [[0.0, 0.3], [0.0, 1.0]], "density": 2.6666666666666665,
                     "pressure": 4.5, "velocity": [u_shock, 0.0]},
                    {"material": "heavy", "disk": {"center": [0.75, 0.0], "radius": 0.3}, "density": 5.0,
                     "pressure": 1.0}],
        "interface": {"model": "single_velocity"},
        "boundaries": {"left": {"velocity": [u_shock, 0.0]}, "right": "wall", "bottom": "wall", "top": "wall"},
    }
    eulerian = {**tube, "name": "interface-eulerian-2d", "description": "the rotated two-material tube on an "
                "Eulerian mesh: the interface moves through the cells (material-by-material remap)",
                "mesh": {**tube["mesh"], "motion": "eulerian"}}
    # water at 1e9 Pa expanding into air at 30° to an Eulerian mesh: where Γ meets the wall
    # the water cavitates (p < 0) and the air in its cells is drawn to near vacuum
    water_air = {**tube, "name": "water-air-eulerian-2d", "description": "water at 1e9 Pa against air at 1e5 Pa "
                 "(ρ 50) at 30° to an Eulerian mesh: the water cavitates where Γ meets the wall", "t_end": 1e-4,
                 "mesh": {**tube["mesh"], "cells": max(10, 3 * cells // 10), "motion": "eulerian"},
                 "materials": {"air": {"eos": "ideal_gas", "gamma": 1.4},
                               "water": {"eos": "stiffened_gas", "gamma": 4.4, "p_inf": 6e8}},
                 "regions": [{**tube["regions"][0], "material": "air", "density": 50.0, "pressure": 1e5},
                             {**tube["regions"][1], "material": "water", "density": 1000.0, "pressure": 1e9}]}
    cases = [Case(d["name"], d["description"], d, d["mesh"]["cells"], refinement=2)
             for d in (noh, noh_triangles, saltzman, tube, eulerian, disk, water_air)]
    cases[-2].exact = cases[-1].exact = False
    return cases + enriched_cases_2d(disk, water_air, cells)


def enriched_cases_2d(disk: dict, water_air: dict, cells: int = 200) -> list[Case]:
    """The paper's 2D enriched mixed cells on hard cases, with bubbles and with Nitsche:
    water against air at 30° to an Eulerian mesh, the heavy disk struck by a shock, a column
    of sliver cut cells (the interface 10⁻⁶ of a cell from a mesh line, two-gamma Sod along
    its normal: exact, ``cells`` × 2/5 a side), and Noh's implosion through a circular
    interface between two copies of its gas (a smoothed mesh, ``cells`` / 4 a side); the
    first three with bubbles and LVIRA's normals too."""
    n = max(10, 2 * cells // 5)
    sliver_column = {
        "name": "sliver-column-2d", "description": "two-gamma Sod along x, the interface 1e-6 of a cell right of "
        "a mesh line: a column of sliver cut cells (Eulerian)",
        "dimension": 2, "t_end": 0.1,
        "mesh": {"extent": [[0.0, 1.0], [0.0, 1.0]], "cells": n, "motion": "eulerian"},
        "materials": {"left": {"eos": "ideal_gas", "gamma": 1.4}, "right": {"eos": "ideal_gas", "gamma": 1.667}},
        "regions": [{"material": "right", "box": [[0.0, 1.0], [0.0, 1.0]], "density": 0.125, "pressure": 0.1},
                    {"material": "left", "half_plane": {"point": [0.5 + 1e-6 / n, 0.5], "normal": [1.0, 0.0]},
                     "density": 1.0, "pressure": 1.0}],
    }
    gas = {"eos": "ideal_gas", "gamma": 5.0 / 3.0}
    inflow = {"density": 1.0, "pressure": 1e-6, "radial_velocity": {"center": [0.0, 0.0], "speed": -1.0}}
    noh_interface = {
        "name": "noh-interface-2d", "description": "Noh's implosion through a circular interface (r = 0.7 at t = 0, "
        "met by the shock at t = 0.525) between two copies of the gas, on a smoothed mesh",
        "dimension": 2, "t_end": 0.6,
        "mesh": {"extent": [[0.0, 1.0], [0.0, 1.0]], "cells": max(8, cells // 4), "motion": "smoothed"},
        "materials": {"gas": gas, "core": dict(gas)},
        "regions": [{"material": "gas", "box": [[0.0, 1.0], [0.0, 1.0]], **inflow},
                    {"material": "core", "disk": {"center": [0.0, 0.0], "radius": 0.7}, **inflow}],
        "boundaries": {"left": "wall", "bottom": "wall", "right": "free", "top": "free"},
    }
    # each with bubbles and with Nitsche; those whose interface is straight, sliver or struck by
    # a shock also with bubbles and PLIC's normals by LVIRA (interface.normal = "lvira")
    variants = [(base, exact, stabilisation, None)
                for base, exact in ((water_air, False), (disk, False), (sliver_column, True), (noh_interface, False))
                for stabilisation in ("bubble", "nitsche")]
    variants += [(base, exact, "bubble", "lvira") for base, exact in ((water_air, False), (disk, False),
                                                                      (sliver_column, True))]
    cases = []
    for base, exact, stabilisation, normal in variants:
        name = base["name"].removesuffix("-2d") + f"-enriched-{stabilisation}" + (f"-{normal}" if normal else "")
        description = (base["description"].split(" (single-velocity")[0] + f"; enriched mixed cells ({stabilisation})"
                       + (", LVIRA's normals" if normal else ""))
        interface = {"model": "enriched", "stabilisation": stabilisation, **({"normal": normal} if normal else {})}
        data = {**base, "name": name, "description": description, "interface": interface}
        cases.append(Case(name, description, data, data["mesh"]["cells"], exact=exact, refinement=2))
    return cases


def _contact_speed(left, right, gammas) -> float:
    solution = RiemannSolution.solve(GasState(left[0], left[1], left[2], gammas[0]),
                                     GasState(right[0], right[1], right[2], gammas[1]))
    return float(solution.star.velocity)


def random_riemann_cases(count: int, seed: int = 1, cells: int = 200) -> list[Case]:
    """Riemann problems drawn over wide ranges (ρ 1e-2 … 1e2, p 1e-2 … 1e3, u −5 … 5,
    γ 1.2 … 3 on each side), those whose solution holds a vacuum excluded."""
    rng = np.random.default_rng(seed)
    cases = []
    while len(cases) < count:
        left = (10 ** rng.uniform(-2, 2), rng.uniform(-5, 5), 10 ** rng.uniform(-2, 3))
        right = (10 ** rng.uniform(-2, 2), rng.uniform(-5, 5), 10 ** rng.uniform(-2, 3))
        gammas = (rng.uniform(1.2, 3.0), rng.uniform(1.2, 3.0))
        if vacuum_forms(left, right, gammas):
            continue
        cases.append(random_case(len(cases) + 1, left, right, gammas, cells))
    return cases


def random_case(number, left, right, gammas, cells=200) -> Case:
    """A drawn Riemann problem, its end time set so that its fastest wave crosses a third of
    the domain."""
    solution = RiemannSolution.solve(GasState(*left, gammas[0]), GasState(*right, gammas[1]))
    slowest, fastest = solution.wave_speeds()
    speed = max(abs(slowest), abs(fastest), 1e-12)
    return riemann_case(f"random-{number}", f"ρ,u,p = {left[0]:.3g},{left[1]:.3g},{left[2]:.3g} | "
                        f"{right[0]:.3g},{right[1]:.3g},{right[2]:.3g}; γ {gammas[0]:.2f} | {gammas[1]:.2f}",
                        left, right, 0.5, 0.3 / speed, cells=cells, gammas=gammas)


@dataclass
class Extremes:
    """What a run went through: updated by :meth:`observe` after every step."""
    min_density: float = math.inf
    min_volume: float = math.inf  # of a material part, relative to the initial smallest cell
    min_fraction: float = math.inf
    max_fraction: float = -math.inf
    min_ideal_energy: float = math.inf  # specific internal energy of ideal gases
    inadmissible: int = 0  # steps with a non-real or zero sound speed in an occupied slot
    reference_volume: float = 0.0
    min_corner: float = math.inf  # 2D: least corner cross product over the cell's area (≤ 0: inverted)
    ideal: list = field(default_factory=list)

    def observe(self, state, problem) -> None:
        occupied = state.material_volume > 0
        if self.reference_volume == 0.0:
            self.reference_volume = float(state.material_volume[0].min())
            self.ideal = [i for i, m in enumerate(problem.materials)
                          if m.eos_name == "ideal_gas"]
        self.min_density = min(self.min_density, float(state.material_density[occupied].min()))
        self.min_volume = min(self.min_volume, float(state.material_volume[occupied].min()) / self.reference_volume)
        if problem.mixed is not None and state.material_volume.shape[0] > 1:
            cells = problem.mixed.cells
            fraction = state.material_volume[0, cells] / state.material_volume[:, cells].sum(axis=0)
            self.min_fraction = min(self.min_fraction, float(fraction.min()), float((1 - fraction).min()))
            self.max_fraction = max(self.max_fraction, float(fraction.max()), float((1 - fraction).max()))
        material = problem.layout.cell_material
        if self.ideal:
            ideal = np.isin(material, self.ideal) & occupied
            if ideal.any():
                self.min_ideal_energy = min(self.min_ideal_energy, float(state.material_energy[ideal].min()))
        sound = state.material_sound_speed[occupied]
        if not np.all(np.isfinite(sound) & (sound > 0)):
            self.inadmissible += 1
        if problem.mesh.dimension == 2:
            self.min_corner = min(self.min_corner, least_corner(problem.mesh, state.node_position))


def least_corner(mesh, node_position) -> float:
    """The least over cells and corners of (x_{i+1} − x_i) × (x_{i−1} − x_i) / A: positive
    while every cell is convex-oriented at every corner; ≤ 0 for an inverted (or folded)
    cell even when its area is still positive."""
    cross = corner_jacobians(mesh.cell_vertex_positions(node_position))
    return float((cross.min(axis=1) / mesh.cell_volumes(node_position)).min())


def run_case(case: Case, cells: int | None = None, check_convergence: bool = True) -> dict:
    """Run a case (and, with an exact solution, again at REFINEMENT times the cells); return its row."""
    from ale_xfem.problem import build_problem
    from ale_xfem.run import simulate

    cells = cells or case.cells
    if case.data["dimension"] == 2:  # the case fixed its own resolution from the suite's
        cells = case.cells
    clock = time.perf_counter()
    problem = build_problem(case.scene(cells))
    # an exact reference that is the solution of the case for some time: the case stops
    # before it no longer is
    exact = case.exact and problem.exact is not None and problem.exact.holds_at(0.0) \
        and problem.exact.valid_until > 0
    if exact and problem.scene.t_end > problem.exact.valid_until:
        problem = build_problem(case.scene(cells, t_end=0.95 * problem.exact.valid_until))
    extremes = Extremes()
    result = simulate(problem, stop_after_steps=case.max_steps, observe=extremes.observe)
    row = {"case": case.name, "description": case.description, "cells": cells, "status": result.status,
           "diagnostic": result.diagnostic, "steps": result.steps, "t_reached": result.state.time,
           "min_density": extremes.min_density, "min_volume": extremes.min_volume,
           "min_corner": extremes.min_corner,
           "min_ideal_energy": extremes.min_ideal_energy, "inadmissible_steps": extremes.inadmissible,
           "fraction_min": extremes.min_fraction, "fraction_max": extremes.max_fraction,
           # the total's and each material's (the larger)
           "mass_drift": max(abs(result.conservation.get("mass", math.nan)),
                             abs(result.conservation.get("material_mass", math.nan))),
           # |Δ momentum − boundary impulse| over M V, V the scene's velocity scale (summary.json)
           "momentum_drift": abs(result.conservation.get("momentum", math.nan)),
           "energy_drift": result.conservation.get("total_energy", math.nan),
           "remap_kinetic_change": result.conservation.get("remap_kinetic_energy_change", 0.0),
           "iterations_mean": math.nan, "iterations_max": math.nan,
           "L1_density": math.nan, "L1_density_fine": math.nan, "overshoot": math.nan}
    if result.mixed_cells and result.mixed_cells.get("solves"):
        row["iterations_mean"] = result.mixed_cells.get("iterations_mean", math.nan)
        row["iterations_max"] = result.mixed_cells.get("iterations_max", math.nan)
    if exact and result.status == "ok" and result.errors is not None:
        row["L1_density"] = result.errors["L1_density"]
        row["overshoot"] = density_overshoot(problem, result.state)
        points, size = _sample_points(problem, result.state)
        row["L1_negligible"] = 1e-10 * float(np.max(problem.exact.sample(points, result.state.time)["density"])
                                             * size)
        if check_convergence:
            fine = build_problem(case.scene(case.refinement * cells, t_end=problem.scene.t_end))
            fine_result = simulate(fine, stop_after_steps=case.max_steps)
            row["L1_density_fine"] = (fine_result.errors or {}).get("L1_density", math.nan) \
                if fine_result.status == "ok" else math.nan
    row["seconds"] = time.perf_counter() - clock
    row["verdict"] = verdict(row, case)
    return row


def density_overshoot(problem, state) -> float:
    """New extrema of density against the exact solution, relative to its range:
    max(0, max ρ_h − max ρ_exact, min ρ_exact − min ρ_h) / (max ρ_exact − min ρ_exact)."""
    points, _ = _sample_points(problem, state)
    exact = problem.exact.sample(points, state.time)["density"]
    occupied = state.material_volume > 0
    numerical = state.material_density[occupied]
    spread = max(float(exact.max() - exact.min()), 1e-300)
    return max(0.0, float(numerical.max() - exact.max()), float(exact.min() - numerical.min())) / spread


def _sample_points(problem, state):
    """Points covering the domain where the exact solution is compared (1D: 20 000 along
    it; 2D: the cell centroids and corners), and the domain's length or area."""
    if problem.mesh.dimension == 1:
        x = state.node_position[0]
        return np.linspace(x.min(), x.max(), 20_000), float(x.max() - x.min())
    vertices = problem.mesh.cell_vertex_positions(state.node_position)
    points = np.concatenate([vertices.mean(axis=1), vertices.reshape(-1, 2)])
    return points, float(problem.mesh.cell_volumes(state.node_position).sum())


def verdict(row: dict, case: Case) -> str:
    """"pass", or what failed."""
    problems = []
    if row["status"] != "ok":
        problems.append("did not finish")
    if not row["min_density"] > 0:
        problems.append("density ≤ 0")
    if not row["min_volume"] > 0:
        problems.append("volume ≤ 0")
    if not row.get("min_corner", math.inf) > 0:
        problems.append("inverted cell")
    if row["min_ideal_energy"] <= 0:
        problems.append("ideal-gas energy ≤ 0")
    if row["inadmissible_steps"]:
        problems.append("inadmissible state")
    if math.isfinite(row["fraction_min"]) and not (row["fraction_min"] >= 0 and row["fraction_max"] <= 1):
        problems.append("volume fraction outside [0, 1]")
    if not row["mass_drift"] <= MASS_TOLERANCE:
        problems.append(f"mass drift {row['mass_drift']:.1e}")
    if not row["momentum_drift"] <= MOMENTUM_TOLERANCE:
        problems.append(f"momentum drift {row['momentum_drift']:.1e}")
    # (an error at round-off level, e.g. a lone contact on a Lagrangian mesh, need not fall)
    if case.exact and row["status"] == "ok" and math.isfinite(row["L1_density"]) and math.isfinite(
            row["L1_density_fine"]) and not row["L1_density_fine"] < row["L1_density"] \
            and not max(row["L1_density"], row["L1_density_fine"]) <= row.get("L1_negligible", 0.0):
        problems.append("L1(ρ) does not fall with resolution")
    return "pass" if not problems else "; ".join(problems)


TABLE_COLUMNS = (("case", "case"), ("verdict", "verdict"), ("cells", "cells"), ("steps", "steps"),
                 ("min_density", "min ρ"), ("min_volume", "min V/V₀"), ("mass_drift", "mass drift"),
                 ("momentum_drift", "momentum drift"), ("energy_drift", "energy drift"),
                 ("overshoot", "overshoot"), ("L1_density", "L1(ρ) n"), ("L1_density_fine", "L1(ρ) 4n"),
                 ("iterations_mean", "iter. mean"), ("iterations_max", "iter. max"), ("seconds", "s"))


def _cell(value) -> str:
    if isinstance(value, float):
        if math.isnan(value):
            return "–"
        if value == 0.0:
            return "0"
        return f"{value:.3g}" if 1e-3 <= abs(value) < 1e5 else f"{value:.2e}"
    return str(value)


def markdown_table(rows: list[dict]) -> str:
    lines = ["| " + " | ".join(title for _, title in TABLE_COLUMNS) + " |",
             "|" + "|".join("---" if key in ("case", "verdict") else "---:" for key, _ in TABLE_COLUMNS) + "|"]
    for row in rows:
        lines.append("| " + " | ".join(_cell(row[key]) for key, _ in TABLE_COLUMNS) + " |")
    return "\n".join(lines)


def text_table(rows: list[dict]) -> str:
    header = f"{'case':<24} {'verdict':<10} {'cells':>5} {'steps':>7} {'min ρ':>9} {'min V/V0':>9} " \
             f"{'mass':>8} {'momentum':>8} {'overshoot':>9} {'L1 n':>9} {'L1 4n':>9} {'iter':>9} {'s':>6}"
    lines = [header]
    for r in rows:
        iterations = "–" if math.isnan(r["iterations_mean"]) else f"{r['iterations_mean']:.1f}/{r['iterations_max']:.0f}"
        lines.append(f"{r['case']:<24} {r['verdict'][:10]:<10} {r['cells']:>5} {r['steps']:>7} "
                     f"{_cell(r['min_density']):>9} {_cell(r['min_volume']):>9} {_cell(r['mass_drift']):>8} "
                     f"{_cell(r['momentum_drift']):>8} {_cell(r['overshoot']):>9} {_cell(r['L1_density']):>9} "
                     f"{_cell(r['L1_density_fine']):>9} {iterations:>9} {r['seconds']:>6.1f}")
        if r["verdict"] != "pass":
            lines.append(f"    {r['verdict']}" + (f" — {r['diagnostic']}" if r["diagnostic"] else ""))
    return "\n".join(lines)


CSV_COLUMNS = ("case", "verdict", "cells", "status", "steps", "t_reached", "min_density", "min_volume",
               "min_ideal_energy", "inadmissible_steps", "fraction_min", "fraction_max", "mass_drift",
               "momentum_drift", "energy_drift", "remap_kinetic_change", "overshoot", "L1_density",
               "L1_density_fine", "iterations_mean", "iterations_max", "seconds", "diagnostic", "description")


def run_stability_study(out, cells: int = 200, random_count: int = 10, seed: int = 1, echo=print,
                        names: list[str] | None = None) -> list[dict]:
    """Run the suite (and ``random_count`` drawn Riemann problems); print the table as it
    goes; write stability.csv and stability.md into ``out``."""
    import csv
    from pathlib import Path

    out = Path(out)
    cases = suite(cells) + random_riemann_cases(random_count, seed=seed, cells=cells)
    if names:
        cases = [c for c in cases if c.name in names]
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    echo(text_table([]))
    for case in cases:
        rows.append(run_case(case))
        echo("\n".join(text_table(rows[-1:]).splitlines()[1:]))
    with (out / "stability.csv").open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=CSV_COLUMNS, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)
    passed = sum(r["verdict"] == "pass" for r in rows)
    header = [f"# Stability suite: {passed} of {len(rows)} cases pass", "",
              f"Suite resolution {cells} cells (each case with an exact solution also at {REFINEMENT * cells}: "
              f"'L1(ρ) 4n'); {random_count} random Riemann problems, seed {seed}.  min ρ: smallest density "
              "seen during the run; min V/V₀: smallest material volume over the initial smallest cell; drifts "
              "as in summary.json (momentum over total mass × the scene's velocity scale); overshoot: new density extrema against the "
              "exact solution, relative to its range; iterations of the mixed-cell solver per step.", "", ""]
    failures = [f"- **{r['case']}**: {r['verdict']}" + (f" ({r['diagnostic']})" if r["diagnostic"] else "")
                for r in rows if r["verdict"] != "pass"]
    (out / "stability.md").write_text("\n".join(header) + markdown_table(rows) + "\n"
                                      + ("\nFailures:\n\n" + "\n".join(failures) + "\n" if failures else ""))
    return rows
