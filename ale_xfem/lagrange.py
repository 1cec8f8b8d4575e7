"""The explicit Wilkins scheme for pure cells, vectorised over cells and nodes.

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

from ale_xfem.mesh import MeshArrays, constant_gradient, corner_dot
from ale_xfem.state import MaterialLayout, State, thermodynamics


class Breakdown(RuntimeError):
    """The state became unphysical: a one-line diagnostic (step, time, cell, quantity)."""

    def __init__(self, quantity: str, cell: int, value: float, position, allowed: str):
        self.quantity, self.cell, self.value, self.position = quantity, cell, value, position
        where = ", ".join(f"{v:.6g}" for v in np.atleast_1d(position))
        super().__init__(f"cell {cell} (x = {where}): {quantity} = {value:.6g}, must be {allowed}")


@dataclass(frozen=True)
class Boundary:
    """Nodes held by one boundary condition.

    kind ``wall``: no normal velocity (unit outward normal, free tangential slip);
    kind ``velocity``: the whole velocity prescribed (a piston);  ``free``: no constraint."""

    side: str
    kind: str
    nodes: np.ndarray
    normal: np.ndarray | None = None  # (dim,)
    velocity: np.ndarray | None = None  # (dim,)

    def apply(self, node_velocity: np.ndarray) -> None:
        """Impose the condition on node_velocity (dim, n_nodes), in place."""
        if self.kind == "wall":
            u = node_velocity[:, self.nodes]
            normal_part = self.normal @ u
            node_velocity[:, self.nodes] = u - self.normal[:, None] * normal_part
        elif self.kind == "velocity":
            node_velocity[:, self.nodes] = self.velocity[:, None]


@dataclass
class ForceEvaluation:
    """Everything the step needs from one state (shapes: (n_cells,) unless noted)."""

    volume: np.ndarray
    volume_gradient: list  # [corner][component]: ∂V_K/∂x_i (arrays, or scalars ±1 in 1D)
    density: np.ndarray  # (S, n_cells)
    pressure: np.ndarray  # (S, n_cells)
    sound_speed: np.ndarray  # (S, n_cells)
    viscosity: np.ndarray  # artificial viscosity q
    velocity_jump: np.ndarray  # Δu = L ∇·u (negative in compression)
    stress: np.ndarray  # P = p + q, the pressure of the corner forces F_Ki = P ∂V/∂x_i
    nodal_force: np.ndarray  # (dim, n_nodes)


class ExplicitWilkins:
    """One explicit Lagrangian step of pure cells (see module docstring)."""

    def __init__(self, mesh: MeshArrays, materials, layout: MaterialLayout, node_mass,
                 boundaries: list[Boundary], numerics, artificial_viscosity: bool = True):
        if layout.slots != 1:
            raise ValueError("the explicit Wilkins step handles pure cells (one material slot)")
        self.mesh, self.materials, self.layout = mesh, materials, layout
        self.corners = mesh.corners
        self.node_mass = node_mass
        self.inverse_node_mass = 1.0 / node_mass
        self.constraints = [b for b in boundaries if b.kind != "free"]
        self.constrained_nodes = (np.concatenate([b.nodes for b in self.constraints])
                                  if self.constraints else np.zeros(0, dtype=np.int64))
        self.numerics = numerics
        self.artificial_viscosity = artificial_viscosity

    # -- forces -------------------------------------------------------------------------

    def evaluate(self, node_position, node_velocity, material_mass, material_energy) -> ForceEvaluation:
        cell_type, corners = self.mesh.cell_type, self.corners
        volume, gradient = cell_type.volume_and_gradient(corners.gather(node_position))
        density = material_mass / volume
        pressure, sound_speed = thermodynamics(self.materials, self.layout, density, material_energy)
        volume_rate = corner_dot(gradient, corners.gather(node_velocity))  # dV/dt = Σ ∂V/∂x_i·u_i
        velocity_jump = cell_type.velocity_jump(volume_rate, volume)
        if self.artificial_viscosity:
            # Quadratic (von Neumann–Richtmyer) + linear (Landshoff) viscosity in compression:
            # q = ρ (c2 Δu² + c1 c |Δu|) for Δu < 0.
            compression = np.minimum(velocity_jump, 0.0)
            viscosity = self.numerics.q_quadratic * compression
            viscosity -= self.numerics.q_linear * sound_speed[0]
            viscosity *= compression
            viscosity *= density[0]
            stress = pressure[0] + viscosity
        else:
            viscosity = np.zeros_like(volume)
            stress = pressure[0]
        nodal_force = np.empty((cell_type.dimension, corners.n_nodes))
        for d in range(cell_type.dimension):
            corners.scatter_scaled([g_corner[d] for g_corner in gradient], stress, out=nodal_force[d])
        return ForceEvaluation(volume, gradient, density, pressure, sound_speed, viscosity,
                               velocity_jump, stress, nodal_force)

    def evaluate_state(self, state: State) -> ForceEvaluation:
        return self.evaluate(state.node_position, state.node_velocity, state.material_mass,
                             state.material_energy)

    # -- time step ----------------------------------------------------------------------

    def stable_time_step(self, evaluation: ForceEvaluation) -> float:
        """CFL limit with the viscous signal speed: dt_K = L / max(Q + √(Q² + c²), |Δu|),
        Q = c1 c + 2 c2 |Δu| in compression (the form of Benson, CMAME 99, 1992)."""
        c = evaluation.sound_speed[0]
        length = self.mesh.cell_type.length_scale(evaluation.volume)
        if self.artificial_viscosity:
            q_speed = np.minimum(evaluation.velocity_jump, 0.0)
            q_speed *= -2.0 * self.numerics.q_quadratic
            q_speed += self.numerics.q_linear * c
            signal = q_speed * q_speed
            signal += c * c
            np.sqrt(signal, out=signal)
            signal += q_speed
        else:
            signal = c
        # No cell may change its length by more than its own size in a step (cold gas
        # pushed by a piston has c ≈ 0: the velocity jump is then the only signal).
        signal = np.maximum(signal, np.abs(evaluation.velocity_jump))
        with np.errstate(divide="ignore"):
            dt = np.min(length / signal)
        return self.numerics.cfl * float(dt)

    # -- the step -----------------------------------------------------------------------

    def _advance_velocity(self, velocity, force, dt_over_node_mass):
        new_velocity = force * dt_over_node_mass
        new_velocity += velocity
        for boundary in self.constraints:
            boundary.apply(new_velocity)
        return new_velocity

    def _corner_work(self, evaluations, velocity_sum, scale):
        """scale · Σ_i F_Ki·(u^n + u)_i per cell, with F_Ki the sum over ``evaluations`` of
        their corner forces P_K ∂V_K/∂x_i.  When ∂V/∂x_i is constant (intervals) the
        stresses are summed first and the corner velocities are gathered once."""
        gather = self.corners.gather(velocity_sum)
        gradients = [e.volume_gradient for e in evaluations]
        if len(evaluations) > 1 and all(constant_gradient(g) for g in gradients) \
                and all(g == gradients[0] for g in gradients):
            stress = evaluations[0].stress + evaluations[1].stress
            for extra in evaluations[2:]:
                stress += extra.stress
            work = corner_dot(gradients[0], gather)
            work *= stress
        else:
            work = None
            for evaluation in evaluations:
                term = corner_dot(evaluation.volume_gradient, gather)
                term *= evaluation.stress
                work = term if work is None else np.add(work, term, out=work)
        work *= scale
        return work

    def step(self, state: State, dt: float, start: ForceEvaluation | None = None):
        """Advance by dt.  Returns (new state, evaluation of the new state, boundary work,
        boundary impulse).  Raises :class:`Breakdown` on an unphysical predicted or final
        state; ``state`` itself is never modified."""
        first = start if start is not None else self.evaluate_state(state)
        mass, energy = state.material_mass, state.material_energy
        u0, x0 = state.node_velocity, state.node_position
        dt_over_node_mass = dt * self.inverse_node_mass
        # The velocity sums u^n + u are carried instead of means: the ½ of ū is folded into
        # the scalars below.
        half_dt_over_mass = (0.5 * dt) / mass[0]

        # Predictor.
        u_pred = self._advance_velocity(u0, first.nodal_force, dt_over_node_mass)
        velocity_sum = u0 + u_pred
        x_pred = velocity_sum * (0.5 * dt)
        x_pred += x0
        e_pred = energy - self._corner_work([first], velocity_sum, half_dt_over_mass)
        predicted = self.evaluate(x_pred, u_pred, mass, e_pred)
        if not predicted.volume.min() > 0.0:
            self._check(predicted, x_pred, e_pred, "predicted ")

        # Corrector with the time-centred forces F̄ = (F^n + F*)/2.
        mean_force = first.nodal_force + predicted.nodal_force
        mean_force *= 0.5
        u_new = self._advance_velocity(u0, mean_force, dt_over_node_mass)
        velocity_sum = u0 + u_new
        x_new = velocity_sum * (0.5 * dt)
        x_new += x0
        half_dt_over_mass *= 0.5  # F̄ = ½ (F^n + F*)
        e_new = energy - self._corner_work([first, predicted], velocity_sum, half_dt_over_mass)

        # Work and impulse of the boundary reactions R = M du/dt − F̄ on held nodes.
        boundary_work, boundary_impulse = 0.0, np.zeros(u0.shape[0])
        if self.constrained_nodes.size:
            held = self.constrained_nodes
            reaction = (self.node_mass[held] * (u_new[:, held] - u0[:, held]) / dt
                        - mean_force[:, held])
            boundary_work = float(0.5 * dt * np.sum(reaction * velocity_sum[:, held]))
            boundary_impulse = dt * reaction.sum(axis=1)

        final = self.evaluate(x_new, u_new, mass, e_new)
        if not self._healthy(final, e_new):
            self._check(predicted, x_pred, e_pred, "predicted ")  # report the first cause
            self._check(final, x_new, e_new, "")
        new_state = state.evolved(
            time=state.time + dt, node_position=x_new, node_velocity=u_new,
            material_energy=e_new, material_volume=final.volume[None, :],
            material_density=final.density, material_pressure=final.pressure,
            material_sound_speed=final.sound_speed)
        return new_state, final, boundary_work, boundary_impulse

    @staticmethod
    def _healthy(evaluation: ForceEvaluation, energy) -> bool:
        """Cheap whole-array test: positive volumes, finite energies, sound speeds, stresses."""
        return bool(evaluation.volume.min() > 0.0 and np.isfinite(
            evaluation.sound_speed[0].sum() + energy.sum() + evaluation.stress.sum()))

    def _check(self, evaluation: ForceEvaluation, position, energy, prefix: str) -> None:
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
