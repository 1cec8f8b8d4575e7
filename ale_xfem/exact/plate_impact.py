"""Impedance matching for the plate impact of two Mie–Grüneisen solids.

Both plates start at their reference state (ρ = ρ0, p = 0, e = 0); the flyer (left) moves
at u_L, the target (right) at u_R < u_L.  On contact a shock runs into each plate.  Across a
shock with particle-velocity jump w into material at rest in its own frame, the linear
Hugoniot gives Us = c0 + s·w and p = ρ0·Us·w.  Equal pressure and velocity at the contact:

    ρ0L (c0L + sL (u_L − u)) (u_L − u) = ρ0R (c0R + sR (u − u_R)) (u − u_R)

a quadratic in the contact velocity u, with exactly one root in (u_R, u_L).
The shocked densities follow from mass conservation, ρ = ρ0 Us / (Us − w).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Plate:
    rho0: float
    c0: float
    s: float
    velocity: float


@dataclass(frozen=True)
class PlateImpactSolution:
    flyer: Plate
    target: Plate
    x0: float
    contact_velocity: float
    contact_pressure: float

    @classmethod
    def solve(cls, flyer: Plate, target: Plate, x0: float = 0.0) -> "PlateImpactSolution":
        if not flyer.velocity > target.velocity:
            raise ValueError("plate impact: the flyer (left) must move faster than the target (right)")
        # Write w_R = u − u_R, w_L = u_L − u = Δ − w_R with Δ = u_L − u_R, and expand
        # ρ0L (c0L + sL w_L) w_L − ρ0R (c0R + sR w_R) w_R = 0 as a·w_R² + b·w_R + c = 0.
        d = flyer.velocity - target.velocity
        zl, zr = flyer.rho0, target.rho0
        a = zl * flyer.s - zr * target.s
        b = -zl * flyer.c0 - 2.0 * zl * flyer.s * d - zr * target.c0
        c = zl * flyer.c0 * d + zl * flyer.s * d * d
        if abs(a) < 1e-14 * (abs(b) + abs(c) / d):
            w_r = -c / b
        else:
            disc = np.sqrt(b * b - 4.0 * a * c)
            roots = np.array([(-b - disc) / (2.0 * a), (-b + disc) / (2.0 * a)])
            inside = roots[(roots > -1e-12 * d) & (roots < d * (1 + 1e-12))]
            w_r = float(inside[0])
        u = target.velocity + w_r
        p = target.rho0 * (target.c0 + target.s * w_r) * w_r
        return cls(flyer, target, x0, u, p)

    def _shock(self, plate: Plate, sign: int):
        """Lab-frame shock speed and shocked density in one plate (sign −1: flyer)."""
        w = abs(self.contact_velocity - plate.velocity)
        us = plate.c0 + plate.s * w
        return plate.velocity + sign * us, plate.rho0 * us / (us - w)

    def wave_speeds(self) -> tuple[float, float]:
        return self._shock(self.flyer, -1)[0], self._shock(self.target, +1)[0]

    def sample(self, x, t: float) -> dict[str, np.ndarray]:
        x = np.asarray(x, dtype=float)
        xi = (x - self.x0) / t
        left_speed, left_density = self._shock(self.flyer, -1)
        right_speed, right_density = self._shock(self.target, +1)
        shocked = (xi > left_speed) & (xi < right_speed)
        side = np.where(xi < self.contact_velocity, 0, 1)
        density = np.where(side == 0, self.flyer.rho0, self.target.rho0).astype(float)
        density = np.where(shocked, np.where(side == 0, left_density, right_density), density)
        velocity = np.where(side == 0, self.flyer.velocity, self.target.velocity).astype(float)
        velocity = np.where(shocked, self.contact_velocity, velocity)
        pressure = np.where(shocked, self.contact_pressure, 0.0)
        # Rankine–Hugoniot energy from (p = 0, e = 0): e = p (1/ρ0 − 1/ρ) / 2.
        rho0 = np.where(side == 0, self.flyer.rho0, self.target.rho0)
        energy = 0.5 * pressure * (1.0 / rho0 - 1.0 / density)
        return {"density": density, "velocity": velocity, "pressure": pressure,
                "internal_energy": energy, "side": side}
