"""The time loop: step the problem to t_end, watch for breakdown, measure conservation and
the error against the exact solution.

    while simulation.proceed:
        dt = stepper.stable_time_step(...)   # CFL, growth limit, t_end
        state = stepper.step(state, dt)
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from functools import partial

import numpy as np
from tqdm.auto import tqdm

from ale_xfem.lagrange.breakdown import Breakdown
from ale_xfem.lagrange import compile_clock
from ale_xfem.lagrange.compile_clock import compile_seconds, own_clock
from ale_xfem.lagrange.memory import keep_freed_memory
from ale_xfem.lagrange.wilkins import ExplicitWilkins
from ale_xfem.mixed.closures import Closures
from ale_xfem.mixed.cut_cells_2d import material_geometry
from ale_xfem.model.plic import reconstruct_state
from ale_xfem.model.state import State, material_masses, totals
from ale_xfem.parallel.distribution import (REMAP_GHOST_RINGS, Distribution, RemapOnEveryRank, check_distributable,
                                            has_interface_system, ranks)
from ale_xfem.problem.build import Problem
from ale_xfem.remap.failure import RemapFailure
from ale_xfem.remap.remapper_1d import Remapper
from ale_xfem.remap.remapper_2d import Remapper2D

SUBSAMPLES_PER_CELL = 16  # midpoint rule for ∫|f_h − f_exact| dx inside each cell
SUBSAMPLES_PER_SIDE_2D = 4  # 2D: 4 × 4 points per quadrilateral, 16 per triangle


@dataclass
class RunResult:
    status: str  # "ok" | "failed"
    state: State  # the last good state
    steps: int
    wall_seconds: float  # the run's own: compiling the compiled kernels left out (lagrange.compile_clock)
    diagnostic: str = ""
    conservation: dict = field(default_factory=dict)
    errors: dict | None = None
    dt_min: float = 0.0
    dt_max: float = 0.0
    phase_seconds: dict = field(default_factory=dict)  # seconds per phase of the step
    remaps: dict | None = None  # with a remap: how many were done, and how
    mixed_cells: dict | None = None
    ranks: int = 1  # the MPI ranks it ran on
    interface_solve: str | None = None  # on several ranks, with an interface system: how it was solved
    compile_seconds: float = 0.0  # spent compiling compiled kernels during the run (not cached yet)

    @property
    def zone_cycles_per_second(self) -> float:
        cells = self.state.material_mass.shape[1]
        return cells * self.steps / self.wall_seconds if self.wall_seconds > 0 else 0.0


def compiled_so_far() -> float:
    """Seconds this process has spent compiling compiled kernels so far
    (ale_xfem.lagrange.compile_clock): read before a problem is built and after its run, the
    compiling a whole command did."""
    return compile_clock.compile_seconds()  # (through the module: a test stands in a clock for it)


class Progress:
    """The run's progress in simulated time, a tqdm bar on stderr: shown on a terminal or in
    a notebook, silent when stderr is redirected (``enabled`` None), or as asked."""

    def __init__(self, t_end: float, enabled: bool | None = None):
        self.t_end = t_end
        self.bar = tqdm(total=t_end, disable=None if enabled is None else not enabled, file=sys.stderr,
                        unit="", mininterval=0.2, leave=True,
                        bar_format="{l_bar}{bar}| t = {n:.4g} / {total:.4g} [{elapsed}<{remaining}]{postfix}")

    def update(self, t: float, steps: int, force: bool = False) -> None:
        """``force``: draw now (the last state), not at most five times a second."""
        self.bar.n = min(t, self.t_end)
        self.bar.set_postfix_str(f"step {steps}", refresh=False)
        if force:
            self.bar.refresh()
        else:
            self.bar.update(0)  # redraws when mininterval has passed

    def close(self) -> None:
        self.bar.close()


def make_stepper(problem: Problem, mesh=None, layout=None, node_mass=None, boundaries=None, mixed=None,
                 stepper_class=ExplicitWilkins, closures_class=Closures) -> ExplicitWilkins:
    """The Lagrange step of a problem, its mixed cells closed as the scene asks (the
    assembled predictor's UFL forms are compiled here, once per run); ``mesh``, ``layout``,
    ``node_mass``, ``boundaries``, ``mixed``: a part of the problem's (one rank's), in place of its own,
    stepped by ``stepper_class`` (ExplicitWilkins or a subclass), its mixed cells closed by
    ``closures_class``'s (Closures or a subclass)."""
    keep_freed_memory()
    interface = problem.scene.interface
    enriched_2d = {}
    if interface is not None and interface.stabilisation is not None:  # 2D enriched mixed cells
        enriched_2d = dict(stabilisation=interface.stabilisation, slip=interface.slip,
                           nitsche_penalty=interface.nitsche_penalty or 1.0, normal=interface.normal,
                           ghost_viscosity=interface.ghost_viscosity)
    closures = closures_class(problem.mesh if mesh is None else mesh, problem.materials,
                        assembled_predictor="interface_predictor_assembled" in problem.effects,
                        petsc_options=dict(interface.petsc_options) if interface is not None else None,
                        **enriched_2d)
    return stepper_class(problem.mesh if mesh is None else mesh, problem.materials,
                         problem.layout if layout is None else layout,
                         problem.node_mass if node_mass is None else node_mass,
                         problem.boundaries if boundaries is None else boundaries, problem.scene.numerics,
                         artificial_viscosity="artificial_viscosity" in problem.effects,
                         mixed=problem.mixed if mixed is None else mixed,
                         viscous_time_step="viscous_time_step" in problem.effects, closures=closures)


# Steps in a row at a time step too small to reach t_end within numerics.max_steps before a
# run is stopped as failed (a cell collapsing: dt → 0)
STALLED_STEPS = 1000
# A step whose mixed cell breaks down is taken again from the same state with half the time
# step, at most this many times (then the run stops with the last attempt's diagnostic).
MIXED_CELL_RETRIES = 12


def simulate(problem: Problem, progress: Progress | None = None, t_end: float | None = None,
             stop_after_steps: int | None = None, observe=None, observe_from=None,
             compiled_chunks: bool = True, interface_solve: str = "replicated") -> RunResult:
    """Run to t_end (the scene's by default).  ``stop_after_steps`` ends the run early as a
    normal stop (benchmarks); numerics.max_steps reached first is a failure.  ``observe``:
    called with each new state (and the initial one), e.g. to track extremes;
    ``observe_from``: if given, a function saying from which time ``observe`` needs a state
    again — it is then called only with the states from that time on (and the last one of
    each compiled chunk of steps), which lets the steps before it run compiled.
    ``compiled_chunks`` False: every step through the staged step (the same numbers; the
    tests compare the two).  ``interface_solve``: on several MPI ranks, how enriched cells'
    interface system is solved (ale_xfem.parallel.distribution.INTERFACE_SOLVES).
    With a remapped mesh, problem.layout, problem.mixed and
    problem.node_mass follow the run (they describe the returned state; on several MPI
    ranks they are the ranks' own gathered, at the end and at each observed state):
    ``problem.state = result.state`` continues the run, and a problem whose state is still
    the one it was built with runs from it again, as built (Problem.start_run)."""
    problem.start_run()
    t_end = problem.scene.t_end if t_end is None else t_end
    max_steps = problem.scene.numerics.max_steps
    # On several MPI ranks each steps its share of the cells (ale_xfem.parallel), and the
    # serial state is gathered at the end; one rank pays nothing for it.
    distribution = None
    remapped = any(name.startswith("remap_") for name in problem.effects)
    if ranks() > 1:
        check_distributable(problem)
        # a 2D remap reads further than a Lagrange step: a deeper ghost layer (the 1D remap
        # takes the whole mesh on every rank: RemapOnEveryRank)
        distribution = Distribution(problem, rings=REMAP_GHOST_RINGS if remapped and problem.mesh.dimension == 2
                                    else 1, interface_solve=interface_solve)
        stepper = distribution.stepper(partial(make_stepper, problem))
    else:
        stepper = make_stepper(problem)
    remapper = None
    if remapped:
        if problem.mesh.dimension == 2:
            remapper = Remapper2D(problem, problem.scene.mesh.motion, problem.scene.numerics.remap_order,
                                  **({} if distribution is None else distribution.remap_parts()))
            interface = problem.scene.interface
            if interface is not None and interface.model == "enriched":  # the step's masses
                remapper.material_geometry = partial(material_geometry, remapper.mesh, normal=interface.normal)
        else:
            remapper = Remapper(problem, problem.scene.mesh.motion, problem.scene.numerics.remap_order)
            if distribution is not None:
                remapper = RemapOnEveryRank(distribution, remapper)
    remap_energy_change, remap_seconds = 0.0, 0.0
    # 2D enriched cells on a Lagrangian mesh (remapped in place): a mesh that follows both
    # materials shears where they slide, which ends the run when the slide nears a cell
    slide_hint = ("; a Lagrangian mesh is sheared where its materials slide along Γ (about a cell of slide is "
                  "what its cut cells take): mesh.motion = \"smoothed\" or \"eulerian\" for longer slides"
                  if remapper is not None and remapper.motion == "lagrangian" else "")
    state = problem.state
    start_totals = totals(state, problem.node_mass)
    scale = velocity_scale(problem)
    start_materials = material_masses(state, problem.layout)
    boundary_work, boundary_impulse = 0.0, np.zeros_like(start_totals["momentum"])
    growth = problem.scene.numerics.dt_growth
    if distribution is not None:
        state = distribution.local_state(state)
        observe = distribution.observer(observe, observe_from, problem)
        observe_from = None
    evaluation = stepper.evaluate_state(state)
    dt_previous, dt_min, dt_max = np.inf, np.inf, 0.0
    steps, status, diagnostic, stalled, halved_steps = 0, "ok", "", 0, 0
    watch_stall = stop_after_steps is None or stop_after_steps > max_steps
    # A remap of the whole state after every step evaluates the remapped state's forces:
    # the step then leaves out those of the Lagrangian state.
    remap_all = remapper is not None and remapper.motion != "interface"
    stepper.relax_end_state = not remap_all  # a full remap relaxes the state it makes instead
    # A Lagrangian mesh whose cells are all pure (or whose mixed cells' closure can: 1D
    # enriched cells), nothing to watch between steps: the steps run in compiled chunks
    # (ExplicitWilkins.steps), each stopping before a step that is not plain, which the
    # loop below then takes itself; the same steps, to the bit.
    # Observed at every state, pure cells take their steps one by one (a chunk of one step
    # would evaluate its state twice); a closure's compiled steps are still far cheaper than
    # its staged step, and go in chunks of one step.
    observe_each = observe is not None and observe_from is None
    compiled_steps = (compiled_chunks and remapper is None and stepper.compiles_steps()
                      and not (observe_each and stepper.closure is None))
    chunk = max(1, min(1000, 2_000_000 // problem.mesh.n_cells))  # about 0.1 s between progress updates
    clock, compiling = own_clock(), compile_seconds()
    if problem.setup_failure:
        status, diagnostic = "failed", f"step 0, t = 0: {problem.setup_failure}"
    if observe is not None:
        observe(state, problem)
    while status == "ok" and state.time < t_end * (1.0 - 1e-14):
        if stop_after_steps is not None and steps >= stop_after_steps:
            break
        if steps >= max_steps:
            status = "failed"
            diagnostic = (f"step {steps}, t = {state.time:.6g}: numerics.max_steps = {max_steps} "
                          f"reached before t_end = {t_end:g}")
            break
        if compiled_steps and stalled == 0:
            budget = 1 if observe_each else chunk if stop_after_steps is None else min(chunk, stop_after_steps - steps)
            taken, state, evaluation, dt_previous, least, largest, boundary_work, boundary_impulse = \
                stepper.steps(state, evaluation, {"t_end": t_end, "dt_previous": dt_previous, "growth": growth,
                                                  "budget": budget, "steps_left": max_steps - steps,
                                                  "watch_stall": watch_stall, "boundary_work": boundary_work,
                                                  "t_stop": np.inf if observe is None or observe_each
                                                  else observe_from()},
                              boundary_impulse)
            if taken:
                steps += taken
                dt_min, dt_max = min(dt_min, least), max(dt_max, largest)
                if observe is not None:
                    observe(state, problem)
                if progress is not None:
                    progress.update(state.time, steps)
                continue
        dt = min(stepper.stable_time_step(evaluation), growth * dt_previous, t_end - state.time)
        if not dt > 0.0 or not np.isfinite(dt):
            status = "failed"
            diagnostic = f"step {steps + 1}, t = {state.time:.6g}: time step dt = {dt:.3g}, must be > 0{slide_hint}"
            break
        # A collapsing cell drives dt towards 0: the run would crawl on to max_steps.  It is
        # stopped once dt has stayed too small to reach t_end within max_steps for
        # STALLED_STEPS steps in a row, naming the cell that sets the time step (not when
        # stop_after_steps ends the run first: it is not meant to reach t_end).
        stalled = stalled + 1 if watch_stall and t_end - state.time > dt * (max_steps - steps) else 0
        if stalled >= STALLED_STEPS:
            status = "failed"
            diagnostic = (f"step {steps + 1}, t = {state.time:.6g}: the time step collapsed to dt = {dt:.3g} "
                          f"({stalled} steps too small to reach t_end = {t_end:g} within numerics.max_steps = "
                          f"{max_steps}); {stepper.limiting_cell(evaluation, state.node_position)}{slide_hint}")
            break
        try:
            new_state, evaluation, work, impulse, taken = _step(stepper, state, dt, evaluation, remap_all)
            halved_steps += int(round(np.log2(dt / taken)))
            dt = taken
            if remapper is not None:
                remap_clock = own_clock()
                new_state, evaluation, impulse, kinetic_change = _remap(
                    problem, stepper, remapper, new_state, evaluation, impulse, distribution)
                work += remapper.wall_work
                remap_energy_change += kinetic_change
                remap_seconds += own_clock() - remap_clock
            state = new_state
        except (Breakdown, RemapFailure) as failure:
            status = "failed"
            diagnostic = f"step {steps + 1}, t = {state.time:.6g}: {failure}{slide_hint}"
            break
        boundary_work += work
        boundary_impulse = boundary_impulse + impulse
        dt_previous = dt
        dt_min, dt_max = min(dt_min, dt), max(dt_max, dt)
        steps += 1
        if observe is not None:
            observe(state, problem)
        if progress is not None:
            progress.update(state.time, steps)
    compiled = compile_seconds() - compiling  # (no part of the run's own time: compile_clock)
    wall = own_clock() - clock
    if distribution is not None:
        state = distribution.gathered(state)
        distribution.gather_problem()  # the layout, masses and mixed cells a remap left
        wall = -distribution.least(-wall)  # the slowest rank's
    if progress is not None:
        progress.update(state.time, steps, force=True)
        progress.close()
    phases = {"lagrange": wall - remap_seconds - stepper.mixed_seconds,
              "mixed_cell_solve": stepper.mixed_seconds, "remap": remap_seconds}
    if distribution is not None:  # within the others: exchanges and reductions, the most any rank spent
        phases["communication"] = -distribution.least(-distribution.seconds)
    problem.end_run(state)
    result = RunResult(status, state, steps, wall, diagnostic, dt_min=float(dt_min if steps else 0.0),
                       dt_max=float(dt_max), phase_seconds=phases, ranks=ranks(),
                       interface_solve=interface_solve if distribution is not None and has_interface_system(problem)
                       else None, compile_seconds=compiled)
    result.conservation = conservation(start_totals, totals(state, problem.node_mass),
                                       boundary_work, boundary_impulse, scale)
    # each material's own mass: the worst relative change (a remap moves them one by one)
    change = (material_masses(state, problem.layout) - start_materials) / np.where(start_materials > 0, start_materials, 1.0)
    result.conservation["material_mass"] = float(change[np.argmax(np.abs(change))])
    if remapper is not None and remapper.motion == "interface":  # windows around a mixed cell
        result.remaps = {"local": remapper.windows_remapped}
    elif remapper is not None:  # every step; those the swept form did not cover
        result.remaps = {"steps": steps, "general_intersection": remapper.general_remaps}
    if remapper is not None and remapper.energy_limited:
        result.remaps["energy_limited"] = remapper.energy_limited
    if remapper is not None:
        # The remap conserves mass, momentum and internal energy; it dissipates kinetic
        # energy, reported on the scale of the total energy's drift.
        result.conservation["remap_kinetic_energy_change"] = remap_energy_change / result.conservation[
            "energy_scale"]
    if problem.mixed is not None or stepper.mixed_calls:
        stats = problem.mixed.stats if problem.mixed is not None else {}
        result.mixed_cells = {
            "count": int(problem.mixed.count) if problem.mixed is not None else 0,
            "solves": stats.get("steps", 0),
            "iterations_mean": stats.get("iterations", 0) / max(stats.get("steps", 0), 1),
            "iterations_max": stats.get("max_iterations", 0),
            "relaxations": stats.get("relaxations", 0),
            "halved_steps": halved_steps,
        }
        if "volume_mismatch" in stats:  # 2D enriched cells: the O(dt²) rest scaled to the Lagrangian cell
            result.mixed_cells["volume_mismatch"] = stats["volume_mismatch"]
    if problem.exact is not None and state.time > 0 and problem.exact.holds_at(state.time):
        result.errors = l1_errors(problem, state)
    return result


def _step(stepper, state, dt, evaluation, remapped_next):
    """One Lagrange step (``stepper.step``), taken again from the same state with dt halved
    while a mixed cell breaks down in it, at most MIXED_CELL_RETRIES times: an interface
    solve may have no admissible root at the time step the pure cells allow (a sliver of hot
    air expanding against water: the cell's nodes open faster than its materials can fill at
    a pressure ≥ 0).  The run's dt_growth then brings the step back.  Returns the step's
    results and the dt it took."""
    for attempt in range(MIXED_CELL_RETRIES + 1):
        try:
            return (*stepper.step(state, dt, evaluation, remapped_next=remapped_next), dt)
        except Breakdown as failure:
            if attempt == MIXED_CELL_RETRIES or not stepper.breaks_mixed_cell(failure):
                raise
            dt *= 0.5


def _remap(problem, stepper, remapper, state, evaluation, impulse, distribution=None):
    """The transport phase: remap, take the new layout, hold the walls, relax mixed cells.
    Returns (state, its evaluation, boundary impulse, kinetic energy change).  On several
    MPI ranks (``distribution``) the rank's share: the remapper hands back its mixed cells
    solved with all the ranks' (RankScope.solved_mixed, RemapOnEveryRank), the walls'
    impulse and work are summed over the ranks' own nodes."""
    state, layout, mixed, node_mass, kinetic_change = remapper.apply(state, stepper.layout, stepper.mixed)
    if node_mass is None:  # nothing was remapped this step
        return state, evaluation, impulse, 0.0
    stepper.rebuild(layout, node_mass, mixed)
    if distribution is None:  # (on several ranks the problem takes the ranks' at the end)
        problem.layout, problem.mixed, problem.node_mass = layout, mixed, node_mass
    # The walls hold the remapped velocities too: their impulse is a boundary reaction, the
    # kinetic energy it removes part of the remap's change.
    held = stepper.constrained_nodes
    before = state.node_velocity[:, held].copy()
    for boundary in stepper.constraints:
        boundary.apply(state.node_velocity)  # the remap's own array
    after = state.node_velocity[:, held]
    held_impulse = (node_mass[held] * (after - before)).sum(axis=1)
    held_kinetic = 0.5 * float(np.sum(node_mass[held] * (after**2 - before**2)))
    if distribution is not None:
        held_impulse, held_kinetic = distribution.summed(held_impulse), distribution.summed(held_kinetic)
    impulse = impulse + held_impulse + remapper.wall_impulse
    kinetic_change += held_kinetic
    if stepper.closure is not None:  # the remap leaves a pressure jump in mixed cells
        state, _ = stepper.closure.relax_start(state, in_place=True)
    evaluation = stepper.evaluate_state(state, thermodynamics_known=True)
    stepper.check_remapped(evaluation, state.node_position, state.material_energy)
    return state, evaluation, impulse, kinetic_change


def velocity_scale(problem: Problem) -> float:
    """The scene's velocity scale V: the largest of the initial speeds, the initial sound
    speeds and the pistons' speeds.  It vanishes only for cold matter at rest with no
    piston, where nothing can move."""
    state = problem.state
    speeds = [float(np.max(np.linalg.norm(state.node_velocity, axis=0), initial=0.0)),
              float(np.max(np.where(state.material_mass > 0, state.material_sound_speed, 0.0), initial=0.0))]
    speeds += [float(np.linalg.norm(b.velocity)) for b in problem.boundaries if b.kind == "velocity"]
    return max(speeds)


def _relative(drift: float, scale: float) -> float:
    return drift / scale if scale > 0 else (0.0 if drift == 0 else float("inf"))


def conservation(start, end, boundary_work, boundary_impulse, velocity_scale: float) -> dict:
    """Drifts relative to scales that do not vanish while anything can move (README,
    'Outputs'): mass by the initial mass M; momentum |ΔP − boundary impulse| by M V, with V
    the scene's velocity scale; total energy (ΔE − boundary work) by the largest of |E⁰|,
    |E| and M V².  The balances include what the boundaries gave (reactions of walls and
    pistons)."""
    mass = start["mass"]
    momentum_scale = mass * velocity_scale
    energy_scale = max(abs(start["total_energy"]), abs(end["total_energy"]), mass * velocity_scale**2)
    momentum_drift = float(np.linalg.norm(end["momentum"] - start["momentum"] - boundary_impulse))
    return {
        "mass": (end["mass"] - mass) / mass,
        "momentum": _relative(momentum_drift, momentum_scale),
        "total_energy": _relative(end["total_energy"] - start["total_energy"] - boundary_work, energy_scale),
        "boundary_work": boundary_work,
        "momentum_scale": momentum_scale,
        "energy_scale": energy_scale,
    }


def l1_errors(problem: Problem, state: State) -> dict:
    """Σ_K ∫_K |f_h − f_exact| dx for density, velocity, pressure (midpoint rule on
    SUBSAMPLES_PER_CELL points per cell).  f_h: constant per material part of a cell
    (a mixed cell holds α left of Γ, β right of it); velocity piecewise linear through the
    nodes (and Γ in a mixed cell)."""
    if problem.mesh.dimension == 2:
        return _l1_errors_2d(problem, state)
    nodes = problem.mesh.cell_nodes
    x = state.node_position[0][nodes]  # (n_cells, 2)
    u = state.node_velocity[0][nodes]
    swap = x[:, 0] > x[:, 1]
    x[swap], u[swap] = x[swap, ::-1], u[swap, ::-1]
    s = (np.arange(SUBSAMPLES_PER_CELL) + 0.5) / SUBSAMPLES_PER_CELL
    points = x[:, :1] + (x[:, 1:] - x[:, :1]) * s  # (n_cells, m)
    weights = (x[:, 1:] - x[:, :1]) / SUBSAMPLES_PER_CELL
    density = np.repeat(state.material_density[0][:, None], s.size, axis=1)
    pressure = np.repeat(state.material_pressure[0][:, None], s.size, axis=1)
    velocity = u[:, :1] + (u[:, 1:] - u[:, :1]) * s
    if problem.mixed is not None:
        cells = problem.mixed.cells
        xa, xb = x[cells, :1], x[cells, 1:]
        xg = xa + state.material_volume[0, cells][:, None]
        ug = state.interface_velocity[:, None]
        ua, ub = u[cells, :1], u[cells, 1:]
        p = points[cells]
        left = p < xg
        density[cells] = np.where(left, state.material_density[0, cells][:, None],
                                  state.material_density[1, cells][:, None])
        pressure[cells] = np.where(left, state.material_pressure[0, cells][:, None],
                                   state.material_pressure[1, cells][:, None])
        velocity[cells] = np.where(left, ua + (ug - ua) * (p - xa) / (xg - xa),
                                   ug + (ub - ug) * (p - xg) / (xb - xg))
    reference = problem.exact.sample(points, state.time)
    numerical = {"density": density, "velocity": velocity, "pressure": pressure}
    errors = {f"L1_{k}": float(np.sum(np.abs(v - reference[k]) * weights)) for k, v in numerical.items()}
    errors["exact"] = problem.exact.kind
    errors["exact_valid_until"] = problem.exact.valid_until
    return errors


def cell_sample_points(cell_name: str, per_side: int):
    """Reference sample points and shape-function values for the 2D error integrals:
    quadrilaterals (corners going round) a per_side × per_side grid of sub-square centres;
    triangles the centroids of the per_side² sub-triangles.  Returns (shape values
    (m, corners), weights (m,) summing to 1 on the reference cell, and for quadrilaterals the
    derivatives (m, corners, 2) of the shape functions, else None)."""
    k = per_side
    if cell_name == "quadrilateral":
        s = (np.arange(k) + 0.5) / k
        xi, eta = (a.ravel() for a in np.meshgrid(s, s, indexing="ij"))
        shape = np.stack([(1 - xi) * (1 - eta), xi * (1 - eta), xi * eta, (1 - xi) * eta], axis=1)
        derivative = np.stack([np.stack([-(1 - eta), -(1 - xi)], -1), np.stack([1 - eta, -xi], -1),
                               np.stack([eta, xi], -1), np.stack([-eta, 1 - xi], -1)], axis=1)
        return shape, np.full(xi.size, 1.0 / xi.size), derivative
    points = []
    for i in range(k):  # sub-triangles of a k-fold subdivision: upright then inverted
        for j in range(k - i):
            points.append(((i + 1 / 3) / k, (j + 1 / 3) / k))
            if j < k - i - 1:
                points.append(((i + 2 / 3) / k, (j + 2 / 3) / k))
    a, b = np.array(points).T
    shape = np.stack([1 - a - b, a, b], axis=1)
    return shape, np.full(a.size, 1.0 / a.size), None


def _l1_errors_2d(problem: Problem, state: State) -> dict:
    """Σ_K ∫_K |f_h − f_exact| dA over SUBSAMPLES_PER_SIDE_2D² points per cell: density and
    pressure constant per material part (a mixed cell's parts split by its PLIC segment),
    velocity (Euclidean norm of the error) bilinear/linear through the nodes, and for a
    planar Riemann problem its components along the normal and along the contact apart;
    over the reference's window only when it has one."""
    mesh = problem.mesh
    shape, weight, derivative = cell_sample_points(mesh.cell_type.name, SUBSAMPLES_PER_SIDE_2D)
    x = np.moveaxis(state.node_position[:, mesh.cell_nodes], 0, -1)  # (n_cells, corners, 2)
    u = np.moveaxis(state.node_velocity[:2, mesh.cell_nodes], 0, -1)
    points = np.einsum("mc,ncd->nmd", shape, x)
    velocity = np.einsum("mc,ncd->nmd", shape, u)
    if derivative is None:
        area = mesh.cell_volumes(state.node_position)[:, None] * weight[None, :]
    else:
        jacobian = np.einsum("mce,ncd->nmde", derivative, x)
        area = np.abs(np.linalg.det(jacobian)) * weight[None, :]
    density = np.repeat(state.material_density[0][:, None], shape.shape[0], axis=1)
    pressure = np.repeat(state.material_pressure[0][:, None], shape.shape[0], axis=1)
    if problem.mixed is not None:  # the points on β's side of the reconstructed interface
        plic = reconstruct_state(problem, state, normal=problem.scene.interface.normal)
        c = plic.cells
        beta = np.einsum("cmd,cd->cm", points[c], plic.normal) > plic.offset[:, None]
        density[c] = np.where(beta, state.material_density[1, c][:, None], density[c])
        pressure[c] = np.where(beta, state.material_pressure[1, c][:, None], pressure[c])
    if problem.exact.window is not None:  # only where no wave from the walls has arrived
        centre, radius = problem.exact.window
        area = area * (np.linalg.norm(points - np.asarray(centre), axis=-1) <= radius)
    reference = problem.exact.sample(points, state.time)
    errors = {
        "L1_density": float(np.sum(np.abs(density - reference["density"]) * area)),
        "L1_velocity": float(np.sum(np.linalg.norm(velocity - reference["velocity"], axis=-1) * area)),
        "L1_pressure": float(np.sum(np.abs(pressure - reference["pressure"]) * area)),
        "exact": problem.exact.kind,
        "exact_valid_until": problem.exact.valid_until if np.isfinite(problem.exact.valid_until) else None,
    }
    if problem.exact.kind == "planar_riemann":
        # along the normal (the 1D solution's velocity, continuous across the contact) and
        # along the contact, a slip line across which the tangential velocity jumps
        along_normal, along_contact = problem.exact.solution.components(velocity - reference["velocity"])
        errors["L1_normal_velocity"] = float(np.sum(np.abs(along_normal) * area))
        errors["L1_tangential_velocity"] = float(np.sum(np.abs(along_contact) * area))
    if problem.exact.window is not None:
        errors["window"] = {"centre": list(problem.exact.window[0]), "radius": problem.exact.window[1]}
    return errors
