"""The implicit system of 2D enriched mixed cells (forms/enriched_interface.py with the cut
geometry of ale_xfem/mixed/cut_cells_2d.py), one step at a time on triangles and
quadrilaterals (the case: ale_xfem/studies/interface.InterfaceCase): a uniform
pressure at rest stays at rest whatever the reconstruction, free slip leaves each
material's tangential velocity alone, stick couples it, and the unstabilised P1–P0 pair
checkerboards its interface pressure where bubbles and Nitsche do not."""

import numpy as np
import pytest

import dolfinx_solver  # noqa: F401
import dolfinx

from ale_xfem.studies.interface import DENSITY, DT, PRESSURE, InterfaceCase, interface_forms
from forms.enriched_interface import InterfaceSystem

@pytest.mark.parametrize("stabilisation", ["bubble", "nitsche"])
@pytest.mark.parametrize("slip", ["free", "stick"])
@pytest.mark.parametrize("shape", ["disk", "line"])
@pytest.mark.parametrize("cell", ["triangle", "quadrilateral"])
def test_a_uniform_pressure_at_rest_stays_at_rest(stabilisation, slip, shape, cell):
    """The PLIC lines of neighbouring cells do not meet on their shared edges (the disk);
    the edge parts shared by both cells make the forces of a uniform pressure cancel at
    every node anyway.  Velocities stay 0 and pressures p to round-off."""
    case = InterfaceCase(12, shape, cell=cell)
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
    case = InterfaceCase(n, "line", offset=float(normal @ node) + 3e-4 / n, angle=angle, cell=cell)
    smallest = np.minimum(case.fraction[case.mixed], 1 - case.fraction[case.mixed]).min()
    assert smallest < 1e-6
    # every material's mass in every mixed cell is on the cell's nodes, each positive
    for m in range(2):
        assert np.allclose(case.condensed[m].sum(axis=1), DENSITY[m] * case.cut.volume[m], rtol=1e-12)
        assert case.condensed[m].min() >= 0.0
    out, interface = case.solve(stabilisation)
    carrying = [case.node_mass[m] > 1e-9 * case.node_mass.max() for m in range(2)]
    assert max(np.abs(out["velocity"][m][:, carrying[m]]).max() for m in range(2)) < 1e-10
    assert max(np.abs(u).max() for u in out["velocity"]) < 1e-3
    kinetic = sum(np.sum(case.node_mass[m] * out["velocity"][m] ** 2) for m in range(2))
    assert kinetic < 1e-20
    assert np.abs(out["pressure"] - PRESSURE).max() < 1e-8  # (a 1e-7 part's pressure: 1e-9 measured)
    assert np.abs(interface - PRESSURE).max() < 1e-8


def test_a_part_holding_none_of_its_cells_nodes_gives_its_mass_to_the_nearest():
    """The sliver rule: where a material's part holds none of its cell's nodes (around a
    disk some cells hold a trace of β in a corner whose node lies in α), the part's mass
    goes to the cell's node with the largest ∫_{K_m} ψ_i, which becomes internal to it;
    the other nodes keep EXTERNAL_SHARE of their consistent share.  (The rule is the same
    on quadrilaterals, where this disk on 12² happens to leave no such part.)"""
    from ale_xfem.mixed.cut_cells_2d import EXTERNAL_SHARE

    case = InterfaceCase(12, "disk")
    nodes = case.mesh.cell_nodes[case.mixed]
    shares = case.cut.vertex_integrals()
    fired = 0
    for m in range(2):
        holds_none = ~np.any(case.owner[nodes] == m, axis=1) & (case.cut.volume[m] > 0.0)
        for cell_index in np.flatnonzero(holds_none):
            fired += 1
            nearest = np.argmax(shares[m, cell_index])
            assert case.internal_in_cell[m, cell_index].tolist() == [j == nearest for j in range(nodes.shape[1])]
            others = np.arange(nodes.shape[1]) != nearest
            masses = case.condensed[m, cell_index]
            ratio = masses[others] / masses[nearest]
            assert np.allclose(ratio, EXTERNAL_SHARE * shares[m, cell_index, others] / shares[m, cell_index, nearest])
    assert fired > 0


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
    case = InterfaceCase(12, "line", cell=cell)
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
    case = InterfaceCase(24, "line", cell=cell)
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
    case = InterfaceCase(8, "disk")
    forms = interface_forms("bubble", "free", "triangle")

    import dolfinx.jit

    def refuse(*args, **kwargs):
        raise AssertionError("compiled while binding")

    # every DOLFINx compilation goes through its FFCx JIT (tests/test_effects.py counts it so)
    monkeypatch.setattr(dolfinx.jit, "ffcx_jit", refuse)
    for cells in (case.mixed, case.mixed[: case.mixed.size // 2]):
        InterfaceSystem(case.dolfinx_mesh, cells, forms)


@pytest.mark.parametrize("stabilisation", ["bubble", "nitsche"])
@pytest.mark.parametrize("cell", ["triangle", "quadrilateral"])
def test_a_node_between_pure_cells_of_both_materials_is_tied(stabilisation, cell):
    """An interface along mesh edges that turns into cut cells: at the turn pure cells of
    both materials meet along an edge,
    where no mixed cell carries an interface; each material's share of a uniform pressure
    does not balance there, only their sum.  The node's two velocities are one unknown
    (InterfaceSystem._constraint): the state at rest stays at rest to round-off; untied, it
    would not."""
    case = InterfaceCase(12, "kink", cell=cell)  # along mesh edges left of (½, ½), through cells right of it
    assert case.tied.any()
    out, interface = case.solve(stabilisation)
    assert max(np.abs(u).max() for u in out["velocity"]) < 1e-12
    assert np.abs(interface - PRESSURE).max() < 1e-12
    case.tied[:] = False
    out, _ = case.solve(stabilisation)
    assert max(np.abs(u).max() for u in out["velocity"]) > 1e-4


def test_the_interface_study_writes_its_tables_and_says_what_it_measured(tmp_path):
    """`ale-xfem study interface` at one small resolution: the CSVs, the Markdown table and
    the chart are written, and its conclusions name the smoothest method of each cell type
    from the figures (bubbles here, as in the checkerboard test)."""
    from ale_xfem.cli import main

    assert main(["study", "interface", "--cells", "12", "--out", str(tmp_path)]) == 0
    for name in ("interface.csv", "slivers.csv", "interface.md", "interface.png"):
        assert (tmp_path / name).stat().st_size > 0
    text = (tmp_path / "interface.md").read_text()
    assert "triangles, 12²: the smoothest interface pressure is bubble's" in text
    assert "quadrilaterals, 12²: the smoothest interface pressure is bubble's" in text
    rows = (tmp_path / "interface.csv").read_text().splitlines()
    assert len(rows) == 1 + 2 * 6  # two cell types × six methods
    assert main(["study", "interface", "--cells", "4", "--out", str(tmp_path)]) == 2


@pytest.mark.parametrize("nonlinear", [True, False], ids=["nonlinear", "linearised"])
@pytest.mark.parametrize("stabilisation", ["none", "bubble", "nitsche"])
@pytest.mark.parametrize("cell", ["triangle", "quadrilateral"])
def test_the_predictor_corrector_conserves_energy_with_the_full_equation_of_state(stabilisation, cell, nonlinear):
    """α (ideal gas, γ = 1.4) striking β (γ = 5/3) across the line, one step with the
    nonlinear corrector: the pressures it ends with are the equations of state's, and the
    kinetic energy the nodes gain less the pure cells' work is the internal energy the two
    materials lose, to round-off (the interface pressure does no work: the normal jump's
    mean vanishes on every Γ_K).  Nitsche's penalty dissipates: the balance is short, by
    2.1e-4 (triangles) and 1.3e-4 (quadrilaterals) of the internal energy change.
    With the linearised law alone (``interface.solver = "linearised"``): one solve, the
    same balance (each material's energy works against the system's pressure, as its
    nodes do), and the equations of state's pressures off the system's by what the
    corrector would have closed."""
    from ale_xfem.eos import IdealGas
    from ale_xfem.mixed.implicit_step import ImplicitStep, MaterialStart

    case = InterfaceCase(24, "line", cell=cell)
    gases = (IdealGas(1.4), IdealGas(5.0 / 3.0))
    volume = case.cut.volume
    energy = np.stack([np.full(volume.shape[1], PRESSURE / ((g.gamma - 1.0) * DENSITY[k]))
                       for k, g in enumerate(gases)])
    start = MaterialStart(mass=np.stack([DENSITY[k] * volume[k] for k in range(2)]), volume=volume,
                          energy=energy, pressure=np.full(volume.shape, PRESSURE))
    u0 = [0.1 * case.normal_line[:, None] * np.ones((2, case.mesh.n_nodes)), np.zeros((2, case.mesh.n_nodes))]
    mass, rhs = case.inertia_and_rhs(u0)
    step = ImplicitStep(case.bind(stabilisation), case.mixed, [g.state for g in gases],
                        case.cut.reconstruction.length, nonlinear=nonlinear)
    result = step.solve(DT, start, mass, rhs, case.tied)
    # the equations of state's pressures against the system's, on the smaller ρc² = γp
    gap = np.abs(result["pressure"] - result["linearised_pressure"]).max() / (min(g.gamma for g in gases) * PRESSURE)
    if nonlinear:
        assert 1 < result["iterations"] <= 10
        assert gap <= 1e-10
    else:
        assert result["iterations"] == 1
        assert gap > 1e-6
    rho = start.mass / result["volume"]
    for k, gas in enumerate(gases):
        assert np.allclose(result["pressure"][k], gas.pressure(rho[k], result["energy"][k]), rtol=1e-12)
    nodes = np.unique(case.mesh.cell_nodes[case.mixed])
    kinetic, pure_work = 0.0, 0.0
    for k in range(2):
        mean = result["velocity"][k][:, nodes]
        new = 2.0 * mean - u0[k][:, nodes]
        free = ~case.held[:, nodes]
        kinetic += 0.5 * np.sum((case.node_mass[k][nodes] * (new ** 2 - u0[k][:, nodes] ** 2))[free])
        pure_work += DT * np.sum((mean * case.explicit_forces(k)[0][:, nodes])[free])
    internal = np.sum(start.mass * (result["energy"] - energy))
    balance = (kinetic - pure_work + internal) / abs(internal)
    if stabilisation == "nitsche":  # energy lost to the penalty, and only a little
        assert -1e-3 < balance < -1e-5
    else:
        assert abs(balance) < 1e-10


def test_an_equation_of_state_that_softens_under_compression_stops_the_corrector_naming_the_cell():
    """Along an adiabat the pressure must rise as a material is compressed (D = dp/dV < 0);
    where it does not, the step stops before any solve, naming the mesh cell."""
    from ale_xfem.mixed.implicit_step import ImplicitStep, MaterialStart
    from ale_xfem.mixed.equilibrium import MixedCellFailure

    case = InterfaceCase(12, "line")
    n = case.mixed.size

    def softening(rho, e):  # p falls with density: ∂p/∂ρ < 0
        return 1.0 - rho, -np.ones_like(rho), np.zeros_like(rho), np.ones_like(rho)

    step = ImplicitStep(case.bind("bubble"), case.mixed, [softening, softening], case.cut.reconstruction.length)
    start = MaterialStart(mass=case.cut.volume.copy(), volume=case.cut.volume, energy=np.ones((2, n)),
                          pressure=np.zeros((2, n)))
    with pytest.raises(MixedCellFailure, match=rf"mixed cell {case.mixed[0]}: the pressure does not rise"):
        step.solve(DT, start, *case.inertia_and_rhs())


def test_a_corrector_state_outside_the_equation_of_states_domain_stops_the_step():
    """A root with c² ≤ 0 (an ideal gas at a negative energy, a stiffened gas below −p∞) is
    no state: the step stops naming the cell, and the run takes it again with a shorter dt
    (the sliver of air at a wall struck by water, ``ale-xfem study stability``)."""
    from ale_xfem.mixed.implicit_step import ImplicitStep, MaterialStart
    from ale_xfem.mixed.equilibrium import MixedCellFailure

    case = InterfaceCase(12, "line")
    n = case.mixed.size

    def gas(rho, e):  # an ideal gas (γ = 1.4) whose sound speed is reported imaginary
        return 0.4 * rho * e, 0.4 * e, 0.4 * rho, -np.ones_like(rho)

    def honest(rho, e):
        return 0.4 * rho * e, 0.4 * e, 0.4 * rho, 1.4 * 0.4 * e

    start = MaterialStart(mass=case.cut.volume.copy(), volume=case.cut.volume, energy=np.full((2, n), 2.5),
                          pressure=np.ones((2, n)))
    fine = ImplicitStep(case.bind("bubble"), case.mixed, [honest, honest], case.cut.reconstruction.length)
    assert fine.solve(DT, start, *case.inertia_and_rhs())["iterations"] >= 1
    step = ImplicitStep(case.bind("bubble"), case.mixed, [honest, gas], case.cut.reconstruction.length)
    with pytest.raises(MixedCellFailure, match=rf"mixed cell {case.mixed[0]}: the corrector's state leaves"):
        step.solve(DT, start, *case.inertia_and_rhs())


def test_nitsches_stiffness_keeps_a_floor_where_the_sound_speed_vanishes():
    """κ_m = ρ_m c_m² dt, at least a hundredth of the inertia's scale ρ_m |K| / dt: a cold gas
    (Noh's) or a state with c² ≤ 0 at an iterate keeps a penalty and finite weights (without
    the floor: 0/0 weights, a NaN matrix, the factorisation failed); at the time step the
    sound speed allows the floor does not act."""
    from ale_xfem.mixed.implicit_step import NITSCHE_STIFFNESS_FLOOR, nitsche_stiffness
    from forms.enriched_interface import nitsche_weights

    rho, area, dt = np.array([[1.0, 1.0], [2.0, 2.0]]), np.array([1e-2, 1e-2]), 1e-3
    c2 = np.array([[0.0, -1.0], [1e-12, 1e-12]])
    kappa = nitsche_stiffness(rho, c2, area, dt)
    assert np.allclose(kappa, NITSCHE_STIFFNESS_FLOOR * rho * area / dt)
    weight, penalty = nitsche_weights(np.full((2, 2), 5e-3), kappa, np.array([0.1, 0.1]), 1.0)
    assert np.all(np.isfinite(weight)) and np.all(penalty > 0)
    assert np.allclose(weight, 2.0 / 3.0)  # V/κ: the lighter material is the softer
    sound = np.sqrt(area) / (2.0 * dt)  # c dt = h / 2
    loud = nitsche_stiffness(rho, np.full((2, 2), sound**2), area, dt)
    assert np.array_equal(loud, rho * sound**2 * dt)


def _kink_system(petsc_options=None):
    """The kink case (tied nodes) bound with ``petsc_options``, its geometry and materials set
    as InterfaceCase.solve sets them; returns (case, system, mass, rhs)."""
    from ale_xfem.studies.interface import BULK

    case = InterfaceCase(12, "kink")
    system = InterfaceSystem(case.dolfinx_mesh, case.mixed, interface_forms("bubble", "free", case.cell),
                             petsc_options)
    system.vertex_order(case.mesh.cell_nodes[case.mixed])
    reconstruction = case.cut.reconstruction
    system.set_geometry((reconstruction.alpha, reconstruction.beta), reconstruction.start, reconstruction.end,
                        case.cut.edge_flux, case.cut.normal)
    bulk = np.array(BULK)[:, None] * np.ones((2, case.mixed.size))
    system.set_materials(1.0 / (bulk * DT), np.full((2, case.mixed.size), PRESSURE))
    return case, system, *case.inertia_and_rhs()


def test_the_scenes_petsc_options_reach_every_factorisation():
    """A new constraint matrix C every step (set_geometry) makes a new reduced operator: its
    factorisation must still read the scene's options (MUMPS's ICNTL(14) here), though they
    left PETSc's database after the first solve (a review found them dropped after step 1
    when C kept its size)."""
    case, system, mass, rhs = _kink_system({"mat_mumps_icntl_14": 77})
    assert case.tied.any()
    for _ in range(3):
        system.solve(mass, rhs, case.tied)
        factor = system.system.solver.getPC().getFactorMatrix()
        assert factor.getMumpsIcntl(14) == 77
        reconstruction = case.cut.reconstruction
        system.set_geometry((reconstruction.alpha, reconstruction.beta), reconstruction.start, reconstruction.end,
                            case.cut.edge_flux, case.cut.normal)


def test_a_sliding_tie_without_a_direction_leaves_the_node_untied():
    """A sliding tied node whose cells' normals cancel (a filament one cell thick) has no
    normal to tie along: it stays untied instead of giving C empty columns (a singular
    reduced system, the KSP failing)."""
    case, system, mass, rhs = _kink_system()
    out = system.solve(mass, rhs, case.tied, sliding=case.tied, tie_normal=np.zeros((2, case.mesh.n_nodes)))
    assert all(np.all(np.isfinite(u)) for u in out["velocity"])


@pytest.mark.parametrize("cell", ["triangle", "quadrilateral"])
def test_the_compiled_node_materials_give_the_numpy_bits(cell):
    """The material each node lies in (ale_xfem.mixed.cut_cells_2d.node_materials, compiled)
    against the numpy code it replaced (tests/oracles.py): the same owners and two-material
    flags with pure cells of two and three materials, mixed cells in one slot or two, and
    ties of pure cells decided by the areas."""
    from oracles import node_materials as numpy_node_materials

    from ale_xfem.mixed.cut_cells_2d import node_materials
    from ale_xfem.model.mesh import rectangle_mesh

    mesh = rectangle_mesh([[0.0, 1.0], [0.0, 1.0]], [9, 7], cell)
    rng = np.random.default_rng(29)
    for n_materials in (2, 3):
        cell_material = rng.integers(0, n_materials, mesh.n_cells)
        mixed = rng.random(mesh.n_cells) < 0.3
        cell_material[mixed] = -1
        slots = np.stack([np.where(mixed, rng.integers(0, n_materials, mesh.n_cells), cell_material),
                          np.where(mixed, -1, -1)])
        slots[1, mixed] = (slots[0, mixed] + 1) % n_materials
        for volume in (rng.uniform(0.0, 1.0, (2, mesh.n_cells)) * (slots >= 0), 1.0 * (slots >= 0)):  # and ties
            args = (mesh.cell_nodes, mesh.n_nodes, cell_material, volume, slots)
            owner, two = node_materials(*args)
            expected_owner, expected_two = numpy_node_materials(*args)
            np.testing.assert_array_equal(owner, expected_owner)
            np.testing.assert_array_equal(two, expected_two)
        assert np.any(two) and np.any(~two) and len(np.unique(owner)) == n_materials


@pytest.mark.parametrize("cell", ["triangle", "quadrilateral"])
def test_the_enriched_cells_node_materials_are_node_materials_of_their_slots(cell):
    """enriched_node_materials (two materials, enriched mixed cells: what the cut geometry
    reads) gives node_materials' owners and flags on the slots it stands for — a pure cell's
    material with its whole area, a mixed cell's material 0 then material 1 with their
    areas — with traces (zero areas), ties of pure cells, and nodes among mixed cells only."""
    from ale_xfem.mixed.cut_cells_2d import enriched_node_materials, node_materials
    from ale_xfem.model.mesh import rectangle_mesh

    mesh = rectangle_mesh([[0.0, 1.0], [0.0, 1.0]], [9, 7], cell)
    rng = np.random.default_rng(31)
    n, flagged = mesh.n_cells, []
    for trial, mixed_share in enumerate((0.3, 0.9)):
        cell_material = rng.integers(0, 2, n)
        mixed = rng.random(n) < mixed_share
        cell_material[mixed] = -1
        volume = rng.uniform(0.0, 1.0, (2, n)) * (rng.random((2, n)) < 0.9)
        if trial == 1:
            volume = np.round(volume, 1)  # (equal areas: ties)
        pure = np.flatnonzero(~mixed)
        volume[1 - cell_material[pure], pure] = 0.0  # a pure cell holds its own material
        slots = np.stack([np.where(mixed, 0, cell_material), np.where(mixed, 1, -1)])
        slot_volume = np.stack([np.where(mixed, volume[0], volume.sum(axis=0)), np.where(mixed, volume[1], 0.0)])
        owner, two = enriched_node_materials(mesh.cell_nodes.astype(np.int64), mesh.n_nodes, cell_material, volume)
        expected_owner, expected_two = node_materials(mesh.cell_nodes, mesh.n_nodes, cell_material, slot_volume, slots)
        np.testing.assert_array_equal(owner, expected_owner)
        np.testing.assert_array_equal(two, expected_two)
        assert np.any(~two) and set(np.unique(owner)) == {0, 1}
        flagged.append(bool(np.any(two)))
    assert flagged[0]  # (nodes with pure cells of both materials around them)


def test_a_form_binder_makes_create_forms_forms_and_names_a_missing_coefficient():
    """forms.bound_system.FormBinder: the compiled form over chosen cells assembles to what
    dolfinx.fem.create_form's does (the same C++ form, the coefficients and constants looked
    up once), for one set of cells after another, two subdomains given out of order; a
    coefficient or constant the maps lack is named."""
    import dolfinx.fem.petsc
    import ufl
    from mpi4py import MPI

    from forms.bound_system import FormBinder

    mesh = dolfinx.mesh.create_unit_square(MPI.COMM_WORLD, 6, 6)
    space = dolfinx.fem.functionspace(mesh, ("Lagrange", 1))
    weight = dolfinx.fem.Function(space)
    weight.interpolate(lambda x: 1.0 + x[0] * x[1])
    u, v = ufl.TrialFunction(space), ufl.TestFunction(space)
    scale = dolfinx.fem.Constant(mesh, 2.5)
    dx = ufl.dx(domain=mesh)
    compiled = dolfinx.fem.compile_form(MPI.COMM_WORLD, weight * u * v * dx(3) + scale * u.dx(0) * v.dx(0) * dx(5))
    binder = FormBinder(compiled, [space, space], mesh, {weight: weight}, {scale: scale})
    rng = np.random.default_rng(3)
    for count in (5, 40):
        cells = np.sort(rng.choice(mesh.topology.index_map(2).size_local, count, replace=False)).astype(np.int32)
        subdomains = {dolfinx.fem.IntegralType.cell: [(5, cells[::2].copy()), (3, cells)]}  # ids out of order
        want = dolfinx.fem.assemble_matrix(dolfinx.fem.create_form(compiled, [space, space], mesh, subdomains,
                                                                   {weight: weight}, {scale: scale})).to_dense()
        have = dolfinx.fem.assemble_matrix(binder.over(subdomains)).to_dense()
        assert np.abs(want).max() > 0.0
        np.testing.assert_array_equal(have, want)
    with pytest.raises(RuntimeError, match="missing coefficient"):
        FormBinder(compiled, [space, space], mesh, {}, {scale: scale})
    with pytest.raises(RuntimeError, match="missing constants"):
        FormBinder(compiled, [space, space], mesh, {weight: weight})


def _enriched_geometry_of(case):
    """enriched_geometry of an InterfaceCase's state: each material's areas and masses."""
    from ale_xfem.mixed.cut_cells_2d import enriched_geometry
    from ale_xfem.studies.interface import DENSITY

    mesh, mixed = case.mesh, case.mixed
    area = mesh.cell_volumes(mesh.node_position)
    volume = np.zeros((2, mesh.n_cells))
    for m in range(2):
        volume[m, case.cell_material == m] = area[case.cell_material == m]
        volume[m, mixed] = case.cut.volume[m]
    mass = np.stack([DENSITY[m] * volume[m] for m in range(2)])
    return enriched_geometry(mesh, mesh.node_position, volume, mass, mixed), mass


@pytest.mark.parametrize("cell", ["triangle", "quadrilateral"])
def test_the_enriched_geometry_of_a_kinked_and_a_diagonal_interface(cell):
    """enriched_geometry (what the step and the remap hand each material's momentum to the
    nodes with) on an interface along mesh edges left of (½, ½) and through cells right of
    it: each material's nodal masses and the nodes carrying them as the study's case builds
    them apart from it (ale_xfem.studies.interface), the pure cells' corner masses m_K/k and
    the mixed cells' condensed ones; the nodes with pure cells of both materials are tied,
    and where Γ runs along mesh edges into them they do not slide (their two velocities are
    one).  On a line through mesh nodes across the cells' diagonals, Γ reaches its tied
    nodes through cut cells only: they slide (only their normal velocities are tied)."""
    case = InterfaceCase(12, "kink", cell=cell)
    geometry, mass = _enriched_geometry_of(case)
    mesh, x, mixed = case.mesh, case.mesh.node_position, case.mixed
    np.testing.assert_allclose(geometry.node_mass, case.node_mass, rtol=1e-13, atol=1e-16)
    np.testing.assert_array_equal(geometry.internal, case.internal)
    np.testing.assert_array_equal(geometry.tied, case.tied)
    k = mesh.cell_nodes.shape[1]
    for m in range(2):
        pure = case.cell_material == m
        np.testing.assert_array_equal(geometry.corner_mass[m][:, pure],
                                      np.broadcast_to(mass[m, pure] / k, (k, np.count_nonzero(pure))))
        np.testing.assert_allclose(geometry.corner_mass[m][:, mixed], case.condensed[m].T, rtol=1e-13, atol=1e-16)
    along = (np.abs(x[1] - 0.5) < 1e-12) & (x[0] < 0.5 + 1e-12)  # Γ on mesh edges
    assert np.count_nonzero(along) == 7 and np.array_equal(geometry.tied, along)
    assert not geometry.sliding.any()

    diagonal = InterfaceCase(12, "line", offset=np.sqrt(0.5), angle=np.pi / 4, cell=cell)  # x + y = 1
    geometry, _ = _enriched_geometry_of(diagonal)
    x = diagonal.mesh.node_position
    on_line = (np.abs(x[0] + x[1] - 1.0) < 1e-12) & (np.minimum(x[0], x[1]) > 1e-12)
    assert np.count_nonzero(on_line) == 11
    np.testing.assert_array_equal(geometry.tied, on_line)
    np.testing.assert_array_equal(geometry.sliding, on_line)


@pytest.mark.parametrize("stabilisation", ["none", "bubble", "nitsche"])
def test_resolving_with_new_compliances_equals_assembling_them(stabilisation):
    """InterfaceSystem.resolve (the corrector's later iterations) changes only the pressure
    rows' diagonal and right side, without assembling: on the kink (tied nodes, a reduced
    system) it gives what set_materials + solve give, to 10⁻¹² of each field's scale —
    after a change of 30 % (factorised again) and one of 0.1 % (refined on the last
    factors, which happens: the factorisation is not redone).  Nitsche's weight and penalty
    are kept as set_materials set them (the step's start's: ale_xfem/mixed/implicit_step.py),
    and the system assembled with them is the one resolved."""
    from ale_xfem.studies.interface import BULK
    from forms.enriched_interface import nitsche_weights

    case = InterfaceCase(12, "kink")
    system = InterfaceSystem(case.dolfinx_mesh, case.mixed, interface_forms(stabilisation, "free", case.cell))
    system.vertex_order(case.mesh.cell_nodes[case.mixed])
    reconstruction = case.cut.reconstruction
    system.set_geometry((reconstruction.alpha, reconstruction.beta), reconstruction.start, reconstruction.end,
                        case.cut.edge_flux, case.cut.normal)
    mass, rhs = case.inertia_and_rhs(velocity=[0.1 * case.normal_line[:, None] * np.ones((2, case.mesh.n_nodes)),
                                               np.zeros((2, case.mesh.n_nodes))])
    compliance = 1.0 / (np.array(BULK)[:, None] * np.ones((2, case.mixed.size)) * DT)
    offset = np.full((2, case.mixed.size), PRESSURE)
    weight = penalty = None
    if stabilisation == "nitsche":
        weight, penalty = nitsche_weights(case.cut.volume, np.array(BULK)[:, None] * DT * np.ones((2, case.mixed.size)),
                                          case.cut.reconstruction.length, 1.0)
    system.set_materials(compliance, offset, weight, penalty)
    system.solve(mass, rhs, case.tied)
    generator = np.random.default_rng(3)
    factorisations = []
    for change in (0.3, 1e-3):
        compliance = compliance * (1.0 + change * generator.uniform(-1.0, 1.0, compliance.shape))
        offset = offset * (1.0 + change * generator.uniform(-1.0, 1.0, offset.shape))
        resolved = system.resolve(compliance, offset)
        factorisations.append(system.system.solver.getPC().getFactorMatrix().stateGet())
        reference_system = InterfaceSystem(case.dolfinx_mesh, case.mixed,
                                           interface_forms(stabilisation, "free", case.cell))
        reference_system.vertex_order(case.mesh.cell_nodes[case.mixed])
        reference_system.set_geometry((reconstruction.alpha, reconstruction.beta), reconstruction.start,
                                      reconstruction.end, case.cut.edge_flux, case.cut.normal)
        reference_system.set_materials(compliance, offset, weight, penalty)
        assembled = reference_system.solve(mass, rhs, case.tied)
        for key in ("pressure", "interface_pressure") if stabilisation != "nitsche" else ("pressure",):
            assert np.allclose(resolved[key], assembled[key], rtol=0, atol=1e-12 * np.abs(assembled[key]).max())
        for m in range(2):
            scale = np.abs(assembled["velocity"][m]).max()
            assert np.allclose(resolved["velocity"][m], assembled["velocity"][m], rtol=0, atol=1e-12 * scale)
    assert factorisations[1] == factorisations[0]  # the small change refined on the factors of the large one


def test_the_same_unknowns_step_after_step_keep_the_reduced_system():
    """A steady interface gives the same tied unknowns step after step: after set_geometry
    the constraint C is rebuilt, found to have the last one's pattern, and the last one is
    kept with its values refreshed — the reduced matrix (and so the factorisation's
    analysis) is kept.  With the tied node sliding along another direction (C's values
    change, its pattern does not) the solution is a fresh system's; one more tied node gives
    a new C."""
    case, system, *_ = _kink_system()
    mass, rhs = case.inertia_and_rhs(velocity=[0.1 * case.normal_line[:, None] * np.ones((2, case.mesh.n_nodes)),
                                               np.zeros((2, case.mesh.n_nodes))])
    assert case.tied.any()
    sliding = case.tied.copy()
    first_normal = np.zeros((2, case.mesh.n_nodes))
    first_normal[0] = 1.0
    system.solve(mass, rhs, case.tied, sliding, first_normal)
    reduced, constraint = system.system._reduced[0], system._unknowns[1]
    reconstruction = case.cut.reconstruction
    system.set_geometry((reconstruction.alpha, reconstruction.beta), reconstruction.start, reconstruction.end,
                        case.cut.edge_flux, case.cut.normal)
    turned = np.zeros((2, case.mesh.n_nodes))
    turned[:, :] = np.array([[np.cos(0.4)], [np.sin(0.4)]])
    again = system.solve(mass, rhs, case.tied, sliding, turned)
    assert system._unknowns[1] is constraint and system.system._reduced[0] is reduced
    _, fresh, *_ = _kink_system()
    expected = fresh.solve(mass, rhs, case.tied, sliding, turned)
    for m in range(2):
        scale = np.abs(expected["velocity"][m]).max()
        assert np.allclose(again["velocity"][m], expected["velocity"][m], rtol=0, atol=1e-12 * scale)
    # other unknowns (one more node tied): a new C and a new reduced system
    more = case.tied.copy()
    more[system.nodes[~more[system.nodes]][0]] = True
    system.solve(mass, rhs, more)
    assert system._unknowns[1] is not constraint and system.system._reduced[0] is not reduced


@pytest.mark.parametrize("cell", ["triangle", "quadrilateral"])
@pytest.mark.parametrize("stabilisation,slip", [("none", "free"), ("bubble", "free"), ("bubble", "stick"),
                                                ("nitsche", "free"), ("nitsche", "stick")])
def test_the_interface_system_is_symmetric(stabilisation, slip, cell):
    """The system is solved by LDLᵀ (forms.bound_system, ``symmetric``), which reads one
    triangle of the matrix: every form must be symmetric — the assembled matrix of a disk
    with a ghost viscosity, Nitsche's weights and a moving state equals its transpose to
    round-off (a term written on one side only, such as the ghost viscosity's weight on the
    test function alone with another on the trial, would show here)."""
    from ale_xfem.studies.interface import BULK
    from forms.enriched_interface import nitsche_weights
    from petsc4py import PETSc

    case = InterfaceCase(8, "disk", cell=cell)
    system = case.bind(stabilisation, slip)
    n = case.mixed.size
    generator = np.random.default_rng(5)
    bulk = np.array(BULK)[:, None] * generator.uniform(0.5, 2.0, (2, n))
    weight, gamma = nitsche_weights(case.cut.volume, bulk * DT, case.cut.reconstruction.length, 1.0)
    system.set_materials(1.0 / (bulk * DT), np.full((2, n), PRESSURE), weight, gamma)
    system.set_ghost(generator.uniform(0.0, 1.0, (2, n)))
    mass, _ = case.inertia_and_rhs()
    system._set_mass(mass)
    system.system.assemble()
    matrix = system.system.matrix
    difference = matrix.copy()
    difference.axpy(-1.0, matrix.transpose(PETSc.Mat()))
    assert difference.norm(PETSc.NormType.INFINITY) <= 1e-14 * matrix.norm(PETSc.NormType.INFINITY)
    factor = system.system.solver.getPC()
    assert factor.getType() == "cholesky"


def test_a_constraint_that_only_selects_unknowns_reduces_to_the_submatrix_with_ptaps_bits():
    """Cᵀ A C of a constraint that only selects unknowns (the band's inactive cells left
    out, nothing tied) is taken as A's submatrix (forms.bound_system.BoundSystem._reduce):
    the same pattern and the same bits as PETSc's PtAP; a constraint that joins unknowns
    (tied nodes, and sliding ones along a normal: coefficients other than 1) is the compiled
    product's, with PtAP's pattern and bits too, and so is its refill when the same
    constraint comes back with new values of A."""
    from petsc4py import PETSc

    case, system, mass, rhs = _kink_system()
    system._set_mass(mass)
    bound = system.system
    bound.assemble()
    size = bound.matrix.getSize()[0]
    generator = np.random.default_rng(2)
    kept = np.flatnonzero(generator.random(size) < 0.4)

    def constraint(rows, columns, values=None):
        pointer = np.zeros(size + 1, dtype=PETSc.IntType)
        np.cumsum(np.bincount(rows, minlength=size), out=pointer[1:])
        values = np.ones(rows.size) if values is None else values
        return PETSc.Mat().createAIJ(size=(size, int(columns.max()) + 1),
                                     csr=(pointer, columns.astype(PETSc.IntType), values))

    def same_bits(ours, theirs):
        for a, b in zip(ours.getValuesCSR(), theirs.getValuesCSR()):
            assert a.shape == b.shape and np.array_equal(a.view(np.uint8), b.view(np.uint8))

    selection = constraint(kept, np.arange(kept.size))
    reduced = bound._reduce(selection)
    assert bound._selection[1] is not None  # taken as a submatrix
    same_bits(reduced, bound.matrix.PtAP(selection))
    # the first two kept unknowns one; the next two kept rows each split between two columns
    # (a sliding node's components along a normal)
    rows = np.concatenate([kept[:2], np.repeat(kept[2:4], 2), kept[4:]])
    columns = np.concatenate([[0, 0], [1, 2, 1, 2], np.arange(3, kept.size - 1)])
    values = np.concatenate([[1.0, 1.0], [0.6, -0.8, 0.8, 0.6], np.ones(kept.size - 4)])
    joined = constraint(rows, columns, values)
    reduced = bound._reduce(joined)
    assert bound._selection[1] is None  # the compiled product
    same_bits(reduced, bound.matrix.PtAP(joined))
    bound.matrix.scale(generator.uniform(0.5, 2.0))  # new values, the same pattern
    assert bound._reduce(joined, reduced) is reduced
    same_bits(reduced, bound.matrix.PtAP(joined))


def test_the_backward_errors_row_scales_are_the_sums_of_the_rows_magnitudes():
    """forms.bound_system.row_scales: Σ_j |A_ij x_j| + |b_i| over A's CSR rows, each sum
    from +0 in the entries' order — the bits of np.bincount over the entries, which it
    replaced (a run's refinement on the factors stops on them); rows twenty orders of
    magnitude apart, as the system's are."""
    from forms.bound_system import row_scales

    case, system, mass, _ = _kink_system()
    system._set_mass(mass)
    system.system.assemble()
    pointer, columns, values = system.system.matrix.getValuesCSR()
    generator = np.random.default_rng(3)
    x, b = generator.normal(size=pointer.size - 1), generator.normal(size=pointer.size - 1)
    rows = np.repeat(np.arange(pointer.size - 1), np.diff(pointer))
    expected = np.bincount(rows, np.abs(values) * np.abs(x[columns]), minlength=b.size) + np.abs(b)
    scale = row_scales(pointer, columns, values, x, b)
    assert np.array_equal(scale.view(np.uint64), expected.view(np.uint64))
    assert expected.max() > 1e15 * expected.min()


def test_a_scene_asking_for_lu_keeps_mumps():
    """The system factorises by LDLᵀ by default; a scene's ``pc_type = "lu"`` switches the
    factorisation, which made PETSc forget MUMPS and fall back to its own LU, which stops on
    the multiplier rows' zero diagonal (a review found it: "the KSP failed").  MUMPS is kept
    unless the options choose another solver, and the solution is the default's."""
    case, system, *_ = _kink_system({"pc_type": "lu"})
    mass, rhs = case.inertia_and_rhs(velocity=[0.1 * case.normal_line[:, None] * np.ones((2, case.mesh.n_nodes)),
                                               np.zeros((2, case.mesh.n_nodes))])
    out = system.solve(mass, rhs, case.tied)
    preconditioner = system.system.solver.getPC()
    assert preconditioner.getType() == "lu" and preconditioner.getFactorSolverType() == "mumps"
    _, default, *_ = _kink_system()
    expected = default.solve(mass, rhs, case.tied)
    for m in range(2):
        scale = np.abs(expected["velocity"][m]).max()
        assert np.allclose(out["velocity"][m], expected["velocity"][m], rtol=0, atol=1e-12 * scale)


@pytest.mark.parametrize("cell", ["triangle", "quadrilateral"])
def test_what_crosses_the_mesh_edges_closes_each_cut_cells_area_balance(cell):
    """CutCells.crossing_volumes R_m (what each material carries across the edges of a cut
    cell relative to them, while the nodes move with the material they lie in): for any
    velocities, in every mixed cell off the boundary, Σ_m (dt ∫_{K_m} ∇·ū_m + Σ_edges R_m)
    = dt (d|K|/dt + Σ_m ∫_Γ ū_m·n_m) — the parts moved with their own materials plus what
    crossed are the cell moved with the mesh, up to the normal jump the interface system
    makes vanish.  ∂|K|/∂x_i by the polygon's formula; random velocities on the disk.  An
    edge between two mixed cells passes the same volume out of one as into the other."""
    case = InterfaceCase(10, "disk", cell=cell)
    geometry, _ = _enriched_geometry_of(case)
    cut, mesh = geometry.cut, case.mesh
    nodes = mesh.cell_nodes[cut.cells]
    rng = np.random.default_rng(7)
    velocity = rng.normal(size=(2, 2, mesh.n_nodes))
    mesh_velocity = velocity[geometry.owner, :, np.arange(mesh.n_nodes)].T
    dt = 0.01
    crossing = cut.crossing_volumes(mesh_velocity, velocity, nodes, dt)
    gradient = cut.part_integrals()[1]
    own = np.stack([np.einsum("dnk,nkd->n", velocity[m][:, nodes], gradient[m]) for m in range(2)])
    jump = sum(cut.normal_flux(m, velocity[m], nodes) for m in range(2))
    x = cut.vertices  # (n, k, 2) counter-clockwise
    before, after = np.roll(x, 1, axis=1), np.roll(x, -1, axis=1)
    area_gradient = 0.5 * np.stack([after[..., 1] - before[..., 1], before[..., 0] - after[..., 0]], axis=-1)
    area_rate = np.einsum("dnk,nkd->n", mesh_velocity[:, nodes], area_gradient)
    interior = np.all(cut.edge_neighbour >= 0, axis=1)
    assert np.count_nonzero(interior) > 10
    left = (dt * own + crossing.sum(axis=2)).sum(axis=0)
    right = dt * (area_rate + jump)
    np.testing.assert_allclose(left[interior], right[interior], rtol=0, atol=1e-15)
    assert np.abs(crossing).max() > 1e-4  # (the nodes' materials differ: something crosses)
    where = {c: j for j, c in enumerate(cut.cells)}
    pairs = 0
    for j, c in enumerate(cut.cells):
        for k, other in enumerate(cut.edge_neighbour[j]):
            if other in where:
                back = list(cut.edge_neighbour[where[other]]).index(c)
                np.testing.assert_allclose(crossing[:, j, k], -crossing[:, where[other], back], rtol=0, atol=1e-17)
                pairs += 1
    assert pairs > 10


def test_the_mixed_cells_viscosity_sees_the_materials_compression_not_their_slide():
    """EnrichedClosure2D._own_viscosity on the disk's mixed cells: q̄, the mean of q at the two
    evaluations, is q = ρ (c2 Δu² + c1 c |Δu|) of the cell's compression less the slip's
    part (_slip_rate): none where the slip makes all of the cell's area rate, one velocity
    field's q where nothing slides; a slip that would add compression adds none; off, zero.
    ρ the parts' harmonic mean.  The slip's rate is what crosses the cells' edges a unit of
    time (the area balance of the test above)."""
    from ale_xfem.mixed.enriched_2d import EnrichedClosure2D

    case = InterfaceCase(10, "disk", cell="quadrilateral")
    geometry, mass = _enriched_geometry_of(case)
    cut, mesh = geometry.cut, case.mesh
    nodes = mesh.cell_nodes[cut.cells]
    volume, part_mass = cut.volume, mass[:, cut.cells]
    area = volume.sum(axis=0)
    rng = np.random.default_rng(3)
    velocity = rng.normal(size=(2, 2, mesh.n_nodes))
    mesh_velocity = velocity[geometry.owner, :, np.arange(mesh.n_nodes)].T
    slip = EnrichedClosure2D._slip_rate(cut, mesh_velocity, velocity, nodes)
    np.testing.assert_allclose(slip, cut.crossing_volumes(mesh_velocity, velocity, nodes, 0.5).sum(axis=(0, 2)) / 0.5,
                               rtol=1e-12)
    law = (1.0, 0.5, True)
    sound = [np.full(cut.cells.size, 2.0), np.full(cut.cells.size, 3.0)]
    jump = -0.4 * np.sqrt(area)  # compressed
    evaluations = [(jump, area, c) for c in sound]
    density = 1.0 / np.sum((volume / area) * volume / part_mass, axis=0)
    q_whole = 0.5 * sum(density * (jump**2 + 0.5 * c * np.abs(jump)) for c in sound)
    own = EnrichedClosure2D._own_viscosity
    np.testing.assert_allclose(own(law, evaluations, np.zeros(area.size), volume, part_mass), q_whole, rtol=1e-12)
    np.testing.assert_allclose(own(law, evaluations, jump * np.sqrt(area), volume, part_mass), 0.0, atol=1e-15)
    half = own(law, evaluations, 0.5 * jump * np.sqrt(area), volume, part_mass)
    np.testing.assert_allclose(half, 0.5 * sum(density * (0.25 * jump**2 + 0.25 * c * np.abs(jump)) for c in sound),
                               rtol=1e-12)
    np.testing.assert_allclose(own(law, evaluations, -jump * np.sqrt(area), volume, part_mass), q_whole, rtol=1e-12)
    assert np.all(own((1.0, 0.5, False), evaluations, slip, volume, part_mass) == 0.0)
