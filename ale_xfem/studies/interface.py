"""The interface system of 2D enriched mixed cells on its own (`ale-xfem study interface`):
bubbles against Nitsche against the unstabilised P1–P0 pair, one implicit step at a time.

The case: a unit square at a uniform pressure, α striking β at 0.1 across a straight line
at 17° to the mesh (the interface pressure should rise alike all along it), triangles and
quadrilaterals, several resolutions and Nitsche penalty factors; then the same line moved
towards a node until the smallest cut fraction is below 1e-6 (slivers).  Reported: the
spread of the interface pressure's rise along Γ (standard deviation over |mean|, interior
cells), its mean, the size of the system and the time of its assembly and solve; for
slivers, how far the state at rest moves and how the spread behaves.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

import dolfinx_solver  # noqa: F401  (before dolfinx: it loads MPI and PETSc)
import dolfinx
from mpi4py import MPI

from ale_xfem.geometry.shapes import clip_half_plane, disk_polygon_area, polygon_area
from ale_xfem.mixed.cut_cells_2d import condensed_masses, cut_cells, node_materials
from ale_xfem.model.mesh import from_dolfinx
from ale_xfem.model.plic import reconstruct, youngs_normals
from forms.enriched_interface import InterfaceForms, InterfaceSystem, nitsche_weights

PRESSURE, DT = 1.0, 0.01
DENSITY, BULK = (1.0, 10.0), (1.0, 10.0)  # ρ_m and κ_m = ρ_m c_m² of α (inside) and β
_FORMS = {}


def interface_forms(stabilisation, slip, cell):
    """The compiled forms of a (stabilisation, slip, cell type), compiled once a process."""
    key = (stabilisation, slip, cell)
    if key not in _FORMS:
        _FORMS[key] = InterfaceForms(MPI.COMM_WORLD, stabilisation, slip, cell)
    return _FORMS[key]


class InterfaceCase:
    """One implicit step of the mixed cells of a unit square of n × n triangles or
    quadrilaterals at a uniform pressure, walls on all sides; α (ρc² = 1) inside a disk,
    below a straight line at ``angle`` (offset ``offset`` along its normal), or below a
    line with a kink along mesh edges; β (ρc² = 10) elsewhere.  Exact volume fractions,
    PLIC (the disk and the kink with Youngs' normals, the line with its own); the pure
    cells' forces those of the uniform pressure."""

    def __init__(self, n, shape="disk", offset=0.55, angle=0.3, cell="triangle"):
        self.cell = cell
        self.dolfinx_mesh = dolfinx.mesh.create_unit_square(MPI.COMM_WORLD, n, n, dolfinx.mesh.CellType[cell])
        mesh = self.mesh = from_dolfinx(self.dolfinx_mesh)
        x = mesh.node_position
        vertices = np.moveaxis(x[:, mesh.cell_nodes], 0, -1)
        area = polygon_area(vertices)
        self.normal_line = np.array([np.cos(angle), np.sin(angle)])
        if shape == "disk":
            fraction = disk_polygon_area(vertices, (0.5, 0.5), 0.3) / area
        elif shape == "kink":  # y ≤ ½ left of x = ½ (along mesh edges), a slope of 0.3 right of it
            below = clip_half_plane(vertices, np.array([0.0, 1.0]), np.full(area.size, 0.5))
            right = clip_half_plane(vertices, np.array([-1.0, 0.0]), np.full(area.size, -0.5))
            above = clip_half_plane(right, np.array([0.0, -1.0]), np.full(area.size, -0.5))
            wedge = clip_half_plane(above, np.array([-0.3, 1.0]), np.full(area.size, 0.5 - 0.15))
            fraction = (np.abs(polygon_area(below)) + np.abs(polygon_area(wedge))) / area
        else:
            inside = clip_half_plane(vertices, self.normal_line, np.full(area.size, offset))
            fraction = np.abs(polygon_area(inside)) / area
        fraction = np.clip(fraction, 0.0, 1.0)
        self.fraction = fraction
        trace = 1e-12  # below this a material is round-off of the exact overlap
        mixed = self.mixed = np.flatnonzero((fraction > trace) & (fraction < 1.0 - trace))
        material = np.where(fraction >= 1.0 - trace, 0, 1)
        material[mixed] = -1
        self.cell_material = material
        if shape != "line":  # Youngs' normals: the PLIC lines do not meet across edges
            normals = youngs_normals(mesh, x, fraction[None, :], mixed)[0]
        else:  # the line's own normal: an exact reconstruction
            normals = np.broadcast_to(self.normal_line, (mixed.size, 2)).copy()
        reconstruction = reconstruct(vertices[mixed], normals, fraction[mixed], mixed)
        alpha = np.zeros(mixed.size, dtype=np.int64)
        self.cut = cut_cells(mesh.cell_nodes, x, mixed, reconstruction, material, alpha)
        volume = np.zeros((2, mesh.n_cells))
        slots = np.full((2, mesh.n_cells), -1)
        volume[0], slots[0] = area, np.maximum(material, 0)
        volume[0, mixed], volume[1, mixed] = self.cut.volume
        slots[0, mixed], slots[1, mixed] = 0, 1
        self.owner, self.tied = node_materials(mesh.cell_nodes, mesh.n_nodes, material, volume, slots)
        masses, internal = condensed_masses(self.cut, mesh.cell_nodes, self.owner,
                                            np.stack([DENSITY[m] * self.cut.volume[m] for m in range(2)]),
                                            np.stack([alpha, 1 - alpha]))
        self.condensed, self.internal_in_cell = masses, internal
        self.node_mass = np.zeros((2, mesh.n_nodes))
        # a (material, node) is internal where a pure cell of the material or a mixed cell's
        # condensation puts its mass (its row trapezoidal); external elsewhere (its row the
        # static equilibrium at n+1)
        self.internal = np.zeros((2, mesh.n_nodes), dtype=bool)
        k = mesh.cell_nodes.shape[1]
        for m in range(2):
            pure = material == m
            np.add.at(self.node_mass[m], mesh.cell_nodes[pure].ravel(), np.repeat(DENSITY[m] * area[pure] / k, k))
            np.add.at(self.node_mass[m], mesh.cell_nodes[mixed].ravel(), masses[m].ravel())
            self.internal[m, mesh.cell_nodes[pure].ravel()] = True
            self.internal[m, mesh.cell_nodes[mixed][internal[m]]] = True
        on_side = [(np.abs(x[d]) < 1e-12) | (np.abs(x[d] - 1) < 1e-12) for d in range(2)]
        self.held = np.stack(on_side)  # walls hold the normal component
        self.boundary = on_side[0] | on_side[1]

    def explicit_forces(self, m):
        """(F̄, f^n) of material m under the uniform pressure (pure cells: P ∂|K|/∂x_i;
        mixed cells at n, P_m = p_Γ: P G_mi)."""
        mesh = self.mesh
        cells = np.flatnonzero(self.cell_material == m)
        _, gradient = mesh.cell_geometry(mesh.node_position, cells)  # ∂|K|/∂x_i, [corner][component]
        pure = np.zeros((2, mesh.n_nodes))
        for k, corner in enumerate(gradient):  # the explicit step's corner forces P ∂|K|/∂x_i
            for d in range(2):
                np.add.at(pure[d], mesh.cell_nodes[cells, k], PRESSURE * corner[d])
        mixed = np.zeros((2, mesh.n_nodes))
        for d in range(2):
            np.add.at(mixed[d], mesh.cell_nodes[self.mixed].ravel(), PRESSURE * self.cut.edge_flux[m][..., d].ravel())
        return pure, mixed

    def bind(self, stabilisation, slip="free"):
        """The interface system of the mixed cells, its cut geometry set."""
        mesh, cut = self.mesh, self.cut
        system = InterfaceSystem(self.dolfinx_mesh, self.mixed, interface_forms(stabilisation, slip, self.cell))
        system.vertex_order(mesh.cell_nodes[self.mixed])
        reconstruction = cut.reconstruction
        system.set_geometry((reconstruction.alpha, reconstruction.beta), reconstruction.start, reconstruction.end,
                            cut.edge_flux, cut.normal)
        return system

    def inertia_and_rhs(self, velocity=None, walls=True):
        """Each material's 4M/dt and right side 4M u^n/dt + 2F̄ + f^n (module docstring of
        forms/enriched_interface.py) from u^n = ``velocity`` [m] (default rest)."""
        mass, rhs = [], []
        for m in range(2):
            u0 = np.zeros((2, self.mesh.n_nodes)) if velocity is None else velocity[m]
            inertia = np.repeat(4.0 * self.node_mass[m][None] / DT, 2, axis=0)
            pure, mixed = self.explicit_forces(m)
            # internal rows: 2F̄ + f^n; external rows: nothing explicit (their equilibrium
            # at n+1, with only their small inertia)
            right = inertia * u0 + np.where(self.internal[m], 2.0 * pure + mixed, 0.0)
            if walls:
                inertia[self.held], right[self.held] = 1e20, 0.0
            else:  # the outside pressure on the sides, on each material's part of them: what
                # holds the state at rest there (an internal row holds 2F̄ + f^n + f^{n+1},
                # an external one f^{n+1})
                outside = np.where(self.internal[m], 2.0, 1.0) * (pure + mixed)
                right[:, self.boundary] -= outside[:, self.boundary]
            mass.append(inertia)
            rhs.append(right)
        return mass, rhs

    def solve(self, stabilisation, slip="free", velocity=None, penalty=1.0, walls=True):
        """One implicit solve from a uniform pressure, the materials' pressures linearised
        with the bulk moduli κ_m = ρc² of the case; ``velocity`` [m] (2, n_nodes) each
        material's u^n (default rest); ``walls``: the sides hold the normal velocity
        (otherwise a pressure p acts on them from outside).  Returns (the solution, the
        interface pressure)."""
        mesh, cut = self.mesh, self.cut
        clock = time.perf_counter()
        system = self.bind(stabilisation, slip)
        self.bind_seconds = time.perf_counter() - clock  # the forms bound, the cut weights fitted
        n = self.mixed.size
        bulk = np.array(BULK)[:, None] * np.ones((2, n))
        weight, gamma = nitsche_weights(cut.volume, bulk * DT, cut.reconstruction.length, penalty)
        system.set_materials(1.0 / (bulk * DT), np.full((2, n), PRESSURE), weight, gamma)
        mass, rhs = self.inertia_and_rhs(velocity, walls)
        clock = time.perf_counter()
        out = system.solve(mass, rhs, self.tied)
        self.solve_seconds = time.perf_counter() - clock
        self.unknowns = system.system.matrix.getSize()[0]
        if "interface_pressure" in out:
            interface = out["interface_pressure"]
        else:  # Nitsche: p̂ = w_α P_α + w_β P_β + γ [ū·n], averaged over Γ_K
            nodes = mesh.cell_nodes[self.mixed]
            jump = sum(cut.normal_flux(m, out["velocity"][m], nodes) for m in range(2))
            interface = weight * out["pressure"][0] + (1 - weight) * out["pressure"][1] \
                + gamma * jump / cut.reconstruction.length
        return out, interface

    def impact(self, stabilisation, penalty=1.0, speed=0.1):
        """α striking β at ``speed`` along the line's normal: (spread, mean) of the rise of
        the interface pressure over the cells of Γ away from the walls (0.15 < x, y < 0.85)."""
        velocity = [speed * self.normal_line[:, None] * np.ones((2, self.mesh.n_nodes)),
                    np.zeros((2, self.mesh.n_nodes))]
        _, interface = self.solve(stabilisation, velocity=velocity, penalty=penalty)
        centroid = self.cut.reconstruction.centroid
        interior = np.all((centroid > 0.15) & (centroid < 0.85), axis=1)
        rise = interface[interior] - PRESSURE
        return float(rise.std() / abs(rise.mean())), float(rise.mean())

    def rest(self, stabilisation):
        """The state at rest: (the largest velocity of a node carrying mass, the largest
        |p_Γ − p| / p)."""
        out, interface = self.solve(stabilisation)
        carrying = [self.node_mass[m] > 1e-9 * self.node_mass.max() for m in range(2)]
        velocity = max(float(np.abs(out["velocity"][m][:, carrying[m]]).max()) for m in range(2))
        return velocity, float(np.abs(interface - PRESSURE).max() / PRESSURE)


METHODS = (("none", 1.0), ("bubble", 1.0), ("nitsche", 0.1), ("nitsche", 1.0), ("nitsche", 10.0), ("nitsche", 100.0))
CELL_TYPES = ("triangle", "quadrilateral")
DEFAULT_CELLS = (24, 48, 96)
SLIVER_DISTANCES = (1e-1, 1e-2, 1e-3, 1e-4)  # of a cell's width, between the line and a node


def method_label(stabilisation: str, penalty: float) -> str:
    return f"nitsche {penalty:g}" if stabilisation == "nitsche" else stabilisation


def run_interface_study(out: Path, cells=DEFAULT_CELLS, echo=print) -> dict:
    """Every method on both cell types at every resolution, then the sliver sweep (on the
    coarsest resolution); writes interface.csv, slivers.csv, interface.md, interface.png.
    Returns {"rows": ..., "slivers": ..., "conclusions": [...]}."""
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for cell in CELL_TYPES:
        for n in cells:
            case = InterfaceCase(n, "line", cell=cell)
            for stabilisation, penalty in METHODS:
                case.impact(stabilisation, penalty)  # the first solve of a binding: warm-up
                spread, mean = case.impact(stabilisation, penalty)
                row = dict(cell=cell, cells=n, method=method_label(stabilisation, penalty),
                           mixed_cells=int(case.mixed.size), unknowns=int(case.unknowns),
                           spread=spread, mean_rise=mean, solve_ms=1e3 * case.solve_seconds,
                           bind_ms=1e3 * case.bind_seconds)
                rows.append(row)
                echo(f"{cell:13s} {n:4d}²  {row['method']:12s} spread {spread:8.3g}  mean rise {mean:9.3g}  "
                     f"{row['unknowns']:6d} unknowns  solve {row['solve_ms']:6.1f} ms  bind {row['bind_ms']:6.1f} ms")
    slivers = []
    n, angle = cells[0], 0.3
    normal = np.array([np.cos(angle), np.sin(angle)])
    node = np.array([n // 2, n // 2]) / n
    for cell in CELL_TYPES:
        for distance in SLIVER_DISTANCES:
            case = InterfaceCase(n, "line", offset=float(normal @ node) + distance / n, angle=angle, cell=cell)
            fraction = case.fraction[case.mixed]
            smallest = float(np.minimum(fraction, 1.0 - fraction).min())
            for stabilisation, penalty in (("bubble", 1.0), ("nitsche", 1.0)):
                velocity, pressure = case.rest(stabilisation)
                spread, _ = case.impact(stabilisation, penalty)
                slivers.append(dict(cell=cell, cells=n, distance=distance, smallest_fraction=smallest,
                                    method=method_label(stabilisation, penalty), rest_velocity=velocity,
                                    rest_pressure_error=pressure, spread=spread))
                echo(f"{cell:13s} sliver {smallest:8.2g}  {method_label(stabilisation, penalty):12s} "
                     f"rest |u| {velocity:8.2g}  |p_Γ − p|/p {pressure:8.2g}  spread {spread:6.3g}")
    conclusions = _conclusions(rows, slivers)
    _write_csv(rows, out / "interface.csv")
    _write_csv(slivers, out / "slivers.csv")
    _write_markdown(rows, slivers, conclusions, out / "interface.md")
    _chart(rows, out / "interface.png")
    for line in conclusions:
        echo(line)
    return {"rows": rows, "slivers": slivers, "conclusions": conclusions}


def _conclusions(rows, slivers) -> list[str]:
    """Plain statements read off the figures (nothing assumed)."""
    lines = []
    for cell in CELL_TYPES:
        mine = [r for r in rows if r["cell"] == cell]
        finest = max(r["cells"] for r in mine)
        at = {r["method"]: r for r in mine if r["cells"] == finest}
        best = min(at, key=lambda m: at[m]["spread"])
        worst = max(at, key=lambda m: at[m]["spread"])
        lines.append(f"{cell}s, {finest}²: the smoothest interface pressure is {best}'s (spread "
                     f"{at[best]['spread']:.2g}), the roughest {worst}'s ({at[worst]['spread']:.2g}); "
                     f"solve times {min(r['solve_ms'] for r in at.values()):.0f}–"
                     f"{max(r['solve_ms'] for r in at.values()):.0f} ms.")
        penalties = [at[f"nitsche {p:g}"]["spread"] for _, p in METHODS[2:]]
        trend = "grows" if all(a < b for a, b in zip(penalties, penalties[1:])) else "does not grow monotonically"
        lines.append(f"{cell}s: Nitsche's spread {trend} with its penalty factor "
                     f"({', '.join(f'{s:.2g}' for s in penalties)} for {', '.join(f'{p:g}' for _, p in METHODS[2:])}).")
    smallest = min(s["smallest_fraction"] for s in slivers)
    moved = max(s["rest_velocity"] for s in slivers)
    lines.append(f"Slivers down to a cut fraction of {smallest:.1g}: the nodes carrying mass rest to {moved:.1g}; "
                 f"the largest impact spread is {max(s['spread'] for s in slivers):.2g}.")
    return lines


def _write_csv(rows, path: Path) -> None:
    keys = list(rows[0])
    with path.open("w") as handle:
        handle.write(",".join(keys) + "\n")
        for row in rows:
            handle.write(",".join(f"{row[k]:.6g}" if isinstance(row[k], float) else str(row[k]) for k in keys) + "\n")


def _write_markdown(rows, slivers, conclusions, path: Path) -> None:
    methods = [method_label(s, p) for s, p in METHODS]
    lines = ["# Interface system: spread of the interface pressure under a uniform impact", "",
             "Spread = standard deviation over |mean| of the rise of p_Γ along a straight interface at 17°; "
             "0 is exact.", "",
             "| cells | mixed cells | " + " | ".join(methods) + " | solve (ms) |",
             "|---|---|" + "---|" * len(methods) + "---|"]
    for cell in CELL_TYPES:
        for n in sorted({r["cells"] for r in rows}):
            mine = {r["method"]: r for r in rows if r["cell"] == cell and r["cells"] == n}
            times = [r["solve_ms"] for r in mine.values()]
            lines.append(f"| {cell} {n}² | {next(iter(mine.values()))['mixed_cells']} | "
                         + " | ".join(f"{mine[m]['spread']:.3g}" for m in methods)
                         + f" | {min(times):.0f}–{max(times):.0f} |")
    lines += ["", "Slivers (the line moved towards a node):", "",
              "| cell | smallest fraction | method | rest: largest velocity | rest: \\|p_Γ − p\\|/p | impact spread |",
              "|---|---|---|---|---|---|"]
    for s in slivers:
        lines.append(f"| {s['cell']} | {s['smallest_fraction']:.2g} | {s['method']} | {s['rest_velocity']:.2g} | "
                     f"{s['rest_pressure_error']:.2g} | {s['spread']:.3g} |")
    lines += [""] + [f"- {line}" for line in conclusions] + [""]
    path.write_text("\n".join(lines))


def _chart(rows, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    for axis, cell in zip(axes, CELL_TYPES):
        for stabilisation, penalty in METHODS:
            label = method_label(stabilisation, penalty)
            mine = sorted((r for r in rows if r["cell"] == cell and r["method"] == label), key=lambda r: r["cells"])
            axis.loglog([r["cells"] for r in mine], [r["spread"] for r in mine], "o-", label=label)
        axis.set_title(f"{cell}s")
        axis.set_xlabel("cells per side")
        axis.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("spread of p_Γ's rise (std / |mean|)")
    axes[1].legend(fontsize=8)
    figure.suptitle("Interface pressure under a uniform impact: bubble, Nitsche, unstabilised")
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    plt.close(figure)
