"""Exact Riemann problem for two stiffened gases (each side its own γ and p∞).

Toro, *Riemann Solvers and Numerical Methods for Fluid Dynamics*, ch. 4, with every
pressure p replaced by p + p∞ of its own side: a stiffened gas is an ideal gas in the
shifted pressure, so the wave curves keep their form (shock: Rankine–Hugoniot; rarefaction:
isentrope (p + p∞)/ρ^γ = const).  The star pressure is found by Newton's method on
f_L(p) + f_R(p) + u_R − u_L = 0 (Toro eq. 4.5).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class GasState:
    density: float
    velocity: float
    pressure: float
    gamma: float
    p_inf: float = 0.0

    @property
    def sound_speed(self) -> float:
        return float(np.sqrt(self.gamma * (self.pressure + self.p_inf) / self.density))


@dataclass(frozen=True)
class StarState:
    pressure: float
    velocity: float
    density_left: float
    density_right: float


def _wave_curve(p, side: GasState):
    """f_K(p) and f_K'(p) of Toro eqs. 4.6–4.7 in the shifted pressure of side K."""
    g, pinf = side.gamma, side.p_inf
    pk = side.pressure + pinf
    ps = p + pinf
    if ps > pk:  # shock
        a = 2.0 / ((g + 1.0) * side.density)
        b = (g - 1.0) / (g + 1.0) * pk
        root = np.sqrt(a / (ps + b))
        return (ps - pk) * root, root * (1.0 - 0.5 * (ps - pk) / (ps + b))
    c = side.sound_speed  # rarefaction
    ratio = ps / pk
    f = 2.0 * c / (g - 1.0) * (ratio ** ((g - 1.0) / (2.0 * g)) - 1.0)
    if ratio <= 0.0:  # at the pressure floor p + p∞ = 0: the curve is vertical
        return f, np.inf
    df = 1.0 / (side.density * c) * ratio ** (-(g + 1.0) / (2.0 * g))
    return f, df


class VacuumError(ValueError):
    """The two states separate fast enough to open a vacuum: no star region."""


def star_state(left: GasState, right: GasState, tolerance: float = 1e-14) -> StarState:
    du = right.velocity - left.velocity
    # Pressure positivity condition (Toro eq. 4.40), shifted: the rarefaction curves
    # reach p + p∞ = 0 on the side with the larger p∞ first.
    floor = -min(left.p_inf, right.p_inf)
    f_floor = sum(_wave_curve(floor + 1e-300, s)[0] for s in (left, right)) + du
    if f_floor >= 0.0:
        raise VacuumError(f"the states separate into vacuum (Δu = {du:g})")
    # Start from the two-rarefaction guess (Toro eq. 4.46) in the shifted pressure of the
    # stiffer side, clipped above the floor.
    p = max(0.5 * (left.pressure + right.pressure), floor + 1e-8 * (abs(floor) + 1.0))
    for _ in range(200):
        fl, dfl = _wave_curve(p, left)
        fr, dfr = _wave_curve(p, right)
        step = (fl + fr + du) / (dfl + dfr)
        p_new = p - step
        if p_new <= floor:  # Newton overshoot below the admissible floor: bisect toward it
            p_new = 0.5 * (p + floor)
        change = abs(p_new - p) / (0.5 * (abs(p_new) + abs(p)) + abs(floor) + 1e-300)
        p = p_new
        if change < tolerance:
            break
    else:
        raise RuntimeError("exact Riemann solver: Newton iteration did not converge")
    fl, _ = _wave_curve(p, left)
    fr, _ = _wave_curve(p, right)
    u = 0.5 * (left.velocity + right.velocity) + 0.5 * (fr - fl)
    return StarState(p, u, _star_density(p, left), _star_density(p, right))


def _star_density(p, side: GasState):
    g, pinf = side.gamma, side.p_inf
    pk, ps = side.pressure + pinf, p + pinf
    if ps > pk:  # Toro eq. 4.50
        r = (g - 1.0) / (g + 1.0)
        return side.density * (ps / pk + r) / (r * ps / pk + 1.0)
    return side.density * (ps / pk) ** (1.0 / g)  # eq. 4.53


@dataclass(frozen=True)
class RiemannSolution:
    """The self-similar solution of a Riemann problem with the discontinuity at x0, t = 0."""

    left: GasState
    right: GasState
    x0: float
    star: StarState

    @classmethod
    def solve(cls, left: GasState, right: GasState, x0: float = 0.0) -> "RiemannSolution":
        return cls(left, right, x0, star_state(left, right))

    def wave_speeds(self) -> tuple[float, float]:
        """Slowest and fastest signal speeds (head of the outermost waves)."""
        s = self.star
        lo = self._side_speeds(self.left, -1)[0]
        hi = self._side_speeds(self.right, +1)[0]
        return min(lo, s.velocity), max(hi, s.velocity)

    def _side_speeds(self, side: GasState, sign: int):
        """(head, tail) speeds of the wave on one side; equal for a shock."""
        s, g, pinf = self.star, side.gamma, side.p_inf
        c = side.sound_speed
        ps, pk = s.pressure + pinf, side.pressure + pinf
        if ps > pk:
            shock = side.velocity + sign * c * np.sqrt((g + 1) / (2 * g) * ps / pk + (g - 1) / (2 * g))
            return shock, shock
        c_star = c * (ps / pk) ** ((g - 1.0) / (2.0 * g))
        return side.velocity + sign * c, s.velocity + sign * c_star

    def sample(self, x, t: float) -> dict[str, np.ndarray]:
        """Density, velocity, pressure, specific internal energy and side (0 left, 1 right)
        at positions x (any shape) and time t ≥ 0 (at t = 0 the initial data: the left state
        on x < x0)."""
        if t < 0:
            raise ValueError(f"a Riemann solution is sampled at t ≥ 0, not t = {t}")
        x = np.asarray(x, dtype=float)
        xi = (x - self.x0) / t if t > 0 else np.where(x < self.x0, -np.inf, np.inf)
        out = {k: np.empty_like(xi) for k in ("density", "velocity", "pressure")}
        side_of = np.where(xi < self.star.velocity, 0, 1)
        for index, (side, sign, rho_star) in enumerate(
            ((self.left, -1, self.star.density_left), (self.right, +1, self.star.density_right))
        ):
            mask = side_of == index
            head, tail = self._side_speeds(side, sign)
            g, pinf, c = side.gamma, side.p_inf, side.sound_speed
            z = xi[mask]
            # outer state, star state, then the rarefaction fan between head and tail.
            outer = sign * (z - head) > 0
            fan = (sign * (z - tail) > 0) & ~outer
            rho = np.full_like(z, rho_star)
            u = np.full_like(z, self.star.velocity)
            p = np.full_like(z, self.star.pressure)
            rho[outer], u[outer], p[outer] = side.density, side.velocity, side.pressure
            if np.any(fan):  # Toro eqs. 4.56 / 4.63 in shifted pressure
                zf = z[fan]
                factor = 2.0 / (g + 1.0) - sign * (g - 1.0) / ((g + 1.0) * c) * (side.velocity - zf)
                rho[fan] = side.density * factor ** (2.0 / (g - 1.0))
                u[fan] = 2.0 / (g + 1.0) * (-sign * c + (g - 1.0) / 2.0 * side.velocity + zf)
                p[fan] = (side.pressure + pinf) * factor ** (2.0 * g / (g - 1.0)) - pinf
            out["density"][mask], out["velocity"][mask], out["pressure"][mask] = rho, u, p
        gamma = np.where(side_of == 0, self.left.gamma, self.right.gamma)
        p_inf = np.where(side_of == 0, self.left.p_inf, self.right.p_inf)
        out["internal_energy"] = (out["pressure"] + gamma * p_inf) / ((gamma - 1.0) * out["density"])
        out["side"] = side_of
        return out
