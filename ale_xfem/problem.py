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
    state, node_mass = state_from_cells(mesh, materials, layout, mass[None, :],
                                        (energy_total / mass)[None, :], momentum[None, :])
    boundaries = side_boundaries(mesh, scene.mesh.extent, scene.boundaries)
    for boundary in boundaries:  # walls and pistons hold from t = 0
        boundary.apply(state.node_velocity)
    effects = ["lagrange_explicit"]
    if scene.numerics.q_quadratic > 0 or scene.numerics.q_linear > 0:
        effects.append("artificial_viscosity")
    if any(b.kind == "velocity" for b in boundaries):
        effects.append("piston")
    return Problem(scene, mesh, materials, layout, node_mass, state, boundaries,
                   exact_reference(scene), effects)


def state_from_cells(mesh: MeshArrays, materials, layout: MaterialLayout, material_mass,
                     material_energy, cell_momentum) -> tuple[State, np.ndarray]:
    """Initial state from per-cell, per-material mass and specific energy (S, n_cells) and
    per-cell momentum (dim, n_cells).  Lumped nodal masses take equal corner shares of
    their cells' mass; nodal velocities carry each cell's momentum in the same shares (a
    node on a velocity jump takes the mass-weighted mean, so momentum is exact)."""
    cell_mass = material_mass.sum(axis=0)
    node_mass = mesh.scatter_cell_shares(cell_mass)
    velocity = np.stack([mesh.scatter_cell_shares(p) for p in cell_momentum]) / node_mass
    volume = mesh.cell_volumes()
    density = material_mass / volume
    pressure, sound_speed = thermodynamics(materials, layout, density, material_energy)
    state = State(0.0, mesh.node_position.copy(), velocity, material_mass.copy(),
                  material_energy.copy(), volume[None, :].copy(), density, pressure, sound_speed)
    return state, node_mass


def box_sides(extent) -> dict[str, tuple[int, float, np.ndarray]]:
    """Sides of an interval or a rectangle: name → (axis, position, outward unit normal)."""
    if np.ndim(extent) == 1:
        extent = [extent]
    dim = len(extent)
    names = (("left", "right"), ("bottom", "top"))
    sides = {}
    for axis, (lo, hi) in enumerate(extent):
        for name, position, sign in ((names[axis][0], lo, -1.0), (names[axis][1], hi, 1.0)):
            normal = np.zeros(dim)
            normal[axis] = sign
            sides[name] = (axis, float(position), normal)
    return sides


def side_boundaries(mesh: MeshArrays, extent, specs: dict) -> list[Boundary]:
    """Boundary conditions on the sides of a box; specs: side → BoundarySpec-like
    (``kind`` and ``velocity``)."""
    sides = box_sides(extent)
    size = max(hi - lo for lo, hi in (extent if np.ndim(extent) == 2 else [extent]))
    boundaries = []
    for side, spec in specs.items():
        axis, position, normal = sides[side]
        nodes = mesh.nodes_where(lambda x: np.abs(x[axis] - position) < 1e-9 * size)
        velocity = None if spec.velocity is None else np.array(spec.velocity, dtype=float)
        boundaries.append(Boundary(side, spec.kind, nodes, normal, velocity))
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
    # The solution holds until its outermost waves meet the domain's ends, which move with
    # the outer material (free end), the piston, or not at all (wall).
    slow, fast = solution.wave_speeds()
    end_left = _end_velocity(scene.boundaries["left"], left.velocity[0])
    end_right = _end_velocity(scene.boundaries["right"], right.velocity[0])
    times = [(x0 - a) / (end_left - slow) if end_left > slow else np.inf,
             (b - x0) / (fast - end_right) if fast > end_right else np.inf]
    return ExactReference(kind, solution, float(min(times)))


def _end_velocity(boundary, material_velocity: float) -> float:
    if boundary.kind == "wall":
        return 0.0
    if boundary.kind == "velocity":
        return boundary.velocity[0]
    return material_velocity
