"""Scene validation: every bad input is one line naming key, value and what is allowed;
the CLI exits with code 2 and writes nothing."""

import copy
import subprocess
import sys
import tomllib

import pytest
import tomli_w

from ale_xfem.scene import SceneError, load_scene, resolve_scene_path, shipped_scenes, validate

BASE = tomllib.loads(resolve_scene_path("sod-two-gamma").read_text())


def modified(change):
    data = copy.deepcopy(BASE)
    change(data)
    return data


def set_path(data, path, value):
    *parents, last = path
    for key in parents:
        data = data[key]
    data[last] = value


BAD = {
    "unknown key": (lambda d: set_path(d, ["mesh", "celss"], 10), "mesh.celss", "unknown key"),
    "unknown top-level key": (lambda d: d.update(t_final=1.0), "t_final", "unknown key"),
    "wrong type": (lambda d: set_path(d, ["mesh", "cells"], "many"), "mesh.cells", "integer"),
    "wrong type, list": (lambda d: set_path(d, ["mesh", "extent"], 1.0), "mesh.extent", "list of 2"),
    "missing key": (lambda d: d["regions"][0].pop("density"), "regions[0].density", "required"),
    "missing table": (lambda d: d.pop("materials"), "materials", "required"),
    "non-positive density": (lambda d: set_path(d, ["regions", 1, "density"], 0.0),
                             "regions[1].density", "> 0"),
    "non-positive pressure of an ideal gas": (lambda d: set_path(d, ["regions", 0, "pressure"], -1.0),
                                              "regions[0].pressure", "pressure > 0"),
    "gamma out of range": (lambda d: set_path(d, ["materials", "left", "gamma"], 1.0),
                           "materials.left.gamma", "> 1"),
    "unknown eos": (lambda d: set_path(d, ["materials", "left", "eos"], "perfect"),
                    "materials.left.eos", "one of ideal_gas"),
    "eos parameter of another model": (lambda d: set_path(d, ["materials", "left", "p_inf"], 1.0),
                                       "materials.left.p_inf", "unknown key"),
    "domain not covered": (lambda d: set_path(d, ["regions", 1, "interval"], [0.6, 1.0]),
                           "regions", "cover the whole domain"),
    "region covering nothing": (lambda d: d["regions"].append(dict(d["regions"][0], interval=[2.0, 3.0])),
                                "regions[2].interval", "inside the domain"),
    # it was clipped silently to [0.5, 1.0]
    "region partly outside": (lambda d: set_path(d, ["regions", 1, "interval"], [0.5, 1.2]),
                              "regions[1].interval", "inside the domain [0.0, 1.0] (nothing is clipped)"),
    # accepted and ignored: nothing in 1D reads it
    "stabilisation in 1D": (lambda d: d.setdefault("interface", {}).update(stabilisation="nitsche"),
                            "interface.stabilisation", "2D enriched mixed cells"),
    "solver without enriched cells": (lambda d: d.setdefault("interface", {}).update(
        model="single_velocity", solver="linearised"), "interface.solver", "acts only on enriched"),
    # accepted and ignored: one velocity field moves both materials alike
    "slip without enriched cells": (lambda d: d.setdefault("interface", {}).update(
        model="single_velocity", slip="free"), "interface.slip", "acts only on enriched"),
    # accepted and ignored: the closed form solves no PETSc system
    "PETSc options without an assembled system": (lambda d: d.setdefault("interface", {}).update(
        petsc_options={"ksp_type": "gmres"}), "interface.petsc_options", "assembled by PETSc"),
    "PETSc option name with its dash": (lambda d: d.setdefault("interface", {}).update(
        predictor="assembled", petsc_options={"-ksp_type": "gmres"}), "interface.petsc_options",
        "without its leading '-'"),
    "PETSc option value PETSc does not know": (lambda d: d.setdefault("interface", {}).update(
        predictor="assembled", petsc_options={"pc_type": "nonsense"}), "interface.petsc_options",
        "options PETSc accepts"),
    "PETSc option of the LU factorisation with a value it does not know": (
        lambda d: d.setdefault("interface", {}).update(predictor="assembled",
                                                       petsc_options={"pc_factor_shift_type": "nonsense"}),
        "interface.petsc_options", "options PETSc accepts"),
    "PETSc option name PETSc does not read": (lambda d: d.setdefault("interface", {}).update(
        predictor="assembled", petsc_options={"ksp_typo": "gmres"}), "interface.petsc_options",
        "did not read this one"),
    "coulomb friction between fluids": (lambda d: d.setdefault("interface", {}).update(slip="coulomb"),
                                        "interface.slip", "carry none"),
    "stick slip": (lambda d: d.setdefault("interface", {}).update(slip="stick"),
                   "interface.slip", "it is for 2D enriched cells"),
    "unknown material": (lambda d: set_path(d, ["regions", 1, "material"], "steel"),
                         "regions[1].material", "one of the materials"),
    "material boundary inside a cell": (lambda d: [set_path(d, ["regions", 0, "interval"], [0.0, 0.5037]),
                                                   set_path(d, ["regions", 1, "interval"], [0.5037, 1.0])],
                                        "regions[1].interval", "inside cell 201"),
    "bad boundary": (lambda d: set_path(d, ["boundaries", "left"], "sticky"), "boundaries.left", "'wall'"),
    "bad cfl": (lambda d: d.setdefault("numerics", {}).update(cfl=1.5), "numerics.cfl", "(0, 1]"),
    "bad trace fraction": (lambda d: d.setdefault("numerics", {}).update(trace_fraction=0.1),
                           "numerics.trace_fraction", "(0, 0.01]"),
    "remapped mesh without [interface]": (lambda d: set_path(d, ["mesh", "motion"], "eulerian"),
                                          "mesh.motion", "unless the scene has [interface]"),
    "eulerian mesh with a free end": (lambda d: [d.update(interface={"model": "enriched"}),
                                                 set_path(d, ["mesh", "motion"], "eulerian"),
                                                 set_path(d, ["boundaries", "right"], "free")],
                                      "boundaries.right", "'wall' with mesh.motion"),
    "two interfaces in one cell": (lambda d: [d.update(interface={"model": "enriched"}),
                                              d["regions"].append(dict(d["regions"][0], interval=[0.5011, 0.5022]))],
                                   "regions[1].interval", "a second interface"),
    "interfaces in neighbouring cells": (lambda d: [d.update(interface={"model": "enriched"}),
                                                    d["regions"].append(dict(d["regions"][0], interval=[0.5011, 0.5037]))],
                                         "regions[1].interval", "neighbouring cells"),
    "unknown interface model": (lambda d: d.update(interface={"model": "xfem"}), "interface.model", "one of enriched"),
    "velocity with three components": (lambda d: set_path(d, ["regions", 0, "velocity"], [0.0, 1.0, 2.0]),
                                       "regions[0].velocity", "[u] or [u, v]"),
    "[interface] with one material": (lambda d: [set_path(d, ["regions", 1, "material"], "left"),
                                                 d.update(interface={"slip": "free"})],
                                      "interface", "the regions hold one material"),
    "a boolean shown as the scene writes it": (lambda d: d.setdefault("numerics", {}).update(
        viscous_time_step=True), "numerics.viscous_time_step", "= true: no value with a 1D mesh"),
    # keys of 2D scenes, named so (not as unknown keys, which reads as a typo)
    "a 2D mesh's cell type in 1D": (lambda d: set_path(d, ["mesh", "cell_type"], "triangle"), "mesh.cell_type",
                                    "a key of 2D scenes: it cannot act in this one, of dimension = 1"),
    "a 2D region's rotation in 1D": (lambda d: set_path(d, ["regions", 0, "rotation"], {}), "regions[0].rotation",
                                     "a key of 2D scenes"),
    "a 2D region's shape in 1D": (lambda d: set_path(d, ["regions", 0, "box"], [[0, 1], [0, 1]]), "regions[0].box",
                                  "a key of 2D scenes"),
    "a 2D boundary in 1D": (lambda d: set_path(d, ["boundaries", "top"], "wall"), "boundaries.top",
                            "a key of 2D scenes"),
}


@pytest.mark.parametrize("case", BAD)
def test_bad_scene_is_one_line_naming_key_value_and_allowed(case):
    change, key, allowed = BAD[case]
    with pytest.raises(SceneError) as error:
        validate(modified(change))
    message = str(error.value)
    assert message.startswith(f"{key} = "), message
    assert allowed in message
    assert "\n" not in message


def test_later_regions_overwrite_earlier_ones():
    """A region entirely overwritten by later ones is not an error; the owner of each
    piece is the last region that covers it."""
    data = modified(lambda d: d["regions"].insert(0, dict(d["regions"][0], interval=[0.0, 1.0], density=7.0)))
    pieces = validate(data).pieces()
    assert [(lo, hi, r.material) for lo, hi, r in pieces] == [(0.0, 0.5, "left"), (0.5, 1.0, "right")]


def test_same_material_boundary_may_cut_a_cell_and_is_averaged(tmp_path):
    from ale_xfem.problem import build_problem

    data = modified(lambda d: [set_path(d, ["regions", 1, "material"], "left"),
                               set_path(d, ["regions", 0, "interval"], [0.0, 0.5037]),
                               set_path(d, ["regions", 1, "interval"], [0.5037, 1.0])])
    problem = build_problem(validate(data))
    exact_mass = 1.0 * 0.5037 + 0.125 * (1.0 - 0.5037)
    assert problem.state.material_mass.sum() == pytest.approx(exact_mass, rel=1e-13)


def test_overrides_reach_any_key():
    scene = load_scene(resolve_scene_path("sod"), ["mesh.cells=123", "regions.1.density=0.25",
                                                   "boundaries.right={velocity=[-1.0]}",
                                                   "numerics.cfl=0.3"])
    assert scene.mesh.cells == 123
    assert scene.regions[1].density == 0.25
    assert scene.boundaries["right"].kind == "velocity" and scene.boundaries["right"].velocity == (-1.0,)
    assert scene.numerics.cfl == 0.3
    with pytest.raises(SceneError, match=r"^regions.7 = '7': a list position 0..1"):
        load_scene(resolve_scene_path("sod"), ["regions.7.density=1"])


def test_an_override_takes_a_key_as_an_error_names_it():
    """An error names a list's entry as the scene file reads (`regions[1].density`); pasted
    into --set it sets the same key as `regions.1.density`."""
    with pytest.raises(SceneError) as error:
        load_scene(resolve_scene_path("sod"), ["regions.1.density=-1"])
    assert error.value.key == "regions[1].density"
    scene = load_scene(resolve_scene_path("sod"), [f"{error.value.key}=0.25"])
    assert scene.regions[1].density == 0.25 and scene.regions[0].density == 1.0


def test_every_shipped_scene_is_valid_and_described():
    paths = shipped_scenes()
    assert len(paths) >= 5
    for path in paths:
        scene = load_scene(path)
        assert scene.description and scene.name == path.stem


def test_cli_rejects_bad_scene_with_exit_code_2_and_runs_nothing(tmp_path):
    scene_file = tmp_path / "bad.toml"
    scene_file.write_text(tomli_w.dumps(modified(lambda d: set_path(d, ["regions", 1, "material"], "steel"))))
    out = tmp_path / "out"
    done = subprocess.run([sys.executable, "-m", "ale_xfem.cli", "run", str(scene_file), "--out", str(out)],
                          capture_output=True, text=True)
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert lines == ["error: regions[1].material = 'steel': one of the materials defined: left, right"]
    assert not out.exists()
    done = subprocess.run([sys.executable, "-m", "ale_xfem.cli", "run", "sod", "--set", "mesh.cells=0",
                           "--out", str(out)], capture_output=True, text=True)
    assert done.returncode == 2 and done.stderr.strip() == "error: mesh.cells = 0: an integer >= 1"
    assert not out.exists()


def test_a_scene_name_that_is_not_shipped_points_to_the_list():
    """A bare name that is neither a shipped scene nor a file: the one line says where the
    shipped scenes are listed, and names the one meant when it is close."""
    with pytest.raises(SceneError) as error:
        load_scene(resolve_scene_path("sod-2D"))
    assert error.value.key == "scene" and "see `ale-xfem list`" in str(error.value)
    assert "did you mean 'sod-2d'?" in str(error.value) and "\n" not in str(error.value)
    with pytest.raises(SceneError) as error:
        load_scene(resolve_scene_path("no-scene-of-that-name"))
    assert "did you mean" not in str(error.value)


@pytest.mark.parametrize("base", ["rotated-tube-shear", "shock-disk", "spinning-disk"])
def test_the_shipped_enriched_2d_scenes_are_their_single_velocity_scenes_with_enriched_cells(base):
    """``<base>-enriched`` ships the paper's 2D method on a scene shipped with one velocity
    field: the same scene to the last resolved key, but its interface's model (enriched,
    with bubbles and free slip written out), its name and its description."""
    enriched = load_scene(resolve_scene_path(f"{base}-enriched"))
    switched = load_scene(resolve_scene_path(base), ["interface.model=enriched", 'interface.stabilisation="bubble"',
                                                     'interface.slip="free"'])
    assert enriched.interface.model == "enriched" and enriched.name == f"{base}-enriched"
    differing = {key for key in enriched.resolved if enriched.resolved[key] != switched.resolved[key]}
    assert differing == {"name", "description"}, differing
