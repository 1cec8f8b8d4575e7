"""Compiled pressure and sound speed of every equation of state, for the per-step loops.

Each model of ``ale_xfem.eos`` has a code (``KIND``) and a row of parameters
(``kernel_parameters``).  Two functions dispatch on the code, and no others:
:func:`pressure_sound_speed_squared` (p and c², for the explicit loops) and
:func:`state_derivatives` (p, ∂p/∂ρ, ∂p/∂e and c², for the implicit solves of the mixed
cells).  A new model adds its code, its row and one branch to each, and no loop that calls
them changes.  The two write p and c² in their own orders of operations, as the models'
numpy methods did (tests/test_eos.py holds them equal to 10⁻¹³).
"""

from __future__ import annotations

import math

import numba
import numpy as np

# How every compiled loop of the project is built: cached on disk; IEEE arithmetic (x/0 is
# ±inf or NaN, as numpy gives, not an exception); and without reference counting.  Loops
# take their arrays from the caller and allocate none, and the small functions they inline
# take arrays as arguments, whose reference counts the compiler could not always prove
# unneeded: a loop over 10⁵ cells took 3.7 ms with them and 0.28 ms without (measured on
# one volume-and-velocity-jump loop of the 1D step).
LOOP = {"cache": True, "error_model": "numpy", "_nrt": False}
# A loop written once for a cell type argument is inlined into its entry point once per
# cell type, the type a constant there (ale_xfem.model.cell_kernels).
BODY = {**LOOP, "inline": "always"}

STIFFENED_GAS, MIE_GRUNEISEN, LINEAR = 0, 1, 2
PARAMETERS = 4  # the longest row of parameters


@numba.njit(**LOOP)
def hugoniot(rho0, c0, s, rho):  # pragma: no cover (compiled)
    """The Mie–Grüneisen reference curve, the linear Us = c0 + s up Hugoniot from (ρ0, e = 0),
    at ρ: (p_H, dp_H/dη, e_H, de_H/dη), η = 1 − ρ0/ρ."""
    eta = 1.0 - rho0 / rho
    denom = 1.0 - s * eta
    stiffness = rho0 * c0 ** 2.0
    p_h = stiffness * eta / (denom * denom)
    dp_h_deta = stiffness * (1.0 + s * eta) / denom ** 3.0
    e_h = p_h * eta / (2.0 * rho0)
    return p_h, dp_h_deta, e_h, (p_h + eta * dp_h_deta) / (2.0 * rho0)


@numba.njit(**LOOP)
def pressure_sound_speed_squared(kind, parameters, material, rho, e):  # pragma: no cover (compiled)
    """(p, c²) of one state of the material of row ``material`` of ``parameters``: every
    model's formulas, which the models' ``pressure`` and ``sound_speed_squared`` and the
    compiled loops all use (``state`` of each model writes them again beside its
    derivatives, for the implicit solves)."""
    if kind == STIFFENED_GAS:  # p = (γ − 1) ρ e − γ p∞,  c² = γ (γ − 1) (e − p∞/ρ)
        gamma, p_inf = parameters[material, 0], parameters[material, 1]
        if p_inf == 0.0:
            p = (gamma - 1.0) * rho * e
            c2 = gamma * (gamma - 1.0) * e
        else:
            p = (gamma - 1.0) * rho * e - gamma * p_inf
            c2 = gamma * (gamma - 1.0) * (e - p_inf / rho)
    elif kind == MIE_GRUNEISEN:  # about the linear Us–up Hugoniot (MieGruneisen)
        rho0, c0, s, gamma0 = (parameters[material, 0], parameters[material, 1], parameters[material, 2],
                               parameters[material, 3])
        p_h, dp_h_deta, e_h, de_h_deta = hugoniot(rho0, c0, s, rho)
        k = gamma0 * rho0
        p = p_h + k * (e - e_h)
        dp_drho = (dp_h_deta - k * de_h_deta) * (rho0 / (rho * rho))
        c2 = dp_drho + p / (rho * rho) * gamma0 * rho0
    else:  # LINEAR: p = p0 + c0² (ρ − ρ0), c = c0
        rho0, c0, p0 = parameters[material, 0], parameters[material, 1], parameters[material, 2]
        p = p0 + c0 ** 2.0 * (rho - rho0) + 0.0 * e
        c2 = c0 ** 2.0
    return p, c2


@numba.njit(**LOOP)
def pressure_sound_speed(kind, parameters, material, rho, e):  # pragma: no cover (compiled)
    """(p, c) of one state (:func:`pressure_sound_speed_squared`); c is NaN where c² < 0
    (outside the model's domain: the breakdown checks report it)."""
    p, c2 = pressure_sound_speed_squared(kind, parameters, material, rho, e)
    return p, math.sqrt(c2) if c2 >= 0.0 else np.nan


@numba.njit(**LOOP)
def fill_pressure_sound_speed_squared(kind, parameters, rho, e, pressure,
                                      sound_speed_squared):  # pragma: no cover (compiled)
    """p and c² of one model (row 0 of ``parameters``) at every entry of flat arrays."""
    for i in range(rho.size):
        pressure[i], sound_speed_squared[i] = pressure_sound_speed_squared(kind, parameters, 0, rho[i], e[i])


@numba.njit(**LOOP)
def fill_pressure_sound_speed(kinds, parameters, cell_material, density, energy, pressure,
                              sound_speed):  # pragma: no cover (compiled)
    """p and c of every occupied slot of (S, n_cells) arrays (material −1: p = c = 0)."""
    for slot in range(density.shape[0]):
        for cell in range(density.shape[1]):
            material = cell_material[slot, cell]
            if material < 0:
                pressure[slot, cell], sound_speed[slot, cell] = 0.0, 0.0
            else:
                pressure[slot, cell], sound_speed[slot, cell] = pressure_sound_speed(
                    kinds[material], parameters, material, density[slot, cell], energy[slot, cell])


@numba.njit(**LOOP)
def state_derivatives(kind, parameters, material, rho, e):  # pragma: no cover (compiled)
    """(p, ∂p/∂ρ|_e, ∂p/∂e|_ρ, c²) of one state of the material of row ``material`` of
    ``parameters``: what the implicit solves linearise (every model's ``state``)."""
    if kind == STIFFENED_GAS:  # p = (γ − 1) ρ e − γ p∞
        gamma, p_inf = parameters[material, 0], parameters[material, 1]
        g1 = gamma - 1.0
        p = g1 * rho * e - gamma * p_inf
        return p, g1 * e, g1 * rho, gamma * g1 * (e - p_inf / rho)
    if kind == MIE_GRUNEISEN:  # p = p_H + Γ0 ρ0 (e − e_H) about the linear Us–up Hugoniot
        rho0, c0, s, gamma0 = (parameters[material, 0], parameters[material, 1], parameters[material, 2],
                               parameters[material, 3])
        p_h, dp_h_deta, e_h, de_h_deta = hugoniot(rho0, c0, s, rho)
        k = gamma0 * rho0
        p = p_h + k * (e - e_h)
        dp_drho = (dp_h_deta - k * de_h_deta) * rho0 / (rho * rho)
        return p, dp_drho, k, dp_drho + p / (rho * rho) * k
    # LINEAR: p = p0 + c0² (ρ − ρ0)
    p, c2 = pressure_sound_speed_squared(kind, parameters, material, rho, e)
    return p, c2, 0.0, c2


@numba.njit(**LOOP)
def fill_state(kind, parameters, rho, e, pressure, dp_drho, dp_de, sound_speed_squared):  # pragma: no cover
    """:func:`state_derivatives` of one model (row 0 of ``parameters``) at every entry of
    flat arrays."""
    for i in range(rho.size):
        pressure[i], dp_drho[i], dp_de[i], sound_speed_squared[i] = state_derivatives(kind, parameters, 0, rho[i],
                                                                                      e[i])
