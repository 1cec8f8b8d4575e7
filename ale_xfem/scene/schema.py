"""Scenes: TOML files validated strictly, with `--set key=value` overrides.

Loading order (pyro2's habit): defaults → scene file → command-line overrides; the result
is validated as a whole and the fully resolved scene can be written next to the outputs.
Every problem is reported as one line naming the key, the value and what is allowed
(:class:`SceneError`); the CLI turns it into exit code 2 before anything runs.
"""

from __future__ import annotations

import copy
import difflib
import math
import re
import tomllib
import xml.etree.ElementTree as ElementTree
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ale_xfem import eos as eos_models
from ale_xfem.geometry import shapes
from ale_xfem.scene import effects

BOUNDARY_SIDES_1D = ("left", "right")
BOUNDARY_SIDES_2D = ("left", "right", "bottom", "top")
MESH_KEYS_2D = ("cell_type", "kind", "file")  # (beside extent, cells and motion, which both have)
REGION_KEYS_2D = ("total_energy", "radial_velocity", "rotation")  # and a shape (shapes.SHAPES)
MOTIONS_AVAILABLE = ("lagrangian", "eulerian", "smoothed", "interface")
MOTIONS_2D = ("lagrangian", "eulerian", "smoothed")  # interface-following is 1D only
CELL_TYPES_2D = ("quadrilateral", "triangle")
MESH_KINDS_2D = ("rectangle", "saltzman", "file")

NUMERICS_DEFAULTS = {
    "cfl": 0.5,  # fraction of the sound-crossing time of the smallest cell
    "dt_growth": 1.1,  # largest ratio between two successive time steps
    "q_quadratic": 1.0,  # von Neumann–Richtmyer coefficient: q ∋ c2 ρ Δu²
    "q_linear": 0.5,  # linear (Landshoff) coefficient: q ∋ c1 ρ c |Δu|
    "max_steps": 10_000_000,
    "interface_tolerance": 1e-10,  # mixed cells: pressure balance, relative to ρc²
    "interface_max_iterations": 50,  # predictor/corrector iterations per step
    "remap_order": 2,  # 1: constant per piece; 2: limited linear reconstruction
    # total: the kinetic energy the momentum remap loses goes into the internal energy of
    # the cells around each node (total energy conserved); internal: it is lost (reported)
    "remap_energy": "total",
    # 2D remap with [interface]: a material the remap leaves below this fraction of a cell's
    # area leaves the cell (its mass and energy to a neighbour holding more of it, its volume
    # to the cell's other material, whose pressure moves by about ρc² × the fraction):
    # ale_xfem.remap.remapper_2d, "Traces"
    "trace_fraction": 1e-4,
    # 2D quadrilaterals: viscous hourglass control, f_i = −(κ/4) ρ c √A (Σ_j γ_j u_j) γ_i;
    # 0.3: with 0.1 a cell of the rotated tube (50 × 50) turned a corner inside out
    "hourglass": 0.3,
    # 2D: the time step resolves the viscosity's stiffness (its signal speed scaled by √A
    # over the cell's least width); false: Benson's 1D form alone, fewer steps on compressed
    # cells, but sliver triangles can break down (ExplicitWilkins.stable_time_step)
    "viscous_time_step": True,
}

INTERFACE_DEFAULTS = {
    "model": "enriched",  # enriched (the paper) | single_velocity (baseline closure)
    "solver": "nonlinear",  # nonlinear (predictor + corrector) | linearised (predictor alone)
    "slip": "free",  # enriched cells: free | stick (2D; coulomb an error: fluids carry no shear)
    "relaxation": True,  # pressure relaxation of mixed cells at the start of every step
    "predictor": "closed_form",  # closed_form (1D elimination) | assembled (UFL forms + PETSc)
}


class SceneError(ValueError):
    """A scene that cannot run, reported as one line: key, value, what is allowed."""

    def __init__(self, key: str, value: Any, allowed: str):
        self.key, self.value, self.allowed = key, value, allowed
        super().__init__(f"{key} = {_show(value)}: {allowed}")


def _show(value: Any) -> str:
    if value is _MISSING:
        return "(missing)"
    if isinstance(value, bool):  # as the scene writes it (TOML)
        return "true" if value else "false"
    text = repr(value) if isinstance(value, str) else str(value)
    return text if len(text) < 80 else text[:77] + "..."


_MISSING = object()


# ----------------------------------------------------------------------------- dataclasses


@dataclass(frozen=True)
class MeshSpec:
    extent: tuple  # 1D (x0, x1); 2D ((x0, x1), (y0, y1))
    cells: int | tuple[int, int]  # 1D n; 2D (nx, ny)
    motion: str
    cell_type: str = "interval"  # 2D: quadrilateral | triangle
    kind: str = "interval"  # 2D: rectangle | saltzman | file
    file: str = ""  # kind = "file": an XDMF mesh


@dataclass(frozen=True)
class MaterialSpec:
    name: str
    eos: str
    parameters: dict[str, float]

    def make_eos(self):
        return eos_models.make_eos(self.eos, self.parameters)


@dataclass(frozen=True)
class RegionSpec:
    index: int
    material: str
    interval: tuple[float, float] | None  # 1D
    density: float
    pressure: float
    velocity: tuple[float, ...]
    shape: object = None  # 2D: a shape of ale_xfem.geometry.shapes
    radial_velocity: tuple[float, float, float] | None = None  # 2D: (cx, cy, speed), u = speed r̂
    total_energy: float | None = None  # 2D: the region's internal energy (instead of its pressure)
    # 2D: (cx, cy, ω): u += ω ẑ × (x − c), and the region in radial equilibrium about c,
    # p = pressure + ½ ρ ω² |x − c|² (``pressure``: the pressure at the centre)
    rotation: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class BoundarySpec:
    kind: str  # wall | free | velocity
    velocity: tuple[float, ...] | None = None


@dataclass(frozen=True)
class Numerics:
    cfl: float
    dt_growth: float
    q_quadratic: float
    q_linear: float
    max_steps: int
    interface_tolerance: float = 1e-10
    interface_max_iterations: int = 50
    remap_order: int = 2
    remap_energy: str = "total"
    trace_fraction: float = 1e-4
    hourglass: float = 0.3
    viscous_time_step: bool = True


@dataclass(frozen=True)
class InterfaceSpec:
    model: str
    solver: str
    stabilisation: str | None  # 2D enriched mixed cells only: bubble | nitsche | none
    slip: str
    relaxation: bool = True
    predictor: str = "closed_form"
    petsc_options: tuple = ()  # (name, value) pairs for the assembled interface system's KSP
    nitsche_penalty: float | None = None  # 2D enriched, Nitsche: the dimensionless penalty factor
    # 2D enriched: the weight of each material's ghost viscosity over the other material's
    # part of a cut cell, relative to the inertia 4ρ_m|K|/dt (ale_xfem.mixed.enriched_2d)
    ghost_viscosity: float | None = None
    normal: str = "youngs"  # 2D: PLIC's normals, youngs | lvira (Youngs' refined: ale_xfem.model.plic)


@dataclass(frozen=True)
class Scene:
    name: str
    description: str
    dimension: int
    t_end: float
    mesh: MeshSpec
    materials: dict[str, MaterialSpec]
    regions: tuple[RegionSpec, ...]
    boundaries: dict[str, BoundarySpec]
    numerics: Numerics
    interface: InterfaceSpec | None
    resolved: dict = field(repr=False)  # the validated dictionary, defaults filled in
    source: str = ""

    def pieces(self) -> list[tuple[float, float, RegionSpec]]:
        """The domain cut into maximal intervals each owned by one region (later regions
        overwrite earlier ones), left to right."""
        return region_pieces(self.mesh.extent, self.regions)


# ----------------------------------------------------------------------------- loading


def load_scene(path: str | Path, overrides: list[str] | tuple[str, ...] = ()) -> Scene:
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as error:
        if not path.exists() and path.parent == Path(".") and path.suffix in ("", ".toml"):
            close = difflib.get_close_matches(path.stem, [p.stem for p in shipped_scenes()], n=1, cutoff=0.75)
            hint = f"; did you mean '{close[0]}'?" if close else ""
            raise SceneError("scene", str(path), f"a shipped scene (see `ale-xfem list`) or a readable TOML file "
                             f"(no such file{hint})") from None
        raise SceneError("scene", str(path), f"a readable TOML file ({error.strerror})") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise SceneError("scene", str(path), f"valid TOML ({error})") from None
    for item in overrides:
        apply_override(data, item)
    return validate(data, source=str(path))


def apply_override(data: dict, item: str) -> None:
    """Apply one `key=value` (dotted key, list positions as integers: `regions.1.density=2`,
    or as the errors name them: `regions[1].density=2`).  The value is read as a TOML value
    when it parses as one, else as a string."""
    if "=" not in item:
        raise SceneError("--set", item, "key=value, e.g. mesh.cells=400")
    key, text = item.split("=", 1)
    key = re.sub(r"\[([0-9]+)\]", r".\1", key.strip())  # regions[1].density: regions.1.density
    try:
        value = tomllib.loads(f"v = {text.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        value = text.strip()
    parts = key.split(".")
    if not key or any(p == "" for p in parts):
        raise SceneError("--set", item, "a dotted key such as mesh.cells")
    node: Any = data
    for depth, part in enumerate(parts[:-1]):
        where = ".".join(parts[: depth + 1])
        if isinstance(node, list):
            if not part.isdigit() or int(part) >= len(node):
                raise SceneError(where, part, f"a list position 0..{len(node) - 1}")
            node = node[int(part)]
        elif isinstance(node, dict):
            node = node.setdefault(part, {})
        else:
            raise SceneError(where, node, "a table or a list to set a key in")
    last = parts[-1]
    if isinstance(node, list):
        if not last.isdigit() or int(last) >= len(node):
            raise SceneError(key, last, f"a list position 0..{len(node) - 1}")
        node[int(last)] = value
    elif isinstance(node, dict):
        node[last] = value
    else:
        raise SceneError(".".join(parts[:-1]), node, "a table or a list to set a key in")


# ----------------------------------------------------------------------------- validation helpers


def _keys(table: Any, where: str, required: tuple[str, ...], optional: tuple[str, ...] = (),
          other_dimension: tuple[str, ...] = (), dimension: int = 1) -> dict:
    """``table`` checked to hold the ``required`` keys and no others but the ``optional``
    ones; a key of the scenes of the other dimension (``other_dimension``) is named so."""
    if not isinstance(table, dict):
        raise SceneError(where or "scene", table, "a table")
    prefix = f"{where}." if where else ""
    for key in table:
        if key in other_dimension:
            raise SceneError(f"{prefix}{key}", table[key], f"a key of {3 - dimension}D scenes: it cannot act in "
                             f"this one, of dimension = {dimension}")
        if key not in required and key not in optional:
            allowed = ", ".join(sorted(required + optional))
            # (known keys: whether one can act in this scene is checked after, with its own error)
            raise SceneError(f"{prefix}{key}", table[key], f"unknown key; the known ones here: {allowed}")
    for key in required:
        if key not in table:
            raise SceneError(f"{prefix}{key}", _MISSING, "required")
    return table


def _real(value: Any, key: str, condition=lambda v: True, allowed: str = "a real number") -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise SceneError(key, value, allowed)
    if not condition(float(value)):
        raise SceneError(key, value, allowed)
    return float(value)


def _integer(value: Any, key: str, minimum: int = 1) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise SceneError(key, value, f"an integer >= {minimum}")
    return int(value)


def _choice(value: Any, key: str, choices: tuple[str, ...]) -> str:
    if not isinstance(value, str) or value not in choices:
        raise SceneError(key, value, f"one of {', '.join(choices)}")
    return value


def _reals(value: Any, key: str, length: int) -> tuple[float, ...]:
    if not isinstance(value, list) or len(value) != length:
        raise SceneError(key, value, f"a list of {length} real number{'s' if length > 1 else ''}")
    return tuple(_real(v, f"{key}[{i}]") for i, v in enumerate(value))


# ----------------------------------------------------------------------------- validation


def validate(data: dict, source: str = "") -> Scene:
    data = copy.deepcopy(data)
    _keys(data, "", ("name", "dimension", "t_end", "mesh", "materials", "regions"),
          ("description", "boundaries", "numerics", "interface"))
    name = data["name"]
    if not isinstance(name, str) or not re.fullmatch(r"[A-Za-z0-9_.\-]+", name):
        raise SceneError("name", name, "a non-empty name of letters, digits, '-', '_' or '.'")
    description = data.setdefault("description", "")
    if not isinstance(description, str):
        raise SceneError("description", description, "a string")
    dimension = data["dimension"]
    if isinstance(dimension, bool) or dimension not in (1, 2):
        raise SceneError("dimension", dimension, "1 or 2")
    t_end = _real(data["t_end"], "t_end", lambda v: v > 0, "a real number > 0")

    cell_type_given = isinstance(data["mesh"], dict) and "cell_type" in data["mesh"]
    mesh = _validate_mesh(data["mesh"]) if dimension == 1 else _validate_mesh_2d(data["mesh"])
    if dimension == 2 and mesh.kind == "file":
        mesh = _cells_of_the_file(mesh, data["mesh"], source, cell_type_given)
    materials = _validate_materials(data["materials"])
    regions = _validate_regions(data["regions"], materials, mesh, dimension)
    boundaries = _validate_boundaries(data.setdefault("boundaries", {}), dimension)
    numerics_table = data.setdefault("numerics", {})
    written = set(numerics_table) if isinstance(numerics_table, dict) else set()
    numerics = _validate_numerics(numerics_table)
    if "interface" in data and len({r.material for r in regions}) < 2:
        raise SceneError("interface", data["interface"], "no table: the regions hold one material, so no cell holds "
                         "two and an interface has nothing to act on (remove [interface])")
    interface = _validate_interface(data["interface"], dimension, mesh.cell_type) if "interface" in data else None

    scene = Scene(name, description, dimension, t_end, mesh, materials, regions, boundaries, numerics,
                  interface, resolved=data, source=source)
    _numerics_that_act(scene, written)
    if dimension == 1:
        _check_coverage(scene)
    _check_motion(scene)
    return scene


def _validate_mesh(table: Any) -> MeshSpec:
    mesh_table = _keys(table, "mesh", ("extent", "cells"), ("motion",), MESH_KEYS_2D, dimension=1)
    extent = _reals(mesh_table["extent"], "mesh.extent", 2)
    if not extent[0] < extent[1]:
        raise SceneError("mesh.extent", mesh_table["extent"], "[x0, x1] with x0 < x1")
    cells = _integer(mesh_table["cells"], "mesh.cells")
    motion = _choice(mesh_table.setdefault("motion", "lagrangian"), "mesh.motion",
                     MOTIONS_AVAILABLE)
    return MeshSpec(extent, cells, motion)


def _validate_mesh_2d(table: Any) -> MeshSpec:
    """2D: extent [[x0, x1], [y0, y1]]; cells [nx, ny] (or n: n along x and the same
    spacing along y); kind rectangle | saltzman (the rectangle's nodes shifted by
    (y1 − y) sin(π (x − x0)/(x1 − x0)) along x: Saltzman's skewed mesh) | file (an XDMF
    mesh; extent then gives the box whose sides carry the boundary conditions)."""
    mesh_table = _keys(table, "mesh", ("extent", "cells"), ("motion",) + MESH_KEYS_2D, dimension=2)
    raw = mesh_table["extent"]
    if not isinstance(raw, list) or len(raw) != 2 or not all(isinstance(r, list) for r in raw):
        raise SceneError("mesh.extent", raw, "[[x0, x1], [y0, y1]] in 2D")
    extent = tuple(_reals(r, f"mesh.extent[{i}]", 2) for i, r in enumerate(raw))
    for i, (lo, hi) in enumerate(extent):
        if not lo < hi:
            raise SceneError(f"mesh.extent[{i}]", list(raw[i]), "[lo, hi] with lo < hi")
    cells_raw = mesh_table["cells"]
    if isinstance(cells_raw, list):
        if len(cells_raw) != 2:
            raise SceneError("mesh.cells", cells_raw, "[nx, ny] (two integers >= 1) or n in 2D")
        cells = tuple(_integer(v, f"mesh.cells[{i}]") for i, v in enumerate(cells_raw))
    else:
        nx = _integer(cells_raw, "mesh.cells")
        (x0, x1), (y0, y1) = extent
        cells = (nx, max(1, round(nx * (y1 - y0) / (x1 - x0))))
    motion = mesh_table.setdefault("motion", "lagrangian")
    if motion in MOTIONS_AVAILABLE and motion not in MOTIONS_2D:
        raise SceneError("mesh.motion", motion, f"one of {', '.join(MOTIONS_2D)} in 2D ('{motion}' is 1D only)")
    motion = _choice(motion, "mesh.motion", MOTIONS_2D)
    cell_type = _choice(mesh_table.setdefault("cell_type", "quadrilateral"), "mesh.cell_type", CELL_TYPES_2D)
    kind = _choice(mesh_table.setdefault("kind", "rectangle"), "mesh.kind", MESH_KINDS_2D)
    file = mesh_table.get("file", "")
    (x0, x1), (y0, y1) = extent
    if kind == "saltzman" and not (y1 - y0) < (x1 - x0) / math.pi:
        raise SceneError("mesh.extent", raw, "with mesh.kind = 'saltzman', a height below the width / π "
                         "(the skew (y1 − y) sin(π x) folds the mesh beyond that)")
    if kind == "file":
        if not isinstance(file, str) or not file.endswith(".xdmf"):
            raise SceneError("mesh.file", file if file else _MISSING, "the path of an XDMF mesh (.xdmf) "
                             "with mesh.kind = 'file'")
    elif "file" in mesh_table:
        raise SceneError("mesh.file", file, "only with mesh.kind = 'file'")
    return MeshSpec(extent, cells, motion, cell_type, kind, file)


def _validate_materials(table: Any) -> dict[str, MaterialSpec]:
    if not isinstance(table, dict) or not table:
        raise SceneError("materials", table, "at least one [materials.NAME] table")
    materials = {}
    for name, spec in table.items():
        where = f"materials.{name}"
        if not isinstance(spec, dict):
            raise SceneError(where, spec, "a table with eos = ... and its parameters")
        eos_name = _choice(spec.get("eos", _MISSING), f"{where}.eos", tuple(eos_models.MODELS))
        _, required, optional = eos_models.MODELS[eos_name]
        _keys(spec, where, ("eos",) + required, tuple(optional))
        ranges = eos_models.parameter_ranges(eos_name)
        parameters = {}
        for key in required + tuple(optional):
            if key in spec:
                description, predicate = ranges[key]
                parameters[key] = _real(spec[key], f"{where}.{key}", predicate,
                                        f"a real number {description}" if description != "any real"
                                        else "a real number")
        materials[name] = MaterialSpec(name, eos_name, parameters)
    return materials


def _validate_regions(regions: Any, materials: dict[str, MaterialSpec], mesh: MeshSpec, dimension: int = 1):
    if not isinstance(regions, list) or not regions:
        raise SceneError("regions", regions, "at least one [[regions]] table")
    specs = []
    for index, table in enumerate(regions):
        where = f"regions[{index}]"
        interval = shape = radial = rotation = None
        if dimension == 1:
            _keys(table, where, ("material", "interval", "density", "pressure"), ("velocity",),
                  REGION_KEYS_2D + shapes.SHAPES, dimension=1)
        else:
            _keys(table, where, ("material", "density"), ("pressure", "velocity") + REGION_KEYS_2D + shapes.SHAPES,
                  ("interval",), dimension=2)
            if ("pressure" in table) == ("total_energy" in table):
                raise SceneError(where, ", ".join(k for k in ("pressure", "total_energy") if k in table) or _MISSING,
                                 "exactly one of pressure, total_energy (the region's internal energy)")
        material = table["material"]
        if material not in materials:
            raise SceneError(f"{where}.material", material,
                             f"one of the materials defined: {', '.join(materials)}")
        if dimension == 1:
            interval = _reals(table["interval"], f"{where}.interval", 2)
            if not interval[0] < interval[1]:
                raise SceneError(f"{where}.interval", table["interval"], "[x0, x1] with x0 < x1")
            a, b = mesh.extent
            slack = 1e-12 * (b - a)
            if interval[0] < a - slack or interval[1] > b + slack:
                raise SceneError(f"{where}.interval", table["interval"],
                                 f"an interval inside the domain {list(mesh.extent)} (nothing is clipped)")
        else:
            shape = _validate_shape(table, where)
        density = _real(table["density"], f"{where}.density")
        total_energy = None
        if "total_energy" in table:
            total_energy = _real(table["total_energy"], f"{where}.total_energy", lambda v: v > 0, "a real number > 0")
        pressure = _real(table["pressure"], f"{where}.pressure") if total_energy is None else 0.0
        raw_velocity = table.setdefault("velocity", [0.0] * dimension)
        if dimension == 1 and (not isinstance(raw_velocity, list) or len(raw_velocity) not in (1, 2)):
            raise SceneError(f"{where}.velocity", raw_velocity,
                             "[u] or [u, v] (v: a transverse component, carried by the remap)")
        if dimension == 2 and (not isinstance(raw_velocity, list) or len(raw_velocity) != 2):
            raise SceneError(f"{where}.velocity", raw_velocity, "[vx, vy] in 2D")
        velocity = _reals(raw_velocity, f"{where}.velocity", len(raw_velocity))
        if "radial_velocity" in table:
            key = f"{where}.radial_velocity"
            spec = _keys(table["radial_velocity"], key, ("center", "speed"))
            center = _reals(spec["center"], f"{key}.center", 2)
            radial = (*center, _real(spec["speed"], f"{key}.speed"))
        if "rotation" in table:
            key = f"{where}.rotation"
            spec = _keys(table["rotation"], key, ("center", "angular_velocity"))
            center = _reals(spec["center"], f"{key}.center", 2)
            rotation = (*center, _real(spec["angular_velocity"], f"{key}.angular_velocity"))
            if "total_energy" in table:
                raise SceneError(key, table["rotation"], "a region with a pressure (at the centre of rotation), "
                                 "not total_energy")
        eos = materials[material].make_eos()
        if not density > 0.0:
            raise SceneError(f"{where}.density", density, "a real number > 0")
        reason = eos.admissible(density, pressure) if total_energy is None else None
        if reason is not None:
            key = "density" if reason.startswith("density") else "pressure"
            value = density if key == "density" else pressure
            raise SceneError(f"{where}.{key}", value,
                             f"{reason} for {materials[material].eos} material '{material}'")
        specs.append(RegionSpec(index, material, interval, density, pressure, velocity, shape, radial, total_energy,
                                rotation))
    return tuple(specs)


def _validate_shape(table: dict, where: str):
    """Exactly one of box, half_plane, disk, polygon (see ale_xfem.geometry.shapes)."""
    given = [k for k in shapes.SHAPES if k in table]
    if len(given) != 1:
        raise SceneError(where, ", ".join(given) if given else _MISSING,
                         f"exactly one shape among {', '.join(shapes.SHAPES)}")
    kind = given[0]
    key = f"{where}.{kind}"
    value = table[kind]
    if kind == "box":
        if not isinstance(value, list) or len(value) != 2:
            raise SceneError(key, value, "[[x0, x1], [y0, y1]]")
        (x0, x1), (y0, y1) = (_reals(v, f"{key}[{i}]", 2) for i, v in enumerate(value))
        if not (x0 < x1 and y0 < y1):
            raise SceneError(key, value, "[[x0, x1], [y0, y1]] with x0 < x1 and y0 < y1")
        return shapes.Box((x0, y0), (x1, y1))
    if kind == "half_plane":
        spec = _keys(value, key, ("point", "normal"))
        point = _reals(spec["point"], f"{key}.point", 2)
        normal = _reals(spec["normal"], f"{key}.normal", 2)
        if normal[0] == 0.0 and normal[1] == 0.0:
            raise SceneError(f"{key}.normal", list(normal), "a non-zero vector (pointing out of the region)")
        return shapes.HalfPlane(point, normal)
    if kind == "disk":
        spec = _keys(value, key, ("center", "radius"))
        center = _reals(spec["center"], f"{key}.center", 2)
        radius = _real(spec["radius"], f"{key}.radius", lambda v: v > 0, "a real number > 0")
        return shapes.Disk(center, radius)
    if not isinstance(value, list) or len(value) < 3:
        raise SceneError(key, value, "a list of at least 3 vertices [[x, y], ...]")
    vertices = tuple(_reals(v, f"{key}[{i}]", 2) for i, v in enumerate(value))
    if abs(float(shapes.polygon_area(np.array(vertices)[None])[0])) <= 0.0:
        raise SceneError(key, value, "a polygon of non-zero area")
    return shapes.Polygon(vertices)


def _validate_boundaries(table: Any, dimension: int = 1) -> dict[str, BoundarySpec]:
    sides = BOUNDARY_SIDES_1D if dimension == 1 else BOUNDARY_SIDES_2D
    _keys(table, "boundaries", (), sides, tuple(side for side in BOUNDARY_SIDES_2D if side not in sides),
          dimension=dimension)
    boundaries = {}
    for side in sides:
        value = table.setdefault(side, "wall")
        key = f"boundaries.{side}"
        if isinstance(value, dict):
            _keys(value, key, ("velocity",))
            boundaries[side] = BoundarySpec("velocity", _reals(value["velocity"], f"{key}.velocity", dimension))
        elif value in ("wall", "free"):
            boundaries[side] = BoundarySpec(value)
        else:
            allowed = "{velocity = [u]}" if dimension == 1 else "{velocity = [vx, vy]}"
            raise SceneError(key, value, f"'wall', 'free' or {allowed}")
    return boundaries


def _validate_numerics(table: Any) -> Numerics:
    _keys(table, "numerics", (), tuple(NUMERICS_DEFAULTS))
    for key, default in NUMERICS_DEFAULTS.items():
        table.setdefault(key, default)
    return Numerics(
        cfl=_real(table["cfl"], "numerics.cfl", lambda v: 0 < v <= 1, "a real number in (0, 1]"),
        dt_growth=_real(table["dt_growth"], "numerics.dt_growth", lambda v: v >= 1, "a real number >= 1"),
        q_quadratic=_real(table["q_quadratic"], "numerics.q_quadratic", lambda v: v >= 0, "a real number >= 0"),
        q_linear=_real(table["q_linear"], "numerics.q_linear", lambda v: v >= 0, "a real number >= 0"),
        max_steps=_integer(table["max_steps"], "numerics.max_steps"),
        interface_tolerance=_real(table["interface_tolerance"], "numerics.interface_tolerance",
                                  lambda v: 0 < v < 1e-2, "a real number in (0, 0.01)"),
        interface_max_iterations=_integer(table["interface_max_iterations"],
                                          "numerics.interface_max_iterations"),
        remap_order=_choice_int(table["remap_order"], "numerics.remap_order", (1, 2)),
        remap_energy=_choice(table["remap_energy"], "numerics.remap_energy", ("total", "internal")),
        trace_fraction=_real(table["trace_fraction"], "numerics.trace_fraction", lambda v: 0 < v <= 1e-2,
                             "a real number in (0, 0.01]"),
        hourglass=_real(table["hourglass"], "numerics.hourglass", lambda v: 0 <= v <= 1, "a real number in [0, 1]"),
        viscous_time_step=_boolean(table["viscous_time_step"], "numerics.viscous_time_step"),
    )


def _numerics_that_act(scene: Scene, written: set) -> None:
    """A [numerics] key that cannot act in the scene is an error if the scene (or --set)
    wrote it, and its default is left out of the resolved scene otherwise (which holds only
    keys that act, as [interface] does): the remap's keys without a remap, the hourglass
    control off quadrilaterals, the viscous time step outside 2D or without viscosity, the
    mixed cells' solver settings without [interface].  Whether a remap sweeps, remaps in
    place, and whether the cells have hourglass modes or a viscosity is decided where the
    effects are (ale_xfem.scene.effects); the [interface] table may hold mixed cells."""
    table = scene.resolved["numerics"]
    motion, cell_type, interface = scene.mesh.motion, scene.mesh.cell_type, scene.interface
    where = {
        "remap_order": (effects.sweeps(scene), f"mesh.motion = '{motion}': it sets the order of the remap's "
                        "reconstruction, and a Lagrangian mesh sweeps nothing (remove it, or set mesh.motion = "
                        "'eulerian' or 'smoothed')"),
        "remap_energy": (effects.sweeps(scene) or effects.remaps_in_place(scene, interface is not None),
                         f"mesh.motion = '{motion}': nothing is remapped (remove it, or set mesh.motion = "
                         "'eulerian' or 'smoothed')"),
        "trace_fraction": (scene.dimension == 2 and interface is not None
                           and (effects.sweeps(scene) or effects.remaps_in_place(scene, True)),
                           "a 1D mesh: its remap leaves no traces (remove it)" if scene.dimension == 1
                           else "no [interface] table: a cell never holds two materials (remove it)"
                           if interface is None else f"mesh.motion = '{motion}' with "
                           f"interface.model = '{interface.model}': nothing is remapped (remove it, or set "
                           "mesh.motion = 'eulerian' or 'smoothed')"),
        "hourglass": (effects.has_hourglass_modes(scene),
                      (f"mesh.cell_type = '{cell_type}': triangles have no hourglass modes" if scene.dimension == 2
                       else "a 1D mesh: intervals have no hourglass modes") + " (remove it)"),
        "viscous_time_step": (scene.dimension == 2 and effects.has_viscosity(scene.numerics),
                              "a 1D mesh: the 1D time step has no such choice (remove it)" if scene.dimension == 1
                              else "numerics.q_quadratic = numerics.q_linear = 0: there is no viscosity to resolve "
                              "(remove it)"),
        "interface_tolerance": (interface is not None, "no [interface] table: no mixed cell is ever solved "
                                "(remove it)"),
        "interface_max_iterations": (interface is not None, "no [interface] table: no mixed cell is ever solved "
                                     "(remove it)"),
    }
    for key, (acts, why) in where.items():
        if acts:
            continue
        if key in written:
            raise SceneError(f"numerics.{key}", table[key], f"no value with {why}")
        del table[key]


def _choice_int(value: Any, key: str, choices: tuple[int, ...]) -> int:
    if isinstance(value, bool) or value not in choices:
        raise SceneError(key, value, f"one of {', '.join(map(str, choices))}")
    return int(value)


# [interface] keys that act only with enriched mixed cells (their interface solve)
# (``slip``: a single-velocity cell moves its materials alike, it sticks by construction)
ENRICHED_ONLY = ("solver", "predictor", "slip")
# [interface] keys of the 1D enriched cell's predictor: its closed form, or the 2D cells' assembled
# system and predictor/corrector (ale_xfem.mixed.implicit_step), which 2D enriched cells always are
ONE_D_ONLY = ("predictor",)
# [interface] keys of 2D enriched mixed cells, with their defaults (ghost_viscosity's by the
# mesh's cell type: ale_xfem.mixed.enriched_2d.GHOST_VISCOSITY, which the scene may not import)
TWO_D_DEFAULTS = {"stabilisation": "bubble", "nitsche_penalty": 1.0,
                  "ghost_viscosity": {"quadrilateral": 0.3, "triangle": 1.0}}
# [interface] keys of every 2D scene with an interface, with their defaults: PLIC's normals
PLIC_DEFAULTS = {"normal": "youngs"}


def mesh_file_path(file: str, source: str) -> Path:
    """Where ``mesh.file`` is: as given when absolute, else beside the scene file
    ``source`` (or in the working folder, for a scene with no file)."""
    path = Path(file)
    return Path(source).parent / path if not path.is_absolute() and source else path


def _cells_of_the_file(mesh: MeshSpec, table: dict, source: str, given: bool) -> MeshSpec:
    """A file mesh's cell type is its file's (the topology type of the XDMF file, read here
    so that what depends on it — hourglass control, the 2D enriched cells' ghost viscosity —
    is resolved at load): written into the resolved scene; a ``mesh.cell_type`` the scene
    gives that is not the file's is an error.  A file that cannot be read is left to the
    mesh's reading, which names it."""
    try:
        root = ElementTree.parse(mesh_file_path(mesh.file, source)).getroot()
    except (OSError, ElementTree.ParseError):
        return mesh
    topology = next((e for e in root.iter() if e.tag.rsplit("}", 1)[-1] == "Topology"), None)
    found = "" if topology is None else str(topology.get("TopologyType", "")).lower()  # (XDMF: "Triangle", ...)
    if found not in CELL_TYPES_2D or found == mesh.cell_type:
        return mesh
    if given:
        raise SceneError("mesh.cell_type", mesh.cell_type, f"'{found}', the cells of {mesh.file} (or leave it out: a "
                         "file mesh's cells are its file's)")
    table["cell_type"] = found
    return replace(mesh, cell_type=found)


def _validate_interface(table: Any, dimension: int, cell_type: str) -> InterfaceSpec:
    """[interface] of a mesh of ``cell_type`` cells; a key that cannot act in the scene is an
    error naming what would make it act (the resolved scene holds only keys that act)."""
    _keys(table, "interface", (), tuple(INTERFACE_DEFAULTS) + tuple(TWO_D_DEFAULTS) + tuple(PLIC_DEFAULTS)
          + ("petsc_options",))
    model = _choice(table.setdefault("model", INTERFACE_DEFAULTS["model"]), "interface.model",
                    ("enriched", "single_velocity"))
    enriched_2d = dimension == 2 and model == "enriched"
    if dimension == 1 and "normal" in table:
        raise SceneError("interface.normal", table["normal"], "no value in 1D: it chooses the normals of the 2D "
                         "interface reconstruction (PLIC); remove it")
    if dimension == 2:
        normal = _choice(table.setdefault("normal", PLIC_DEFAULTS["normal"]), "interface.normal", ("youngs", "lvira"))
    for key in TWO_D_DEFAULTS:
        if key in table and not enriched_2d:
            raise SceneError(f"interface.{key}", table[key], "no value: it acts only on 2D enriched mixed cells "
                             f"(this scene: {dimension}D, interface.model = '{model}'); remove the key")
    for key in ENRICHED_ONLY:
        if key in table and model != "enriched":
            raise SceneError(f"interface.{key}", table[key], "no value with interface.model = "
                             f"'{model}': it acts only on enriched mixed cells (remove it, or set "
                             "interface.model = 'enriched')")
    if enriched_2d:
        for key in ONE_D_ONLY:
            if key in table:
                raise SceneError(f"interface.{key}", table[key], "no value in 2D: it chooses how the 1D enriched "
                                 "cell is solved; 2D enriched cells always solve the assembled system "
                                 "(remove it)")
        stabilisation = _choice(table.setdefault("stabilisation", TWO_D_DEFAULTS["stabilisation"]),
                                "interface.stabilisation", ("bubble", "nitsche", "none"))
        if "nitsche_penalty" in table and stabilisation != "nitsche":
            raise SceneError("interface.nitsche_penalty", table["nitsche_penalty"], "no value with "
                             f"interface.stabilisation = '{stabilisation}': it scales Nitsche's penalty "
                             "(remove it, or set interface.stabilisation = 'nitsche')")
        if stabilisation == "nitsche":
            table.setdefault("nitsche_penalty", TWO_D_DEFAULTS["nitsche_penalty"])
        table.setdefault("ghost_viscosity", TWO_D_DEFAULTS["ghost_viscosity"][cell_type])
    for key, default in INTERFACE_DEFAULTS.items():
        if (key not in ENRICHED_ONLY or model == "enriched") and not (enriched_2d and key in ONE_D_ONLY):
            table.setdefault(key, default)
    assembled = enriched_2d or (model == "enriched" and table.get("predictor") == "assembled")
    if "petsc_options" in table and not assembled:
        hint = ("set interface.model = 'enriched'" if dimension == 2 else
                "set interface.model = 'enriched' and interface.predictor = 'assembled'")
        raise SceneError("interface.petsc_options", table["petsc_options"], "no value unless the interface system is "
                         "assembled by PETSc (2D enriched cells, or in 1D interface.model = 'enriched' and "
                         f"interface.predictor = 'assembled'); remove it, or {hint}")
    if assembled:
        table.setdefault("petsc_options", {})
    penalty, ghost = None, None
    if not enriched_2d:
        stabilisation = None
    else:
        ghost = _real(table["ghost_viscosity"], "interface.ghost_viscosity", lambda v: v >= 0, "a real number >= 0")
        if stabilisation == "nitsche":
            penalty = _real(table["nitsche_penalty"], "interface.nitsche_penalty", lambda v: v > 0,
                            "a real number > 0")
    return InterfaceSpec(
        model=model,
        solver=_choice(table.get("solver", "nonlinear"), "interface.solver", ("nonlinear", "linearised")),
        stabilisation=stabilisation,
        slip=_slip(table.get("slip"), model, enriched_2d),
        relaxation=_boolean(table["relaxation"], "interface.relaxation"),
        predictor=_choice(table.get("predictor", "closed_form"), "interface.predictor",
                          ("closed_form", "assembled")),
        petsc_options=_petsc_options(table.get("petsc_options", {})),
        nitsche_penalty=penalty,
        ghost_viscosity=ghost,
        **({"normal": normal} if dimension == 2 else {}),
    )


def _petsc_options(value: Any) -> tuple:
    """``[interface] petsc_options``: PETSc options of the interface system's KSP and PC
    (names without the leading '-', e.g. ``{ksp_type = "gmres", pc_type = "ilu"}``; default
    empty: a direct LDLᵀ solve by MUMPS, the system being symmetric).  Returned as sorted
    (name, value) pairs."""
    if not isinstance(value, dict):
        raise SceneError("interface.petsc_options", value, "a table of PETSc options, e.g. "
                         "{ksp_type = \"preonly\", pc_type = \"lu\"}")
    for name, option in value.items():
        if not re.fullmatch(r"[a-z][a-z0-9_]*", name):
            raise SceneError("interface.petsc_options", name, "a PETSc option name without its leading '-' "
                             "(lower case letters, digits, underscores)")
        if isinstance(option, (dict, list)):
            raise SceneError(f"interface.petsc_options.{name}", option, "a string, number or boolean")
    options = tuple(sorted((name, str(option).lower() if isinstance(option, bool) else str(option))
                           for name, option in value.items()))
    if options:
        _check_petsc_options(options)
    return options


def _check_petsc_options(options: tuple) -> None:
    """Let PETSc read the options on a solver set up as the interface system's is (direct
    LDLᵀ by MUMPS, the matrix marked symmetric) on a small matrix: a value it does not know, or an option it does not read
    for that solver (a misspelt name), is an error at load, not in the middle of a run."""
    import dolfinx_solver  # noqa: F401  (before petsc4py: it loads MPI and PETSc)
    from petsc4py import PETSc

    prefix = "ale_xfem_check_"
    database = PETSc.Options()
    for name, option in options:
        database[prefix + name] = option
    matrix = PETSc.Mat().createAIJ([2, 2], nnz=1, comm=PETSc.COMM_SELF)
    matrix.setValue(0, 0, 1.0)
    matrix.setValue(1, 1, 1.0)
    matrix.assemble()
    matrix.setOption(PETSc.Mat.Option.SYMMETRIC, True)
    ksp = PETSc.KSP().create(PETSc.COMM_SELF)
    try:
        ksp.setOperators(matrix)
        ksp.setType("preonly")
        ksp.getPC().setType("cholesky")
        ksp.getPC().setFactorSolverType("mumps")
        ksp.setOptionsPrefix(prefix)
        ksp.setFromOptions()
        if ksp.getPC().getType() in ("lu", "cholesky") and "pc_factor_mat_solver_type" not in dict(options):
            ksp.getPC().setFactorSolverType("mumps")  # as forms.bound_system.keep_factor_solver does
        ksp.setUp()
        unread = [name for name, _ in options if not database.used(prefix + name)]
        if unread:
            raise SceneError("interface.petsc_options", unread[0], "an option PETSc reads for this solver (it "
                             "did not read this one: a misspelt name, or an option of a solver not chosen)")
    except PETSc.Error as error:  # PETSc's traceback, one frame a line: its last line says why
        reason = str(error).strip().splitlines()[-1].removeprefix("[0]").strip()
        raise SceneError("interface.petsc_options", dict(options), f"options PETSc accepts ({reason})") from None
    finally:
        ksp.destroy()
        matrix.destroy()
        for name, _ in options:
            database.delValue(prefix + name)


def _slip(value: Any, model: str, enriched_2d: bool = False) -> str:
    """The tangential traction at Γ: 'free' (enriched cells; none), 'stick' (2D enriched
    cells: the whole velocity continuous across Γ; in 1D there is no tangent), and a
    single-velocity cell's 'stick' (one velocity field), which is not a key.  Coulomb friction is an error
    that says why: a friction law bounds a shear stress, and the materials here (fluids
    with an equation of state, no deviatoric stress) carry none."""
    if model == "single_velocity":
        return "stick"
    if value == "coulomb":
        raise SceneError("interface.slip", value, "'free': Coulomb friction bounds the shear stress the "
                         "materials transmit across Γ, and these materials (fluids: an equation of state, no "
                         "deviatoric stress) carry none, so it has nothing to act on")
    if enriched_2d:
        return _choice(value, "interface.slip", ("free", "stick"))
    if value == "stick":
        raise SceneError("interface.slip", value, "'free' in 1D (stick holds the tangential velocity, which 1D does "
                         "not have: it is for 2D enriched cells)")
    return _choice(value, "interface.slip", ("free",))


def _boolean(value: Any, key: str) -> bool:
    if not isinstance(value, bool):
        raise SceneError(key, value, "true or false")
    return value


# ----------------------------------------------------------------------------- region geometry


def region_pieces(extent, regions) -> list[tuple[float, float, RegionSpec]]:
    """Cut the domain at every region end; each piece belongs to the last region that
    contains it (later regions overwrite earlier ones); consecutive pieces of one region
    are merged.  Pieces no region covers carry ``None``."""
    a, b = extent
    cuts = sorted({a, b, *(x for r in regions for x in r.interval if a < x < b)})
    pieces: list[tuple[float, float, RegionSpec | None]] = []
    for lo, hi in zip(cuts[:-1], cuts[1:]):
        middle = 0.5 * (lo + hi)
        owner = None
        for region in regions:
            if region.interval[0] <= middle <= region.interval[1]:
                owner = region
        if pieces and pieces[-1][2] is owner:
            pieces[-1] = (pieces[-1][0], hi, owner)
        else:
            pieces.append((lo, hi, owner))
    return pieces


def _check_coverage(scene: Scene) -> None:
    pieces = scene.pieces()
    for lo, hi, owner in pieces:
        if owner is None:
            raise SceneError("regions", f"[{lo:g}, {hi:g}] uncovered",
                             "regions whose intervals cover the whole domain "
                             f"{list(scene.mesh.extent)}")
    # Without [interface] materials never share a cell: each boundary between two
    # materials must sit on a node of the initial mesh.  With it, a cell may hold one
    # interface (two materials), never two.
    a, b = scene.mesh.extent
    h = (b - a) / scene.mesh.cells
    cut_cells: dict[int, tuple[float, RegionSpec]] = {}
    for (_, x, left), (_, _, right) in zip(pieces[:-1], pieces[1:]):
        if left.material == right.material:
            continue
        position = (x - a) / h
        if abs(position - round(position)) <= 1e-9 * max(1.0, position):
            continue
        cell = int(math.floor(position))
        where = f"[{a + cell * h:g}, {a + (cell + 1) * h:g}]"
        if scene.interface is None:
            raise SceneError(f"regions[{right.index}].interval", list(right.interval),
                             f"the boundary x = {x:g} between '{left.material}' and "
                             f"'{right.material}' falls inside cell {cell} {where}; without "
                             "[interface] material boundaries must sit on mesh nodes")
        if cell in cut_cells:
            raise SceneError(f"regions[{right.index}].interval", list(right.interval),
                             f"a second interface (x = {cut_cells[cell][0]:g} and x = {x:g}) in "
                             f"cell {cell} {where}: a mixed cell holds one interface; refine "
                             "the mesh or move a region boundary")
        for neighbour in (cell - 1, cell + 1):
            if neighbour in cut_cells:
                raise SceneError(f"regions[{right.index}].interval", list(right.interval),
                                 f"interfaces in neighbouring cells {min(cell, neighbour)} and "
                                 f"{max(cell, neighbour)} (x = {cut_cells[neighbour][0]:g}, "
                                 f"x = {x:g}): mixed cells must be separated by a pure cell in "
                                 "this version; refine the mesh")
        cut_cells[cell] = (x, right)


def _check_motion(scene: Scene) -> None:
    """A regularised mesh moves materials across cells: boundaries between materials then
    fall inside cells, which needs [interface]; the Eulerian mesh is fixed, so material
    must not leave it (walls at both ends)."""
    interface = scene.interface
    if scene.dimension == 2 and interface is not None and interface.model == "enriched":
        if len(scene.materials) != 2:
            raise SceneError("materials", sorted(scene.materials), "exactly two materials with 2D enriched mixed "
                             "cells (each node carries one velocity per material), or interface.model = "
                             "'single_velocity'")
    if scene.mesh.motion == "lagrangian":
        return
    if len({r.material for r in scene.regions}) > 1 and scene.interface is None:
        raise SceneError("mesh.motion", scene.mesh.motion,
                         "'lagrangian' unless the scene has [interface]: a remapped mesh puts "
                         "material boundaries inside cells")
    if scene.mesh.motion == "eulerian":
        for side, spec in scene.boundaries.items():
            if spec.kind != "wall":
                raise SceneError(f"boundaries.{side}", spec.kind if spec.kind != "velocity" else
                                 {"velocity": list(spec.velocity)},
                                 "'wall' with mesh.motion = 'eulerian' (the fixed mesh must hold "
                                 "the material); use 'smoothed' for moving ends")


# ----------------------------------------------------------------------------- shipped scenes

SCENES_DIR = Path(__file__).resolve().parents[2] / "demos" / "scenes"


def shipped_scenes() -> list[Path]:
    return sorted(SCENES_DIR.glob("*.toml"))


def resolve_scene_path(name_or_path: str) -> Path:
    """A path, or the name of a shipped scene (with or without .toml)."""
    path = Path(name_or_path)
    if path.exists():
        return path
    for candidate in (SCENES_DIR / name_or_path, SCENES_DIR / f"{name_or_path}.toml"):
        if candidate.exists():
            return candidate
    return path
