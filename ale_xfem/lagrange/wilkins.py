"""The explicit Wilkins scheme for pure cells, driving its compiled kernels (kernels.py).

Staggered grid: velocities at nodes, thermodynamic state constant per cell.  Lumped nodal
masses M_i = Σ_K m_K / (nodes per cell).  Corner forces F_Ki = (p_K + q_K) ∂V_K/∂x_i (the
weak form −∫_K σ:∇ψ_i of the paper's momentum equation with σ = −(p + q) I constant in K).

Time-centring: the compatible predictor–corrector of Caramana, Burton, Shashkov & Whalen
(JCP 146, 1998), which DESIGN.md §5 recommends:

    F^n from the state n; predictor u* = u^n + dt F^n/M, x* = x^n + dt (u^n + u*)/2,
    m e* = m e^n − dt Σ_i F^n_Ki·(u^n + u*)/2;  F* from the predicted state;
    F̄ = (F^n + F*)/2;  u^{n+1} = u^n + dt F̄/M;  ū = (u^n + u^{n+1})/2;  x^{n+1} = x^n + dt ū;
    m_K e_K^{n+1} = m_K e_K^n − dt Σ_i F̄_Ki·ū_i.

The kinetic energy gained, Σ_i M_i (u^{n+1} − u^n)·ū_i = dt Σ_i F̄_i·ū_i, is exactly the
internal energy lost: total energy is conserved to round-off (boundary work aside).  The
paper's trapezoidal stresses in mixed cells (§2.2.1) are the same time-centring.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ale_xfem.lagrange import kernels
from ale_xfem.lagrange.breakdown import Breakdown
from ale_xfem.lagrange.compile_clock import own_clock
from ale_xfem.lagrange.interval_steps import BLOCK_CELLS, one_gas_steps, one_gas_steps_in_blocks, runs_in_passes
from ale_xfem.eos import kernel_tables
from ale_xfem.model.cell_kernels import CELL_TYPE_CODES, cell_geometry, quad_combinations
from ale_xfem.model.diagnostics import place
from ale_xfem.lagrange.closure import MixedCellClosure, MixedView
from ale_xfem.model.boundaries import Boundary, held_arrays
from ale_xfem.model.mesh import MeshArrays, corner_jacobians
from ale_xfem.model.mixed_cells import MixedCells
from ale_xfem.model.state import MaterialLayout, State, TwoSlotArrays, thermodynamics


@dataclass
class ForceEvaluation:
    """Everything the step needs from one state (shapes: (n_cells,) unless noted)."""

    volume: np.ndarray
    shape: np.ndarray  # (3, 2, n_cells): the cells' shape (ale_xfem.model.cell_kernels; 1D: empty)
    density: np.ndarray  # (S, n_cells)
    pressure: np.ndarray  # (S, n_cells)
    sound_speed: np.ndarray  # (S, n_cells)
    viscosity: np.ndarray  # artificial viscosity q
    velocity_jump: np.ndarray  # Δu = L ∇·u (negative in compression)
    stress: np.ndarray  # P = p + q, the pressure of the corner forces F_Ki = P ∂V/∂x_i
    corner_force: np.ndarray  # (dim, k, n_cells): F_Ki (+ hourglass forces), component first
    nodal_force: np.ndarray  # (dim, n_nodes)
    mixed_sound_speed: np.ndarray | None  # c of each mixed cell (the larger of its two)
    mixed_viscosity: np.ndarray | None = None  # q of the mixed cells (n_mixed,)
    length: np.ndarray | None = None  # CFL length of each cell (1D: its volume)
    hourglass_force: tuple | None = None  # quadrilaterals: (s_0, s_1, Q (2, n_cells)) (kernels.hourglass_forces)
    corner_velocity: np.ndarray | None = None  # quadrilaterals: the velocity's corner combinations (3, dim, n_cells)
    least_corner: np.ndarray | None = None  # quadrilaterals: each cell's least corner det J (> 0: untangled)


class ExplicitWilkins:
    """One explicit Lagrangian step of pure cells (see module docstring)."""

    def __init__(self, mesh: MeshArrays, materials, layout: MaterialLayout, node_mass,
                 boundaries: list[Boundary], numerics, artificial_viscosity: bool = True,
                 mixed: MixedCells | None = None, viscous_time_step: bool = True,
                 closures=None):
        if layout.slots != 1 and (mixed is None or closures is None):
            raise ValueError("two material slots need mixed cells and their closures")
        self.mesh, self.materials, self.layout = mesh, materials, layout
        # The explicit loop evaluates slot 0 of every cell (a mixed cell's α); the mixed
        # cells' stresses are then replaced by their interface pressure.
        self.pure_layout = layout.first_slot()
        # closures(mixed cells) → their MixedCellClosure (ale_xfem.mixed.closures.Closures)
        self.closures = closures
        self.closure: MixedCellClosure | None = None if mixed is None else closures(mixed)
        self.corners = mesh.corners
        self.node_mass = node_mass
        self.inverse_node_mass = 1.0 / node_mass
        self.constraints = [b for b in boundaries if b.kind != "free"]
        # a node on two sides (a corner of a 2D box) counts once in the reactions
        self.constrained_nodes = (np.unique(np.concatenate([b.nodes for b in self.constraints]))
                                  if self.constraints else np.zeros(0, dtype=np.int64))
        self.free_nodes = np.ones(mesh.n_nodes)
        self.free_nodes[self.constrained_nodes] = 0.0
        self.numerics = numerics
        self.artificial_viscosity = artificial_viscosity
        # the time step resolves the viscosity's stiffness (stable_time_step); in 1D its
        # factor L_q/L is 1
        self.viscous_time_step = viscous_time_step and artificial_viscosity and mesh.cell_type.dimension > 1
        # viscous hourglass control: quadrilaterals only (triangles have no hourglass modes)
        self.quadrilaterals = mesh.cell_type.name == "quadrilateral"
        self.hourglass = numerics.hourglass if self.quadrilaterals else 0.0
        self.mixed_seconds, self.mixed_calls = 0.0, 0  # time in the implicit interface solve
        # The state a step ends with starts the next step (no remap of the whole state in
        # between, which relaxes the state it makes): its mixed cells are relaxed before its
        # forces are evaluated (the closure's finish).  simulate() sets it from the mesh motion.
        self.relax_end_state = True
        # the (2, n_cells) arrays of the states the step makes (slot 1: the mixed cells')
        self.two_slots = TwoSlotArrays(mesh.n_cells)
        # what the compiled kernels take (ale_xfem.lagrange.kernels)
        self.cell_code = CELL_TYPE_CODES[mesh.cell_type.name]
        self.cell_nodes = mesh.compiled_cell_nodes
        self.runs = mesh.corner_runs  # cells whose corners run on: no index array read
        corners = mesh.corners
        # the order numpy summed corner values in (kernels.scatter_corners)
        self.scatter_mode = (kernels.RUNS if corners.grid is not None or corners.all_slices
                             else kernels.FLAT if self.quadrilaterals else kernels.PER_CORNER)
        self.corner_is_run = np.array([isinstance(i, slice) for i in corners.index])
        self.scratch = np.empty(mesh.n_nodes)
        self.held = held_arrays(self.constraints, mesh.dimension)
        self.no_shape = np.empty((3, 2, 0))
        self.no_cells, self.no_values = np.zeros(0, dtype=np.int64), np.zeros(0)
        self.no_hourglass = (self.no_values, self.no_values, np.empty((2, 0)))
        self.viscosity_law = (float(numerics.q_quadratic), float(numerics.q_linear), bool(artificial_viscosity))
        self.held_nodes = self.constrained_nodes.astype(np.int64)
        self.eos_tables = kernel_tables(tuple(m.eos for m in materials))  # (kinds, parameters)
        # 1D meshes whose cell k is nodes k + r_0, k + r_1 (every DOLFINx interval mesh in
        # serial): their pure states are evaluated by the intervals' loops alone, with one
        # gas's model a constant of the loop where there is one
        self.gas_model = kernels.one_gas_model(self.eos_tables)
        self.running_intervals = self.cell_code == CELL_TYPE_CODES["interval"] and self.runs[4] == 1
        self.predicted_arrays = None  # kernels.pure_step's arrays of the predicted state, reused
        # On several ranks (ale_xfem.parallel): replaces the ghost nodes' values of a nodal
        # force by their owners', after each evaluation; None on one rank.
        self.exchange = None
        # and the serial run's number of each of its nodes, for diagnostics (None: the same)
        self.node_numbers = None
        self.sum_stack, self.sum_partial = np.empty((3, 64), dtype=np.int64), np.empty(64)  # kernels.pairwise_sum's

    @property
    def mixed(self) -> MixedCells | None:
        """The current mixed cells (None: every cell is pure)."""
        return None if self.closure is None else self.closure.mixed

    def rebuild(self, layout: MaterialLayout, node_mass, mixed: MixedCells | None) -> None:
        """Take the material layout, lumped masses and mixed cells left by a remap."""
        self.layout = layout
        self.pure_layout = layout.first_slot()
        self.node_mass = node_mass
        self.inverse_node_mass = 1.0 / node_mass
        self.closure = None if mixed is None else self.closures(mixed)

    # -- forces -------------------------------------------------------------------------

    def corner_velocities(self, node_velocity):
        """What the corner work needs of a nodal velocity field beyond the field itself: for
        quadrilaterals its corner combinations (3, components, n_cells) (linear: those of
        u^n + u are the sum of theirs); otherwise None."""
        if not self.quadrilaterals:
            return None
        combos = np.empty((3, node_velocity.shape[0], self.mesh.n_cells))
        quad_combinations(node_velocity, self.cell_nodes, self.runs, True, combos)
        return combos

    def evaluate(self, node_position, node_velocity, material_mass, material_energy,
                 mixed_view: MixedView | None = None, slots: int = 1, known=None,
                 with_length: bool = True, hourglass=None, tangle_check: bool = True,
                 corner_velocity=None) -> ForceEvaluation:
        """Forces of a state.  Density, pressure and sound speed come out as (slots,
        n_cells) arrays with slot 0 filled (slots = 2: the caller fills slot 1 of the
        mixed cells, every other entry of slot 1 is 0), so that the mixed-cell step takes
        them as they are instead of copying rows.  ``known``: the (density, pressure, sound
        speed) of a state at these positions, taken instead of evaluated again.
        ``with_length``: also the cells' CFL lengths (not needed of the predicted state);
        ``hourglass``: hourglass forces to use instead of evaluating them;
        ``tangle_check``: quadrilaterals: each cell's least corner det J (not needed of
        the predicted state); the positions' hourglass shape is formed for it and where
        the hourglass forces are computed;
        ``corner_velocity`` (corner_velocities of node_velocity): already known.

        Without mixed cells and with the thermodynamics to evaluate, one compiled loop does
        it all (kernels.evaluate_pure; on running intervals kernels.evaluate_one_gas_intervals
        or evaluate_any_intervals, which compile the intervals' loop alone); otherwise the same functions run in stages, between
        which the mixed cells' closure sets their entries."""
        n, code, nodes, runs = self.mesh.n_cells, self.cell_code, self.cell_nodes, self.runs
        dim, k = self.mesh.cell_type.dimension, self.mesh.cell_type.nodes_per_cell
        numerics = self.numerics
        volume = np.empty(n)
        shape = self.no_shape if dim == 1 else np.empty((3, 2, n))
        # a triangle's corners all have det J = 2A: the volume says it
        least_corner = np.empty(n) if self.quadrilaterals and tangle_check else None
        length = np.empty(n) if dim > 1 and with_length else None
        if self.quadrilaterals and corner_velocity is None:
            corner_velocity = self.corner_velocities(node_velocity)
        combos = self.no_shape if corner_velocity is None else corner_velocity
        compute_hourglass = self.quadrilaterals and self.hourglass > 0.0 and hourglass is None
        # the hourglass shape h where the tangle check or the hourglass forces need it
        hourglass_shape = tangle_check or compute_hourglass
        if compute_hourglass:
            hourglass = (np.empty(n), np.empty(n), np.empty((2, n)))
        hourglass_arrays = self.no_hourglass if hourglass is None else hourglass
        corner_force = np.empty((dim, k, n)) if dim > 1 else None
        rows = self.no_shape if corner_force is None else corner_force
        jump, viscosity, stress = np.empty(n), np.empty(n), np.empty(n)
        mass0, energy0 = material_mass[:1], material_energy[:1]
        mixed_viscosity = mixed_sound_speed = None
        if mixed_view is None and known is None:
            density, pressure, sound_speed = (
                np.empty((1, n)) if slots == 1 else self.two_slots.take(self.mixed.cells) for _ in range(3))
            out = (volume, shape, self.no_values if least_corner is None else least_corner,
                   self.no_values if length is None else length, density[0], pressure[0], sound_speed[0], jump,
                   viscosity, stress)
            hourglass_control = (hourglass is not None, compute_hourglass, self.hourglass, *hourglass_arrays)
            if self.running_intervals:  # the intervals' loops alone (compiled for the one gas's model)
                nodal_force = np.empty((dim, self.mesh.n_nodes))
                (kernels.evaluate_one_gas_intervals if self.gas_model >= 0 else kernels.evaluate_any_intervals)(
                    node_position, node_velocity, combos, nodes, runs, self.eos_tables,
                    self.pure_layout.cell_material[0], mass0[0], energy0[0], self.viscosity_law, hourglass_control,
                    out, rows, (self.scatter_mode, self.corner_is_run, self.scratch), nodal_force)
                if self.exchange is not None:
                    self.exchange(nodal_force)
                return ForceEvaluation(volume, shape, density, pressure, sound_speed, viscosity, jump, stress, None,
                                       nodal_force, None, None, volume, hourglass, corner_velocity, least_corner)
            kernels.evaluate_pure(code, node_position, node_velocity, combos, nodes, runs, hourglass_shape,
                                  length is not None, self.eos_tables,
                                  self.pure_layout.cell_material[0], mass0[0], energy0[0], self.viscosity_law,
                                  hourglass_control, out, rows, True)
        else:
            cells = self.mixed.cells if mixed_view is not None else self.no_cells
            if known is not None:
                density, pressure, sound_speed = known
            else:
                density = self.two_slots.take(self.mixed.cells) if slots == 2 else np.empty((1, n))
            kernels.geometry_and_rates(code, node_position, node_velocity, combos, nodes, runs, hourglass_shape,
                                       length is not None, known is None, mass0[0], volume, shape,
                                       self.no_values if least_corner is None else least_corner,
                                       self.no_values if length is None else length, density[0], jump)
            if known is None:
                if mixed_view is not None:  # slot 0 of a mixed cell is its α part
                    density[0, cells] = mass0[0, cells] / mixed_view.volume_left
                if slots == 2:  # into slot 0 of two-slot arrays
                    pressure, sound_speed = (self.two_slots.take(self.mixed.cells) for _ in range(2))
                else:
                    pressure, sound_speed = np.empty((1, n)), np.empty((1, n))
                thermodynamics(self.materials, self.pure_layout, density[:1], energy0,
                               out=(pressure[:1], sound_speed[:1]))
            mixed_density, interface_pressure = self.no_values, self.no_values
            if mixed_view is not None:
                # the density and sound speed a mixed cell's viscosity sees: its closure's
                mixed_density, mixed_sound_speed = self.closure.viscosity_medium(mixed_view, volume, density,
                                                                                 sound_speed, self.node_mass)
                interface_pressure = mixed_view.interface_pressure
            kernels.stress_and_corner_forces(
                code, volume, shape, combos, jump, density[0], sound_speed[0], pressure[0], numerics.q_quadratic,
                numerics.q_linear, self.artificial_viscosity, cells, mixed_density,
                self.no_values if mixed_sound_speed is None else mixed_sound_speed, interface_pressure,
                hourglass is not None, compute_hourglass, self.hourglass, *hourglass_arrays, viscosity, stress, rows)
            if mixed_view is not None:
                mixed_viscosity = viscosity[cells]
        nodal_force = np.empty((dim, self.mesh.n_nodes))
        kernels.scatter_corners(code, stress, rows, nodes, runs, self.scatter_mode, self.corner_is_run, self.scratch,
                                nodal_force)
        if self.exchange is not None:
            self.exchange(nodal_force)
        if dim == 1:
            length = volume  # the CFL length of an interval
        return ForceEvaluation(volume, shape, density, pressure, sound_speed, viscosity, jump, stress,
                               corner_force, nodal_force, mixed_sound_speed, mixed_viscosity, length, hourglass,
                               corner_velocity, least_corner)

    def evaluate_state(self, state: State, thermodynamics_known: bool = False) -> ForceEvaluation:
        """Forces of a state; ``thermodynamics_known``: its densities, pressures and sound
        speeds are those of its positions and energies (a state just built by the remap),
        so they are taken as they are."""
        view = None if self.mixed is None else MixedView.of(state, self.mixed.cells)
        known = (state.material_density, state.material_pressure,
                 state.material_sound_speed) if thermodynamics_known else None
        return self.evaluate(state.node_position, state.node_velocity, state.material_mass,
                             state.material_energy, view, known=known)

    # -- time step ----------------------------------------------------------------------

    def stable_time_step(self, evaluation: ForceEvaluation) -> float:
        """CFL limit with the viscous signal speed: dt_K = L / max(Q + √(Q² + c²), |Δu|),
        Q = (c1 c + 2 c2 |Δu|) L_q/L in compression (the form of Benson, CMAME 99, 1992).  A
        mixed cell counts with its whole length and the larger sound speed of its materials.

        L_q/L: the viscosity's length (√A in 2D) over the CFL length (the least width).  The
        viscosity is a diffusion of coefficient ν = (c1 c + c2 |Δu|) L_q across the cell's
        width L, stable for dt ≲ L²/ν: Benson's 1D form, where L_q = L, scaled by L_q/L.
        Measured (2026-11-22, tenth session): without it (``numerics.viscous_time_step =
        false``) Noh on crossed triangles broke down on 80 × 80 (t = 0.53) and 100 × 100
        (t = 0.42) — a sliver triangle on the diagonal, √A ≈ 6 × its width, its centre node
        oscillating from step to step, the viscosity of the compression half cooling the
        cell; with it, 80 × 80 runs to t = 0.6 (L1(ρ) 0.117).  On cells that keep their
        shape L_q/L = 1 (squares, the crossed triangles of a square); compressed cells take
        smaller steps (Saltzman and Sedov: about twice as many, L1(ρ) within 0.2 %)."""
        return self._time_limits(evaluation)[0]

    def limiting_cell(self, evaluation: ForceEvaluation, position) -> str:
        """The cell whose CFL limit sets the time step, described for a diagnostic: its
        index, centroid, CFL length, sound speed and velocity jump (2D with the viscous time
        step: also the viscosity's length √A, which makes a sliver's steps small)."""
        cell = int(np.argmin(self._cell_time_limits(evaluation)))
        sound_speed = evaluation.sound_speed[0, cell]
        if evaluation.mixed_sound_speed is not None and cell in self.mixed.cells:
            sound_speed = evaluation.mixed_sound_speed[np.flatnonzero(self.mixed.cells == cell)[0]]
        viscous = ""
        if self.viscous_time_step:
            length_q = float(self.mesh.cell_type.viscosity_length(evaluation.volume[cell]))
            viscous = f", viscosity length √A {length_q:.3g}"
        where = place(cell, self.mesh.cell_centroids(position)[cell])
        return (f"{where} sets it: length {evaluation.length[cell]:.3g}{viscous}, "
                f"sound speed {sound_speed:.3g}, velocity jump {evaluation.velocity_jump[cell]:.3g}")

    def _cell_time_limits(self, evaluation: ForceEvaluation):
        """Each cell's time step limit before the CFL number: its signal speed's or its
        nodes' acceleration's (:meth:`_time_limits`), the smaller."""
        _, times, ratio = self._time_limits(evaluation)
        np.minimum(times, np.sqrt(0.5 * ratio), out=times)
        return times

    def _time_limits(self, evaluation: ForceEvaluation):
        """(the CFL time step (kernels.stable_time_step), each cell's time limit from its
        signal speed, each cell's L / a).  A mixed cell's sound limit counts the larger sound speed
        of its materials.  a is the largest acceleration F_i / M_i of the cell's nodes (held
        directions removed), and its time step limit √(L / 2a): a node starting from rest
        moves by at most a sixteenth of the cell's length in the step (with the CFL number
        ½).  The sound speeds of a state do not see the pressure jumps it is about to
        release: air at 1e5 Pa struck by water at 1e9 Pa is shocked at 3e4 m/s, and the
        first step, taken at the sound speeds, turned the air cell beside the interface
        inside out (a quarter of a cell still let 24 of 80 such cases break down; a
        sixteenth, 6).  Where pressures vary smoothly a ≈ Δp/(ρL) is small and the limit
        does not bind: no pure-cell run of the regression captures changed."""
        mixed = evaluation.mixed_sound_speed is not None
        sound_times, ratio = np.empty(evaluation.volume.size), np.empty(evaluation.volume.size)
        dt = kernels.stable_time_step(evaluation.nodal_force, self.inverse_node_mass, self.held, evaluation.volume,
                                      evaluation.length, evaluation.sound_speed[0], evaluation.velocity_jump,
                                      self.viscous_time_step, self.viscosity_law,
                                      self.mixed.cells if mixed else self.no_cells,
                                      evaluation.mixed_sound_speed if mixed else self.no_values, self.cell_nodes,
                                      self.runs, float(self.numerics.cfl), np.empty_like(evaluation.nodal_force),
                                      sound_times, ratio)
        return float(dt), sound_times, ratio

    # -- the step -----------------------------------------------------------------------

    def _advance_velocity(self, velocity, force, dt):
        """u = u^n + dt F/M on the free directions, the boundaries held."""
        new_velocity = np.empty_like(velocity)
        kernels.advance_velocity(velocity, force, dt, self.inverse_node_mass, new_velocity)
        kernels.hold(new_velocity, *self.held, False)
        return new_velocity

    def _moved(self, u0, u, x0, dt):
        """(u^n + u, x^n + dt (u^n + u)/2)."""
        velocity_sum, x = np.empty_like(u0), np.empty_like(x0)
        kernels.velocity_sum_and_position(u0, u, x0, dt, velocity_sum, x)
        return velocity_sum, x

    def _energy(self, energy, mass, dt, evaluations, velocity_sum, corner_sum, out):
        """The compatible energy update (kernels.compatible_energy) into slot 0 of ``out``:
        with the forces of ``evaluations[0]`` (the predictor) or the mean of the two (the
        corrector)."""
        a, b = evaluations[0], evaluations[-1]
        hourglass = a.hourglass_force
        kernels.compatible_energy(self.cell_code, self.cell_nodes, self.runs, energy, mass, dt,
                                  a.shape, a.stress, b.shape, b.stress, len(evaluations) == 2,
                                  hourglass is not None, *(self.no_hourglass if hourglass is None else hourglass),
                                  velocity_sum, self.no_shape if corner_sum is None else corner_sum, out[0])
        return out

    def step(self, state: State, dt: float, start: ForceEvaluation | None = None,
             remapped_next: bool = False):
        """Advance by dt.  Returns (new state, evaluation of the new state, boundary work,
        boundary impulse).  Raises :class:`Breakdown` on an unphysical predicted or final
        state; ``state`` itself is never modified.

        ``remapped_next``: the whole state is remapped after this step (Eulerian or smoothed
        mesh), which evaluates the remapped state's forces itself: the forces of the
        Lagrangian state are not evaluated (the evaluation returned is None) and the new
        state holds only what the remap reads — positions, velocities, masses, energies and
        volumes; its densities, pressures and sound speeds are None."""
        if self.closure is not None:
            state, relaxed = self.closure.relax_start(state)
            if relaxed:
                start = None
        first = start if start is not None else self.evaluate_state(state)
        if self.closure is None:  # every cell pure: the whole step in one compiled call
            return self._pure_step(state, dt, first, remapped_next)
        mass, energy = state.material_mass, state.material_energy
        u0, x0 = state.node_velocity, state.node_position
        # The velocity sums u^n + u are carried instead of means: the ½ of ū is folded into
        # the scalars of the energy update.

        # Predictor.
        u_pred = self._advance_velocity(u0, first.nodal_force, dt)
        self.closure.hold_predictor(u0, u_pred)
        velocity_sum, x_pred = self._moved(u0, u_pred, x0, dt)
        corner_velocity = corner_sum = None
        if self.quadrilaterals:  # the corners of u^n + u* by a sum, not a gather
            corner_velocity = self.corner_velocities(u_pred)
            corner_sum = np.add(first.corner_velocity, corner_velocity)
        e_pred = self._energy(energy[0], mass[0], dt, [first], velocity_sum, corner_sum,
                              np.empty((1, energy.shape[1])))
        view = None
        if self.closure is not None:  # the mixed cells at x*, for their viscosity q*
            view = self.closure.predicted_view(state, first, x_pred, e_pred)
        # the hourglass forces of the start serve the predicted state too (a damping device,
        # evaluated once a step; the same forces enter momentum and energy: still compatible);
        # its hourglass shape is not needed
        predicted = self.evaluate(x_pred, u_pred, mass, e_pred, view, with_length=False,
                                  hourglass=first.hourglass_force, tangle_check=False,
                                  corner_velocity=corner_velocity)
        if not predicted.volume.min() > 0.0:
            self.check_predicted(predicted, x_pred, e_pred)

        # Corrector with the time-centred forces F̄ = (F^n + F*)/2.
        mean_force = first.nodal_force + predicted.nodal_force
        mean_force *= 0.5
        solution = None
        if self.closure is not None and self.closure.implicit:  # the mixed cells' n+1 stress
            clock = own_clock()  # (compiling a kernel at its first call is no part of the solve's time)
            solution = self.closure.implicit_solve(self, state, first, predicted, mean_force, dt,
                                                   dt * self.inverse_node_mass)
            if self.exchange is not None:  # the mixed cells' stress on a ghost node: its owner's sum
                self.exchange(mean_force)
            self.mixed_seconds += own_clock() - clock
            self.mixed_calls += 1
        u_new = self._advance_velocity(u0, mean_force, dt)
        velocity_sum, x_new = self._moved(u0, u_new, x0, dt)
        # With mixed cells the new energies fill slot 0 of a two-slot array (slot 1: the
        # mixed cells' second materials, set by the interface solve).
        e_new = (np.empty((1, energy.shape[1])) if self.mixed is None
                 else self.two_slots.take(self.mixed.cells))
        corner_velocity = corner_sum = None
        if self.quadrilaterals:
            corner_velocity = self.corner_velocities(u_new)
            corner_sum = np.add(first.corner_velocity, corner_velocity)
        self._energy(energy[0], mass[0], dt, [first, predicted], velocity_sum, corner_sum, e_new)

        boundary_work, boundary_impulse = self._boundary_reaction(u0, u_new, velocity_sum, mean_force, dt)

        if self.mixed is None and remapped_next:
            return self._state_for_remap(state, None, x_new, u_new, e_new, dt), None, \
                boundary_work, boundary_impulse
        if self.mixed is None:
            final = self.evaluate(x_new, u_new, mass, e_new, corner_velocity=corner_velocity)
            if not self._healthy(final, e_new):
                self.check_predicted(predicted, x_pred, e_pred)  # report the first cause
                self.check(final, x_new, e_new, "")
            new_state = state.evolved(
                time=state.time + dt, node_position=x_new, node_velocity=u_new,
                material_energy=e_new, material_volume=final.volume[None, :],
                material_density=final.density, material_pressure=final.pressure,
                material_sound_speed=final.sound_speed)
            return new_state, final, boundary_work, boundary_impulse
        solution = self.closure.end_of_step(state, first, predicted, x_new, e_new, solution)
        if remapped_next:
            return self._state_for_remap(state, solution, x_new, u_new, e_new, dt), None, \
                boundary_work, boundary_impulse
        new_state, final = self.closure.finish(self, state, solution, x_new, u_new, e_new, dt)
        if not self._healthy(final, new_state.material_energy[:1]):
            self.check_predicted(predicted, x_pred, e_pred)
            self.check(final, x_new, new_state.material_energy[:1], "")
        return new_state, final, boundary_work, boundary_impulse

    def breaks_mixed_cell(self, failure: Breakdown) -> bool:
        """Whether ``failure`` is a mixed cell's (a step the run may take again with a
        smaller dt)."""
        return self.mixed is not None and failure.cell in self.mixed.cells

    def _stage_arrays(self, u0, x0, final: bool):
        """The arrays kernels.pure_step fills for one state (its order): new ones for the
        final state (they become the new state and its evaluation), the stepper's own,
        reused, for the predicted state."""
        n, dim, k = self.mesh.n_cells, self.mesh.dimension, self.mesh.cell_type.nodes_per_cell
        quadrilateral = self.quadrilaterals

        def cells(rows=None):
            return np.empty(n) if rows is None else np.empty((rows, n))
        return [np.empty_like(u0), np.empty_like(u0), np.empty_like(x0),
                np.empty((3, u0.shape[0], n)) if quadrilateral else self.no_shape, self.no_shape,
                cells(1), cells(), self.no_shape if dim == 1 else np.empty((3, 2, n)),
                cells() if quadrilateral and final else self.no_values,
                cells() if dim > 1 and final else self.no_values,
                cells(1), cells(1), cells(1), cells(), cells(), cells(),
                np.empty((dim, k, n)) if dim > 1 else self.no_shape, np.empty((dim, self.mesh.n_nodes))]

    def _predicted_arrays(self, u0, x0):
        """(the predicted state's arrays, the tuple kernels.pure_step takes of them): made
        once, reused by every step."""
        if self.predicted_arrays is None or self.predicted_arrays[0][0].shape != u0.shape:
            arrays = self._stage_arrays(u0, x0, final=False)
            self.predicted_arrays = (arrays, tuple(a[0] if i in (5, 10, 11, 12) else a for i, a in enumerate(arrays)))
        return self.predicted_arrays

    def _pure_step(self, state: State, dt: float, first: ForceEvaluation, remapped_next: bool):
        """step() of a state whose cells are all pure: kernels.pure_step, then the boundary
        reactions' work and impulse, the new state and its evaluation."""
        u0, x0 = state.node_velocity, state.node_position
        mass, energy = state.material_mass, state.material_energy
        n = self.mesh.n_cells
        predicted, final = self._predicted_arrays(u0, x0), self._stage_arrays(u0, x0, final=True)
        compute_hourglass = self.quadrilaterals and self.hourglass > 0.0
        final_hourglass = ((np.empty(n), np.empty(n), np.empty((2, n))) if compute_hourglass and not remapped_next
                           else self.no_hourglass)
        hourglass = first.hourglass_force
        start = (x0, u0, mass[0], energy[0], first.nodal_force, first.stress, first.shape,
                 self.no_shape if first.corner_velocity is None else first.corner_velocity,
                 *(self.no_hourglass if hourglass is None else hourglass), hourglass is not None)
        mean_force = np.empty_like(first.nodal_force)
        # e, density, pressure, sound speed are (1, n_cells) arrays: the kernel fills row 0
        as_rows = (5, 10, 11, 12)
        arguments = (self.cell_code, (self.cell_nodes, self.runs, self.scatter_mode, self.corner_is_run, self.scratch),
                     self.held, self.eos_tables, self.pure_layout.cell_material[0], self.viscosity_law,
                     float(self.hourglass), dt, self.inverse_node_mass, start)
        final_arrays = tuple(a[0] if i in as_rows else a for i, a in enumerate(final))
        step = (*arguments, predicted[1], final_arrays, final_hourglass, mean_force, not remapped_next, False)
        if self.exchange is None:
            status = kernels.pure_step(*step, kernels.BOTH_STAGES)
        else:  # the two stages apart, each evaluation's ghost forces exchanged after it
            predicted_status = kernels.pure_step(*step, kernels.PREDICTOR_STAGE)
            self.exchange(predicted[1][17])
            # the corrector runs after a failed predictor too: every rank exchanges alike
            final_status = kernels.pure_step(*step, kernels.CORRECTOR_STAGE)
            if not remapped_next:
                self.exchange(final_arrays[17])
            status = predicted_status or final_status
        u_new, velocity_sum, x_new = final[0], final[1], final[2]
        e_new = final[5]
        if status == 1:
            self.check_predicted(self._stage_evaluation(predicted[0], first.hourglass_force), predicted[0][2],
                                 predicted[0][5])
        work, impulse = self._boundary_reaction(u0, u_new, velocity_sum, mean_force, dt)
        if remapped_next:
            return self._state_for_remap(state, None, x_new, u_new, e_new, dt), None, work, impulse
        evaluation = self._stage_evaluation(final, None if final_hourglass is self.no_hourglass else final_hourglass)
        if status == 2:
            self.check_predicted(self._stage_evaluation(predicted[0], first.hourglass_force), predicted[0][2],
                                 predicted[0][5])  # report the first cause
            self.check(evaluation, x_new, e_new, "")
        new_state = state.evolved(
            time=state.time + dt, node_position=x_new, node_velocity=u_new, material_energy=e_new,
            material_volume=evaluation.volume[None, :], material_density=evaluation.density,
            material_pressure=evaluation.pressure, material_sound_speed=evaluation.sound_speed)
        return new_state, evaluation, work, impulse

    def compiles_steps(self) -> bool:
        """Whether a Lagrangian run's steps go in compiled chunks (:meth:`steps`): every
        cell pure, or mixed cells whose closure can (MixedCellClosure.compiles_steps)."""
        return self.closure is None or self.closure.compiles_steps(self)

    def steps(self, state: State, evaluation: ForceEvaluation, clock: dict, boundary_impulse):
        """Steps of a Lagrangian run in one compiled call: :meth:`pure_steps`, or the mixed
        cells' closure's (MixedCellClosure.steps); the same clock and results."""
        if self.closure is None:
            return self.pure_steps(state, evaluation, clock, boundary_impulse)
        return self.closure.steps(self, state, evaluation, clock, boundary_impulse)

    def pure_steps(self, state: State, evaluation: ForceEvaluation, clock: dict, boundary_impulse,
                   in_passes: bool = True):
        """Steps of a state whose cells are all pure on a Lagrangian mesh, in one compiled
        call (kernels.pure_steps): the steps simulate() would take one by one, stopping
        before one that is not plain (see there).  ``clock``: t_end, dt_previous, growth,
        budget, steps_left, watch_stall, boundary_work, and t_stop (optional: stop once the
        time reaches it).  One gas on intervals numbered along the tube takes its steps in
        three stages, four loops over the cells and nodes (``in_passes``,
        ale_xfem.lagrange.interval_steps; block by block above BLOCK_CELLS cells), other
        states in stages (kernels.pure_steps): the same numbers.  Returns (steps taken, state,
        evaluation, last dt, least dt, largest dt, boundary work, boundary impulse)."""
        u0, x0 = np.ascontiguousarray(state.node_velocity), np.ascontiguousarray(state.node_position)
        n, n_nodes = self.mesh.n_cells, self.mesh.n_nodes
        as_rows = (5, 10, 11, 12)
        evaluation_arrays = [u0, np.empty_like(u0), x0,
                             self.no_shape if evaluation.corner_velocity is None else evaluation.corner_velocity,
                             self.no_shape,
                             state.material_energy[:1], evaluation.volume, evaluation.shape,
                             self.no_values if evaluation.least_corner is None else evaluation.least_corner,
                             evaluation.length if self.mesh.dimension > 1 else self.no_values,
                             evaluation.density[:1], evaluation.pressure[:1], evaluation.sound_speed[:1],
                             evaluation.velocity_jump, evaluation.viscosity, evaluation.stress,
                             self.no_shape if evaluation.corner_force is None else evaluation.corner_force,
                             evaluation.nodal_force]
        compute_hourglass = self.quadrilaterals and self.hourglass > 0.0
        sets = [evaluation_arrays] + [self._stage_arrays(u0, x0, final=True) for _ in range(2)]
        hourglass_sets = [evaluation.hourglass_force or self.no_hourglass] + [
            (np.empty(n), np.empty(n), np.empty((2, n))) if compute_hourglass else self.no_hourglass for _ in range(2)]

        def kernel_set(arrays, hourglass):
            return (tuple(np.ascontiguousarray(a[0]) if i in as_rows else a for i, a in enumerate(arrays)),
                    hourglass, hourglass is not self.no_hourglass)
        first, one, two = (kernel_set(a, h) for a, h in zip(sets, hourglass_sets))
        dim = self.mesh.dimension
        held = self.held_nodes
        impulse = np.array(boundary_impulse, dtype=float)
        passes = in_passes and runs_in_passes(self.cell_code, self.runs, self.scatter_mode, held, n, n_nodes,
                                              u0.shape[0], self.gas_model)
        in_stages = (one_gas_steps_in_blocks if n > BLOCK_CELLS else one_gas_steps) if passes else kernels.pure_steps
        steps, t, dt_previous, dt_min, dt_max, work, current = in_stages(
            self.cell_code, (self.cell_nodes, self.runs, self.scatter_mode, self.corner_is_run, self.scratch),
            self.held, self.eos_tables, self.pure_layout.cell_material[0],
            self.viscosity_law, float(self.hourglass), self.inverse_node_mass, state.material_mass[0],
            (self.node_mass, float(self.numerics.cfl), self.viscous_time_step, np.empty((dim, n_nodes)), np.empty(n),
             np.empty(n), self.no_cells, self.no_values),
            (held, np.empty(2 * dim * held.size), self.sum_stack, self.sum_partial, np.empty((dim, n_nodes))),
            (float(state.time), float(clock["t_end"]), float(clock["dt_previous"]), float(clock["growth"]),
             int(clock["budget"]), int(clock["steps_left"]), bool(clock["watch_stall"]),
             float(clock["boundary_work"]), float(clock.get("t_stop", np.inf))),
            first, self._predicted_arrays(u0, x0)[1], (one, two), impulse)
        if steps == 0:
            return 0, state, evaluation, dt_previous, dt_min, dt_max, work, impulse
        arrays, hourglass = sets[current], hourglass_sets[current]
        new_evaluation = self._stage_evaluation(arrays, None if hourglass is self.no_hourglass else hourglass)
        new_state = state.evolved(
            time=t, node_position=arrays[2], node_velocity=arrays[0], material_energy=arrays[5],
            material_volume=new_evaluation.volume[None, :], material_density=new_evaluation.density,
            material_pressure=new_evaluation.pressure, material_sound_speed=new_evaluation.sound_speed)
        return steps, new_state, new_evaluation, dt_previous, dt_min, dt_max, work, impulse

    def _stage_evaluation(self, arrays, hourglass) -> ForceEvaluation:
        """The ForceEvaluation of a state kernels.pure_step evaluated (its arrays)."""
        (_, _, _, combos, _, _, volume, shape, least_corner, length, density, pressure, sound_speed, jump,
         viscosity, stress, rows, nodal_force) = arrays
        dim = self.mesh.dimension
        return ForceEvaluation(volume, shape, density, pressure, sound_speed, viscosity, jump, stress,
                               rows if dim > 1 else None, nodal_force, None, None,
                               volume if dim == 1 else (length if length.size else None), hourglass,
                               combos if self.quadrilaterals else None,
                               least_corner if least_corner.size else None)

    def _boundary_reaction(self, u0, u_new, velocity_sum, mean_force, dt):
        """Work and impulse of the boundary reactions R = M du/dt − F̄ on held nodes
        (kernels.boundary_reaction: the sums in numpy's order)."""
        dim = mean_force.shape[0]
        boundary_impulse = np.zeros(u0.shape[0])
        held = self.constrained_nodes
        if not held.size:
            return 0.0, boundary_impulse
        boundary_work = kernels.boundary_reaction(
            self.node_mass, self.held_nodes, u0, u_new, velocity_sum, mean_force, dt, np.empty(2 * dim * held.size),
            self.sum_stack, self.sum_partial, boundary_impulse)
        return float(boundary_work), boundary_impulse

    def _state_for_remap(self, state, solution, x_new, u_new, e_new, dt):
        """The new state as the remap reads it (no force evaluation): volumes from the
        positions, the mixed cells' volumes and energies from the interface solve.  The
        remap's own evaluation then checks what it derives (density, EOS, stress)."""
        volume = np.empty(self.mesh.n_cells)
        shape = self.no_shape if self.mesh.dimension == 1 else np.empty((3, 2, volume.size))
        # the Lagrangian mesh the remap reads must not be tangled
        least_corner = np.empty(volume.size) if self.quadrilaterals else self.no_values
        cell_geometry(self.cell_code, x_new, self.cell_nodes, self.runs, True, volume, shape, least_corner)
        interface = {}
        if self.mixed is None:
            volumes = volume[None, :]
        else:
            volumes, interface = self.closure.state_for_remap(self, state, solution, x_new, u_new, volume, e_new, dt)
        if self.quadrilaterals:
            self.check_corners(least_corner, x_new)
        occupied = volumes[:, self.mixed.cells] if self.mixed is not None else volume
        # (on several MPI ranks a rank may hold none of the mixed cells)
        if not (volume.min() > 0.0 and occupied.min(initial=np.inf) > 0.0 and np.isfinite(e_new.sum())):
            for name, values, allowed, good in (("volume", volumes, "> 0", lambda v: v > 0.0),
                                                ("specific internal energy", e_new, "finite", np.isfinite)):
                bad = np.any(~good(values) & (state.material_mass > 0.0), axis=0)
                if np.any(bad):
                    cell = int(np.flatnonzero(bad)[0])
                    raise Breakdown(name, cell, float(np.min(values[:, cell])),
                                    self.mesh.cell_centroids(x_new)[cell], allowed)
        return state.evolved(time=state.time + dt, node_position=x_new, node_velocity=u_new,
                             material_energy=e_new, material_volume=volumes, material_density=None,
                             material_pressure=None, material_sound_speed=None, **interface)

    def _healthy(self, evaluation: ForceEvaluation, energy) -> bool:
        """Positive volumes, no corner turned inside out (quadrilaterals; a triangle's
        corners all have det J = 2A), finite energies, sound speeds, stresses."""
        least_corner = self.no_values if evaluation.least_corner is None else evaluation.least_corner
        return kernels.healthy(evaluation.volume, evaluation.sound_speed[0], energy[0], evaluation.stress,
                               least_corner)

    def check(self, evaluation: ForceEvaluation, position, energy, prefix: str) -> None:
        """Raise :class:`Breakdown` naming the first offending cell and quantity, causes
        before consequences (a NaN sound speed makes NaN positions one stage later)."""
        if self._healthy(evaluation, energy):
            return
        centroids = self.mesh.cell_centroids(position)
        volume, density = evaluation.volume, evaluation.density[0]
        checks = (
            ("volume", volume, "> 0", lambda v: ~(v <= 0.0)),
            ("density", density, "> 0", lambda v: ~(v <= 0.0)),
            ("specific internal energy", energy[0], "finite", np.isfinite),
            ("sound speed", evaluation.sound_speed[0],
             "real (the EOS was evaluated outside its domain)", np.isfinite),
            ("pressure", evaluation.pressure[0], "finite", np.isfinite),
            ("volume", volume, "finite", np.isfinite),
            ("stress p + q", evaluation.stress, "finite", np.isfinite),
        )
        for name, values, allowed, good in checks:
            bad = ~good(values)
            if np.any(bad):
                cell = int(np.flatnonzero(bad)[0])
                raise Breakdown(prefix + name, cell, float(values[cell]), centroids[cell], allowed)
            if name == "volume" and evaluation.least_corner is not None:
                self.check_corners(evaluation.least_corner, position, prefix)

    def check_predicted(self, evaluation: ForceEvaluation, position, energy) -> None:
        """:meth:`check` of a step's predicted state (its diagnostic says "predicted")."""
        self.check(evaluation, position, energy, "predicted ")

    def check_remapped(self, evaluation: ForceEvaluation, position, energy) -> None:
        """:meth:`check` of a state the remap made (its diagnostic says "remapped")."""
        self.check(evaluation, position, energy, "remapped ")

    def check_corners(self, least_corner, position, prefix: str = "") -> None:
        """Raise :class:`Breakdown` if a quadrilateral's corner has turned inside out (the
        mesh has tangled, even where every area is still positive), naming the cell and the
        corner; ``least_corner``: each cell's least corner det J."""
        if least_corner.min() > 0.0:
            return
        cell = int(np.argmin(least_corner))
        x = self.mesh.cell_vertex_positions(position)[cell]  # (4, 2), corners going round
        jacobian = corner_jacobians(x)
        corner = int(np.argmin(jacobian))
        node = int(self.mesh.cell_nodes[cell, corner])
        node = node if self.node_numbers is None else int(self.node_numbers[node])
        raise Breakdown(f"{prefix}corner {corner} (node {node}) det J",
                        cell, float(jacobian[corner]), x.mean(axis=0),
                        "> 0 (the corner has turned inside out: the mesh is tangled)")
