"""The data model is dimension-generic: the same explicit loop on 2D quadrilaterals and
triangles, and the compiled corner forces equal to the assembled UFL weak form."""

import numpy as np
import pytest

from ale_xfem.eos import IdealGas
from ale_xfem.lagrange.wilkins import ExplicitWilkins
from ale_xfem.model.mesh import from_dolfinx, interval_mesh, rectangle_mesh
from ale_xfem.problem import side_boundaries, state_from_cells
from ale_xfem.scene import BoundarySpec, Numerics
from ale_xfem.model.state import Material, MaterialLayout
from forms.corner_forces import CornerForceForm

NUMERICS = Numerics(cfl=0.5, dt_growth=1.1, q_quadratic=1.0, q_linear=0.5, max_steps=10**6)


@pytest.mark.parametrize("cell_type", ["quadrilateral", "triangle"])
def test_uniform_state_stays_uniform_and_at_rest_in_2d(cell_type):
    extent = [[0.0, 2.0], [0.0, 1.0]]
    mesh = rectangle_mesh(extent, [12, 7], cell_type)
    materials = [Material("gas", "ideal_gas", IdealGas(1.4))]
    layout = MaterialLayout(np.zeros((1, mesh.n_cells), dtype=np.int64), 1)
    volume = mesh.cell_volumes()
    state, node_mass = state_from_cells(mesh, materials, layout, 1.3 * volume[None, :],
                                        np.full((1, mesh.n_cells), 2.0), np.zeros((2, mesh.n_cells)))
    specs = {side: BoundarySpec("wall") for side in ("left", "right", "bottom", "top")}
    stepper = ExplicitWilkins(mesh, materials, layout, node_mass,
                              side_boundaries(mesh, extent, specs), NUMERICS)
    evaluation = stepper.evaluate_state(state)
    for _ in range(200):
        dt = stepper.stable_time_step(evaluation)
        state, evaluation, work, _ = stepper.step(state, dt, evaluation)
        assert work == pytest.approx(0.0, abs=1e-13)
    assert np.abs(state.node_velocity).max() < 1e-12
    np.testing.assert_allclose(state.material_density, 1.3, rtol=1e-12)
    np.testing.assert_allclose(state.material_pressure, 0.4 * 1.3 * 2.0, rtol=1e-12)


def _perturbed(mesh, amplitude, seed=0):
    """Move interior nodes of the DOLFINx mesh at random, then read it again."""
    x = mesh.dolfinx_mesh.geometry.x
    rng = np.random.default_rng(seed)
    dim = mesh.dimension
    lo, hi = x[:, :dim].min(axis=0), x[:, :dim].max(axis=0)
    interior = np.all((x[:, :dim] > lo + 1e-12) & (x[:, :dim] < hi - 1e-12), axis=1)
    x[interior, :dim] += amplitude * rng.uniform(-1, 1, size=(interior.sum(), dim))
    return from_dolfinx(mesh.dolfinx_mesh)


def _compiled(mesh, x, u, stress, coefficient=0.0, rho=None, c=None):
    """What the step's compiled kernels give on a mesh: (volume, shape, CFL length, velocity
    jump, corner forces (dim, k, n), the nodal forces (dim, n_nodes) of each way of summing
    the corners the mesh allows, hourglass (s0, s1, Q), the velocity's combinations)."""
    from ale_xfem.lagrange import kernels
    from ale_xfem.model.cell_kernels import CELL_TYPE_CODES, corner_runs, quad_combinations

    n, k, dim = mesh.n_cells, mesh.cell_type.nodes_per_cell, mesh.dimension
    code, nodes = CELL_TYPE_CODES[mesh.cell_type.name], np.ascontiguousarray(mesh.cell_nodes)
    runs, none = corner_runs(nodes), np.zeros(0)
    volume, shape, length, jump = np.empty(n), np.empty((3, 2, n if dim > 1 else 0)), np.empty(n), np.empty(n)
    combos = np.empty((3, u.shape[0], n if k == 4 else 0))
    if k == 4:
        quad_combinations(u, nodes, runs, True, combos)
    kernels.geometry_and_rates(code, x, u, combos, nodes, runs, True, dim > 1, False, none, volume, shape, none,
                               length, none, jump)
    rho = np.ones(n) if rho is None else rho
    c = np.ones(n) if c is None else c
    hourglass = (np.empty(n), np.empty(n), np.empty((2, n)))
    rows = np.empty((dim, k, n))
    kernels.stress_and_corner_forces(code, volume, shape, combos, jump, rho, c, stress, 1.0, 0.5, False,
                                     np.zeros(0, dtype=np.int64), none, none, none, coefficient > 0, coefficient > 0,
                                     coefficient, *hourglass, np.empty(n), np.empty(n), rows)
    forces = []
    for mode in ((kernels.RUNS,) if mesh.corners.grid is not None or mesh.corners.all_slices
                 else (kernels.PER_CORNER, kernels.FLAT)):
        forces.append(np.empty((dim, mesh.n_nodes)))
        kernels.scatter_corners(code, stress, rows, nodes, runs, mode, np.zeros(k, dtype=bool),
                                np.empty(mesh.n_nodes), forces[-1])
    if dim == 1:
        rows[0] = [-stress, stress]
        length = volume
    return volume, shape, length, jump, rows, forces, hourglass, combos


@pytest.mark.parametrize("make", [lambda: interval_mesh([0.0, 1.0], 9),
                                  lambda: rectangle_mesh([[0.0, 1.0], [0.0, 1.0]], [5, 4], "quadrilateral"),
                                  lambda: rectangle_mesh([[0.0, 1.0], [0.0, 1.0]], [5, 4], "triangle")],
                         ids=["interval", "quadrilateral", "triangle"])
def test_compiled_corner_forces_equal_the_assembled_weak_form(make):
    mesh = _perturbed(make(), 0.04)
    stress = np.random.default_rng(1).uniform(0.5, 2.0, mesh.n_cells)
    form_forces = CornerForceForm(mesh.dolfinx_mesh).nodal_forces(stress, mesh.n_nodes)
    for forces in _compiled(mesh, mesh.node_position, np.zeros((mesh.dimension, mesh.n_nodes)), stress)[5]:
        np.testing.assert_allclose(forces, form_forces, atol=1e-13 * np.abs(form_forces).max())
    assert np.abs(form_forces).max() > 0.1


def test_cell_volumes_sum_to_the_domain_and_cells_are_counter_clockwise():
    for cell_type in ("quadrilateral", "triangle"):
        mesh = rectangle_mesh([[0.0, 3.0], [0.0, 2.0]], [6, 5], cell_type)
        volume = mesh.cell_volumes()
        assert volume.min() > 0
        assert volume.sum() == pytest.approx(6.0, rel=1e-14)


def test_quadrilateral_two_corner_kernel_equals_the_textbook_corner_sums():
    """The compiled quadrilateral kernels (two independent corners) give the shoelace area
    and gradient, Flanagan–Belytschko's hourglass forces written corner by corner
    (γ_i = h_i − (Σ_j h_j x_j)·∇_i A / A), the compatible work of the corner forces, the
    volume rate and the CFL length from the medians, on a perturbed mesh with random
    velocities."""
    from ale_xfem.lagrange import kernels
    from ale_xfem.model.cell_kernels import CELL_TYPE_CODES, corner_runs
    from ale_xfem.model.mesh import _polygon_geometry

    mesh = _perturbed(rectangle_mesh([[0.0, 1.0], [0.0, 1.0]], [6, 5], "quadrilateral"), 0.05)
    rng = np.random.default_rng(3)
    x = mesh.corners.gather(mesh.node_position)
    velocity = rng.normal(size=(2, mesh.n_nodes))
    u = mesh.corners.gather(velocity)
    rho, c, kappa = rng.uniform(1, 2, mesh.n_cells), rng.uniform(1, 2, mesh.n_cells), 0.3
    stress = rng.uniform(0.5, 2.0, mesh.n_cells)
    area, shape, length, jump, rows, _, hourglass, combos = _compiled(mesh, mesh.node_position, velocity, stress,
                                                                      kappa, rho, c)
    shoelace_area, shoelace_gradient = _polygon_geometry(x)
    np.testing.assert_allclose(area, shoelace_area, rtol=1e-14)
    h = (1.0, -1.0, 1.0, -1.0)
    hourglass_shape = [sum(h[j] * x[j][d] for j in range(4)) for d in range(2)]
    gamma = [h[i] - (hourglass_shape[0] * shoelace_gradient[i][0] + hourglass_shape[1] * shoelace_gradient[i][1])
             / area for i in range(4)]
    expected = []
    for i in range(4):
        q = [sum(gamma[j] * u[j][d] for j in range(4)) for d in range(2)]
        expected.append([-0.25 * kappa * rho * c * np.sqrt(area) * q[d] * gamma[i] for d in range(2)])
    for d in range(2):
        for i in range(4):
            np.testing.assert_allclose(rows[d, i], stress * shoelace_gradient[i][d] + expected[i][d], atol=1e-13)
    # the compatible work of these forces on the velocities, Σ_i F_i·u_i: the energy update
    # with dt = 2 and unit masses from e = 0 gives −Σ_i F_i·u_i
    work = np.empty(mesh.n_cells)
    kernels.compatible_energy(CELL_TYPE_CODES["quadrilateral"], np.ascontiguousarray(mesh.cell_nodes),
                              corner_runs(mesh.cell_nodes), np.zeros(mesh.n_cells), np.ones(mesh.n_cells), 2.0,
                              shape, stress, shape, stress, False, True, *hourglass, velocity, combos, work)
    expected_work = sum((stress * shoelace_gradient[i][d] + expected[i][d]) * u[i][d]
                        for i in range(4) for d in range(2))
    np.testing.assert_allclose(-work, expected_work, atol=1e-13)
    rate = sum(shoelace_gradient[i][d] * u[i][d] for i in range(4) for d in range(2))
    np.testing.assert_allclose(jump * np.sqrt(area), rate, atol=1e-13)
    medians = [np.hypot(x[2][0] + x[3][0] - x[0][0] - x[1][0], x[2][1] + x[3][1] - x[0][1] - x[1][1]),
               np.hypot(x[3][0] + x[0][0] - x[1][0] - x[2][0], x[3][1] + x[0][1] - x[1][1] - x[2][1])]
    np.testing.assert_allclose(length, area / (0.5 * np.maximum(*medians)), rtol=1e-14)


def test_a_rectangle_numbered_as_a_grid_reads_its_corners_from_views_and_maps_back_to_dolfinx(tmp_path):
    """A rectangle of quadrilaterals is numbered row by row (Corners' strided views): its
    corner combinations and scatters equal the indexed ones on the same cells, its nodes and
    cells map back to DOLFINx's, and the VTK series writes each field at its own node and
    cell (a velocity linear in the position and the density come back where they belong)."""
    import pyvista

    from ale_xfem.output.cells_2d import VTKSeries
    from ale_xfem.model.mesh import Corners, QuadCorners
    from ale_xfem.run import simulate

    mesh = rectangle_mesh([[0.0, 2.0], [0.0, 1.0]], [7, 5], "quadrilateral")
    assert mesh.grid == (7, 5)
    indexed = Corners(mesh.cell_nodes, mesh.n_nodes)  # the same cells through index arrays
    rng = np.random.default_rng(5)
    field = rng.normal(size=(2, mesh.n_nodes))
    from_views, gathered = mesh.corners.quad_corners(field), QuadCorners.gathered(indexed.gather(field))
    for name in QuadCorners.__slots__:
        np.testing.assert_array_equal(getattr(from_views, name), getattr(gathered, name))
    for cells in ([1, 4], [6, 1], [1, 1]):  # a single column, row or cell: the ends of the slices
        thin = rectangle_mesh([[0.0, 2.0], [0.0, 1.0]], cells, "quadrilateral")
        thin_field = rng.normal(size=(2, thin.n_nodes))
        from_views = thin.corners.quad_corners(thin_field)
        gathered = QuadCorners.gathered(Corners(thin.cell_nodes, thin.n_nodes).gather(thin_field))
        for name in QuadCorners.__slots__:
            np.testing.assert_array_equal(getattr(from_views, name), getattr(gathered, name))
    rows = rng.normal(size=(4, mesh.n_cells))
    np.testing.assert_allclose(mesh.corners.scatter(list(rows)), indexed.scatter(list(rows)), atol=1e-15)
    # the step's compiled scatter: corner by corner along the grid's rows (each corner's
    # nodes distinct), or one running sum through the index array
    from ale_xfem.lagrange import kernels
    from ale_xfem.model.cell_kernels import QUADRILATERAL, corner_runs

    by_runs, flat = np.empty((1, mesh.n_nodes)), np.empty((1, mesh.n_nodes))
    for mode, out in ((kernels.RUNS, by_runs), (kernels.FLAT, flat)):
        kernels.scatter_corners(QUADRILATERAL, np.zeros(mesh.n_cells), rows[None], mesh.cell_nodes,
                                corner_runs(mesh.cell_nodes), mode, np.zeros(4, dtype=bool), np.empty(mesh.n_nodes),
                                out)
    np.testing.assert_allclose(by_runs[0], mesh.corners.scatter(list(rows)), atol=1e-15)
    np.testing.assert_allclose(flat[0], mesh.corners.scatter(list(rows)), atol=1e-15)
    x = mesh.dolfinx_mesh.geometry.x
    np.testing.assert_array_equal(x[mesh.dolfinx_node, :2].T, mesh.node_position)
    dolfinx_cells = np.asarray(mesh.dolfinx_mesh.geometry.dofmaps[0])[mesh.dolfinx_cell]
    np.testing.assert_array_equal(np.sort(dolfinx_cells, axis=1), np.sort(mesh.dolfinx_node[mesh.cell_nodes], axis=1))

    from ale_xfem.problem import build_problem
    from ale_xfem.scene import load_scene, resolve_scene_path

    problem = build_problem(load_scene(resolve_scene_path("noh"), ["mesh.cells=[6,4]"]))
    state = simulate(problem, stop_after_steps=3).state
    position = state.node_position
    state.node_velocity[:] = np.stack([position[0], 2.0 * position[1]])
    series = VTKSeries(problem, tmp_path, frames=1)
    series.write(state, problem)
    series.close()
    written = pyvista.read(str(tmp_path / "noh_0000.vtu"))
    np.testing.assert_allclose(written.point_data["velocity"][:, :2], written.points[:, :2] * [1.0, 2.0], atol=1e-14)
    expected = state.material_mass.sum(axis=0) / problem.mesh.cell_volumes(position)
    centres = written.cell_centers().points[:, :2]
    np.testing.assert_allclose(centres, problem.mesh.cell_centroids(position), atol=1e-14)
    np.testing.assert_allclose(written.cell_data["density"], expected, rtol=1e-14)
    assert np.ptp(expected) > 0.1  # Noh's cells differ


@pytest.mark.parametrize("cell", ["quadrilateral", "triangle"])
def test_the_vtx_files_hold_each_cells_fields_and_each_nodes_velocity(tmp_path, cell):
    """The VTX files (ParaView's ADIOS2 reader; ale_xfem/output/vtx.py) of a moved state:
    read back by the serial cell numbers and node numbers they carry, each cell's nodes are
    the mesh's, each cell field is the VTK series' (cells_2d.cell_fields) and each node's
    velocity and position the state's."""
    from vtx_files import read_cells, read_velocity

    from ale_xfem.output.cells_2d import cell_fields
    from ale_xfem.output.vtx import VTXFiles
    from ale_xfem.problem import build_problem
    from ale_xfem.run import simulate
    from ale_xfem.scene import load_scene, resolve_scene_path

    problem = build_problem(load_scene(resolve_scene_path("noh"), ["mesh.cells=[6,4]", f"mesh.cell_type={cell}"]))
    state = simulate(problem, stop_after_steps=3).state
    position = state.node_position
    state.node_velocity[:] = np.stack([position[0], 2.0 * position[1]])
    files = VTXFiles(problem, tmp_path)
    files.write(state, problem)
    files.close()
    (cells,), (nodes,) = read_cells(tmp_path / "noh-cells.bp"), read_velocity(tmp_path / "noh-velocity.bp")
    assert cells["time"] == nodes["time"] == state.time
    np.testing.assert_array_equal(cells["cell"], np.arange(problem.mesh.n_cells))
    np.testing.assert_array_equal(cells["cell_nodes"], problem.mesh.cell_nodes)  # (going round)
    np.testing.assert_array_equal(cells["position"][:, :2], position.T)
    for name, values in cell_fields(problem, state).items():
        np.testing.assert_array_equal(cells[name], values, err_msg=name)
    np.testing.assert_array_equal(nodes["velocity"][:, :2], state.node_velocity.T)
    np.testing.assert_allclose(nodes["position"][:, :2], position.T, rtol=0.0, atol=1e-15)
