"""One implicit step of enriched mixed cells with the full equations of state: the
paper's predictor/corrector (§3) on the system of ``forms/enriched_interface.py``, in 2D
(:mod:`ale_xfem.mixed.enriched_2d`) and in 1D, where that system is the intervals' case of
the same forms (``interface.predictor = "assembled"``, :mod:`ale_xfem.mixed.assembled_predictor`;
the closed-form elimination of :mod:`ale_xfem.mixed.equilibrium` is 1D's fast path).

*Predictor*: each material's pressure linearised about the current iterate along its
trapezoidal adiabat, P_m = c_m + D_m ΔV_m, ΔV_m = dt ∫_{K_m} ∇·ū_m (bubbles included),
D_m = dp/dV with the energy following e = e^n − ½(P^n + P)(V − V^n)/m:

    D (1 + ½ ∂p/∂e ΔV/m) = −(ρ/V) ∂p/∂ρ − ½ ∂p/∂e (P^n + p)/m;

the linear system gives ū, the materials' pressures and ΔV_m = (P_m − c_m)/D_m.
*Corrector*: at those volumes each material's energy solves the trapezoidal update with
its full equation of state, e = e^n − ½(P^n + p(ρ, e)) ΔV/m — one division, every EOS here
being affine in e (p = p₀(ρ) + ∂p/∂e(ρ) e).  Repeated, relinearised at the corrected state,
until the linearised and the full pressures agree to ``tolerance`` of the bulk modulus ρc².

Energy: each material's internal energy changes by −½(P^n + P^{n+1}) ΔV_m, which is the
work of the mixed cells' forces on the nodes (trapezoidal on every node with mass; the
interface pressure's work vanishes with the normal jump, Σ_m ∫_Γ ū·n_m = 0 per cell, which
the multiplier methods impose exactly; a massless bubble's row is the equilibrium of the
pressures at n+1 and does no work from a start in equilibrium).  So total energy is
conserved to round-off with bubbles and without stabilisation.  With Nitsche the weighted
average cancels against its symmetric term and the penalty dissipates γ ∫_Γ [ū·n]² dt:
the balance is short by that (2 × 10⁻⁴ of the internal energy change in the impact of
tests/test_enriched_2d.py).

Nitsche's weights and penalty are those of the step's start (an accepted state, c² > 0),
kept over its iterations: the iterations then change only the materials' compliances, as
with bubbles, and solve again without assembling (``InterfaceSystem.resolve``).  Following
the iterate instead assembled the system at each of a step's four or five iterations, for
L1 errors within 0.6 % of these on the sheared tube and the slip line (docs/design.md §4).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ale_xfem.mixed.equilibrium import MixedCellFailure
from forms.enriched_interface import nitsche_weights


# the least stiffness κ_m of Nitsche's weights and penalty, as a fraction of the inertia's
# scale ρ_m |K| / dt: ρ_m c_m² dt vanishes in a cold gas (Noh's, p = 1e-6); the penalty then
# vanished too, and the two materials' normal velocities came apart until the corrector found
# negative energies (and, while the weights followed the iterate, c² ≤ 0 at an iterate gave
# 0/0 weights, a NaN matrix).
# Inactive at the time steps the sound speed allows (c dt ≈ h/2 gives ρ c² dt ≈ ρ|K|/(4 dt));
# active where dt is far below them (cold gas; a step cut short by the viscosity or a retry).
NITSCHE_STIFFNESS_FLOOR = 0.01


def nitsche_stiffness(rho, c2, cell_area, dt):
    """κ_m = ρ_m c_m² dt, at least NITSCHE_STIFFNESS_FLOOR · ρ_m |K| / dt (arrays (2, n);
    ``cell_area`` (n,) the mixed cells' |K|)."""
    return np.maximum(rho * np.maximum(c2, 0.0) * dt, NITSCHE_STIFFNESS_FLOOR * rho * cell_area / dt)


@dataclass
class MaterialStart:
    """Each material's start of the step in the mixed cells, arrays (2, n): mass, volume
    (the part's area), specific internal energy and pressure."""

    mass: np.ndarray
    volume: np.ndarray
    energy: np.ndarray
    pressure: np.ndarray


class ImplicitStep:
    """The predictor/corrector of one step (module docstring) on a bound
    :class:`forms.enriched_interface.InterfaceSystem` bound to the mixed cells ``cells`` (mesh
    cell indices, for diagnostics).  ``eos[m](ρ, e)`` → (p, ∂p/∂ρ, ∂p/∂e, c²) of material
    slot m in each mixed cell; ``interface_length`` (n,) |Γ_K| (Nitsche's
    penalty); ``nonlinear`` false: one predictor, its volumes taken as they are and each
    material's energy working against the system's pressure (the linearised law alone,
    ``interface.solver = "linearised"``, which the paper reports unstable when a shock
    crosses Γ)."""

    def __init__(self, system, cells, eos, interface_length, nitsche_penalty: float = 1.0,
                 tolerance: float = 1e-10, max_iterations: int = 30, nonlinear: bool = True):
        self.system, self.cells, self.eos = system, np.asarray(cells), eos
        self.nitsche = system.forms.stabilisation == "nitsche"
        self.interface_length, self.nitsche_penalty = interface_length, nitsche_penalty
        self.tolerance, self.max_iterations, self.nonlinear = tolerance, max_iterations, nonlinear

    def solve(self, dt: float, start: MaterialStart, mass, rhs, tied=None, viscosity=None, sliding=None,
              start_stress=None) -> dict:
        """ū_m, the materials' end volumes, energies, pressures, densities and squared sound speeds,
        the interface pressure and the iterations (``mass``, ``rhs``, ``tied``, ``sliding``:
        as :meth:`InterfaceSystem.solve`).
        ``viscosity`` (n,): the mixed cells' artificial viscosity q̄ over the step, a stress
        on both materials alike: each works against ½(P^n + p) + q̄, and the system's
        pressures are p + q̄ (``rhs`` holds f^n with P^n + q̄).  ``start_stress`` (n,): the
        work's start W^n in place of P^n + 2q̄, each material working against ½(W^n + p)
        (1D: π^n + q^n + q̄, the viscosity trapezoidal too, as the closed form has it)."""
        m, v0, e0, p0 = start.mass, start.volume, start.energy, start.pressure
        q = np.zeros_like(v0) if viscosity is None else np.broadcast_to(viscosity, v0.shape)
        if start_stress is None:
            p0 = p0 + 2.0 * q  # the work pressure ½(p0 + p) + q̄, written as ½((p0 + 2q̄) + p)
        else:
            p0 = np.broadcast_to(start_stress, v0.shape)
        volume, energy = v0.copy(), e0.copy()
        for iteration in range(1, self.max_iterations + 1):
            rho = m / volume
            states = [self.eos[k](rho[k], energy[k]) for k in range(2)]
            p = np.stack([s[0] for s in states])
            dp_drho = np.stack([s[1] for s in states])
            dp_de = np.stack([s[2] for s in states])
            c2 = np.stack([s[3] for s in states])
            change = volume - v0
            slope = (-(rho / volume) * dp_drho - 0.5 * dp_de * (p0 + p) / m) / (1.0 + 0.5 * dp_de * change / m)
            if not np.all(slope < 0.0):
                index = int(np.flatnonzero(~np.all(slope < 0.0, axis=0))[0])
                raise MixedCellFailure(self.cells, index, "the pressure does not rise with compression along the adiabat")
            offset = p + q - slope * change
            compliance = -1.0 / (slope * dt * v0)
            if iteration == 1:
                weight = penalty = None
                if self.nitsche:  # κ_m = ρ_m c_m² dt (forms/enriched_interface.py), at the step's start
                    weight, penalty = nitsche_weights(v0, nitsche_stiffness(rho, c2, v0.sum(axis=0), dt),
                                                      self.interface_length, self.nitsche_penalty)
                self.system.set_materials(compliance, offset, weight, penalty)
                out = self.system.solve(mass, rhs, tied, sliding)
            else:  # the same system but for the compliances: not assembled again
                out = self.system.resolve(compliance, offset)
            linearised = out["pressure"]
            volume_change = (linearised - offset) / slope
            volume = v0 + volume_change
            if not np.all(volume > 0.0):
                index = int(np.flatnonzero(~np.all(volume > 0.0, axis=0))[0])
                raise MixedCellFailure(self.cells, index, "a material's volume is not positive at the end of the step")
            rho = m / volume
            work = 0.5 * volume_change / m
            if not self.nonlinear:  # the linearised law alone: each material's energy works
                # against the system's pressure, as its nodes do (energy kept to round-off)
                energy = e0 - work * (p0 + (linearised - q))
                states = [self.eos[k](rho[k], energy[k]) for k in range(2)]
                pressure, sound = np.stack([s[0] for s in states]), np.stack([s[3] for s in states])
                break
            # the corrector: e = e^n − ½(P^n + p₀(ρ) + ∂p/∂e e) ΔV/m, solved for e
            cold = [self.eos[k](rho[k], np.zeros_like(rho[k])) for k in range(2)]
            base = np.stack([s[0] for s in cold])
            dp_de = np.stack([s[2] for s in cold])
            energy = (e0 - work * (p0 + base)) / (1.0 + work * dp_de)
            pressure = base + dp_de * energy
            sound = np.stack([self.eos[k](rho[k], energy[k])[3] for k in range(2)])
            bulk = rho * np.abs(sound)
            if np.all(np.abs(pressure + q - linearised) <= self.tolerance * bulk):
                break
        else:
            index = int(np.argmax(np.abs(pressure + q - linearised).max(axis=0)))
            raise MixedCellFailure(self.cells, index, f"the corrector did not converge in {self.max_iterations} iterations")
        # a root outside the equations of state's domain (c² ≤ 0: an ideal gas at a negative
        # energy, a stiffened gas below −p∞) is no state: the run takes the step again with a
        # shorter dt (a sliver of air at a wall struck by water at 1e9 Pa reached c² < 0 here)
        if not np.all(sound > 0.0):
            index = int(np.flatnonzero(~np.all(sound > 0.0, axis=0))[0])
            raise MixedCellFailure(self.cells, index, "the corrector's state leaves its equation of state's domain "
                                   "(c² ≤ 0)")
        result = dict(velocity=out["velocity"], volume=volume, energy=energy, pressure=pressure, density=rho,
                      sound_speed_squared=sound, iterations=iteration, linearised_pressure=linearised)
        if "interface_pressure" in out:
            result["interface_pressure"] = out["interface_pressure"]
        return result
