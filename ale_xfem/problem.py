"""From a validated scene to a problem: DOLFINx mesh, materials, initial state, boundary
conditions, the exact solution when the scene has one, and the list of active effects."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ale_xfem import exact
from ale_xfem.lagrange import Boundary
from ale_xfem.mesh import MeshArrays, interval_mesh
from ale_xfem.scene import Scene
from ale_xfem.state import Material, MaterialLayout, State, thermodynamics


@dataclass
class ExactReference:
    kind: str  # "riemann" | "plate_impact"
    solution: object
    valid_until: float  # first time a wave reaches a boundary (the exact solution is for ∞ domain)

    def sample(self, x, t):
        return self.solution.sample(x, t)


@dataclass
class Problem:
    scene: Scene
    mesh: MeshArrays
    materials: list[Material]
    layout: MaterialLayout
    node_mass: np.ndarray  # (n_nodes,) lumped nodal masses
    state: State
    boundaries: list[Boundary]
    exact: ExactReference | None
    effects: list[str] = field(default_factory=list)


def build_problem(scene: Scene) -> Problem:
    mesh = interval_mesh(scene.mesh.extent, scene.mesh.cells)
    names = list(scene.materials)
    materials = [Material(n, scene.materials[n].eos, scene.materials[n].make_eos()) for n in names]

    # Region pieces → per-cell mass, energy and momentum by exact overlap lengths (a loop
    # over the few region pieces, vectorised over cells).
    x = mesh.cell_vertex_positions()[:, :, 0]
    left, right = x.min(axis=1), x.max(axis=1)
    n_cells = mesh.n_cells
    mass = np.zeros(n_cells)
    energy_total = np.zeros(n_cells)
    momentum = np.zeros(n_cells)
    dominant = np.zeros(n_cells)
    cell_material = np.full((1, n_cells), -1, dtype=np.int64)
    for lo, hi, region in scene.pieces():
        overlap = np.clip(np.minimum(hi, right) - np.maximum(lo, left), 0.0, None)
        eos = scene.materials[region.material].make_eos()
        piece_mass = region.density * overlap
        mass += piece_mass
        energy_total += piece_mass * float(eos.energy(region.density, region.pressure))
        momentum += piece_mass * region.velocity[0]
        larger = overlap > dominant
        cell_material[0, larger] = names.index(region.material)
        dominant = np.maximum(dominant, overlap)
    layout = MaterialLayout(cell_material, len(materials))

    # Lumped nodal masses; nodal velocities that carry each cell's momentum in equal
    # corner shares (a node on a velocity jump takes the mass-weighted mean).
    node_mass = mesh.scatter_cell_shares(mass)
    velocity = (mesh.scatter_cell_shares(momentum) / node_mass)[None, :]

    volume = mesh.cell_volumes()
    material_mass = mass[None, :]
    material_energy = (energy_total / mass)[None, :]
    density = material_mass / volume
    pressure, sound_speed = thermodynamics(materials, layout, density, material_energy)
    state = State(0.0, mesh.node_position.copy(), velocity, material_mass, material_energy,
                  volume[None, :].copy(), density, pressure, sound_speed)

    boundaries = _boundaries(scene, mesh)
    effects = ["lagrange_explicit"]
    if scene.numerics.q_quadratic > 0 or scene.numerics.q_linear > 0:
        effects.append("artificial_viscosity")
    if any(b.kind == "velocity" for b in boundaries):
        effects.append("piston")
    return Problem(scene, mesh, materials, layout, node_mass, state, boundaries,
                   exact_reference(scene), effects)


def _boundaries(scene: Scene, mesh: MeshArrays) -> list[Boundary]:
    a, b = scene.mesh.extent
    tolerance = 1e-9 * (b - a)
    sides = {"left": (a, -1.0), "right": (b, 1.0)}
    boundaries = []
    for side, spec in scene.boundaries.items():
        position, normal = sides[side]
        nodes = mesh.nodes_where(lambda x: np.abs(x[0] - position) < tolerance)
        velocity = None if spec.velocity is None else np.array(spec.velocity, dtype=float)
        boundaries.append(Boundary(side, spec.kind, nodes, np.array([normal]), velocity))
    return boundaries


def exact_reference(scene: Scene) -> ExactReference | None:
    """A two-state scene of gases is a Riemann problem; two Mie–Grüneisen plates at their
    reference state closing on each other are a plate impact.  Anything else: None."""
    pieces = scene.pieces()
    if len(pieces) != 2:
        return None
    (a, x0, left), (_, b, right) = pieces
    ml, mr = scene.materials[left.material], scene.materials[right.material]
    gases = ("ideal_gas", "stiffened_gas")
    if ml.eos in gases and mr.eos in gases:
        def gas(region, material):
            return exact.GasState(region.density, region.velocity[0], region.pressure,
                                  material.parameters["gamma"], material.parameters.get("p_inf", 0.0))
        try:
            solution = exact.RiemannSolution.solve(gas(left, ml), gas(right, mr), x0)
        except exact.VacuumError:
            return None
        kind = "riemann"
    elif ml.eos == mr.eos == "mie_gruneisen":
        at_rest_reference = all(
            abs(r.density - m.parameters["rho0"]) <= 1e-12 * m.parameters["rho0"] and r.pressure == 0.0
            for r, m in ((left, ml), (right, mr)))
        if not at_rest_reference or not left.velocity[0] > right.velocity[0]:
            return None

        def plate(region, material):
            p = material.parameters
            return exact.Plate(p["rho0"], p["c0"], p["s"], region.velocity[0])
        solution = exact.PlateImpactSolution.solve(plate(left, ml), plate(right, mr), x0)
        kind = "plate_impact"
    else:
        return None
    slow, fast = solution.wave_speeds()
    times = [(a - x0) / slow if slow < 0 else np.inf, (b - x0) / fast if fast > 0 else np.inf]
    return ExactReference(kind, solution, float(min(times)))
