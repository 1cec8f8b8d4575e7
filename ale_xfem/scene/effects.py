"""The effects a scene switches on, and the key that decides each one.

The stepper is composed of these: an effect that is off is not built (no mixed-cell
solver, no compiled form, no remapper, no viscosity arrays, no transverse component) and
costs nothing.  :func:`scene_effects` is the one place that decides; the problem keeps the
names of the active ones (``summary.json`` lists them) and ``ale-xfem run --explain``
prints the whole table.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Effect:
    name: str  # as listed in summary.json
    on: bool
    why: str  # the key(s) and value(s) that decide it


def sweeps(scene) -> bool:
    """Whether every step is remapped onto another mesh (swept regions through the edges:
    mesh.motion other than "lagrangian")."""
    return scene.mesh.motion != "lagrangian"


def remaps_in_place(scene, mixed: bool) -> bool:
    """Whether every step is remapped onto the Lagrangian mesh itself: 2D enriched cells on a
    Lagrangian mesh, whose materials slide across the mesh's edges at Γ (``mixed``: cells
    hold two materials)."""
    interface = scene.interface
    return (scene.mesh.motion == "lagrangian" and mixed and scene.dimension == 2
            and interface.model == "enriched")


def has_hourglass_modes(scene) -> bool:
    """Quadrilaterals (2D): intervals and triangles have no hourglass modes."""
    return scene.dimension == 2 and scene.mesh.cell_type == "quadrilateral"


def has_viscosity(numerics) -> bool:
    return numerics.q_quadratic > 0 or numerics.q_linear > 0


def scene_effects(scene, n_mixed_cells: int, pistons: list[str]) -> list[Effect]:
    """Every effect the code knows, on or off, for a scene whose initial layout has
    ``n_mixed_cells`` cells holding two materials, with velocity boundaries on ``pistons``."""
    numerics, interface = scene.numerics, scene.interface
    effects = [Effect("lagrange_explicit", True, "always: the explicit Wilkins loop of the pure cells")]
    q = f"numerics.q_quadratic = {numerics.q_quadratic:g}, numerics.q_linear = {numerics.q_linear:g}"
    viscosity = has_viscosity(numerics)
    effects.append(Effect("artificial_viscosity", viscosity,
                          q + (" (one > 0)" if viscosity else " (both 0: no viscosity is computed)")))
    effects.append(Effect("piston", bool(pistons),
                          ", ".join(f"boundaries.{side} = {{velocity = ...}}" for side in pistons)
                          if pistons else "no boundary is {velocity = [...]}"))
    if scene.dimension == 1:
        transverse = max(len(r.velocity) for r in scene.regions) > 1
        effects.append(Effect("transverse_velocity", transverse,
                              "a region's velocity has two components (carried by the remap, no part in the "
                              "dynamics)" if transverse else "every region's velocity = [u]: one component"))
    else:
        quadrilaterals = has_hourglass_modes(scene)
        effects.append(Effect("hourglass_control", quadrilaterals and numerics.hourglass > 0,
                              f"mesh.cell_type = \"{scene.mesh.cell_type}\", numerics.hourglass = "
                              f"{numerics.hourglass:g}" + ("" if quadrilaterals else
                                                           " (triangles have no hourglass modes)")))
        effects.append(Effect("viscous_time_step", viscosity and numerics.viscous_time_step,
                              f"numerics.viscous_time_step = {str(numerics.viscous_time_step).lower()}"
                              + (": the time step resolves the viscosity's stiffness (√A over the least width)"
                                 if viscosity else " (no viscosity)")))
    mixed = n_mixed_cells > 0 and interface is not None
    if interface is None:
        why = "no [interface] table: materials never share a cell"
    elif n_mixed_cells == 0:
        why = "[interface] is given but every interface lies on a node: no mixed cell to solve"
    else:
        why = f"interface.model = \"{interface.model}\", {n_mixed_cells} cell(s) hold two materials"
    enriched = mixed and interface.model == "enriched"
    effects.append(Effect("mixed_cells_enriched", enriched, why))
    effects.append(Effect("mixed_cells_single_velocity", mixed and not enriched, why))
    enriched_1d, enriched_2d = enriched and scene.dimension == 1, enriched and scene.dimension == 2
    for solver in ("nonlinear", "linearised"):
        effects.append(Effect(f"interface_solver_{solver}", enriched and interface.solver == solver,
                              f"interface.solver = \"{interface.solver}\"" if enriched
                              else "needs enriched mixed cells"))
    for predictor in ("closed_form", "assembled"):
        effects.append(Effect(
            f"interface_predictor_{predictor}", enriched_1d and interface.predictor == predictor,
            (f"interface.predictor = \"{interface.predictor}\""
             + (" (UFL forms compiled once per run)" if predictor == "assembled" else ""))
            if enriched_1d else "needs enriched mixed cells in 1D"))
    if scene.dimension == 2:
        for stabilisation in ("bubble", "nitsche", "none"):
            effects.append(Effect(
                f"interface_stabilisation_{stabilisation}", enriched_2d and interface.stabilisation == stabilisation,
                f"interface.stabilisation = \"{interface.stabilisation}\"" + (
                    " (the implicit interface system: UFL forms compiled once per run, PETSc; each "
                    f"material's velocity over the other's part held by interface.ghost_viscosity = "
                    f"{interface.ghost_viscosity:g})"
                    if interface.stabilisation == stabilisation else "") if enriched_2d
                else "needs enriched mixed cells in 2D"))
        for slip in ("free", "stick"):
            effects.append(Effect(f"interface_slip_{slip}", enriched_2d and interface.slip == slip,
                                  f"interface.slip = \"{interface.slip}\"" if enriched_2d
                                  else "needs enriched mixed cells in 2D"))
        normal = "youngs" if interface is None else interface.normal
        refined = ": PLIC's normals refined by LVIRA, exact for a straight interface on any mesh"
        effects.append(Effect("interface_normal_lvira", mixed and normal == "lvira",
                              "needs mixed cells" if interface is None else
                              f"interface.normal = \"{normal}\"" + ((refined if normal == "lvira" else "") if mixed
                                                                    else " (needs mixed cells)")))
    effects.append(Effect("pressure_relaxation", mixed and interface.relaxation,
                          f"interface.relaxation = {str(interface.relaxation).lower()}" if mixed
                          else "needs mixed cells"))
    motion = scene.mesh.motion
    # 2D enriched cells on a Lagrangian mesh: their materials slide across the mesh's edges
    # at Γ, so every step is remapped onto the Lagrangian mesh itself (no swept region)
    in_place = remaps_in_place(scene, mixed)
    remapped = sweeps(scene) or in_place
    if in_place:
        motion_why = (": with 2D enriched mixed cells the materials cross the mesh's edges at Γ, so each step "
                      "is remapped onto the Lagrangian mesh itself (no swept region: only what crossed moves)")
    else:
        motion_why = "" if remapped else ": the mesh moves with the material, nothing is remapped"
    effects.append(Effect(f"remap_{motion}" if remapped else "remap", remapped,
                          f"mesh.motion = \"{motion}\"" + motion_why))
    swept = sweeps(scene)  # an in-place remap sweeps nothing to reconstruct
    effects.append(Effect(f"remap_order_{numerics.remap_order}", swept,
                          f"numerics.remap_order = {numerics.remap_order}" if swept
                          else "needs a moving remap (mesh.motion other than \"lagrangian\")"))
    return effects


def active(effects: list[Effect]) -> list[str]:
    return [effect.name for effect in effects if effect.on]


def explain(effects: list[Effect]) -> str:
    """The table printed by ``ale-xfem run --explain``."""
    width = max(len(effect.name) for effect in effects)
    lines = ["effects switched on:"]
    lines += [f"  {e.name:<{width}}  {e.why}" for e in effects if e.on]
    lines.append("switched off (not built, no cost):")
    lines += [f"  {e.name:<{width}}  {e.why}" for e in effects if not e.on]
    return "\n".join(lines)
