"""Exact 2D references: Noh's implosion (cylindrical) and a piston driving a planar shock
into gas at rest (Saltzman's problem).  ``sample(points, t)`` takes points (..., 2) and
returns density, velocity (..., 2) and pressure."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class NohSolution:
    """Ideal gas (γ) of density ρ0 at zero pressure flowing to ``center`` at speed V:
    a cylindrical shock leaves the centre at D = (γ − 1)V/2; behind it the gas is at rest
    with ρ = ρ0 ((γ + 1)/(γ − 1))², p = (γ − 1) ρ V²/2; ahead of it ρ = ρ0 (1 + V t/r).
    (W. F. Noh, JCP 72, 1987.)"""

    center: tuple[float, float]
    density: float
    speed: float  # V > 0: inflow speed
    gamma: float

    @property
    def shock_speed(self) -> float:
        return 0.5 * (self.gamma - 1.0) * self.speed

    @property
    def shocked_density(self) -> float:
        return self.density * ((self.gamma + 1.0) / (self.gamma - 1.0)) ** 2

    def coordinate(self, points):
        """What the solution varies with: the distance r from the centre."""
        return np.linalg.norm(np.asarray(points, dtype=float) - np.asarray(self.center), axis=-1)

    def sample(self, points, t: float) -> dict[str, np.ndarray]:
        offset = np.asarray(points, dtype=float) - np.asarray(self.center)
        r = np.linalg.norm(offset, axis=-1)
        shocked = r < self.shock_speed * t
        unit = np.divide(offset, r[..., None], out=np.zeros_like(offset), where=r[..., None] > 0)
        with np.errstate(divide="ignore"):
            ahead = self.density * (1.0 + self.speed * t / r)
        density = np.where(shocked, self.shocked_density, ahead)
        velocity = np.where(shocked[..., None], 0.0, -self.speed * unit)
        pressure = np.where(shocked, 0.5 * (self.gamma - 1.0) * self.shocked_density * self.speed**2, 0.0)
        return {"density": density, "velocity": velocity, "pressure": pressure}


@dataclass(frozen=True)
class PistonSolution:
    """A piston on a plane wall (unit normal ``direction`` into the gas, through ``origin``)
    moving at speed u_p into an ideal gas (γ, ρ0, p0) at rest: a shock runs ahead of it at
    D = a + √(a² + c0²), a = (γ + 1) u_p/4, with ρ1 = ρ0 D/(D − u_p), p1 = p0 + ρ0 D u_p,
    and the gas between piston and shock moves with the piston."""

    origin: tuple[float, float]
    direction: tuple[float, float]
    piston_speed: float
    density: float
    pressure: float
    gamma: float

    @property
    def shock_speed(self) -> float:
        a = 0.25 * (self.gamma + 1.0) * self.piston_speed
        c2 = self.gamma * self.pressure / self.density
        return a + np.sqrt(a * a + c2)

    @property
    def shocked_density(self) -> float:
        d = self.shock_speed
        return self.density * d / (d - self.piston_speed)

    @property
    def shocked_pressure(self) -> float:
        return self.pressure + self.density * self.shock_speed * self.piston_speed

    def coordinate(self, points):
        """What the solution varies with: the distance from the piston's start along its motion."""
        return (np.asarray(points, dtype=float) - np.asarray(self.origin)) @ np.asarray(self.direction, dtype=float)

    def sample(self, points, t: float) -> dict[str, np.ndarray]:
        n = np.asarray(self.direction, dtype=float)
        s = self.coordinate(points)
        shocked = s < self.shock_speed * t
        density = np.where(shocked, self.shocked_density, self.density)
        pressure = np.where(shocked, self.shocked_pressure, self.pressure)
        velocity = np.where(shocked[..., None], self.piston_speed * n, 0.0)
        return {"density": density, "velocity": velocity, "pressure": pressure}


def contact_tangent(normal) -> np.ndarray:
    """The tangent t = (−n_y, n_x) of a line with unit normal n: the direction a planar
    Riemann problem's tangential velocities are measured along."""
    n = np.asarray(normal, dtype=float)
    return np.array([-n[1], n[0]])


@dataclass(frozen=True)
class PlanarRiemann:
    """A 1D Riemann solution laid along the unit normal ``normal`` through ``point``: the
    left state on (x − point)·n < 0.  The normal velocity is the 1D solution's; the
    tangential velocity (along t = (−n_y, n_x)) is ``tangential[0]`` left of the contact and
    ``tangential[1]`` right of it: in inviscid flow the contact is a slip line, and each
    side keeps its tangential velocity (it is carried with the fluid, across the waves
    unchanged)."""

    solution: object  # ale_xfem.exact.RiemannSolution, x0 = 0
    point: tuple[float, float]
    normal: tuple[float, float]
    tangential: tuple[float, float] = (0.0, 0.0)

    def coordinate(self, points):
        """What the solution varies with: the distance from ``point`` along the normal."""
        return (np.asarray(points, dtype=float) - np.asarray(self.point)) @ np.asarray(self.normal, dtype=float)

    def components(self, vectors) -> tuple[np.ndarray, np.ndarray]:
        """Vectors (…, 2) split along the normal and along the contact (the tangent)."""
        vectors = np.asarray(vectors, dtype=float)
        return vectors @ np.asarray(self.normal, dtype=float), vectors @ contact_tangent(self.normal)

    def sample(self, points, t: float) -> dict[str, np.ndarray]:
        n = np.asarray(self.normal, dtype=float)
        tangent = contact_tangent(n)
        s = self.coordinate(points)
        values = self.solution.sample(s, t)
        shear = np.where(s < self.solution.star.velocity * t, self.tangential[0], self.tangential[1])
        return {"density": values["density"],
                "velocity": values["velocity"][..., None] * n + shear[..., None] * tangent,
                "pressure": values["pressure"]}


@dataclass(frozen=True)
class SpinningDisk:
    """A disk of radius R (density ρ_d) spinning at ω about its centre inside a fluid
    (density ρ_o) at rest at pressure p₀: v_θ = ω r and p = p₀ − ½ ρ_d ω² (R² − r²) inside,
    rest and p₀ outside.  A steady state of the Euler equations (radial equilibrium
    dp/dr = ρ v_θ²/r, div u = 0, u·∇ of everything zero) with a slip line at r = R: it holds
    for ever where the interface lets the disk slide."""

    center: tuple[float, float]
    radius: float
    angular_velocity: float
    density: float  # the disk's
    outer_density: float
    pressure: float  # p₀, outside and at the rim

    def coordinate(self, points):
        """What the solution varies with: the distance r from the centre."""
        return np.linalg.norm(np.asarray(points, dtype=float) - np.asarray(self.center), axis=-1)

    def sample(self, points, t: float) -> dict[str, np.ndarray]:
        offset = np.asarray(points, dtype=float) - np.asarray(self.center)
        r = np.linalg.norm(offset, axis=-1)
        inside = r < self.radius
        omega = self.angular_velocity
        swirl = omega * np.stack([-offset[..., 1], offset[..., 0]], axis=-1)
        return {"density": np.where(inside, self.density, self.outer_density),
                "velocity": np.where(inside[..., None], swirl, 0.0),
                "pressure": np.where(inside, self.pressure - 0.5 * self.density * omega**2 * (self.radius**2 - r**2),
                                     self.pressure)}

    @property
    def angular_momentum(self) -> float:
        """The disk's angular momentum about its centre per unit length, ½ π ρ ω R⁴."""
        return 0.5 * np.pi * self.density * self.angular_velocity * self.radius**4
