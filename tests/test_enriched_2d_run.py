"""2D enriched mixed cells in whole runs (ale_xfem/mixed/enriched_2d.py): the Lagrange
step with one velocity per material on the mixed cells' nodes, the per-material momentum
remap, and the scene keys that switch them on."""

import functools
import tomllib

import numpy as np
import pytest

from ale_xfem.model.state import material_angular_momenta, material_momenta, totals
from ale_xfem.problem.build import build_problem
from ale_xfem.remap.remapper_2d import Remapper2D
from ale_xfem.mixed.cut_cells_2d import by_material, material_geometry
from ale_xfem.mixed.closures import Closures
from ale_xfem.mixed.enriched_2d import GHOST_VISCOSITY
from ale_xfem.run import make_stepper, simulate
from ale_xfem.scene.schema import SceneError, load_scene, resolve_scene_path, validate
from conftest import fitted_rate, run_scene

DISK_AT_REST = {
    "name": "disk-at-rest", "dimension": 2, "t_end": 0.2,
    "mesh": {"extent": [[0.0, 1.0], [0.0, 1.0]], "cells": [12, 12], "motion": "eulerian"},
    "materials": {"outer": {"eos": "ideal_gas", "gamma": 1.4}, "disk": {"eos": "ideal_gas", "gamma": 1.667}},
    "regions": [{"material": "outer", "box": [[0.0, 1.0], [0.0, 1.0]], "density": 10.0, "pressure": 1.0},
                {"material": "disk", "disk": {"center": [0.5, 0.5], "radius": 0.27}, "density": 1.0,
                 "pressure": 1.0}],
    "interface": {"model": "enriched"},
}


def scene(cell="quadrilateral", motion="eulerian", **interface):
    data = {key: (dict(value) if isinstance(value, dict) else value) for key, value in DISK_AT_REST.items()}
    data["mesh"] = dict(data["mesh"], cell_type=cell, motion=motion)
    data["interface"] = dict(data["interface"], **interface)
    return validate(data)


def assert_still_at_rest(result):
    """Every material's velocity zero and every pressure 1, to round-off (10⁻¹³), and mass,
    momentum, energy and each material's mass conserved to 10⁻¹³."""
    state = result.state
    assert np.abs(state.material_node_velocity).max() < 1e-13
    occupied = state.material_mass > 0
    assert np.abs(state.material_pressure[occupied] - 1.0).max() < 1e-13
    for quantity in ("mass", "momentum", "total_energy", "material_mass"):
        assert abs(result.conservation[quantity]) < 1e-13, quantity


@pytest.mark.parametrize("motion", ["eulerian", "lagrangian"])
@pytest.mark.parametrize("cell", ["quadrilateral", "triangle"])
@pytest.mark.parametrize("stabilisation", ["bubble", "nitsche"])
def test_a_disk_at_rest_in_a_uniform_pressure_stays_at_rest(cell, stabilisation, motion):
    """Two materials of different density and γ at one pressure, the interface inside cells
    of an Eulerian mesh or of a Lagrangian one (remapped in place: nothing moves): every
    material's velocity stays zero and every pressure 1, to round-off (≤ 2 × 10⁻¹⁵
    measured, 1.5 × 10⁻¹⁴ in pressure with Nitsche on a Lagrangian mesh; the tied nodes'
    velocities are one unknown, exactly), and mass, momentum and energy are conserved."""
    problem = build_problem(scene(cell, motion, stabilisation=stabilisation))
    assert f"remap_{motion}" in problem.effects
    # (a remap in place sweeps nothing: its order cannot act)
    assert any(name.startswith("remap_order_") for name in problem.effects) == (motion == "eulerian")
    result = simulate(problem)
    assert result.status == "ok" and result.steps >= 10 and result.mixed_cells["solves"] == result.steps
    assert_still_at_rest(result)


@pytest.mark.parametrize("motion", ["eulerian", "lagrangian"])
@pytest.mark.parametrize("cell", ["quadrilateral", "triangle"])
@pytest.mark.parametrize("stabilisation", ["bubble", "nitsche"])
@pytest.mark.parametrize("contact", [{"box": [[0.43, 1.0], [0.0, 1.0]]},
                                     {"half_plane": {"point": [0.5, 0.5], "normal": [0.8660254037844387, 0.5]}}],
                         ids=["along-the-mesh", "at-30-degrees"])
def test_a_contact_at_rest_that_meets_two_walls_stays_at_rest(contact, cell, stabilisation, motion):
    """DISK_AT_REST's gases on either side of a straight contact that cuts cells and meets
    the bottom and top walls (x = 0.43, or at 30° to the mesh): where Γ meets a wall, the
    pressure on the wall cell's wall edge is the wall's to take, not the nodes above it (it
    pushed them towards the wall: 1.35 × 10⁻³ after one step on quadrilaterals).
    Velocities stay zero and pressures 1 to round-off."""
    data = {key: (dict(value) if isinstance(value, dict) else value) for key, value in DISK_AT_REST.items()}
    data["mesh"] = dict(data["mesh"], cell_type=cell, motion=motion)
    data["regions"] = [data["regions"][0], {"material": "disk", "density": 1.0, "pressure": 1.0, **contact}]
    data["interface"] = dict(data["interface"], stabilisation=stabilisation)
    problem = build_problem(validate(data))
    result = simulate(problem)
    assert result.status == "ok" and result.steps >= 10 and result.mixed_cells["count"] >= 12
    assert_still_at_rest(result)


@pytest.mark.parametrize("cell", ["quadrilateral", "triangle"])
@pytest.mark.parametrize("stabilisation", ["bubble", "nitsche"])
def test_a_box_carried_by_its_moving_walls_with_a_contact_meeting_them_moves_as_one(cell, stabilisation):
    """Galilean invariance at pistons: DISK_AT_REST's gases either side of a contact at 30°
    to a Lagrangian mesh, everything moving at (0.5, 0.25) with all four sides held at that
    velocity (`{velocity = [...]}` boundaries, which hold both components where the walls
    hold one).  The state moves as one: every material's velocity stays (0.5, 0.25) and
    every pressure 1, to round-off (velocities within 10⁻¹⁴, pressures 6.4 × 10⁻¹⁴ measured;
    1.5 × 10⁻² and 3.3 × 10⁻² before the pistons took the forces they hold at the external
    nodes)."""
    carried = [0.5, 0.25]
    data = {key: (dict(value) if isinstance(value, dict) else value) for key, value in DISK_AT_REST.items()}
    data["mesh"] = dict(data["mesh"], cell_type=cell, motion="lagrangian")
    data["regions"] = [dict(data["regions"][0], velocity=carried),
                       {"material": "disk", "density": 1.0, "pressure": 1.0, "velocity": carried,
                        "half_plane": {"point": [0.5, 0.5], "normal": [0.8660254037844387, 0.5]}}]
    data["interface"] = dict(data["interface"], stabilisation=stabilisation)
    data["boundaries"] = {side: {"velocity": carried} for side in ("left", "right", "bottom", "top")}
    data["t_end"] = 0.1
    problem = build_problem(validate(data))
    result = simulate(problem)
    state = result.state
    assert result.status == "ok" and result.steps >= 5 and result.mixed_cells["count"] >= 12
    assert np.abs(state.material_node_velocity - np.array(carried)[None, :, None]).max() < 1e-12
    occupied = state.material_mass > 0
    assert np.abs(state.material_pressure[occupied] - 1.0).max() < 1e-12


FLOW = (0.5, -0.25)


def disk_in_a_uniform_flow(cell, model, **interface):
    """DISK_AT_REST's two gases, disk and all carried by one velocity FLOW through an Eulerian
    mesh of 24² cells twice as wide (walls all round, 0.73 from the disk's rim)."""
    data = {key: (dict(value) if isinstance(value, dict) else value) for key, value in DISK_AT_REST.items()}
    data["mesh"] = {"extent": [[0.0, 2.0], [0.0, 2.0]], "cells": [24, 24], "motion": "eulerian", "cell_type": cell}
    data["regions"] = [dict(region, velocity=list(FLOW)) for region in data["regions"]]
    data["regions"][0]["box"] = [[0.0, 2.0], [0.0, 2.0]]
    data["regions"][1]["disk"] = {"center": [1.0, 1.0], "radius": 0.27}
    data["interface"] = {"model": model, **interface}
    return validate(data)


@pytest.mark.parametrize("cell", ["quadrilateral", "triangle"])
@pytest.mark.parametrize("model, interface", [("single_velocity", {}), ("enriched", {"stabilisation": "bubble"}),
                                              ("enriched", {"stabilisation": "nitsche"}),
                                              ("enriched", {"stabilisation": "bubble", "slip": "stick"})])
def test_a_disk_carried_by_a_uniform_flow_keeps_its_pressure_and_velocity(cell, model, interface):
    """Galilean invariance through the remap: a disk of another gas at the same pressure,
    carried by a uniform flow through an Eulerian mesh, crosses cells and changes which
    nodes its mixed cells condense on, and the flow around it stays uniform.  Near the disk
    (cells within 0.5 of its centre, which the walls' waves have not reached by t = 0.2)
    every material's pressure stays 1 and its velocity at its internal nodes FLOW, within
    10⁻³ (at most 2.2 × 10⁻⁴ and 1.3 × 10⁻⁴ measured, with enriched cells as with one velocity
    field: what PLIC's straight cuts of the round rim and the order-2 slopes next to it
    leave).  The remap returns the kinetic energy its momentum remap loses as heat; a
    corner whose share of its cell's mass the condensation changes takes that mass with its
    kinetic energy.  Counted as lost, the re-lumped mass's kinetic energy heated the cells
    around the rim: pressures 15 % off by t = 0.2."""
    problem = build_problem(disk_in_a_uniform_flow(cell, model, **interface))
    result = simulate(problem)
    state = result.state
    assert result.status == "ok" and state.time == pytest.approx(0.2)
    centre = np.array([1.0, 1.0]) + np.array(FLOW) * state.time
    x = state.node_position
    cell_centre = x[:, problem.mesh.cell_nodes].mean(axis=2)
    near_cells = np.hypot(*(cell_centre - centre[:, None])) < 0.5
    near_nodes = np.hypot(*(x - centre[:, None])) < 0.5
    occupied = (state.material_mass > 0) & near_cells[None, :]
    assert np.abs(state.material_pressure[occupied] - 1.0).max() < 1e-3
    if model == "enriched":
        deviations = [state.material_node_velocity[m][:, near_nodes & state.material_node_internal[m]]
                      - np.array(FLOW)[:, None] for m in range(2)]
    else:
        deviations = [state.node_velocity[:, near_nodes] - np.array(FLOW)[:, None]]
    assert max(np.abs(d).max() for d in deviations) < 1e-3
    assert abs(result.conservation["mass"]) < 1e-13 and abs(result.conservation["total_energy"]) < 1e-13


def air_disk_carried_through_water(model, trace_fraction, **interface):
    """A disk of air in water (stiffened gas), both at 10⁵ Pa, carried by one velocity
    (500, −250) m/s through an Eulerian mesh of 48² cells, walls 1.73 m from the rim (the
    walls' waves, 8 × 10⁸ Pa, stay away from the disk), to t = 1.5 × 10⁻⁴ s (0.9 cells)."""
    flow = [500.0, -250.0]
    return validate({
        "name": "air-disk-carried-through-water", "dimension": 2, "t_end": 1.5e-4,
        "mesh": {"extent": [[-1.0, 3.0], [-1.0, 3.0]], "cells": [48, 48], "motion": "eulerian"},
        "materials": {"water": {"eos": "stiffened_gas", "gamma": 4.4, "p_inf": 6.0e8},
                      "air": {"eos": "ideal_gas", "gamma": 1.4}},
        "regions": [{"material": "water", "box": [[-1.0, 3.0], [-1.0, 3.0]], "density": 1000.0, "pressure": 1e5,
                     "velocity": flow},
                    {"material": "air", "disk": {"center": [1.0, 1.0], "radius": 0.27}, "density": 1.0,
                     "pressure": 1e5, "velocity": flow}],
        "numerics": {"trace_fraction": trace_fraction},
        "interface": {"model": model, **interface}}), np.array(flow)


@pytest.mark.parametrize("model, interface", [("single_velocity", {}), ("enriched", {"stabilisation": "bubble"})])
def test_a_moved_trace_moves_its_cells_other_material_by_about_rho_c2_times_the_trace_fraction(model, interface):
    """A trace the remap moves gives its volume to its cell's other material, whose pressure
    moves by about ρc² × numerics.trace_fraction: for water (ρc² = 2.64 × 10⁹ Pa) beside air
    at 10⁵ Pa, the default 10⁻⁴ moves water's pressure by up to 2.6 × 10⁵ Pa (1.3 and 1.8 ×
    10⁵ measured, one velocity field and enriched cells), 10⁻⁸ by 26 Pa (2 × 10⁻⁴ Pa
    measured: the flow is otherwise kept to round-off).  Near the disk (within 0.5 m of its
    centre), every material's pressure is 10⁵ Pa within ρc² × the fraction, and the traces
    are what moves it."""
    rho_c2 = 4.4 * (1e5 + 6.0e8)  # water: ρc² = γ (p + p∞)
    error = {}
    for fraction in (1e-4, 1e-8):
        scene, flow = air_disk_carried_through_water(model, fraction, **interface)
        problem = build_problem(scene)
        result = simulate(problem)
        state = result.state
        assert result.status == "ok" and state.time == pytest.approx(1.5e-4)
        centre = np.array([1.0, 1.0]) + flow * state.time
        cell_centre = state.node_position[:, problem.mesh.cell_nodes].mean(axis=2)
        near = np.hypot(*(cell_centre - centre[:, None])) < 0.5
        occupied = (state.material_mass > 0) & near[None, :]
        error[fraction] = np.abs(state.material_pressure[occupied] - 1e5).max()
        assert error[fraction] <= rho_c2 * fraction, (fraction, error)
    assert error[1e-8] < 1e-3 * error[1e-4], error


def test_a_remap_onto_the_same_mesh_changes_no_materials_velocity_where_it_has_mass():
    """The per-material momentum remap puts back each corner's deviation from its cell's
    mean at the material's internal nodes: with nothing swept, every material's velocity is
    kept where its mass is (spreading the cells' means alone would damp the spinning disk's
    rotation by about h²/R² a remap); at its external nodes it is re-extended from the
    cells' means, and momentum is exact."""
    problem = build_problem(load_scene(resolve_scene_path("spinning-disk"),
                                       ["mesh.cells=[16,16]", 'interface.model="enriched"']))
    state = problem.state
    remapper = Remapper2D(problem, "eulerian", 2)
    remapper.material_geometry = lambda *args: material_geometry(problem.mesh, *args)
    remapped = remapper.apply(state, problem.layout, problem.mixed)[0]
    scale = np.abs(state.material_node_velocity).max()
    internal = state.material_node_internal
    change = np.moveaxis(np.abs(remapped.material_node_velocity - state.material_node_velocity), 1, 0)
    cut = np.zeros(problem.mesh.n_nodes, dtype=bool)
    cut[problem.mesh.cell_nodes[problem.mixed.cells].ravel()] = True
    assert change[:, :, ~cut].max() < 1e-13 * scale  # away from the interface: exact
    # internal nodes of cut cells: their cells' momentum takes back the external corners'
    # deviations, which weigh EXTERNAL_SHARE (10⁻³) of a consistent share
    assert change[:, internal & cut[None, :]].max() < 1e-3 * scale
    assert change[:, ~internal].max() > 1e-2 * scale  # the extension was re-made
    assert np.array_equal(remapped.material_node_mass, state.material_node_mass)
    momentum = [np.sum(s.material_node_mass[:, None] * s.material_node_velocity, axis=(0, 2)) for s in (state, remapped)]
    assert np.abs(momentum[1] - momentum[0]).max() < 1e-14 * np.sum(state.material_node_mass) * scale


def test_the_spinning_disk_slides_inside_the_fluid_around_it():
    """A light disk spinning in a heavy fluid at rest (a steady slip line, exact for ever):
    with one velocity per material the set-up gives the disk its angular momentum (95 % of
    ½πρωR⁴ on 20², the rest the nodal discretisation's) and the fluid none, and after three steps (each remapped onto the Eulerian mesh) the disk
    still holds 98 % of it and the fluid has taken less than 0.1 % — where one velocity
    field starts the rim's nodes at the mass-weighted mean of the two (the disk holds half
    of its own) and the fluid holds more than the disk."""
    exact = None
    held = {}
    for model in ("single_velocity", "enriched"):
        problem = build_problem(load_scene(resolve_scene_path("spinning-disk"),
                                           ["mesh.cells=[20,20]", f'interface.model="{model}"']))
        exact = problem.exact.solution.angular_momentum
        mesh = problem.mesh

        def momenta(state):
            return material_angular_momenta(state, problem.layout, mesh.cell_nodes,
                                            mesh.cell_centroids(state.node_position), (0.5, 0.5)) / exact

        start = momenta(problem.state)
        result = simulate(problem, stop_after_steps=3)
        held[model] = (start, momenta(result.state), result)
    start, end, result = held["enriched"]
    assert result.status == "ok" and result.steps == 3
    assert start[1] > 0.9 and start[0] == 0.0
    assert end[1] > 0.98 * start[1] and abs(end[0]) < 1e-3
    assert abs(result.conservation["momentum"]) < 1e-10 and abs(result.conservation["mass"]) < 1e-15
    single_start, single_end, _ = held["single_velocity"]
    assert single_start[1] < 0.6 and single_end[0] > single_end[1]


def spinning_disk_at_half_time(side: int, cell: str, closure: list[str]):
    """(the disk's angular momentum kept, the fluid's gain, both as fractions of the disk's
    at the start; L1(u) against the steady state) of the spinning disk at t = 0.5."""
    problem = build_problem(load_scene(resolve_scene_path("spinning-disk"), [
        f"mesh.cells=[{side},{side}]", f"mesh.cell_type={cell}", *closure, "t_end=0.5"]))
    disk = list(problem.scene.materials).index("disk")

    def angular_momenta(state):
        return material_angular_momenta(state, problem.layout, problem.mesh.cell_nodes,
                                        problem.mesh.cell_centroids(state.node_position), (0.5, 0.5))

    start = angular_momenta(problem.state)[disk]
    result = simulate(problem)
    assert result.status == "ok", result.diagnostic
    end = angular_momenta(result.state) / start
    return end[disk], end[1 - disk], result.errors["L1_velocity"]


@pytest.mark.parametrize("cell, stabilisation", [("quadrilateral", "bubble"), ("quadrilateral", "nitsche"),
                                                  ("triangle", "bubble"), ("triangle", "nitsche")])
def test_the_spinning_disks_loss_falls_with_resolution(cell, stabilisation):
    """Free slip keeps the spinning disk's steady state (v_θ = ωr inside, rest outside): the
    disk's loss of its angular momentum and the deviation from that state, L1(u), fall
    from 20² to 40² (t = 0.5), and the fluid gains less than a tenth of what one velocity
    field hands it on the same mesh.  Measured, bubbles / Nitsche: on quadrilaterals the
    disk keeps 0.979 / 0.966 on 20² and 0.984 / 0.981 on 40², the fluid gaining +0.001 /
    +0.015 and −0.001 / +0.003; on crossed triangles 0.980 / 0.975 and 0.992 / 0.991, the
    fluid gaining +0.0003 / +0.005 and +0.003 / +0.004 (a gain of a few thousandths that
    does not fall on triangles), where one velocity field hands it 1.26 and
    0.58 on quadrilaterals, 0.65 and 0.35 on triangles (of the disk's, by its cells' mean
    velocities).  (On 80² the fluid's gain grows again: the rim
    is a vortex sheet whose Kelvin–Helmholtz waves the finer mesh resolves, docs/design.md
    §4.)  Youngs' normals taken from the nodal averages' gradient (turned by 15° rms on
    crossed triangles) tilted the edges' cuts, and normal continuity across the tilted
    chords handed the fluid 0.07 to 0.12 of the disk's angular momentum, more on the finer
    mesh."""
    enriched = ["interface.model=enriched", f"interface.stabilisation={stabilisation}"]
    runs = {side: spinning_disk_at_half_time(side, cell, enriched) for side in (20, 40)}
    (kept_20, _, deviation_20), (kept_40, _, deviation_40) = runs[20], runs[40]
    assert 1.0 - kept_40 < 1.0 - kept_20 and deviation_40 < deviation_20, runs
    for side, (_, gained, _) in runs.items():
        _, handed, _ = spinning_disk_at_half_time(side, cell, ["interface.model=single_velocity"])
        assert abs(gained) < 0.1 * handed, (side, gained, handed)


@pytest.mark.parametrize("cell", ["quadrilateral", "triangle"])
def test_each_remap_of_enriched_cells_keeps_total_energy(cell, monkeypatch):
    """The per-material remap gives back as heat the kinetic energy it loses and takes from
    the internal energies what it makes: each remap of the sheared tube keeps total energy
    to round-off (the fluxes' kinetic energy spread by corner shares of the cells they
    reach, and of the cells a material leaves: by the new shares alone that was lost, 10⁻⁶
    of the total a remap)."""
    changes = []
    apply = Remapper2D.apply

    def checked(self, state, layout, mixed):
        before = totals(state, None)["total_energy"]
        out = apply(self, state, layout, mixed)
        changes.append((totals(out[0], out[3])["total_energy"] - before - self.wall_work) / before)
        return out

    monkeypatch.setattr(Remapper2D, "apply", checked)
    problem = build_problem(load_scene(resolve_scene_path("rotated-tube-shear"), [
        "mesh.cells=[16,16]", 'interface.model="enriched"', f'mesh.cell_type="{cell}"']))
    assert simulate(problem).status == "ok"
    assert len(changes) > 10 and max(abs(c) for c in changes) < 1e-14, changes


@pytest.mark.parametrize("cell, stabilisation", [("quadrilateral", "bubble"), ("triangle", "bubble"),
                                                  ("quadrilateral", "nitsche"), ("triangle", "nitsche")])
def test_the_lagrange_steps_of_enriched_cells_keep_total_energy(cell, stabilisation, monkeypatch):
    """A pure cell's forces enter its own material's momentum rows, so they work on that
    material's velocities — also at a node the other material owns, where the mesh moved
    with the other one: every Lagrange step of the spinning disk keeps total energy to
    round-off, on both cell types and with both stabilisations (worked on the mesh's
    velocity there, the first step changed it by 4.8 × 10⁻⁵ on quadrilaterals, and every
    step by 4 × 10⁻⁵ to 10⁻⁴ on triangles)."""
    problem = build_problem(load_scene(resolve_scene_path("spinning-disk"), [
        "mesh.cells=[20,20]", "interface.model=enriched", f"interface.stabilisation={stabilisation}",
        f"mesh.cell_type={cell}"]))
    energy = [totals(problem.state, None)["total_energy"]]
    apply = Remapper2D.apply

    def checked(self, state, layout, mixed):  # the state a Lagrange step made, then remapped
        energy.append(totals(state, None)["total_energy"])
        out = apply(self, state, layout, mixed)
        energy.append(totals(out[0], out[3])["total_energy"])
        return out

    monkeypatch.setattr(Remapper2D, "apply", checked)
    result = simulate(problem, stop_after_steps=4)
    assert result.status == "ok" and len(energy) == 9
    steps = np.abs(np.diff(energy)[::2])  # each Lagrange step's change
    assert steps.max() < 1e-14 * energy[0], steps


def test_momentum_is_kept_whatever_the_interface_solves_residual(monkeypatch):
    """The interface system's n+1 forces sum to zero only as far as its solve is exact; on
    the nearly singular systems of slivers its residual moved momentum (9 × 10⁻⁶ of it on
    the shock through the heavy disk, 80 × 40 triangles).  With every solve's velocities
    perturbed by 10⁻⁶ of the flow's, the spinning disk (no wall touches its mixed cells)
    still keeps momentum to round-off: the residual is taken out by one shift of the
    nodes' velocities."""
    from ale_xfem.mixed.implicit_step import ImplicitStep

    solve = ImplicitStep.solve
    noise = np.random.default_rng(5)

    def perturbed(self, *args, **kwargs):
        out = solve(self, *args, **kwargs)
        out["velocity"] = [v + 1e-6 * noise.standard_normal(v.shape) for v in out["velocity"]]
        return out

    monkeypatch.setattr(ImplicitStep, "solve", perturbed)
    problem = build_problem(load_scene(resolve_scene_path("spinning-disk"), [
        "mesh.cells=[16,16]", "interface.model=enriched"]))
    result = simulate(problem, stop_after_steps=4)
    assert result.status == "ok"
    assert abs(result.conservation["momentum"]) < 1e-14, result.conservation["momentum"]


@functools.lru_cache(maxsize=None)
def sliding_block_kept(cell="quadrilateral"):
    """What the sliding block keeps of its momentum along its length at t = 0.25 on ``cell``
    cells, by closure ("enriched", "single_velocity") and mesh ("[40,20]", "[80,40]")."""
    kept = {}
    for model in ("enriched", "single_velocity"):
        for cells in ("[40,20]", "[80,40]"):
            problem = build_problem(load_scene(resolve_scene_path("sliding-block"),
                                               [f"mesh.cells={cells}", f'interface.model="{model}"',
                                                f"mesh.cell_type={cell}"]))
            block = list(problem.scene.materials).index("block")
            start = material_momenta(problem.state, problem.layout, problem.mesh.cell_nodes)[block]
            axis = start / np.linalg.norm(start)
            result = simulate(problem)
            assert result.status == "ok", result.diagnostic
            assert abs(result.conservation["momentum"]) < 1e-13 and abs(result.conservation["mass"]) < 1e-14
            end = material_momenta(result.state, problem.layout, problem.mesh.cell_nodes)[block]
            kept[model, cells] = (end @ axis) / (start @ axis)
    return kept


def test_the_sliding_block_keeps_its_momentum_where_one_velocity_field_drags_its_sides():
    """A dense block sliding along its length through a light gas at rest (`sliding-block`,
    at 20° to an Eulerian mesh, to t = 0.25): its ends push and pull the gas (form drag, the
    same for every closure), its long sides slide.  With free slip it keeps more (0.9695 on
    40 × 20, 0.9720 on 80 × 40) than one velocity field, which drags its sides besides
    (0.9617, 0.9649)."""
    kept = sliding_block_kept()
    for cells in ("[40,20]", "[80,40]"):
        assert kept["enriched", cells] > kept["single_velocity", cells] + 0.005, kept
        assert 0.95 < kept["enriched", cells] < 1.0, kept
    assert kept["single_velocity", "[80,40]"] > kept["single_velocity", "[40,20]"], kept


def test_on_triangles_the_block_still_slides_at_their_heavier_ghost_viscosity():
    """The triangles' default ghost weight (1.0, GHOST_VISCOSITY) drags the block more than
    0.3 does (it keeps 0.9677 and 0.9717 on 40 × 20 and 80 × 40 crossed triangles, against
    0.9708 and 0.9729), but still less than one velocity field (0.9651, 0.9676); at 2.0 it
    would not (0.9648 on 40 × 20): docs/design.md §4."""
    kept = sliding_block_kept("triangle")
    for cells in ("[40,20]", "[80,40]"):
        assert kept["enriched", cells] > kept["single_velocity", cells] + 0.002, kept


@pytest.mark.xfail(strict=True, reason=(
    "free slip's block keeps 0.9695 and 0.9720 of its momentum on 40 × 20 and 80 × 40, a change of 0.0025 "
    "with the mesh against one velocity field's 0.0031: the ghost viscosity that holds the light gas's "
    "extension over the block's part of the cut cells drags it (at 0.1, 0.9716 and 0.9728, a change of 0.0012, "
    "but other cases lose accuracy or robustness there): docs/design.md §4"))
def test_what_the_sliding_block_keeps_with_free_slip_depends_less_on_the_mesh():
    """One velocity field's drag of the block's sides shrinks with its mixed cells; free
    slip's, if it only has the ends' form drag, changes less than half as much from 40 × 20
    to 80 × 40."""
    kept = sliding_block_kept()
    enriched_change = abs(kept["enriched", "[80,40]"] - kept["enriched", "[40,20]"])
    single_change = kept["single_velocity", "[80,40]"] - kept["single_velocity", "[40,20]"]
    assert enriched_change < single_change / 2, kept


def test_plic_normals_are_a_key_of_2d_interfaces():
    """``[interface] normal``: youngs (the default: written out, the run is the same to the
    bit) or lvira in 2D (another run), its effect listed when it acts; in 1D (no PLIC) or of
    another value, a one-line error naming the key."""
    lvira = build_problem(load_scene(resolve_scene_path("slip-line"), ["mesh.cells=[8,8]", 'interface.normal="lvira"']))
    assert lvira.scene.interface.normal == "lvira" and "interface_normal_lvira" in lvira.effects
    default = build_problem(load_scene(resolve_scene_path("slip-line"), ["mesh.cells=[8,8]"]))
    assert default.scene.interface.normal == "youngs" and "interface_normal_lvira" not in default.effects
    written = build_problem(load_scene(resolve_scene_path("slip-line"), ["mesh.cells=[8,8]", 'interface.normal="youngs"']))
    plain, youngs = simulate(default, stop_after_steps=4), simulate(written, stop_after_steps=4)
    for name in ("node_position", "material_node_velocity", "material_mass", "material_energy", "material_volume"):
        assert np.array_equal(getattr(plain.state, name), getattr(youngs.state, name)), name
    assert not np.array_equal(simulate(lvira, stop_after_steps=4).state.material_volume, plain.state.material_volume)
    for scene, value in (("sod-two-gamma-enriched", '"lvira"'), ("slip-line", '"elvira"')):
        with pytest.raises(SceneError) as error:
            load_scene(resolve_scene_path(scene), [f"interface.normal={value}"])
        assert error.value.key == "interface.normal"


def test_the_ghost_viscosity_is_a_key_of_2d_enriched_cells():
    """``[interface] ghost_viscosity``: the weight of each material's ghost viscosity in 2D
    enriched cells — by default the closure's GHOST_VISCOSITY of the mesh's cell type
    (heavier on triangles), written into the resolved scene and reaching the closure;
    another value reaches the closure (another run, and with 0 the extension held by
    nothing but the interface conditions, still another); in 1D a one-line error naming
    the key."""
    assert GHOST_VISCOSITY["triangle"] > GHOST_VISCOSITY["quadrilateral"] == 0.3
    for cell in ("quadrilateral", "triangle"):
        scene = load_scene(resolve_scene_path("slip-line"), ["mesh.cells=[8,8]", f"mesh.cell_type={cell}"])
        assert scene.interface.ghost_viscosity == GHOST_VISCOSITY[cell]  # (the scene's default is the closure's)
        assert scene.resolved["interface"]["ghost_viscosity"] == GHOST_VISCOSITY[cell]
        problem = build_problem(scene)
        assert make_stepper(problem).closure.ghost_viscosity == GHOST_VISCOSITY[cell]
        # (a closure made without a weight takes its mesh's cell type's)
        assert Closures(problem.mesh, problem.materials)(problem.mixed).ghost_viscosity == GHOST_VISCOSITY[cell]
    default = build_problem(load_scene(resolve_scene_path("slip-line"), ["mesh.cells=[8,8]"]))
    heavier, none = (build_problem(load_scene(resolve_scene_path("slip-line"),
                                              ["mesh.cells=[8,8]", f"interface.ghost_viscosity={value}"]))
                     for value in ("1.0", "0"))
    plain, other, unheld = (simulate(p, stop_after_steps=4) for p in (default, heavier, none))
    velocities = [r.state.material_node_velocity for r in (plain, other, unheld)]
    assert all(np.all(np.isfinite(v)) for v in velocities)
    assert not np.array_equal(velocities[1], velocities[0]) and not np.array_equal(velocities[2], velocities[0])
    with pytest.raises(SceneError) as error:
        load_scene(resolve_scene_path("sod-two-gamma-enriched"), ["interface.ghost_viscosity=1.0"])
    assert error.value.key == "interface.ghost_viscosity"


@pytest.mark.parametrize("change, key", [
    ({"interface": {"model": "enriched", "stabilisation": "bubble", "nitsche_penalty": 2.0}},
     "interface.nitsche_penalty"),
    ({"interface": {"model": "enriched", "predictor": "assembled"}}, "interface.predictor"),
    ({"interface": {"model": "enriched", "stabilisation": "nitsche", "nitsche_penalty": 0.0}},
     "interface.nitsche_penalty"),
    ({"interface": {"model": "single_velocity", "stabilisation": "bubble"}}, "interface.stabilisation"),
    ({"interface": {"model": "enriched", "slip": "coulomb"}}, "interface.slip"),
    ({"interface": {"model": "single_velocity", "ghost_viscosity": 1.0}}, "interface.ghost_viscosity"),
    ({"interface": {"model": "enriched", "ghost_viscosity": -0.1}}, "interface.ghost_viscosity"),
    ({"interface": {"model": "enriched", "ghost_viscosity": "high"}}, "interface.ghost_viscosity"),
])
def test_keys_that_cannot_act_on_2d_enriched_cells_are_errors(change, key):
    data = dict(DISK_AT_REST, **change)
    with pytest.raises(SceneError) as error:
        validate(data)
    assert error.value.key == key


def test_2d_enriched_cells_need_exactly_two_materials():
    data = dict(DISK_AT_REST, materials=dict(DISK_AT_REST["materials"], third={"eos": "ideal_gas", "gamma": 1.3}))
    with pytest.raises(SceneError) as error:
        validate(data)
    assert error.value.key == "materials"


def test_the_defaults_of_2d_enriched_cells():
    interface = validate(dict(DISK_AT_REST)).interface
    assert (interface.stabilisation, interface.slip, interface.nitsche_penalty) == ("bubble", "free", None)
    nitsche = scene(stabilisation="nitsche").interface
    assert nitsche.nitsche_penalty == 1.0


def shear_tube(model, cells=40, **interface):
    overrides = [f"mesh.cells=[{cells},{cells}]", f'interface.model="{model}"']
    overrides += [f'interface.{key}="{value}"' for key, value in interface.items()]
    problem = build_problem(load_scene(resolve_scene_path("rotated-tube-shear"), overrides))
    return simulate(problem)


def test_the_sheared_tube_keeps_its_slip_line_sharper_than_one_velocity_field():
    """The two-material Riemann problem at 30° to an Eulerian mesh, each side sliding along
    the contact (±0.25): against the exact solution (the 1D one along the normal, each side
    keeping its tangential velocity), on 40² free slip gives a smaller L1 velocity error than
    one velocity field (0.72 of it; on 20² 0.94), and stick — the tangential velocity
    continuous, one velocity field's constraint — a larger one than free slip; density and
    pressure stay as close as one velocity field's (within 30 %).  Momentum is conserved to round-off though
    the interface meets the walls (their reactions on the mixed cells' nodes are counted,
    and the external nodes' force at n acts through the internal ones)."""
    single = shear_tube("single_velocity")
    free = shear_tube("enriched", stabilisation="bubble")
    stick = shear_tube("enriched", stabilisation="bubble", slip="stick")
    for result in (single, free, stick):
        assert result.status == "ok" and result.errors is not None
    assert free.errors["L1_velocity"] < 0.9 * single.errors["L1_velocity"]
    assert stick.errors["L1_velocity"] > free.errors["L1_velocity"]
    for field in ("L1_density", "L1_pressure"):
        assert free.errors[field] < 1.3 * single.errors[field]
    assert abs(free.conservation["momentum"]) < 1e-10 and abs(free.conservation["mass"]) < 1e-15


@pytest.mark.parametrize("cell", ["quadrilateral", "triangle"])
def test_without_a_tangential_jump_stick_changes_only_the_velocity_along_the_contact(cell):
    """The tube without shear (rotated-tube, Eulerian): nothing slides along the contact, so
    stick and free slip model the same flow, and one velocity field too.  Stick's density,
    velocity and pressure errors are free slip's within 5 % (at most 3.6 % here) on 20² and
    40²; its error along the contact is below free slip's (0.53 and 0.77 of it on
    quadrilaterals, 0.70 on triangles: the tangential condition holds the materials'
    extensions together).  Where stick and one velocity field differ (stick 1.08–1.13
    times one velocity field's L1(u) over 20² to 80² on quadrilaterals, 0.98–1.21 on
    triangles) free slip differs as much:
    it is the enriched cells' normal velocity (docs/design.md §4)."""
    errors = {}
    for side in (20, 40):
        for slip in ("free", "stick"):
            _, result = run_scene("rotated-tube", f"mesh.cells=[{side},{side}]", f"mesh.cell_type={cell}",
                                  "mesh.motion=eulerian", "interface.model=enriched", f"interface.slip={slip}")
            assert result.status == "ok" and result.errors is not None
            errors[side, slip] = result.errors
    for side in (20, 40):
        stick, free = errors[side, "stick"], errors[side, "free"]
        for quantity in ("L1_density", "L1_velocity", "L1_pressure"):
            assert abs(stick[quantity] - free[quantity]) < 0.05 * free[quantity], (side, quantity)
        assert stick["L1_tangential_velocity"] < 0.9 * free["L1_tangential_velocity"], side


# The sheared tube's convergence: three resolutions per cell type (fitted over triangles 20²
# to 160² the enriched cells' rates are the same within 0.04; on quadrilaterals u_n and u_t
# slow down at 320²: docs/design.md §4, "Convergence on the sheared tube", gives the local
# rates).
RATE_SIDES = {"quadrilateral": (40, 80, 160), "triangle": (30, 60, 120)}


def run_with_exact_errors(name: str, side: int, cell: str, model: str, *overrides: str):
    """A shipped scene on side × side cells of the given type with the given closure (its
    defaults otherwise, or ``overrides``), run to its end, which its exact solution reaches."""
    _, result = run_scene(name, f"mesh.cells=[{side},{side}]", f"mesh.cell_type={cell}", f"interface.model={model}",
                          *overrides)
    assert result.status == "ok" and result.errors is not None
    return result


@functools.cache
def sheared_tube_errors(cell: str, model: str, *overrides: str) -> dict:
    """The sheared tube's L1 errors at each of RATE_SIDES[cell] (one velocity field, or
    enriched cells with bubbles and free slip; ``overrides``: more scene settings):
    {quantity: [errors]}, run once per test process for the tests below."""
    errors = {}
    for side in RATE_SIDES[cell]:
        result = run_with_exact_errors("rotated-tube-shear", side, cell, model, *overrides)
        for quantity in ("density", "pressure", "normal_velocity", "tangential_velocity"):
            errors.setdefault(quantity, []).append(result.errors[f"L1_{quantity}"])
    return errors


SMEARED_CONTACT = pytest.mark.xfail(strict=True, reason=(
    "the contact's density jump, smeared by the remap: one velocity field's rate is 0.75 on quadrilaterals, "
    "the enriched cells' 0.77: docs/design.md §4, 'Convergence on the sheared tube'"))
SHEARED_CELLS_DENSITY = pytest.mark.xfail(strict=True, reason=(
    "on triangles the enriched density error is 9-10 % above one velocity field's at 30² to 120² (rates 0.799 "
    "and 0.803, both short of 0.8), where on a steady slip line it is 0.15 to 0.33 times one velocity field's: "
    "docs/design.md §4, 'Convergence on the sheared tube'"))
SLOWER_NORMAL_VELOCITY = pytest.mark.xfail(strict=True, reason=(
    "on crossed triangles the normal velocity converges more slowly with free slip than with one velocity "
    "field (rate 0.74 against 0.87, its error 29 % above one velocity field's at 120²; on quadrilaterals 0.84 "
    "against 0.87): docs/design.md §4, 'Convergence on the sheared tube'"))


@pytest.mark.parametrize("cell, quantity", [
    ("quadrilateral", "pressure"), ("triangle", "pressure"),
    pytest.param("quadrilateral", "density", marks=SMEARED_CONTACT),
    pytest.param("triangle", "density", marks=SHEARED_CELLS_DENSITY),
    ("quadrilateral", "normal_velocity"),
    pytest.param("triangle", "normal_velocity", marks=SLOWER_NORMAL_VELOCITY),
])
def test_the_sheared_tube_converges_at_rate_0_8_with_enriched_cells(cell, quantity):
    """The target of the paper's 2D method: on the rotated two-material tube with a
    tangential jump across its contact (the interface inside cells of an Eulerian mesh),
    density, pressure and normal velocity converge to the rotated 1D solution at a rate of
    at least 0.8 in L1, on three resolutions, quadrilaterals and triangles."""
    assert fitted_rate(RATE_SIDES[cell], sheared_tube_errors(cell, "enriched")[quantity]) >= 0.8


@pytest.mark.parametrize("cell", ["quadrilateral", "triangle"])
def test_free_slip_keeps_each_sides_tangential_velocity_where_one_velocity_field_smears_it(cell):
    """The sheared tube at three resolutions: with free slip each material keeps its own
    tangential velocity, so the error along the contact is below one velocity field's at
    every resolution (which smears the jump over cells: its rate is about 0.5, as for a
    contact's smeared width), and on quadrilaterals it converges at first order."""
    free, single = sheared_tube_errors(cell, "enriched"), sheared_tube_errors(cell, "single_velocity")
    assert all(f < 0.9 * s for f, s in zip(free["tangential_velocity"], single["tangential_velocity"]))
    assert fitted_rate(RATE_SIDES[cell], single["tangential_velocity"]) < 0.65
    if cell == "quadrilateral":
        assert fitted_rate(RATE_SIDES[cell], free["tangential_velocity"]) >= 0.85


@pytest.mark.xfail(strict=True, reason=(
    "on crossed triangles free slip's error along the contact converges at 0.75 (0.88 on quadrilaterals): "
    "away from the contact it is a pattern along the contact, of zero mean, that the cut cells' weakly held "
    "extensions send into the gases; the triangles' default ghost viscosity (1.0) halves it (rate 0.53 at 0.3, "
    "the test below) and 2.0 would give 0.95, but a sliding block would then be dragged as by one velocity "
    "field: docs/design.md §4, 'The extension of each material's velocity'"))
def test_free_slips_tangential_velocity_converges_at_first_order_on_triangles():
    """As on quadrilaterals: the error along the contact of free slip converges at a rate of
    at least 0.85."""
    errors = sheared_tube_errors("triangle", "enriched")["tangential_velocity"]
    assert fitted_rate(RATE_SIDES["triangle"], errors) >= 0.85


def test_the_triangles_heavier_ghost_viscosity_lets_free_slip_converge_along_the_contact():
    """What slows free slip's error along the contact on crossed triangles (the expected
    failure above) is a pattern along the contact that the cut cells send into the gases
    from their materials' extensions, which the ghost viscosity holds: at the triangles'
    default weight (GHOST_VISCOSITY, 1.0) the rate is 0.75 (0.53 at the quadrilaterals'
    0.3) and the error at 120² 0.54 times 0.3's; the density and normal velocity gain too
    (rates 0.80 and 0.74, against 0.71 and 0.66)."""
    default = sheared_tube_errors("triangle", "enriched")
    lighter = sheared_tube_errors("triangle", "enriched",
                                  f"interface.ghost_viscosity={GHOST_VISCOSITY['quadrilateral']}")
    assert fitted_rate(RATE_SIDES["triangle"], default["tangential_velocity"]) >= 0.7
    assert default["tangential_velocity"][-1] < 0.7 * lighter["tangential_velocity"][-1]
    for quantity in ("density", "normal_velocity"):
        assert fitted_rate(RATE_SIDES["triangle"], default[quantity]) > fitted_rate(RATE_SIDES["triangle"],
                                                                                      lighter[quantity]) + 0.05


def slip_line(model, cell="quadrilateral", side=40):
    return run_with_exact_errors("slip-line", side, cell, model)


@pytest.mark.parametrize("cell, bound", [("quadrilateral", 0.65), ("triangle", 0.7)])
def test_a_steady_slip_line_keeps_its_jump_with_free_slip(cell, bound):
    """The slip-line scene: two gases at one pressure, at rest along their contact's
    normal, sliding along it at ±0.25 (nothing should change).  Free slip keeps the
    tangential jump that one velocity field smears: its error along the contact is below
    one velocity field's — 0.49 of it on quadrilaterals at 40², 0.53 on crossed triangles,
    where free slip's error along the contact converges slowly on the sheared tube; mass,
    momentum and energy are kept to round-off."""
    free, single = slip_line("enriched", cell), slip_line("single_velocity", cell)
    assert free.errors["L1_tangential_velocity"] < bound * single.errors["L1_tangential_velocity"]
    assert abs(free.conservation["mass"]) < 1e-14 and abs(free.conservation["momentum"]) < 1e-12
    assert abs(free.conservation["total_energy"]) < 1e-13


@pytest.mark.parametrize("cell", ["quadrilateral", "triangle"])
def test_one_step_of_a_steady_slip_line_leaves_the_cells_material_volumes_nearly_as_they_were(cell):
    """The slip line on 24² Eulerian cells: its interface does not move, so no cell's
    material volumes should change.  The edges that Γ cuts turn in the Lagrange step (each
    end moves with its own material) and their swept regions are bow-ties, whose two lobes
    the remap takes each from its own side: after one step the changes within 0.3 of the
    centre add up to 0.0029 and 0.0002 h² (quadrilaterals, triangles), the largest 4.8 ×
    10⁻⁴ and 7.9 × 10⁻⁵ h²; with each bow-tie from one donor they were 0.047 and 0.031 h², the
    largest 6.6 and 2.6 × 10⁻³ h²."""
    problem = build_problem(load_scene(resolve_scene_path("slip-line"), ["mesh.cells=[24,24]",
                                                                          f"mesh.cell_type={cell}"]))
    before = by_material(problem.state.material_volume, problem.layout.cell_material)[0]
    result = simulate(problem, stop_after_steps=1)
    assert result.status == "ok" and result.steps == 1
    after = by_material(result.state.material_volume, problem.layout.cell_material)[0]
    centre = problem.mesh.cell_centroids(result.state.node_position)
    near = np.hypot(centre[:, 0] - 0.5, centre[:, 1] - 0.5) < 0.3
    change = np.abs(after - before)[near] * 24**2  # in h²
    assert change.sum() < 0.02 and change.max() < 1e-3, (change.sum(), change.max())


@pytest.mark.parametrize("cell", ["quadrilateral", "triangle"])
def test_one_step_of_the_spinning_disk_brings_no_fleck_of_the_fluid_into_the_disk(cell):
    """The spinning disk on 40² Eulerian cells: the disk turns in place, so after one step
    no cell wholly inside it should hold any of the fluid.  Near a node a swept region
    reaches out of its mixed donor; that part is split by the donor's interface line,
    extended: no cell inside the disk takes any fluid (the disk's volumes change by
    0.033 h² in all on quadrilaterals, 0.011 h² on triangles).  Shared by the donor's
    volume fractions, it put flecks of the fluid into 28 and 32 cells inside the disk
    (quadrilaterals, triangles; 0.066 h² in all on quadrilaterals), and the disk lost more
    of its angular momentum the finer the mesh."""
    problem = build_problem(load_scene(resolve_scene_path("spinning-disk"), [
        "mesh.cells=[40,40]", f"mesh.cell_type={cell}", "interface.model=enriched"]))
    disk = list(problem.scene.materials).index("disk")
    before = by_material(problem.state.material_volume, problem.layout.cell_material)
    result = simulate(problem, stop_after_steps=1)
    assert result.status == "ok" and result.steps == 1
    after = by_material(result.state.material_volume, problem.layout.cell_material)
    inside = (before[disk] > 0.0) & (before[1 - disk] == 0.0)
    assert inside.sum() > 100 and np.count_nonzero(after[1 - disk, inside]) == 0
    if cell == "quadrilateral":
        assert np.abs(after[disk] - before[disk]).sum() * 40**2 < 0.05


def test_a_node_tied_at_a_wall_keeps_the_interface_solve_well_posed():
    """The sheared tube on crossed triangles (16², 20², 24²), where Γ reaches the bottom
    wall between pure cells of the two materials: the wall's node there has pure cells of
    both around it and is tied whole, its held component an unknown of its own.  Tied by
    its normal part only (each material keeping a tangential unknown), the wall's inertia
    of 10²⁰ mixed into every unknown of the node and its round-off swamped the free
    direction: the interface solve gave every mixed cell wrong volume changes, the step
    was halved again and again and the runs stopped (the time step collapsed).  Now each
    runs to its end without one halved step, in 24, 30 and 35 steps."""
    for side in (16, 20, 24):
        _, result = run_scene("rotated-tube-shear", f"mesh.cells=[{side},{side}]", "mesh.cell_type=triangle",
                              "interface.model=enriched")
        assert result.status == "ok", (side, result.diagnostic)
        assert result.mixed_cells["halved_steps"] == 0 and result.steps < 2 * side, (side, result.steps)


def lagrangian_slip_line(cell, side, t_end, model="enriched"):
    return run_scene("slip-line", f"mesh.cells=[{side},{side}]", f"mesh.cell_type={cell}", "mesh.motion=lagrangian",
                     f"t_end={t_end}", f"interface.model={model}")


@functools.lru_cache(maxsize=None)
def slip_line_by_motion(cell):
    """The steady slip line on 32² cells to t = 0.05 (a slide of 0.025, 0.8 of a cell):
    free slip on a Lagrangian mesh (its problem and result), one velocity field on it, free
    slip on an Eulerian mesh (their results)."""
    return (*lagrangian_slip_line(cell, 32, 0.05), lagrangian_slip_line(cell, 32, 0.05, "single_velocity")[1],
            run_scene("slip-line", "mesh.cells=[32,32]", f"mesh.cell_type={cell}", "t_end=0.05")[1])


@pytest.mark.parametrize("cell, bound", [("quadrilateral", 0.6), ("triangle", 0.7)])
def test_a_lagrangian_mesh_carries_a_slip_line_while_the_slide_stays_below_a_cell(cell, bound):
    """The steady slip line on a Lagrangian mesh of 32² cells (each node moving with the
    material it lies in, each step remapped in place) to t = 0.05, a slide of 0.025 (0.8
    of a cell): the cut cells shear but hold Γ; free slip keeps the tangential jump (its
    error 0.53 and 0.52 of one velocity field's on the same mesh, quadrilaterals and
    triangles), and mass, momentum and energy are kept to round-off."""
    problem, free, single, _ = slip_line_by_motion(cell)
    assert free.status == "ok" and "remap_lagrangian" in problem.effects
    assert free.errors["L1_tangential_velocity"] < bound * single.errors["L1_tangential_velocity"]
    assert abs(free.conservation["mass"]) < 1e-14 and abs(free.conservation["momentum"]) < 1e-14
    assert abs(free.conservation["total_energy"]) < 1e-13 and abs(free.conservation["material_mass"]) < 1e-14


@pytest.mark.parametrize("cell", [pytest.param("quadrilateral", marks=pytest.mark.xfail(strict=True, reason=(
    "on a Lagrangian mesh of quadrilaterals the slip line's density, pressure and normal velocity errors are "
    "8.06, 3.27 and 2.43 times the Eulerian run's (32², t = 0.05; triangles 1.14, 1.11, 0.83): its contact "
    "passes through a node, and Youngs' normals (1.6° off on these quadrilaterals, exact on triangles) "
    "misplace the PLIC lines in the sheared cut cells (61 % of the density error at points of the wrong "
    "material); off the nodes, or with interface.normal = 'lvira', the check holds (the tests below): "
    "docs/design.md §4"))), "triangle"])
def test_a_lagrangian_mesh_gives_the_eulerian_meshs_figures_on_a_slip_line(cell):
    """The slip line below a cell of slide (as above): a Lagrangian mesh gives the
    Eulerian run's density and pressure errors within twice them, its normal velocity's
    within 1.1 times (triangles: 1.14, 1.11 and 0.83 times)."""
    _, free, _, eulerian = slip_line_by_motion(cell)
    for quantity, factor in (("L1_density", 2.0), ("L1_normal_velocity", 1.1), ("L1_pressure", 2.0)):
        assert free.errors[quantity] < factor * eulerian.errors[quantity], quantity


# where the slip line's contact crosses the row of nodes y = 0.5: through the node (0.5, 0.5)
# as shipped, or 0.1, 0.3, 0.5 of a 32² cell off it
CONTACT_POINTS = {"through a node": "[0.5,0.5]", "0.1 cell off": "[0.503125,0.5]", "0.3 cell off": "[0.509375,0.5]",
                  "0.5 cell off": "[0.515625,0.5]"}


@functools.lru_cache(maxsize=None)
def quadrilateral_slip_line(where, motion, normal):
    """The steady slip line on 32² quadrilaterals to t = 0.05 (a slide of 0.8 cell), its
    contact through ``where`` (CONTACT_POINTS), PLIC's normals ``normal``: the result."""
    return run_scene("slip-line", "mesh.cells=[32,32]", f"mesh.motion={motion}", "t_end=0.05",
                     f"regions.1.half_plane.point={CONTACT_POINTS[where]}", f'interface.normal="{normal}"')[1]


@pytest.mark.parametrize("where", ["0.1 cell off", "0.3 cell off", "0.5 cell off"])
def test_a_lagrangian_mesh_of_quadrilaterals_carries_a_slip_line_that_misses_the_nodes(where):
    """The quadrilaterals' failure above is that of a contact through a node, with Youngs'
    normals: moved off the nodes, the Lagrangian run passes the same check, its density,
    normal-velocity and pressure errors within 2, 1.1 and 2 times the Eulerian run's (1.08 to
    1.27, 0.83 to 0.96 and 0.94 to 1.04 measured at these three places; the density's
    depends on where the contact lies: 2.38 times at 0.0992 cell off)."""
    lagrangian = quadrilateral_slip_line(where, "lagrangian", "youngs").errors
    eulerian = quadrilateral_slip_line(where, "eulerian", "youngs").errors
    for quantity, factor in (("L1_density", 2.0), ("L1_normal_velocity", 1.1), ("L1_pressure", 2.0)):
        assert lagrangian[quantity] < factor * eulerian[quantity], (quantity, lagrangian[quantity], eulerian[quantity])


@pytest.mark.parametrize("where", list(CONTACT_POINTS))
def test_lvira_normals_let_a_lagrangian_mesh_give_the_eulerian_meshs_figures_on_a_slip_line(where):
    """``[interface] normal = "lvira"`` (exact for a straight line, where Youngs' errs by
    about 1.6° on these quadrilaterals): through the node, the check that fails above with
    Youngs' normals (8.06, 2.43, 3.27 times) holds, the Lagrangian run's errors within 2,
    1.1 and 2 times the Eulerian run's (1.36, 1.05, 1.28); off the nodes LVIRA's pressure and
    normal-velocity errors are below 0.6 of Youngs' on both meshes (0.35 to 0.53 measured);
    mass and momentum kept to round-off."""
    lagrangian = quadrilateral_slip_line(where, "lagrangian", "lvira")
    eulerian = quadrilateral_slip_line(where, "eulerian", "lvira")
    assert lagrangian.status == "ok"
    assert abs(lagrangian.conservation["mass"]) < 1e-14 and abs(lagrangian.conservation["momentum"]) < 1e-14
    if where == "through a node":
        for quantity, factor in (("L1_density", 2.0), ("L1_normal_velocity", 1.1), ("L1_pressure", 2.0)):
            assert lagrangian.errors[quantity] < factor * eulerian.errors[quantity], quantity
        return
    for motion, result in (("lagrangian", lagrangian), ("eulerian", eulerian)):
        youngs = quadrilateral_slip_line(where, motion, "youngs").errors
        for quantity in ("L1_pressure", "L1_normal_velocity"):
            assert result.errors[quantity] < 0.6 * youngs[quantity], (motion, quantity)


def test_a_slide_of_more_than_a_cell_on_a_lagrangian_mesh_stops_with_a_diagnostic():
    """The slip line on 8² Lagrangian cells for a slide of 0.3 (2.4 cells): the run stops
    cleanly once the slide has sheared the cut cells past what they hold (2.1 cells at t =
    0.52, measured), naming the way out, with its last good state conserved."""
    _, result = lagrangian_slip_line("quadrilateral", 8, 0.6)
    assert result.status == "failed" and 'mesh.motion = "smoothed" or "eulerian"' in result.diagnostic
    assert 1 / 8 < result.state.time < 0.6  # a slide of 0.5 t: more than half a cell
    assert abs(result.conservation["mass"]) < 1e-14 and abs(result.conservation["momentum"]) < 1e-13


@pytest.mark.parametrize("cell", ["quadrilateral", "triangle"])
def test_free_slip_leaves_the_rest_of_a_steady_slip_line_as_one_velocity_field_does(cell):
    """Away from the tangential jump a steady slip line has nothing to get wrong: free
    slip's density, pressure and normal-velocity errors are at most one velocity field's
    (40²: 0.63, 0.38 and 0.19 of them on quadrilaterals, 0.19, 0.23 and 0.12 on crossed
    triangles).  With the explicit predictor accelerating the mixed cells' nodes by the
    mesh's forces (EnrichedClosure2D.hold_predictor) free slip's pressure error on
    quadrilaterals was 1.17 times one velocity field's."""
    free, single = slip_line("enriched", cell), slip_line("single_velocity", cell)
    for quantity in ("L1_density", "L1_pressure", "L1_normal_velocity"):
        assert free.errors[quantity] <= single.errors[quantity]


def test_identical_materials_on_both_sides_do_no_harm():
    """The rotated Sod tube with the same gas (γ = 1.4) on both sides of a contact that
    cuts cells of an Eulerian mesh: enriched cells (bubbles or Nitsche) give L1 errors
    against the exact solution within a fifth of those of the run where both sides are one
    material (no interface at all).  Over 16², 24², 32², 48², 64² their velocity error is
    1.06 to 1.17 times one material's, not falling with resolution (bubbles 1.15, 1.14,
    1.07, 1.06, 1.10); density and pressure 0.85 to 1.05 (the interface,
    reconstructed and remapped material by material, keeps the contact's density jump
    sharper than one material's remap does)."""
    base = ["mesh.cells=[16,16]", "mesh.motion=eulerian", "materials.right.gamma=1.4"]
    single = tomllib.loads(resolve_scene_path("rotated-tube").read_text())
    single["mesh"].update(cells=[16, 16], motion="eulerian")
    single["materials"]["right"]["gamma"] = 1.4
    single["regions"][1]["material"] = "right"
    del single["interface"]  # (one material: an [interface] table would be an error)
    one = simulate(build_problem(validate(single)))
    assert one.mixed_cells is None or one.mixed_cells["count"] == 0
    for stabilisation in ("bubble", "nitsche"):
        two = simulate(build_problem(load_scene(resolve_scene_path("rotated-tube"), base + [
            'interface.model="enriched"', f'interface.stabilisation="{stabilisation}"'])))
        assert two.status == "ok" and two.mixed_cells["count"] > 0
        for field in ("L1_density", "L1_velocity", "L1_pressure"):
            assert two.errors[field] < 1.2 * one.errors[field], (stabilisation, field)


def test_cut_cells_that_appear_during_the_run_take_over_the_materials_velocities():
    """An interface on mesh edges at t = 0 (no cell cut) that the flow moves into cells of
    an Eulerian mesh: each material has its own velocity from the start (equal corner
    shares), the first cut cells take them over, and mass, momentum and total energy stay
    conserved."""
    data = {"name": "aligned", "dimension": 2, "t_end": 0.05,
            "mesh": {"extent": [[0.0, 1.0], [0.0, 0.25]], "cells": [16, 4], "motion": "eulerian"},
            "materials": {"left": {"eos": "ideal_gas", "gamma": 1.4}, "right": {"eos": "ideal_gas", "gamma": 1.667}},
            "regions": [{"material": "right", "box": [[0.0, 1.0], [0.0, 0.25]], "density": 0.125, "pressure": 0.1},
                        {"material": "left", "box": [[0.0, 0.5], [0.0, 0.25]], "density": 1.0, "pressure": 1.0}],
            "interface": {"model": "enriched"}}
    problem = build_problem(validate(data))
    assert problem.mixed is None and problem.state.material_node_velocity is not None
    result = simulate(problem)
    assert result.status == "ok" and result.mixed_cells["count"] > 0 and result.mixed_cells["solves"] > 0
    assert abs(result.conservation["mass"]) < 1e-15 and abs(result.conservation["momentum"]) < 1e-10
    assert abs(result.conservation["total_energy"]) < 1e-6


def test_a_light_disk_spinning_in_a_fluid_a_hundred_times_heavier_stays_steady():
    """A hard case: the spinning disk inside an outer fluid of density 100 on 80² crossed
    triangles, to t = 0.4.  Each material's extension over the other's part is held by a
    ghost viscosity (the triangles' default, 1.0 of its inertia in the cell; it runs at 0.1
    too, since the explicit predictor holds the mixed cells' nodes: moved by the mesh's
    forces, the rim nodes' velocities wandered outwards and drained the disk's cells there
    until the EOS left its domain).  The run finishes with the disk's angular momentum kept
    within 2 % and its mass to round-off."""
    problem = build_problem(load_scene(resolve_scene_path("spinning-disk"), [
        "mesh.cells=[80,80]", "mesh.cell_type=triangle", "interface.model=enriched", "regions.0.density=100",
        "t_end=0.4"]))
    disk = list(problem.scene.materials).index("disk")
    start = material_angular_momenta(problem.state, problem.layout, problem.mesh.cell_nodes, None, (0.5, 0.5))
    result = simulate(problem)
    assert result.status == "ok", result.diagnostic
    end = material_angular_momenta(result.state, problem.layout, problem.mesh.cell_nodes, None, (0.5, 0.5))
    assert abs(end[disk] / start[disk] - 1.0) < 0.02, end / start[disk]
    assert abs(result.conservation["material_mass"]) < 1e-13


@pytest.mark.parametrize("cell", ["quadrilateral", "triangle"])
def test_a_shock_through_a_heavy_disk_on_a_smoothed_mesh(cell):
    """A hard case: a Mach 2 shock in air reaching a disk of stiffened gas five times
    denser, a piston behind it, the mesh smoothed (ALE): enriched cells (bubbles) finish,
    every material keeps its mass, momentum balances the piston's and the walls' impulse,
    and the energy the run makes or loses stays below 10⁻³ of the total."""
    problem = build_problem(load_scene(resolve_scene_path("shock-disk"), [
        "mesh.cells=[32,16]", 'interface.model="enriched"', f'mesh.cell_type="{cell}"']))
    result = simulate(problem)
    assert result.status == "ok" and result.mixed_cells["solves"] == result.steps
    assert abs(result.conservation["material_mass"]) < 1e-14
    assert abs(result.conservation["momentum"]) < 1e-8
    assert abs(result.conservation["total_energy"]) < 1e-3


def test_a_shock_through_a_heavy_disk_on_finer_triangles():
    """The hard case above on 100 × 50 crossed triangles, to t = 0.2: the run finishes,
    total energy kept to round-off.  It broke down at the disk's top at t = 0.17 (a
    remapped sound speed NaN) while the pure cells next to the mixed cells took the work of
    their forces on their material's velocity where the air's slid past a node of theirs,
    but their areas from the mesh, which moves with the air there: two pure cells of the
    disk drifted apart, one to tension below −p∞.  The material's crossings of the edges
    between such cells keep their volumes consistent (EnrichedClosure2D._crossings)."""
    problem = build_problem(load_scene(resolve_scene_path("shock-disk"), [
        "mesh.cells=[100,50]", 'interface.model="enriched"', 'mesh.cell_type="triangle"', "t_end=0.2"]))
    result = simulate(problem)
    assert result.status == "ok", result.diagnostic
    assert abs(result.conservation["total_energy"]) < 1e-12 * result.conservation["energy_scale"]


@pytest.mark.parametrize("cell", ["quadrilateral", "triangle"])
def test_a_band_around_the_interface_gives_the_run_of_a_system_bound_to_the_mixed_cells_alone(cell, monkeypatch):
    """The interface system bound to a band (the mixed cells and two rings around them)
    and active on the mixed cells only solves the same equations as one bound to the mixed
    cells themselves (a band of no rings, bound again at every change), having bound far
    fewer submeshes: on quadrilaterals the sheared tube ends in the same state (1e-13 measured).  On
    triangles the two runs agree to 3e-12 at each of their 21 steps, but a discrete choice
    that round-off can tip (as which material a node lies in, decided by an argmax) can
    move them apart (by 1e-5 at step 15 with the ghost viscosity at 0.3), so the check
    there allows 1e-4."""
    from ale_xfem.mixed import enriched_2d

    def run(rings):
        monkeypatch.setattr(enriched_2d, "BAND_RINGS", rings)
        problem = build_problem(load_scene(resolve_scene_path("rotated-tube-shear"),
                                           ["mesh.cells=[14,14]", 'interface.model="enriched"',
                                            f'mesh.cell_type="{cell}"']))
        result = simulate(problem)
        assert result.status == "ok"
        return result, problem.mixed.stats["bands"]

    banded, bands = run(2)
    alone, binds = run(0)
    assert banded.steps == alone.steps
    assert bands < binds / 2, (bands, binds)
    tolerance = 1e-10 if cell == "quadrilateral" else 1e-4
    for name in ("material_density", "material_pressure", "material_node_velocity"):
        a, b = getattr(banded.state, name), getattr(alone.state, name)
        assert np.abs(a - b).max() <= tolerance * np.abs(b).max(), name


@pytest.mark.parametrize("cell", ["quadrilateral", "triangle"])
def test_both_orders_of_the_materials_give_the_same_run(cell):
    """The interface system's α is material 0 of the scene: listing the disk first or the
    fluid first swaps α and β in every mixed cell (their weights, their rows, the normal's
    sign) and must change nothing — each material's angular momentum and the errors agree
    to round-off on quadrilaterals (1e-14 measured).  On crossed triangles a node often has
    as many pure cells of each material around it: its owner was the lower material id, and
    the fluid's angular momentum differed by 2 % of the disk's between the two orders; the
    tie now goes to the larger area, and the runs agree to round-off there too (at each of
    their 17 steps: angular momenta to 1e-15 of the disk's, L1(p) to 3e-13), but a discrete
    event that round-off can tip may still part them (with the ghost viscosity at 0.3, one
    at step 6 worth 1e-8 of the disk's angular momentum and 7e-6 of L1(p)), so the check
    there allows 1e-6."""
    def spinning(order):
        materials = {"outer": {"eos": "ideal_gas", "gamma": 1.4}, "disk": {"eos": "ideal_gas", "gamma": 1.667}}
        if order:
            materials = {"disk": materials["disk"], "outer": materials["outer"]}
        data = {"name": "spinning", "dimension": 2, "t_end": 0.1,
                "mesh": {"extent": [[0.0, 1.0], [0.0, 1.0]], "cells": [12, 12], "motion": "eulerian",
                         "cell_type": cell},
                "materials": materials,
                "regions": [{"material": "outer", "box": [[0.0, 1.0], [0.0, 1.0]], "density": 10.0, "pressure": 1.0},
                            {"material": "disk", "disk": {"center": [0.5, 0.5], "radius": 0.3}, "density": 1.0,
                             "pressure": 0.82, "rotation": {"center": [0.5, 0.5], "angular_velocity": 2.0}}],
                "interface": {"model": "enriched"}}
        problem = build_problem(validate(data))
        result = simulate(problem)
        assert result.status == "ok"
        momenta = material_angular_momenta(result.state, problem.layout, problem.mesh.cell_nodes, None, (0.5, 0.5))
        return result, dict(zip(problem.scene.materials, momenta))

    first, momenta_first = spinning(0)
    second, momenta_second = spinning(1)
    assert first.steps == second.steps
    scale = abs(momenta_first["disk"])
    tolerance = 1e-10 if cell == "quadrilateral" else 1e-6
    for name in ("outer", "disk"):
        assert abs(momenta_first[name] - momenta_second[name]) < tolerance * scale, name
    for key in ("L1_density", "L1_velocity", "L1_pressure"):
        assert first.errors[key] == pytest.approx(second.errors[key], rel=100 * tolerance), key


def test_a_remapped_2d_enriched_run_relaxes_its_cut_cells_and_reports_its_solves():
    """The sheared tube with enriched cells (Eulerian: every step remapped): the state each
    step ends with — remapped, then relaxed (paper §3) — has its cut cells' two pressures
    in balance, within what the relaxation leaves alone (10 × the interface tolerance of
    the larger pressure); summary.json's mixed-cell figures count one interface solve and
    at least one relaxation a step, and the predictor/corrector's iterations."""
    from ale_xfem.mixed.equilibrium import balanced_cells, cell_arrays
    from ale_xfem.output.files import summary

    problem, result = run_scene("rotated-tube-shear-enriched", "mesh.cells=[12,12]", "t_end=0.05")
    assert result.status == "ok" and result.steps >= 5
    state, cells = result.state, problem.mixed.cells
    pa, pb = state.material_pressure[0, cells], state.material_pressure[1, cells]
    bulk = [state.material_density[m, cells] * state.material_sound_speed[m, cells] ** 2 for m in range(2)]
    assert balanced_cells(*cell_arrays(pa.shape, pa, pb, *bulk), problem.mixed.tolerance)
    assert np.all(np.abs(pa - pb) <= 10 * problem.mixed.tolerance * np.maximum(pa, pb))
    figures = summary(problem, result)["mixed_cells"]
    assert figures["solves"] == result.steps and figures["relaxations"] >= result.steps
    assert 1 <= figures["iterations_mean"] <= figures["iterations_max"]


@pytest.mark.parametrize("stabilisation", ["bubble", "nitsche"])
def test_the_linearised_law_alone_solves_once_a_step_and_gives_the_corrected_runs_figures(stabilisation):
    """``interface.solver = "linearised"`` in 2D: the assembled system once a step, no
    corrector.  On the rotated tube (Eulerian, 20²: the shock leaves Γ at t = 0) it takes one
    iteration a solve where the corrector takes more than two on average, keeps total
    energy as the corrected run does, and its errors against the exact solution are the
    corrected run's within 1 % (0.006-0.7 % measured)."""
    runs = {}
    for solver in ("nonlinear", "linearised"):
        problem, result = run_scene("rotated-tube", "mesh.cells=[20,20]", "mesh.motion=eulerian",
                                    "interface.model=enriched", f"interface.stabilisation={stabilisation}",
                                    f"interface.solver={solver}")
        assert result.status == "ok"
        assert f"interface_solver_{solver}" in problem.effects
        assert abs(result.conservation["total_energy"]) < 1e-14
        runs[solver] = result
    corrected, linearised = runs["nonlinear"], runs["linearised"]
    assert corrected.mixed_cells["iterations_mean"] > 2.0
    assert linearised.mixed_cells["iterations_mean"] == linearised.mixed_cells["iterations_max"] == 1
    assert linearised.steps == corrected.steps
    for key in ("L1_density", "L1_velocity", "L1_pressure"):
        assert linearised.errors[key] == pytest.approx(corrected.errors[key], rel=0.01), key
    assert linearised.errors["L1_density"] != corrected.errors["L1_density"]
