"""From a validated scene to a problem: DOLFINx mesh, materials, initial state, boundary
conditions, the exact solution when the scene has one, and the list of active effects."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ale_xfem import exact
from ale_xfem.mixed.cut_cells_2d import by_material, material_geometry
from ale_xfem.mixed.equilibrium import MixedCellFailure, PressureEquilibrium, start_values
from ale_xfem.geometry.shapes import SHAPES
from ale_xfem.model.boundaries import Boundary
from ale_xfem.model.diagnostics import place
from ale_xfem.model.mesh import MeshArrays, file_mesh, interval_mesh, rectangle_mesh, saltzman_mesh
from ale_xfem.model.mixed_cells import MixedCells, material_names, with_mixed_state
from ale_xfem.model.state import Material, MaterialLayout, State, density_of, ranked_materials, thermodynamics
from ale_xfem.scene.effects import Effect, active, scene_effects
from ale_xfem.scene.schema import Scene, SceneError, mesh_file_path


@dataclass
class ExactReference:
    """An exact solution of the scene as run, while it holds: errors and overlays are taken
    only up to ``valid_until``; ``limit`` says in one phrase what ends it (a wave reaching a
    boundary, or a boundary that is not part of the exact problem: then valid_until = 0)."""

    kind: str  # "riemann" | "plate_impact" | 2D: "noh" | "piston" | "planar_riemann" | "sedov" | "spinning_disk"
    solution: object  # None when the scene only looks like the exact problem (limit says why)
    valid_until: float  # the exact solution is for an unbounded domain: until a wave reaches a boundary
    # 2D: (centre, radius) of the disk the L1 errors are taken over (no wave from the walls
    # reaches it before t_end), or None: the whole domain
    window: tuple | None = None
    limit: str = ""

    def holds_at(self, t: float) -> bool:
        return self.solution is not None and t <= self.valid_until * (1.0 + 1e-12)

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
    mixed: MixedCells | None = None  # the enriched mixed cells, when the scene has any
    corner_mass: np.ndarray | None = None  # (2, n_cells) mass lumped on each cell's left/right node
    setup_failure: str = ""  # a set-up step that could not be done (the run reports it)
    effect_table: list[Effect] = field(default_factory=list)  # every effect, on or off, and why
    # A run leaves layout, mixed and node_mass describing the state it returns (a remap
    # changes them): ``described`` is the state they describe (None while a run changes
    # them), ``built`` the state the problem was built with and its own (start_run)
    built: RunStart | None = None
    described: State | None = None

    def remember_start(self) -> None:
        """The problem as built: the state a run starts from unless told otherwise."""
        self.built = RunStart(self.state, self.layout, self.mixed, self.node_mass)
        self.described = self.state

    def start_run(self) -> None:
        """Before a run: the layout, mixed cells and nodal masses of ``state`` — those the
        last run left if it returned this state (``problem.state = result.state`` continues
        a run), the problem's own as built if it is the built state (a problem run twice
        gives the same result twice); any other state has none here (ValueError).  The
        run's mixed cells count their solves in a copy of the counters, so that a run never
        changes the problem as built."""
        if self.built is None:  # (a problem not made by build_problem: as it is)
            self.remember_start()
        if self.state is not self.described:
            if self.built is None or self.state is not self.built.state:
                raise ValueError("problem.state is neither the state the problem was built with nor the state a "
                                 "run of it returned (result.state), so its material layout and mixed cells are "
                                 "unknown: build the problem again, or set problem.state to a run's result.state")
            self.layout, self.mixed, self.node_mass = self.built.layout, self.built.mixed, self.built.node_mass
        if self.mixed is not None:
            self.mixed = replace(self.mixed, stats=dict(self.mixed.stats))
        self.described = None

    def end_run(self, state: State) -> None:
        """After a run: layout, mixed and node_mass describe ``state``, the state it returned."""
        self.described = state


@dataclass(frozen=True)
class RunStart:
    """A state with the material layout, mixed cells and nodal masses that describe it."""

    state: State
    layout: MaterialLayout
    mixed: MixedCells | None
    node_mass: np.ndarray


def build_problem(scene: Scene) -> Problem:
    """The problem of a validated scene, ready to run from its initial state."""
    problem = _build_problem_2d(scene) if scene.dimension == 2 else _build_problem_1d(scene)
    problem.remember_start()
    return problem


def _build_problem_1d(scene: Scene) -> Problem:
    mesh = interval_mesh(scene.mesh.extent, scene.mesh.cells)
    names = list(scene.materials)
    materials = [Material(n, scene.materials[n].eos, scene.materials[n].make_eos()) for n in names]

    # Region pieces → per-cell, per-material mass, energy, volume and momentum by exact
    # overlap lengths (a loop over the few region pieces, vectorised over cells).
    x = mesh.cell_vertex_positions()[:, :, 0]
    left, right = x.min(axis=1), x.max(axis=1)
    n_cells, n_materials = mesh.n_cells, len(materials)
    components = max(len(r.velocity) for r in scene.regions)  # 2: a transverse component
    per_material = {k: np.zeros((n_materials, n_cells)) for k in ("volume", "mass", "energy")}
    per_material["momentum"] = np.zeros((components, n_materials, n_cells))
    for lo, hi, region in scene.pieces():
        overlap = np.clip(np.minimum(hi, right) - np.maximum(lo, left), 0.0, None)
        eos = scene.materials[region.material].make_eos()
        m = names.index(region.material)
        piece_mass = region.density * overlap
        per_material["volume"][m] += overlap
        per_material["mass"][m] += piece_mass
        per_material["energy"][m] += piece_mass * float(eos.energy(region.density, region.pressure))
        for k, v in enumerate(region.velocity):
            per_material["momentum"][k, m] += piece_mass * v
    # Slivers below round-off of a node-aligned boundary are not materials of the cell.
    present = per_material["volume"] > 1e-9 * (right - left)
    count = present.sum(axis=0)
    mixed_cells = np.flatnonzero(count == 2)
    slots = 2 if mixed_cells.size else 1

    # Slot 0 holds the material of a pure cell, and the left material α of a mixed cell;
    # slot 1 the right material β of a mixed cell.  Slivers are merged into the dominant
    # material of the cell (mass, energy and momentum conserved).
    order = ranked_materials(per_material["volume"])
    cell_material = np.full((slots, n_cells), -1, dtype=np.int64)
    cell_material[0] = order[0]
    total = {k: v.sum(axis=-2) for k, v in per_material.items()}
    material_mass = np.zeros((slots, n_cells))
    material_energy = np.zeros((slots, n_cells))
    material_volume = np.zeros((slots, n_cells))
    material_mass[0], material_volume[0] = total["mass"], right - left
    material_energy[0] = total["energy"] / total["mass"]
    corner_momentum = np.stack([0.5 * total["momentum"], 0.5 * total["momentum"]], axis=1)  # (comp, corner, cell)
    corner_mass = np.stack([0.5 * total["mass"], 0.5 * total["mass"]])
    mixed = None
    if mixed_cells.size:
        first, second = order[0, mixed_cells], order[1, mixed_cells]
        # α is the material on the left of Γ: the one whose pieces start further left.
        left_is_first = _left_material_first(scene, names, left[mixed_cells], right[mixed_cells], first, second)
        alpha = np.where(left_is_first, first, second)
        beta = np.where(left_is_first, second, first)
        cell_material[0, mixed_cells], cell_material[1, mixed_cells] = alpha, beta
        for slot, mat in ((0, alpha), (1, beta)):
            material_mass[slot, mixed_cells] = per_material["mass"][mat, mixed_cells]
            material_volume[slot, mixed_cells] = per_material["volume"][mat, mixed_cells]
            material_energy[slot, mixed_cells] = (per_material["energy"][mat, mixed_cells]
                                                  / per_material["mass"][mat, mixed_cells])
        enriched = scene.interface.model == "enriched"
        if enriched:
            # Mass condensation (paper fig. 3): each material's mass and momentum in a mixed
            # cell go to its internal node; the external nodes are massless.  (The
            # single-velocity closure keeps the halves of the whole cell.)
            corner_mass[0, mixed_cells] = material_mass[0, mixed_cells]
            corner_mass[1, mixed_cells] = material_mass[1, mixed_cells]
            corner_momentum[:, 0, mixed_cells] = per_material["momentum"][:, alpha, mixed_cells]
            corner_momentum[:, 1, mixed_cells] = per_material["momentum"][:, beta, mixed_cells]
        node_left = np.where(x[mixed_cells, 0] < x[mixed_cells, 1], mesh.cell_nodes[mixed_cells, 0],
                             mesh.cell_nodes[mixed_cells, 1])
        node_right = np.where(x[mixed_cells, 0] < x[mixed_cells, 1], mesh.cell_nodes[mixed_cells, 1],
                              mesh.cell_nodes[mixed_cells, 0])
        mixed = MixedCells(mixed_cells, node_left, node_right, alpha, beta, materials,
                           tolerance=scene.numerics.interface_tolerance,
                           max_iterations=scene.numerics.interface_max_iterations,
                           nonlinear=scene.interface.solver == "nonlinear",
                           model=scene.interface.model, relaxation=scene.interface.relaxation)
    layout = MaterialLayout(cell_material, n_materials)
    # Corner shares were written left/right by position (as the remap reads them); the
    # state takes them in each cell's own node order.
    flipped = x[:, 0] > x[:, 1]
    corner_by_position = corner_mass
    own_mass = corner_mass.copy()
    own_mass[:, flipped] = corner_mass[::-1][:, flipped]
    own_momentum = corner_momentum.copy()
    own_momentum[:, :, flipped] = corner_momentum[:, ::-1][:, :, flipped]
    state, node_mass = state_from_cells(mesh, materials, layout, material_mass, material_energy,
                                        material_volume=material_volume, corner_mass=own_mass,
                                        corner_momentum=own_momentum)

    return finish_problem(scene, mesh, materials, layout, node_mass, state, mixed, corner_by_position,
                          exact_reference(scene))


def finish_problem(scene, mesh, materials, layout, node_mass, state, mixed, corner_mass, exact) -> Problem:
    """What 1D and 2D problems share once the state is built: boundary conditions held from
    t = 0, the effects, and the mixed cells' initial pressure relaxation (or, without it or
    when it fails, the volume-weighted mean pressure as the interface pressure)."""
    boundaries = side_boundaries(mesh, scene.mesh.extent, scene.boundaries)
    for boundary in boundaries:  # walls and pistons hold from t = 0
        boundary.apply(state.node_velocity)
    effect_table = scene_effects(scene, 0 if mixed is None else mixed.cells.size,
                                 [b.side for b in boundaries if b.kind == "velocity"])
    effects = active(effect_table)
    setup_failure = ""
    if mixed is not None:
        if "pressure_relaxation" in effects:
            try:
                state = initial_relaxation(mixed, state)
            except MixedCellFailure as failure:  # reported by the run, with this state
                where = place(failure.cell, mesh.cell_centroids()[failure.cell],
                              material_names(mixed, failure.index))
                setup_failure = f"{where}: initial pressure relaxation: {failure.detail}"
        if setup_failure or "pressure_relaxation" not in effects:  # the pressures as given
            cells = mixed.cells
            volumes = state.material_volume[:, cells]
            state = state.evolved(
                interface_pressure=(state.material_pressure[:, cells] * volumes).sum(axis=0) / volumes.sum(axis=0),
                interface_velocity=np.zeros(cells.size))
    return Problem(scene, mesh, materials, layout, node_mass, state, boundaries, exact, effects, mixed,
                   corner_mass, setup_failure, effect_table)


def mesh_2d(scene: Scene) -> MeshArrays:
    spec = scene.mesh
    if spec.kind == "saltzman":
        return saltzman_mesh(spec.extent, spec.cells, spec.cell_type)
    if spec.kind == "file":
        path = mesh_file_path(spec.file, scene.source)
        if not path.exists():
            raise SceneError("mesh.file", spec.file, f"an existing XDMF file (looked for {path})")
        try:
            return file_mesh(path)
        except (RuntimeError, ValueError) as error:
            raise SceneError("mesh.file", spec.file, f"an XDMF mesh of triangles or quadrilaterals ({error})") from None
    return rectangle_mesh(spec.extent, spec.cells, spec.cell_type)


def region_fractions_2d(scene: Scene, mesh: MeshArrays) -> np.ndarray:
    """(n_regions, n_cells): the share of each cell's area each region owns, from the exact
    areas of shape ∩ cell.  Later regions overwrite earlier ones: a region taking a share a
    of a cell scales what the earlier regions hold there by (1 − a) — exact when the earlier
    content of the cell is one region or the later shapes do not overlap inside the cell
    (a background and shapes that do not cross each other inside one cell)."""
    vertices = mesh.cell_vertex_positions()
    area = mesh.cell_volumes()
    fractions = np.zeros((len(scene.regions), mesh.n_cells))
    for r, region in enumerate(scene.regions):
        share = np.clip(region.shape.area_in(vertices) / area, 0.0, 1.0)
        if not np.any(share >= 1e-12):  # a region that acts nowhere
            table = scene.resolved["regions"][r]
            key = next(k for k in SHAPES if k in table)
            raise SceneError(f"regions[{r}].{key}", table[key], "a shape that meets the domain's cells "
                             "(this one covers none of them)")
        share[share < 1e-12] = 0.0
        share[share > 1.0 - 1e-12] = 1.0
        fractions[:r] *= 1.0 - share
        fractions[r] = share
    return fractions


def _build_problem_2d(scene: Scene) -> Problem:
    """2D: without [interface] materials meet on mesh lines (every cell pure); with it
    (single_velocity) a cell may hold two materials, each with its exact area, mass and
    energy (slot 0 the larger).  Node velocities: the region velocity fields sampled at the
    nodes, with the corner momenta of each cell's regions (one velocity field)."""
    mesh = mesh_2d(scene)
    names = list(scene.materials)
    materials = [Material(n, scene.materials[n].eos, scene.materials[n].make_eos()) for n in names]
    fractions = region_fractions_2d(scene, mesh)
    centroids = mesh.cell_centroids()
    covered = fractions.sum(axis=0)
    if np.any(covered < 1.0 - 1e-9):
        c = int(np.argmin(covered))
        raise SceneError("regions", f"cell {c} at ({centroids[c, 0]:.4g}, {centroids[c, 1]:.4g}) covered "
                         f"{covered[c]:.3g}", "regions whose shapes cover the whole domain")
    area = mesh.cell_volumes()
    n_materials, n_cells = len(materials), mesh.n_cells
    material_share = np.zeros((n_materials, n_cells))
    for r, region in enumerate(scene.regions):
        material_share[names.index(region.material)] += fractions[r]
    present = material_share > 1e-9
    count = present.sum(axis=0)
    limit = 1 if scene.interface is None else 2
    if np.any(count > limit):
        c = int(np.flatnonzero(count > limit)[0])
        held = [names[m] for m in np.flatnonzero(present[:, c])]
        owner = max(r for r in range(len(scene.regions)) if fractions[r, c] > 1e-9)
        allowed = (f"a shape whose boundary between '{held[0]}' and '{held[1]}' follows mesh lines, or "
                   "an [interface] table (mixed cells)" if limit == 1 else
                   f"at most two materials in a cell (cell {c} holds {', '.join(held)}): refine the mesh")
        raise SceneError(f"regions[{owner}]", scene.regions[owner].material,
                         f"{allowed}; cell {c} at ({centroids[c, 0]:.4g}, {centroids[c, 1]:.4g})")
    # Slivers below round-off are merged into the cell's main material.
    material_share = np.where(present, material_share, 0.0)
    material_share /= material_share.sum(axis=0)
    corners = mesh.cell_type.nodes_per_cell
    material_mass = np.zeros((n_materials, n_cells))
    material_energy = np.zeros((n_materials, n_cells))
    corner_momentum = np.zeros((2, corners, n_cells))
    # each material's own (enriched 2D mixed cells: one velocity per material on their nodes)
    material_corner_momentum = np.zeros((n_materials, 2, corners, n_cells))
    material_corner_mass = np.zeros((n_materials, corners, n_cells))
    node_x = mesh.cell_vertex_positions()  # (n_cells, corners, 2)
    for r, region in enumerate(scene.regions):
        if not np.any(fractions[r] > 0):
            continue
        m = names.index(region.material)
        eos = scene.materials[region.material].make_eos()
        region_mass = region.density * fractions[r] * area
        material_mass[m] += region_mass
        if region.total_energy is not None:  # spread evenly over the area the region holds
            material_energy[m] += region.total_energy * region_mass / region_mass.sum()
        elif region.rotation is not None:  # radial equilibrium: p at each cell's centroid
            cx, cy, omega = region.rotation
            r2 = (centroids[:, 0] - cx) ** 2 + (centroids[:, 1] - cy) ** 2
            material_energy[m] += region_mass * eos.energy(region.density, region.pressure
                                                           + 0.5 * region.density * omega**2 * r2)
        else:
            material_energy[m] += region_mass * float(eos.energy(region.density, region.pressure))
        velocity = np.broadcast_to(np.array(region.velocity, dtype=float)[:, None, None], (2, corners, n_cells)).copy()
        if region.rotation is not None:
            cx, cy, omega = region.rotation
            velocity[0] -= omega * (node_x[..., 1] - cy).T
            velocity[1] += omega * (node_x[..., 0] - cx).T
        if region.radial_velocity is not None:
            cx, cy, speed = region.radial_velocity
            offset = node_x - np.array([cx, cy])
            distance = np.linalg.norm(offset, axis=-1)
            unit = np.divide(offset, distance[..., None], out=np.zeros_like(offset), where=distance[..., None] > 0)
            velocity += speed * np.moveaxis(unit, -1, 0).transpose(0, 2, 1)
        corner_momentum += velocity * (region_mass / corners)
        material_corner_momentum[m] += velocity * (region_mass / corners)
        material_corner_mass[m] += region_mass / corners
    # Slot 0: the cell's larger material; slot 1: the other one of a mixed cell.
    order = ranked_materials(material_share)
    mixed_cells = np.flatnonzero(count == 2)
    slots = 2 if mixed_cells.size else 1
    cell_material = np.full((slots, n_cells), -1, dtype=np.int64)
    cell_material[0] = order[0]
    slot_mass = np.zeros((slots, n_cells))
    slot_energy = np.zeros((slots, n_cells))
    slot_volume = np.zeros((slots, n_cells))
    # a pure cell takes all the mass (slivers merged), a mixed cell each material's own
    total_mass = material_mass.sum(axis=0)
    slot_mass[0] = total_mass
    slot_energy[0] = material_energy.sum(axis=0) / total_mass
    slot_volume[0] = area
    mixed = None
    if mixed_cells.size:
        c = mixed_cells
        first, second = order[0, c], order[1, c]
        cell_material[1, c] = second
        for slot, m in ((0, first), (1, second)):
            slot_mass[slot, c] = material_mass[m, c]
            slot_energy[slot, c] = material_energy[m, c] / material_mass[m, c]
            slot_volume[slot, c] = material_share[m, c] * area[c]
        mixed = MixedCells(c, None, None, first, second, materials,
                           tolerance=scene.numerics.interface_tolerance,
                           max_iterations=scene.numerics.interface_max_iterations,
                           nonlinear=scene.interface.solver == "nonlinear", model=scene.interface.model,
                           relaxation=scene.interface.relaxation)
    layout = MaterialLayout(cell_material, n_materials)
    state, node_mass = state_from_cells(mesh, materials, layout, slot_mass, slot_energy,
                                        material_volume=slot_volume, corner_momentum=corner_momentum)
    problem = finish_problem(scene, mesh, materials, layout, node_mass, state, mixed, None,
                             exact_reference_2d(scene))
    if scene.interface is not None and scene.interface.model == "enriched":
        with_material_velocities(problem, material_corner_momentum, material_corner_mass)
    return problem


def with_material_velocities(problem: Problem, corner_momentum, corner_mass) -> None:
    """Give a 2D problem with enriched mixed cells one velocity per material on the nodes:
    each material's region velocities at its corners ``corner_momentum`` (n_materials, 2,
    k, n_cells) over ``corner_mass`` (n_materials, k, n_cells), with the condensed masses
    of the Lagrange step (:mod:`ale_xfem.mixed.enriched_2d`); each node moves with the
    material it lies in."""
    state, mesh = problem.state, problem.mesh
    layout = problem.layout.cell_material
    flat = mesh.cell_nodes.T.ravel()
    n_nodes = mesh.n_nodes
    cells = problem.mixed.cells if problem.mixed is not None else np.zeros(0, dtype=np.int64)
    corner, node_mass, owner, internal = material_geometry(
        mesh, state.node_position, by_material(state.material_volume, layout), by_material(state.material_mass, layout),
        cells, problem.scene.interface.normal)
    velocity = np.zeros((2, 2, n_nodes))
    for m in range(2):
        weight = np.bincount(flat, corner_mass[m].ravel(), n_nodes)
        for d in range(2):
            momentum = np.bincount(flat, corner_momentum[m, d].ravel(), n_nodes)
            velocity[m, d] = np.where(weight > 0, momentum / np.where(weight > 0, weight, 1.0), state.node_velocity[d])
        for boundary in problem.boundaries:
            boundary.apply(velocity[m])
    node_velocity = velocity[owner, :, np.arange(n_nodes)].T.copy()
    problem.state = state.evolved(node_velocity=node_velocity, material_node_velocity=velocity,
                                  material_node_mass=node_mass, material_corner_mass=corner,
                                  material_node_internal=internal)
    problem.node_mass = node_mass.sum(axis=0)


def _left_material_first(scene, names, left, right, first, second):
    """For each mixed cell, whether material ``first`` lies left of ``second`` in it."""
    pieces = scene.pieces()
    result = np.zeros(left.size, dtype=bool)
    for i in range(left.size):  # set-up only: one entry per mixed cell
        for lo, hi, region in pieces:
            if hi > left[i] and lo < right[i]:
                result[i] = names.index(region.material) == first[i]
                break
    return result


def initial_relaxation(mixed: MixedCells, state: State) -> State:
    """Equilibrate the pressures of the initial mixed cells (energy conserved): the pressure
    equilibrium of :mod:`ale_xfem.mixed.equilibrium` at fixed cell volumes."""
    cells = mixed.cells
    state0 = start_values(state, cells)
    volume = state.material_volume[0, cells] + state.material_volume[1, cells]
    guess = 0.5 * (state.material_pressure[0, cells] + state.material_pressure[1, cells])
    pressure, va, vb, details = PressureEquilibrium(mixed).relax(volume, state0, guess)
    return with_mixed_state(state, mixed.cells, va, vb, details, interface_velocity=np.zeros_like(va))


def state_from_cells(mesh: MeshArrays, materials, layout: MaterialLayout, material_mass,
                     material_energy, cell_momentum=None, material_volume=None, corner_mass=None,
                     corner_momentum=None) -> tuple[State, np.ndarray]:
    """Initial state from per-cell, per-material mass and specific energy (S, n_cells).

    Lumped nodal masses sum the cells' corner masses (corner_mass (corners, n_cells), in
    each cell's node order; by default equal shares of the cell's mass); nodal velocities
    carry the corner momenta (corner_momentum (components, corners, n_cells); by default
    the same shares of cell_momentum (components, n_cells)), so momentum is exact and a node
    on a velocity jump takes the mass-weighted mean.  material_volume defaults to the whole
    cell for slot 0."""
    corners = mesh.cell_type.nodes_per_cell
    if corner_mass is None:
        corner_mass = np.repeat(material_mass.sum(axis=0)[None, :] / corners, corners, axis=0)
    if corner_momentum is None:
        corner_momentum = np.repeat(np.asarray(cell_momentum)[:, None, :] / corners, corners, axis=1)
    node_mass = mesh.corners.scatter(corner_mass)
    velocity = np.stack([mesh.corners.scatter(c) for c in corner_momentum]) / node_mass
    if material_volume is None:
        material_volume = mesh.cell_volumes()[None, :].copy()
    density = density_of(material_mass, material_volume)
    pressure, sound_speed = thermodynamics(materials, layout, density, material_energy)
    state = State(0.0, mesh.node_position.copy(), velocity, material_mass.copy(),
                  material_energy.copy(), material_volume, density, pressure, sound_speed)
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
    pieces = _merge_identical_states(scene, scene.pieces())
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
        if not left.velocity[0] > right.velocity[0]:
            return None
        if not at_rest_reference:
            ambient = [r.pressure for r, _ in ((left, ml), (right, mr))]
            return ExactReference("plate_impact", None, 0.0, limit=(
                f"the plates are at p = {ambient[0]:g} | {ambient[1]:g}, not at their reference state (ρ = ρ0, "
                "p = 0) from which the linear Us–up Hugoniot of the impedance matching starts"))

        def plate(region, material):
            p = material.parameters
            return exact.Plate(p["rho0"], p["c0"], p["s"], region.velocity[0])
        solution = exact.PlateImpactSolution.solve(plate(left, ml), plate(right, mr), x0)
        kind = "plate_impact"
    else:
        return None
    conflict = _boundary_conflict(scene, left, right)
    if conflict:
        return ExactReference(kind, solution, 0.0, limit=conflict)
    # The solution holds until its outermost waves meet the domain's ends, which move with
    # the outer material (free end), the piston, or not at all (wall).
    slow, fast = solution.wave_speeds()
    end_left = _end_velocity(scene.boundaries["left"], left.velocity[0])
    end_right = _end_velocity(scene.boundaries["right"], right.velocity[0])
    times = [(x0 - a) / (end_left - slow) if end_left > slow else np.inf,
             (b - x0) / (fast - end_right) if fast > end_right else np.inf]
    side = "left" if times[0] <= times[1] else "right"
    valid = float(min(times))
    return ExactReference(kind, solution, valid, limit=(
        f"the {'slowest' if side == 'left' else 'fastest'} wave reaches the {side} end "
        f"({scene.boundaries[side].kind}) at t = {valid:.4g}"))


def _boundary_conflict(scene: Scene, left, right, sides=("left", "right"), component: int = 0) -> str:
    """The boundary that is not part of the exact (unbounded) problem from t = 0, in one
    phrase, or "": a wall holds only material at rest, a piston only material moving with
    it, a free end only material at zero pressure; anything else launches a wave at t = 0.
    ``left``, ``right``: the regions at the ``sides`` (2D: the two sides a planar problem's
    waves face, its velocity along them the ``component``)."""
    speed = max(abs(left.velocity[component]), abs(right.velocity[component]))
    pressure = max(abs(left.pressure), abs(right.pressure))
    scale = max(pressure + r.density * r.velocity[component] ** 2 for r in (left, right))
    for side, region in zip(sides, (left, right)):
        boundary, u, p = scene.boundaries[side], region.velocity[component], region.pressure
        if boundary.kind == "wall" and abs(u) > 1e-12 * speed:
            return f"boundaries.{side} = wall stops material moving at u = {u:g}: a wave starts there at t = 0"
        if boundary.kind == "velocity" and abs(boundary.velocity[component] - u) > 1e-12 * max(
                speed, abs(boundary.velocity[component])):
            held = ", ".join(f"{v:g}" for v in boundary.velocity)
            return (f"boundaries.{side} = {{velocity = [{held}]}} moves material at u = {u:g}: "
                    "a wave starts there at t = 0")
        if boundary.kind == "free" and abs(p) > 1e-6 * scale:
            return f"boundaries.{side} = free releases the pressure p = {p:g}: a rarefaction starts there at t = 0"
    return ""


def exact_reference_2d(scene: Scene) -> ExactReference | None:
    """Noh (one ideal gas at ~zero pressure flowing radially inwards, walls or free sides)
    and a piston into an ideal gas at rest (one side {velocity} along its inward normal,
    walls elsewhere: Saltzman's problem).  Anything else: None."""
    from ale_xfem.exact.planar_2d import NohSolution, PistonSolution

    states = {(r.material, r.density, r.pressure, r.velocity, r.radial_velocity) for r in scene.regions}
    if any(r.rotation is not None for r in scene.regions):
        return _spinning_disk(scene)
    if any(r.total_energy is not None for r in scene.regions):
        return _sedov(scene)
    if len(states) == 2:
        return _planar_riemann(scene)
    if len(states) != 1:
        return None
    material, density, pressure, velocity, radial = states.pop()
    spec = scene.materials[material]
    if spec.eos != "ideal_gas":
        return None
    gamma = spec.parameters["gamma"]
    (x0, x1), (y0, y1) = scene.mesh.extent
    if radial is not None and radial[2] < 0 and velocity == (0.0, 0.0):
        speed = -radial[2]
        if pressure > 1e-6 * density * speed**2:
            return None
        solution = NohSolution((radial[0], radial[1]), density, speed, gamma)
        sides = {"left": (x0, radial[0]), "right": (x1, radial[0]), "bottom": (y0, radial[1]),
                 "top": (y1, radial[1])}
        far = {side: abs(v - c) for side, (v, c) in sides.items() if abs(v - c) > 1e-12}
        # a side off the centre takes gas flowing in through it: only a free side (the gas
        # has no pressure) leaves it as the exact solution has it
        held = [side for side in far if scene.boundaries[side].kind != "free"]
        if held:
            return ExactReference("noh", solution, 0.0, limit=(
                f"boundaries.{held[0]} = {scene.boundaries[held[0]].kind} holds gas that flows in through it: "
                "a wave starts there at t = 0 (a free side is exact)"))
        # the shock meets the nearest side that is not on the centre (those move in at V)
        valid = min(far.values()) / (solution.shock_speed + speed) if far else np.inf
        return ExactReference("noh", solution, float(valid), limit=(
            f"the shock meets the gas at the nearest far side at t = {valid:.4g}"))
    pistons = [side for side, b in scene.boundaries.items() if b.kind == "velocity"]
    if radial is None and velocity == (0.0, 0.0) and len(pistons) == 1 and all(
            b.kind == "wall" for side, b in scene.boundaries.items() if side != pistons[0]):
        side = pistons[0]
        inward = {"left": (1.0, 0.0), "right": (-1.0, 0.0), "bottom": (0.0, 1.0), "top": (0.0, -1.0)}[side]
        piston = np.array(scene.boundaries[side].velocity)
        speed = float(piston @ np.array(inward))
        if speed <= 0 or abs(float(piston @ np.array(inward[::-1]))) > 0:
            return None
        origin = {"left": (x0, y0), "right": (x1, y0), "bottom": (x0, y0), "top": (x0, y1)}[side]
        solution = PistonSolution(origin, inward, speed, density, pressure, gamma)
        length = (x1 - x0) if side in ("left", "right") else (y1 - y0)
        valid = float(length / solution.shock_speed)
        return ExactReference("piston", solution, valid, limit=f"the shock reaches the far wall at t = {valid:.4g}")
    return None


def _spinning_disk(scene: Scene) -> ExactReference | None:
    """A disk spinning about its centre (``rotation``), inside the domain, in a box of fluid
    at rest that covers it, walls on every side, its rim pressure the outer fluid's: the
    steady state of
    :class:`ale_xfem.exact.planar_2d.SpinningDisk`, for ever.  Anything else: None."""
    from ale_xfem.exact.planar_2d import SpinningDisk
    from ale_xfem.geometry.shapes import Box, Disk

    if len(scene.regions) != 2:
        return None
    outer, disk = scene.regions
    (x0, x1), (y0, y1) = scene.mesh.extent
    if not (isinstance(outer.shape, Box) and outer.shape.lower == (x0, y0) and outer.shape.upper == (x1, y1)
            and isinstance(disk.shape, Disk) and disk.rotation is not None and outer.rotation is None
            and outer.velocity == (0.0, 0.0) and disk.velocity == (0.0, 0.0)
            and outer.radial_velocity is None and disk.radial_velocity is None
            and tuple(disk.rotation[:2]) == tuple(disk.shape.center) and outer.total_energy is None):
        return None
    omega, radius = disk.rotation[2], disk.shape.radius
    (cx, cy) = disk.shape.center
    if min(cx - x0, x1 - cx, cy - y0, y1 - cy) < radius:
        return ExactReference("spinning_disk", None, 0.0, limit="the disk reaches a side of the domain: not the "
                              "steady state of a disk in an unbounded fluid at rest")
    held = [side for side, b in scene.boundaries.items() if b.kind != "wall"]
    if held:
        return ExactReference("spinning_disk", None, 0.0, limit=(
            f"boundaries.{held[0]} = {scene.boundaries[held[0]].kind}: the fluid at rest is held by walls only "
            "in the steady state"))
    rim = disk.pressure + 0.5 * disk.density * omega**2 * radius**2
    if abs(rim - outer.pressure) > 1e-9 * max(abs(rim), abs(outer.pressure), disk.density * (omega * radius) ** 2):
        return ExactReference("spinning_disk", None, 0.0, limit=(
            f"the disk's rim pressure {rim:.6g} is not the outer fluid's {outer.pressure:.6g}: not a steady state"))
    solution = SpinningDisk(tuple(disk.shape.center), radius, omega, disk.density, outer.density, outer.pressure)
    return ExactReference("spinning_disk", solution, float("inf"), limit="a steady state: it holds for ever")


def _sedov(scene: Scene) -> ExactReference | None:
    """Sedov's cylindrical blast: one ideal gas at rest at ~zero pressure, and a box at the
    domain's lower-left corner holding ``total_energy`` with walls on the left and bottom
    sides (a quarter of the plane: the blast's energy per unit length is 4 × total_energy).
    Valid until the shock reaches the nearest other side."""
    from ale_xfem.exact.sedov import SedovProfile, SedovSolution
    from ale_xfem.geometry.shapes import Box

    background, source = scene.regions[0], scene.regions[-1]
    (x0, x1), (y0, y1) = scene.mesh.extent
    spec = scene.materials[background.material]
    if (len(scene.regions) != 2 or source.total_energy is None or background.total_energy is not None
            or source.material != background.material or spec.eos != "ideal_gas"
            or not isinstance(source.shape, Box) or source.shape.lower != (x0, y0)
            or scene.boundaries["left"].kind != "wall" or scene.boundaries["bottom"].kind != "wall"
            or source.density != background.density
            or any(np.any(np.array(r.velocity)) or r.radial_velocity for r in scene.regions)):
        return None
    energy = 4.0 * source.total_energy
    if background.pressure > 1e-4 * energy / min(x1 - x0, y1 - y0) ** 2:
        return None  # not a strong blast: the similarity solution does not hold
    solution = SedovSolution((x0, y0), energy, background.density,
                             SedovProfile.solve(spec.parameters["gamma"], 2))
    # R(t) = ξ0 (E t²/ρ0)^{1/4} reaches the nearest far side
    reach = min(x1 - x0, y1 - y0)
    valid = (reach / solution.profile.xi0) ** 2 * np.sqrt(background.density / energy)
    return ExactReference("sedov", solution, float(valid),
                          limit=f"the shock reaches the nearest far side at t = {valid:.4g}")


def _planar_riemann(scene: Scene) -> ExactReference | None:
    """Two gas states, the later one a half-plane over the earlier (a box covering the
    domain): a Riemann problem along the half-plane's normal, each side with its own
    tangential velocity (which the exact solution carries on its side of the contact).
    Walls reflect its waves in 2D, so the L1 errors are taken over the disk around the
    domain's centre that no signal from a wall reaches before t_end."""
    from ale_xfem.exact.planar_2d import PlanarRiemann, contact_tangent
    from ale_xfem.geometry.shapes import Box, HalfPlane

    first, last = scene.regions[0], scene.regions[-1]
    if not (isinstance(last.shape, HalfPlane) and isinstance(first.shape, Box)) or any(
            r.radial_velocity is not None for r in scene.regions):
        return None
    if any(r.shape not in (first.shape, last.shape) for r in scene.regions):
        return None
    (x0, x1), (y0, y1) = scene.mesh.extent
    if first.shape.lower != (x0, y0) or first.shape.upper != (x1, y1):
        return None
    normal = np.array(last.shape.normal, dtype=float)
    normal /= np.linalg.norm(normal)
    tangent = contact_tangent(normal)
    gases = ("ideal_gas", "stiffened_gas")
    states, tangential = [], []
    for region in (last, first):  # left of the line (the half-plane), then right
        material = scene.materials[region.material]
        velocity = np.array(region.velocity)
        if material.eos not in gases:
            return None
        states.append(exact.GasState(region.density, float(velocity @ normal), region.pressure,
                                     material.parameters["gamma"], material.parameters.get("p_inf", 0.0)))
        tangential.append(float(velocity @ tangent))  # each side keeps its own (a slip line)
    try:
        solution = exact.RiemannSolution.solve(states[0], states[1], 0.0)
    except exact.VacuumError:
        return None
    slow, fast = solution.wave_speeds()
    star = solution.star
    behind = [exact.GasState(rho, star.velocity, star.pressure, g.gamma, g.p_inf)
              for rho, g in ((star.density_left, states[0]), (star.density_right, states[1]))]
    # a bound on the speed of any signal: the fastest wave plus the largest sound speed
    # (and the fastest tangential flow, which carries a wall's disturbance along)
    signal = max(abs(slow), abs(fast)) + max(g.sound_speed for g in states + behind) + max(map(abs, tangential))
    centre = (0.5 * (x0 + x1), 0.5 * (y0 + y1))
    radius = min(x1 - x0, y1 - y0) / 2 - signal * scene.t_end
    pistons = [side for side, b in scene.boundaries.items() if b.kind == "velocity"]
    if pistons:  # its wave may outrun the signal bound of the window
        return ExactReference("planar_riemann", None, 0.0, limit=(
            f"boundaries.{pistons[0]} is a piston, which the planar Riemann problem does not have"))
    reference = PlanarRiemann(solution, last.shape.point, tuple(normal), tuple(tangential))
    along_axis = np.flatnonzero(np.abs(normal) == 1.0)
    if along_axis.size == 1 and tangential == [0.0, 0.0]:
        # along x or y, the discontinuity inside the domain, walls on the two sides the waves
        # run along (slip walls that the planar flow, with no tangential velocity, meets as
        # they are), and the two sides they face part of the problem from t = 0: exact over
        # the whole domain until the waves reach those sides
        axis = int(along_axis[0])
        parallel, facing = ((("bottom", "top"), ("left", "right")) if axis == 0
                            else (("left", "right"), ("bottom", "top")))
        lower, upper = scene.mesh.extent[axis]
        point = last.shape.point[axis]
        # the state at each facing side: the half-plane's (``last``) lies behind its normal
        at_lower, at_upper = (last, first) if normal[axis] > 0 else (first, last)
        if (lower < point < upper and all(scene.boundaries[side].kind == "wall" for side in parallel)
                and not _boundary_conflict(scene, at_lower, at_upper, facing, axis)):
            # the distances along n from the discontinuity to the side behind it and the side ahead
            behind_side, ahead_side = ((point - lower, upper - point) if normal[axis] > 0
                                       else (upper - point, point - lower))
            valid = min(behind_side / -slow if slow < 0 else np.inf, ahead_side / fast if fast > 0 else np.inf)
            return ExactReference("planar_riemann", reference, float(valid), limit=(
                f"planar in the whole domain (walls along the waves' path) until a wave reaches a side at "
                f"t = {valid:.4g}"))
    if radius <= 0:
        return None
    return ExactReference("planar_riemann", reference,
                          float("inf"), window=(centre, float(radius)),
                          limit=f"errors over the disk of radius {radius:.4g} that no wave from a side reaches by t_end")


def _merge_identical_states(scene: Scene, pieces):
    """Join neighbouring pieces that hold the same state of the same equation of state
    (an interface between identical materials is not a wave of the exact solution)."""
    merged = []
    for lo, hi, region in pieces:
        if merged:
            previous = merged[-1][2]
            same_eos = (scene.materials[previous.material].eos == scene.materials[region.material].eos
                        and scene.materials[previous.material].parameters
                        == scene.materials[region.material].parameters)
            same_state = (previous.density, previous.pressure, previous.velocity) == (
                region.density, region.pressure, region.velocity)
            if same_eos and same_state:
                merged[-1] = (merged[-1][0], hi, previous)
                continue
        merged.append((lo, hi, region))
    return merged


def _end_velocity(boundary, material_velocity: float) -> float:
    if boundary.kind == "wall":
        return 0.0
    if boundary.kind == "velocity":
        return boundary.velocity[0]
    return material_velocity
