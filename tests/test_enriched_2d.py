"""The implicit system of 2D enriched mixed cells (forms/enriched_interface.py with the cut
geometry of ale_xfem/mixed/cut_cells_2d.py), one step at a time on triangles and
quadrilaterals: a uniform
pressure at rest stays at rest whatever the reconstruction, free slip leaves each
material's tangential velocity alone, stick couples it, and the unstabilised P1–P0 pair
checkerboards its interface pressure where bubbles and Nitsche do not."""

import numpy as np
import pytest

import dolfinx_solver  # noqa: F401
import dolfinx
from mpi4py import MPI

from ale_xfem.geometry.shapes import clip_half_plane, disk_polygon_area, polygon_area
from ale_xfem.mixed.cut_cells_2d import condensed_masses, cut_cells, node_materials
from ale_xfem.model.mesh import from_dolfinx
from ale_xfem.model.plic import reconstruct, youngs_normals
from forms.enriched_interface import InterfaceForms, InterfaceSystem

PRESSURE, DT = 1.0, 0.01
DENSITY, BULK = (1.0, 10.0), (1.0, 10.0)  # ρ_m and κ_m = ρ_m c_m² of α (inside) and β
_FORMS = {}


def _forms(stabilisation, slip, cell):
    key = (stabilisation, slip, cell)
    if key not in _FORMS:
        _FORMS[key] = InterfaceForms(MPI.COMM_WORLD, stabilisation, slip, cell)
    return _FORMS[key]


class Cut:
    """A unit square of n × n triangles or quadrilaterals, walls on all sides, α inside a disk or below a
    straight line, exact volume fractions, PLIC (the disk with Youngs' normals, the line
    with its own)."""

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
        self.owner, self.tied = node_materials(mesh.cell_nodes, mesh.n_nodes, material, area, volume, slots)
        masses = condensed_masses(self.cut, mesh.cell_nodes, self.owner,
                                  np.stack([DENSITY[m] * self.cut.volume[m] for m in range(2)]),
                                  np.stack([alpha, 1 - alpha]))
        self.condensed = masses
        self.node_mass = np.zeros((2, mesh.n_nodes))
        for m in range(2):
            pure = material == m
            k = mesh.cell_nodes.shape[1]
            np.add.at(self.node_mass[m], mesh.cell_nodes[pure].ravel(), np.repeat(DENSITY[m] * area[pure] / k, k))
            np.add.at(self.node_mass[m], mesh.cell_nodes[mixed].ravel(), masses[m].ravel())
        self.held = np.stack([(np.abs(x[0]) < 1e-12) | (np.abs(x[0] - 1) < 1e-12),
                              (np.abs(x[1]) < 1e-12) | (np.abs(x[1] - 1) < 1e-12)])

    def explicit_forces(self, m):
        """(F̄, f^n) of material m under the uniform pressure (pure cells: P ∂|K|/∂x_i;
        mixed cells at n, P_m = p_Γ: P G_mi)."""
        mesh = self.mesh
        x = np.moveaxis(mesh.node_position[:, mesh.cell_nodes], 0, -1)  # (cells, k, 2) going round
        after, before = np.roll(x, -1, axis=1), np.roll(x, 1, axis=1)
        gradient = 0.5 * np.stack([after[..., 1] - before[..., 1], before[..., 0] - after[..., 0]], axis=-1)
        pure = np.zeros((2, mesh.n_nodes))
        cells = self.cell_material == m
        for d in range(2):
            np.add.at(pure[d], mesh.cell_nodes[cells].ravel(), PRESSURE * gradient[cells][..., d].ravel())
        mixed = np.zeros((2, mesh.n_nodes))
        for d in range(2):
            np.add.at(mixed[d], mesh.cell_nodes[self.mixed].ravel(), PRESSURE * self.cut.edge_flux[m][..., d].ravel())
        return pure, mixed

    def solve(self, stabilisation, slip="free", velocity=None, penalty=1.0, walls=True):
        """One implicit solve from a uniform pressure; ``velocity`` [m] (2, n_nodes) each
        material's u^n (default rest); ``walls``: the sides hold the normal velocity
        (otherwise a pressure p acts on them from outside).  Returns (the solution, the
        interface pressure)."""
        mesh, cut = self.mesh, self.cut
        system = InterfaceSystem(self.dolfinx_mesh, self.mixed, _forms(stabilisation, slip, self.cell))
        system.vertex_order(mesh.cell_nodes[self.mixed])
        reconstruction = cut.reconstruction
        system.set_geometry((reconstruction.alpha, reconstruction.beta), reconstruction.start, reconstruction.end,
                            cut.edge_flux, cut.normal)
        n = self.mixed.size
        bulk = np.array(BULK)[:, None] * np.ones((2, n))
        compliance = cut.volume / (bulk * DT)  # V_m / κ_m dt
        weight = compliance[0] / compliance.sum(axis=0)
        gamma = 2.0 * penalty * cut.reconstruction.length / compliance.sum(axis=0)
        system.set_materials(1.0 / (bulk * DT), np.full((2, n), PRESSURE), weight, gamma)
        mass, rhs = [], []
        for m in range(2):
            u0 = np.zeros((2, mesh.n_nodes)) if velocity is None else velocity[m]
            inertia = np.repeat(4.0 * self.node_mass[m][None] / DT, 2, axis=0)
            pure, mixed = self.explicit_forces(m)
            right = inertia * u0 + 2.0 * pure + mixed
            if walls:
                inertia[self.held], right[self.held] = 1e20, 0.0
            else:  # the outside pressure balances the state at rest on the sides
                right -= 2.0 * (pure + mixed)
            mass.append(inertia)
            rhs.append(right)
        out = system.solve(mass, rhs, self.tied)
        if "interface_pressure" in out:
            interface = out["interface_pressure"]
        else:  # Nitsche: p̂ = w_α P_α + w_β P_β + γ [ū·n], averaged over Γ_K
            nodes = mesh.cell_nodes[self.mixed]
            jump = sum(cut.normal_flux(m, out["velocity"][m], nodes) for m in range(2))
            interface = weight * out["pressure"][0] + (1 - weight) * out["pressure"][1] \
                + gamma * jump / cut.reconstruction.length
        return out, interface


@pytest.mark.parametrize("stabilisation", ["bubble", "nitsche"])
@pytest.mark.parametrize("slip", ["free", "stick"])
@pytest.mark.parametrize("shape", ["disk", "line"])
@pytest.mark.parametrize("cell", ["triangle", "quadrilateral"])
def test_a_uniform_pressure_at_rest_stays_at_rest(stabilisation, slip, shape, cell):
    """The PLIC lines of neighbouring cells do not meet on their shared edges (the disk);
    the edge parts shared by both cells make the forces of a uniform pressure cancel at
    every node anyway.  Velocities stay 0 and pressures p to round-off."""
    case = Cut(12, shape, cell=cell)
    out, interface = case.solve(stabilisation, slip)
    scale = PRESSURE * DT / (DENSITY[0] * 1.0 / 12)  # the velocity a p-sized force imparts in a step
    assert max(np.abs(u).max() for u in out["velocity"]) < 1e-9 * scale
    assert np.abs(out["pressure"] - PRESSURE).max() < 1e-10 * PRESSURE
    assert np.abs(interface - PRESSURE).max() < 1e-10 * PRESSURE


@pytest.mark.parametrize("stabilisation", ["bubble", "nitsche"])
@pytest.mark.parametrize("cell", ["triangle", "quadrilateral"])
def test_slivers_rest_and_give_their_mass_to_the_nearest_node(stabilisation, cell):
    """A line through the mesh 3e-4 of a cell's width from a node: cut fractions below
    1e-6.  A sliver holding none of its cell's nodes gives its mass to the node
    nearest it (the other nodes keep a share EXTERNAL_SHARE of their consistent one).  The
    state at rest is the system's exact solution (its residual is round-off); every node
    that carries mass stays at rest to round-off.  The external node of a 1e-7 sliver
    carries 1e-16 of a node's mass: its velocity, an extension nothing physical
    determines, comes out of the nearly singular solve as it may (8e-5 with bubbles),
    bounded, with no kinetic energy."""
    n = 12
    angle = 0.3
    normal = np.array([np.cos(angle), np.sin(angle)])
    node = np.array([6, 6]) / n
    case = Cut(n, "line", offset=float(normal @ node) + 3e-4 / n, angle=angle, cell=cell)
    smallest = np.minimum(case.fraction[case.mixed], 1 - case.fraction[case.mixed]).min()
    assert smallest < 1e-6
    # every material's mass in every mixed cell is on the cell's nodes, each positive
    for m in range(2):
        assert np.allclose(case.condensed[m].sum(axis=1), DENSITY[m] * case.cut.volume[m], rtol=1e-12)
        assert case.condensed[m].min() >= 0.0
    sliver = np.argmin(case.cut.volume[1] / case.cut.volume.sum(axis=0))
    shares = case.cut.vertex_integrals()[1, sliver]
    nodes = case.mesh.cell_nodes[case.mixed[sliver]]
    if not np.any(case.owner[nodes] == 1):  # β's part holds none of the cell's nodes
        assert np.argmax(case.condensed[1, sliver]) == np.argmax(shares)
    out, interface = case.solve(stabilisation)
    carrying = [case.node_mass[m] > 1e-9 * case.node_mass.max() for m in range(2)]
    assert max(np.abs(out["velocity"][m][:, carrying[m]]).max() for m in range(2)) < 1e-10
    assert max(np.abs(u).max() for u in out["velocity"]) < 1e-3
    kinetic = sum(np.sum(case.node_mass[m] * out["velocity"][m] ** 2) for m in range(2))
    assert kinetic < 1e-20
    assert np.abs(out["pressure"] - PRESSURE).max() < 1e-8  # (a 1e-7 part's pressure: 1e-9 measured)
    assert np.abs(interface - PRESSURE).max() < 1e-8


def _sliding(case, speed):
    """α moving along the line at +speed, β at −speed (each material's field everywhere)."""
    tangent = np.array([-case.normal_line[1], case.normal_line[0]])
    shape = (2, case.mesh.n_nodes)
    return [np.broadcast_to(speed * tangent[:, None], shape).copy(),
            np.broadcast_to(-speed * tangent[:, None], shape).copy()], tangent


@pytest.mark.parametrize("stabilisation", ["none", "bubble", "nitsche"])
@pytest.mark.parametrize("cell", ["triangle", "quadrilateral"])
def test_free_slip_keeps_each_materials_tangential_velocity_and_stick_couples_them(stabilisation, cell):
    """Two materials sliding past each other along a straight interface (no walls: the
    outside pressure holds the box).  Free slip: a steady state — each
    material keeps its velocity, pressures stay.  Stick: the tangential jump averaged on
    each Γ_K vanishes (multipliers) or falls (Nitsche's penalty)."""
    case = Cut(12, "line", cell=cell)
    velocity, tangent = _sliding(case, 0.1)
    nodes = np.unique(case.mesh.cell_nodes[case.mixed])
    x = case.mesh.node_position[:, nodes]
    inner = nodes[np.all((x > 0.2) & (x < 0.8), axis=0)]
    out, interface = case.solve(stabilisation, "free", velocity, walls=False)
    for m in range(2):
        assert np.abs(out["velocity"][m][:, inner] - velocity[m][:, inner]).max() < 1e-10
    assert np.abs(out["pressure"] - PRESSURE).max() < 1e-9
    out, _ = case.solve(stabilisation, "stick", velocity, walls=False)
    # the tangential jump on Γ_K, averaged: ∫_Γ u·t_m = I_m(J u) (the nodes of a cell's
    # other material are an extension: their jump is not the interface's)
    nodes = case.mesh.cell_nodes[case.mixed]
    turned = [np.stack([u[1], -u[0]]) for u in out["velocity"]]
    jump = sum(case.cut.normal_flux(m, turned[m], nodes) for m in range(2)) / case.cut.reconstruction.length
    centroid = case.cut.reconstruction.centroid
    interior = np.all((centroid > 0.2) & (centroid < 0.8), axis=1)
    if stabilisation == "nitsche":  # a penalty: the jump falls
        assert np.abs(jump[interior]).max() < 0.5 * 0.2
    else:  # a multiplier: the jump's mean on Γ_K vanishes
        assert np.abs(jump[interior]).max() < 1e-9


@pytest.mark.parametrize("cell", ["triangle", "quadrilateral"])
def test_the_unstabilised_pair_checkerboards_its_interface_pressure_and_both_cures_fix_it(cell):
    """α striking β across a straight line at 17° to the mesh, one implicit step: the rise
    of p_Γ should be the same all along Γ (interior cells).  Its spread (standard deviation
    over |mean|) on 24², triangles: the P1–P0 pair 5.3 (its mean even negative), bubbles
    0.21, Nitsche 0.37 / 0.60 / 0.83 / 1.06 with penalty factors 0.1 / 1 / 10 / 100;
    quadrilaterals: 1.5, 0.16, 0.24 / 0.43 / 0.67 / 0.94.  A larger penalty tends to the
    unstabilised constraint."""
    case = Cut(24, "line", cell=cell)
    velocity = [0.1 * case.normal_line[:, None] * np.ones((2, case.mesh.n_nodes)),
                np.zeros((2, case.mesh.n_nodes))]
    centroid = case.cut.reconstruction.centroid
    interior = np.all((centroid > 0.15) & (centroid < 0.85), axis=1)
    spread = {}
    for stabilisation, penalty in (("none", 1.0), ("bubble", 1.0), ("nitsche", 0.1), ("nitsche", 1.0),
                                   ("nitsche", 100.0)):
        _, interface = case.solve(stabilisation, velocity=velocity, penalty=penalty)
        rise = interface[interior] - PRESSURE
        if stabilisation != "none":
            assert rise.mean() > 0.0  # the interface is compressed
        spread[stabilisation, penalty] = rise.std() / abs(rise.mean())
    assert spread["none", 1.0] > 1.0
    assert spread["bubble", 1.0] < 0.3
    assert spread["nitsche", 1.0] < 0.7
    assert spread["nitsche", 0.1] < spread["nitsche", 1.0] < spread["nitsche", 100.0]


def test_binding_to_other_cells_compiles_nothing(monkeypatch):
    """The forms compile once (InterfaceForms); binding them to another set of mixed cells
    creates spaces and functions only."""
    case = Cut(8, "disk")
    forms = _forms("bubble", "free", "triangle")

    def refuse(*args, **kwargs):
        raise AssertionError("compiled while binding")

    monkeypatch.setattr(dolfinx.fem, "compile_form", refuse)
    for cells in (case.mixed, case.mixed[: case.mixed.size // 2]):
        InterfaceSystem(case.dolfinx_mesh, cells, forms)


@pytest.mark.parametrize("stabilisation", ["bubble", "nitsche"])
@pytest.mark.parametrize("cell", ["triangle", "quadrilateral"])
def test_a_node_between_pure_cells_of_both_materials_is_tied(stabilisation, cell):
    """An interface along mesh edges that turns into cut cells: at the turn pure cells of
    both materials meet along an edge,
    where no mixed cell carries an interface; each material's share of a uniform pressure
    does not balance there, only their sum.  The node's two velocities are tied (a stiff
    spring, TIE_STIFFNESS): the state at rest stays at rest; untied, it would not."""
    case = Cut(12, "kink", cell=cell)  # along mesh edges left of (½, ½), through cells right of it
    assert case.tied.any()
    out, interface = case.solve(stabilisation)
    assert max(np.abs(u).max() for u in out["velocity"]) < 1e-9
    assert np.abs(interface - PRESSURE).max() < 1e-8
    case.tied[:] = False
    out, _ = case.solve(stabilisation)
    assert max(np.abs(u).max() for u in out["velocity"]) > 1e-4
