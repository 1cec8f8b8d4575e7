"""Equations of state, vectorised over numpy arrays.

Every model maps (density ρ [kg/m³ or scene units], specific internal energy e) to
pressure p and gives what an explicit step and an implicit solve need:

- ``pressure(rho, e)``
- ``sound_speed_squared(rho, e)``: c² = ∂p/∂ρ|_e + (p/ρ²) ∂p/∂e|_ρ (isentropic)
- ``dp_drho(rho, e)`` (at constant e) and ``dp_de(rho, e)`` (at constant ρ)
- ``energy(rho, p)``: the inverse in e, to initialise a region from (ρ, p)
- ``state(rho, e)``: (p, ∂p/∂ρ, ∂p/∂e, c²) at once, for implicit solves
- ``admissible(rho, p)``: which initial states the model allows, with the reason

``pressure``, ``sound_speed_squared`` and ``state`` are compiled formulas
(``ale_xfem.eos.kernels``: the per-step loops call them one state at a time); ``state``
writes p and c² again beside the derivatives the implicit solves need, and
tests/test_eos.py holds the two equal to 10⁻¹³.

Models: ideal gas, stiffened gas (γ, p∞), Mie–Grüneisen with a linear Us–up Hugoniot
reference (ρ0, c0, s, Γ0; Γρ = Γ0ρ0 constant), linear (dp = c0² dρ, i.e. dp = ρc² dρ/ρ).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ale_xfem.eos.kernels import (LINEAR, MIE_GRUNEISEN, PARAMETERS, STIFFENED_GAS, fill_pressure_sound_speed_squared,
                                  fill_state)


@functools.lru_cache(maxsize=64)
def _parameter_row(model) -> np.ndarray:
    """A model's parameters as the one row (1, PARAMETERS) the compiled loops take."""
    row = np.zeros((1, PARAMETERS))
    values = model.kernel_parameters()
    row[0, :len(values)] = values
    row.flags.writeable = False
    return row


class CompiledModel:
    """p(ρ, e) and c²(ρ, e) of a model, from its compiled formulas
    (ale_xfem.eos.kernels.pressure_sound_speed_squared: the one place they are written),
    for numbers or arrays of any shape."""

    def _kernel_arguments(self, rho, e):
        """ρ and e as contiguous arrays of one shape, and the model's row of parameters."""
        rho, e = np.asarray(rho, dtype=float), np.asarray(e, dtype=float)
        if rho.shape != e.shape:
            rho, e = np.broadcast_arrays(rho, e)
        contiguous = [a if a.flags.c_contiguous else a.copy() for a in (rho, e)]  # (0-d arrays stay 0-d)
        return contiguous[0], contiguous[1], _parameter_row(self)

    def pressure_and_sound_speed_squared(self, rho, e):
        rho, e, row = self._kernel_arguments(rho, e)
        pressure, sound_speed_squared = np.empty(rho.shape), np.empty(rho.shape)
        fill_pressure_sound_speed_squared(self.KIND, row, rho.reshape(-1), e.reshape(-1), pressure.reshape(-1),
                                          sound_speed_squared.reshape(-1))
        return pressure[()], sound_speed_squared[()]

    def state(self, rho, e):
        """(p, ∂p/∂ρ|_e, ∂p/∂e|_ρ, c²) at once, for the implicit solves
        (ale_xfem.eos.kernels.state_derivatives, where each model writes them)."""
        rho, e, row = self._kernel_arguments(rho, e)
        values = tuple(np.empty(rho.shape) for _ in range(4))
        fill_state(self.KIND, row, rho.reshape(-1), e.reshape(-1), *(v.reshape(-1) for v in values))
        return tuple(v[()] for v in values)

    def pressure(self, rho, e):
        return self.pressure_and_sound_speed_squared(rho, e)[0]

    def sound_speed_squared(self, rho, e):
        """c² = ∂p/∂ρ|_e + (p/ρ²) ∂p/∂e|_ρ (isentropic)."""
        return self.pressure_and_sound_speed_squared(rho, e)[1]


@dataclass(frozen=True)
class StiffenedGas(CompiledModel):
    """p = (γ − 1) ρ e − γ p∞.  p∞ = 0 is the ideal gas."""

    gamma: float
    p_inf: float = 0.0

    KIND = STIFFENED_GAS  # its branch in ale_xfem.eos.kernels.pressure_sound_speed_squared

    def kernel_parameters(self):
        return (self.gamma, self.p_inf)

    def dp_drho(self, rho, e):
        return (self.gamma - 1.0) * e

    def dp_de(self, rho, e):
        return (self.gamma - 1.0) * rho

    def energy(self, rho, p):
        return (p + self.gamma * self.p_inf) / ((self.gamma - 1.0) * rho)

    max_density = float("inf")  # no compression limit

    def admissible(self, rho, p):
        """Return None if (ρ, p) is an allowed state, else what is allowed."""
        if not rho > 0.0:
            return "density > 0"
        if not p + self.p_inf > 0.0:
            return f"pressure > -p_inf = {-self.p_inf:g}" if self.p_inf else "pressure > 0"
        return None


def IdealGas(gamma: float) -> StiffenedGas:
    return StiffenedGas(gamma=gamma, p_inf=0.0)


@dataclass(frozen=True)
class MieGruneisen(CompiledModel):
    """Mie–Grüneisen about the linear Us = c0 + s·up Hugoniot of the state (ρ0, e = 0).

    With η = 1 − ρ0/ρ:  p_H = ρ0 c0² η / (1 − sη)²,  e_H = p_H η / (2ρ0)  (Rankine–Hugoniot
    from p = 0, e = 0), and p = p_H + Γ0 ρ0 (e − e_H).  The same curve is used in
    expansion (η < 0); compression is bounded by η < 1/s.
    """

    rho0: float
    c0: float
    s: float
    gamma0: float

    KIND = MIE_GRUNEISEN

    def kernel_parameters(self):
        return (self.rho0, self.c0, self.s, self.gamma0)

    def _hugoniot(self, rho):
        eta = 1.0 - self.rho0 / rho
        denom = 1.0 - self.s * eta
        p_h = self.rho0 * self.c0**2 * eta / denom**2
        dp_h_deta = self.rho0 * self.c0**2 * (1.0 + self.s * eta) / denom**3
        e_h = p_h * eta / (2.0 * self.rho0)
        de_h_deta = (p_h + eta * dp_h_deta) / (2.0 * self.rho0)
        return eta, p_h, dp_h_deta, e_h, de_h_deta

    def dp_drho(self, rho, e):
        _, _, dp_h_deta, _, de_h_deta = self._hugoniot(rho)
        deta_drho = self.rho0 / rho**2
        return (dp_h_deta - self.gamma0 * self.rho0 * de_h_deta) * deta_drho

    def dp_de(self, rho, e):
        return self.gamma0 * self.rho0 * np.ones_like(np.asarray(rho, dtype=float))

    def energy(self, rho, p):
        _, p_h, _, e_h, _ = self._hugoniot(rho)
        return e_h + (p - p_h) / (self.gamma0 * self.rho0)

    @property
    def max_density(self) -> float:
        """The reference Hugoniot is singular at η = 1/s, i.e. ρ = ρ0 s/(s − 1)."""
        return self.rho0 * self.s / (self.s - 1.0)

    def admissible(self, rho, p):
        if not rho > 0.0:
            return "density > 0"
        if not 1.0 - self.rho0 / rho < 1.0 / self.s:
            return f"density < rho0·s/(s−1) = {self.rho0 * self.s / (self.s - 1.0):g} (Hugoniot limit)"
        return None


@dataclass(frozen=True)
class Linear(CompiledModel):
    """Barotropic linear law p = p0 + c0² (ρ − ρ0): dp = ρc² dρ/ρ with constant c = c0."""

    rho0: float
    c0: float
    p0: float = 0.0

    KIND = LINEAR

    def kernel_parameters(self):
        return (self.rho0, self.c0, self.p0)

    def dp_drho(self, rho, e):
        return self.c0**2 * np.ones_like(np.asarray(rho, dtype=float))

    def dp_de(self, rho, e):
        return np.zeros_like(np.asarray(rho, dtype=float))

    def energy(self, rho, p):
        # e plays no part in the pressure; it still carries the work of compression.
        return np.zeros_like(np.asarray(rho, dtype=float))

    max_density = float("inf")

    def admissible(self, rho, p):
        if not rho > 0.0:
            return "density > 0"
        expected = self.p0 + self.c0**2 * (rho - self.rho0)
        if not np.isclose(p, expected, rtol=1e-9, atol=1e-12 * max(1.0, abs(expected))):
            return f"pressure = p0 + c0²(density − rho0) = {expected:g} (barotropic law)"
        return None


# Scene name → (constructor, required parameters, optional parameters with defaults).
MODELS = {
    "ideal_gas": (IdealGas, ("gamma",), {}),
    "stiffened_gas": (StiffenedGas, ("gamma", "p_inf"), {}),
    "mie_gruneisen": (MieGruneisen, ("rho0", "c0", "s", "gamma0"), {}),
    "linear": (Linear, ("rho0", "c0"), {"p0": 0.0}),
}


def parameter_ranges(eos_name: str) -> dict[str, tuple[str, callable]]:
    """What each parameter of a model must satisfy, as (description, predicate)."""
    positive = ("> 0", lambda v: v > 0.0)
    ranges = {
        "ideal_gas": {"gamma": ("> 1", lambda v: v > 1.0)},
        "stiffened_gas": {"gamma": ("> 1", lambda v: v > 1.0), "p_inf": (">= 0", lambda v: v >= 0.0)},
        "mie_gruneisen": {"rho0": positive, "c0": positive, "s": ("> 1", lambda v: v > 1.0),
                          "gamma0": positive},
        "linear": {"rho0": positive, "c0": positive, "p0": ("any real", lambda v: True)},
    }
    return ranges[eos_name]


@functools.lru_cache(maxsize=64)
def kernel_tables(models: tuple):
    """The codes (n,) and parameter rows (n, PARAMETERS) of a tuple of models, as the
    compiled kernels take them (ale_xfem.eos.kernels)."""
    kinds = np.array([model.KIND for model in models], dtype=np.int64)
    parameters = np.zeros((len(models), PARAMETERS))
    for row, model in zip(parameters, models):
        values = model.kernel_parameters()
        row[:len(values)] = values
    return kinds, parameters


def make_eos(eos_name: str, parameters: dict):
    constructor, required, optional = MODELS[eos_name]
    values = {**optional, **parameters}
    return constructor(**{k: float(v) for k, v in values.items()})
