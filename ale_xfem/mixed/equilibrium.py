"""The pressure equilibrium of enriched mixed cells in 1D: the interface Γ inside a cell,
one velocity field per material, an interface pressure solved implicitly (the paper's
§2–3; DESIGN.md §5).  :mod:`ale_xfem.mixed.enriched` steps the cells; this module solves for
their interface pressure and relaxes their materials' pressures.

A mixed cell K = [x_a, x_b] holds material α on the left (volume V_α) and β on the right
(V_β = V − V_α); Γ sits at x_a + V_α.  Node a is internal to α, node b internal to β.

- **Mass condensation** (paper fig. 3): α's mass in K is lumped on a, β's on b; the
  external nodes (α's velocity at b, β's at a) are massless, so their momentum equations
  become the static equilibrium of the interface, p_α = p_β = p_Γ (eq. 4, which in 1D holds
  strongly, as does the continuity of velocity at Γ, eq. 5).  The force of K on its
  internal nodes is then −P on a and +P on b, P = p_Γ + q: the corner forces of a cell of
  stress P, which is how the explicit loop sees a mixed cell.
- **Time discretisation** (§2.2.1): trapezoidal stresses ½(P^n + P^{n+1}) in the momentum
  of the internal nodes, the equilibrium p_α = p_β imposed fully implicitly at n+1, the
  artificial viscosity of K taken from the explicit predictor (q*).  Each material's energy
  changes by −½(P^n + P^{n+1}) ΔV_α with the *same* stress for both materials and for the
  nodes, so total energy is conserved to round-off.
- **Solve** (§3): with π = p_Γ^{n+1}, the cell volume at n+1 is affine in π,
  V(π) = A + Bπ (B > 0: a higher interface pressure pushes a and b apart).
  *Predictor*: each material's pressure linearised about the current iterate along its
  trapezoidal adiabat, dp = D_α dV_α + E_α dπ (E_α: through the work pressure of its energy
  update, which depends on π), gives a linear system for π and the total deformation V(π)
  of every mixed cell — a Newton step of the coupled system.  *Corrector*: at that total
  volume the deformation is redistributed between the materials with the full equations
  of state and the energy update, until their pressures balance (a bracketed Newton
  iteration per cell on the admissible interval of V_α).  Repeated, relinearised, until
  the corrector changes the pressure by less than ``interface_tolerance`` (relative to the
  bulk modulus ρc²).
  ``solver = "linearised"`` stops after one predictor (the law dp = ρc² dρ/ρ alone),
  which the paper reports unstable when a shock crosses Γ.
- **Pressure relaxation** at the start of a step: the same solve at fixed cell volume
  (B = 0) with the energy exchange dE_α = −p* dV_α, p* the final common pressure.

All mixed cells are solved at once, in compiled loops over them, iterated in lock-step:
the interface solve (:func:`interface_solve`; the predictor's iteration with the
corrector's, :func:`split_cells`, inside it) and the relaxation (:func:`relax_cells`).
"""

from __future__ import annotations

import numba
import numpy as np

from ale_xfem.eos import kernel_tables
from ale_xfem.eos.kernels import state_derivatives
from ale_xfem.geometry.polygon_kernels import KERNEL, maximum, minimum
from ale_xfem.model.mixed_cells import MixedCells

# an iterate that moves by less than this (relative) has stopped moving: round-off
_STALLED = 64 * np.finfo(float).eps


class MixedCellFailure(RuntimeError):
    """The mixed-cell solve did not converge or left the admissible states: ``cell`` the
    mesh cell, ``index`` its place among the mixed cells, ``detail`` what went wrong."""

    def __init__(self, cells, index: int, detail: str):
        """``cells``: the mesh cell of each mixed cell (``MixedCells.cells``)."""
        self.index, self.detail = index, detail
        # index < 0: a cell of another MPI rank (MixedCells.across_ranks)
        self.cell = int(cells[index]) if index >= 0 else -1
        super().__init__(f"mixed cell {self.cell}: {detail}")


def cannot_hold(mixed, index: int, volume: float) -> MixedCellFailure:
    """The failure of a mixed cell whose volume cannot hold its two materials below their
    compression limits (the interface solve's or the relaxation's)."""
    return MixedCellFailure(mixed.cells, index, f"volume {volume:.6g} cannot hold both materials below their "
                            "compression limits")


def start_values(state, cells):
    """(m_α, m_β, V_α, V_β, e_α, e_β) of the mixed cells ``cells`` of a state."""
    return (state.material_mass[0, cells], state.material_mass[1, cells],
            state.material_volume[0, cells], state.material_volume[1, cells],
            state.material_energy[0, cells], state.material_energy[1, cells])


@numba.njit(**KERNEL)
def adiabat(kind, parameters, material, mass, volume, energy0, volume0, work_pressure):  # pragma: no cover
    """One material at volume V when its energy follows e = e0 − W (V − V0)/m (W: the work
    pressure of the step): (p, dp/dV, e, ρ, c², ∂p/∂W at fixed V)."""
    specific_change = (volume - volume0) / mass
    energy = energy0 - work_pressure * specific_change
    rho = mass / volume
    p, dp_drho, dp_de, c2 = state_derivatives(kind, parameters, material, rho, energy)
    dp_dv = -dp_drho * rho / volume - dp_de * work_pressure / mass
    return p, dp_dv, energy, rho, c2, -dp_de * specific_change


@numba.njit(**KERNEL)
def both_adiabats(kinds, parameters, left, right, total, m_a, m_b, va0, vb0, ea0, eb0, work_pressure, v, values,
                  i):  # pragma: no cover (compiled)
    """:func:`adiabat` of cell i's two materials, α at V_α = v[i] and β at total − v[i],
    into values[:, 0, i] and values[:, 1, i]."""
    a, b = left[i], right[i]
    values[0, 0, i], values[1, 0, i], values[2, 0, i], values[3, 0, i], values[4, 0, i], values[5, 0, i] = adiabat(
        kinds[a], parameters, a, m_a[i], v[i], ea0[i], va0[i], work_pressure[i])
    values[0, 1, i], values[1, 1, i], values[2, 1, i], values[3, 1, i], values[4, 1, i], values[5, 1, i] = adiabat(
        kinds[b], parameters, b, m_b[i], total[i] - v[i], eb0[i], vb0[i], work_pressure[i])


@numba.njit(**KERNEL)
def split_cells(kinds, parameters, left, right, total, m_a, m_b, va0, vb0, ea0, eb0, work_pressure, guess,
                max_density_left, max_density_right, balance):  # pragma: no cover (compiled)
    """The corrector of every mixed cell (:meth:`PressureEquilibrium._split`): the volume
    V_α ∈ (0, total) at which both materials' pressures balance on their trapezoidal
    adiabats, Newton bracketed by bisection, all cells iterated together until every one is
    balanced (|p_α − p_β| ≤ ``balance`` |dp/dV| V) or stopped by round-off.  Returns (the
    cell whose volume cannot hold both materials below their compression limits, or −1;
    the iterations; V_α; and at V_α per material (2, n): p, dp/dV, e, ρ, c², ∂p/∂W)."""
    n = total.size
    lo, hi, v = np.empty(n), np.empty(n), np.empty(n)
    values = np.empty((6, 2, n))  # p, dp/dV, e, ρ, c², ∂p/∂W of α (0) and β (1)
    balanced = np.empty(n, dtype=np.bool_)
    for i in range(n):
        lo[i] = maximum(1e-12 * total[i], m_a[i] / max_density_left[i] * (1 + 1e-9))
        hi[i] = minimum((1 - 1e-12) * total[i], total[i] - m_b[i] / max_density_right[i] * (1 + 1e-9))
    for i in range(n):
        if lo[i] >= hi[i]:
            return i, 0, v, values
    for i in range(n):
        v[i] = minimum(maximum(guess[i], lo[i]), hi[i])
    iteration = 0
    for iteration in range(1, 101):
        all_balanced = True
        for i in range(n):
            both_adiabats(kinds, parameters, left, right, total, m_a, m_b, va0, vb0, ea0, eb0, work_pressure, v,
                          values, i)
            h = values[0, 0, i] - values[0, 1, i]  # decreasing in V_α
            slope = values[1, 0, i] + values[1, 1, i]
            # balanced: the pressures agree far below the solver tolerance (|slope|·V is the
            # cell's bulk modulus); such cells keep their volume
            balanced[i] = abs(h) <= balance * abs(slope) * total[i]
            all_balanced &= balanced[i]
        if all_balanced:  # the values just computed are those of the result
            return -1, iteration, v, values
        stopped = True
        for i in range(n):
            h = values[0, 0, i] - values[0, 1, i]
            slope = values[1, 0, i] + values[1, 1, i]
            if h > 0:
                lo[i] = v[i]
            if h <= 0:
                hi[i] = v[i]
            newton = v[i] - h / slope
            inside = np.isfinite(newton) and newton > lo[i] and newton < hi[i]
            new = v[i] if balanced[i] else (newton if inside else 0.5 * (lo[i] + hi[i]))
            change = abs(new - v[i])
            v[i] = new
            # or round-off bounds what Newton can still change (a few ulps of the volume)
            stopped &= balanced[i] or change <= 8e-16 * total[i] or hi[i] - lo[i] <= 8e-16 * total[i]
        if stopped:
            break
    for i in range(n):
        both_adiabats(kinds, parameters, left, right, total, m_a, m_b, va0, vb0, ea0, eb0, work_pressure, v, values, i)
    return -1, iteration, v, values


RELAXED, CANNOT_HOLD, NOT_CONVERGED = 0, 1, 2  # what relax_cells returns as its status


def cell_arrays(shape, *values):
    """``values`` as contiguous float arrays of ``shape`` (numbers spread over it), as the
    compiled loops take them — cheaply: a set of mixed cells is often one cell, and
    np.broadcast_to alone took 11 µs a call."""
    out = []
    for value in values:
        array = np.asarray(value, dtype=float)
        if array.shape != shape:
            array = np.full(shape, array)
        elif not array.flags.c_contiguous:
            array = np.ascontiguousarray(array)
        out.append(array)
    return out


@numba.njit(**KERNEL)
def relaxed_pressure(kind, parameters, material, mass, volume, energy0, volume0):  # pragma: no cover (compiled)
    """π(V) of one material at volume V when its energy follows e = e0 − π (V − V0)/m, with
    dπ/dV and S = −∂p/∂e (V − V0)/m (:meth:`PressureEquilibrium.relax`): π = p(ρ, e0)/(1 − S)
    where 1 − S > 0, else π = +∞ and dπ/dV = 0.  (∂p/∂V)_W is taken at the energy of
    W = π: at e0 it missed how a trace's ∂p/∂ρ changes with its energy, and Newton, its
    slope half the true one, swung about the root without converging.)"""
    rho = mass / volume
    p0, _, dp_de, _ = state_derivatives(kind, parameters, material, rho, energy0)
    coupling = dp_de * (volume0 - volume) / mass
    keep = 1.0 - coupling
    if not keep > 0.0:
        return np.inf, 0.0, coupling
    pi = p0 / keep
    dp_drho = state_derivatives(kind, parameters, material, rho, energy0 - pi * (volume - volume0) / mass)[1]
    return pi, -(dp_drho * rho + dp_de * pi / mass * volume) / (volume * keep), coupling


# The relaxation's iterations: Newton in the bracket for the first NEWTON_ITERATIONS, then
# bisection.  Where the root lies between two neighbouring floating-point volumes of a
# stiff material (water against a trace of air: one ulp of the water's volume moves its
# pressure by 2 × 10⁻⁷ of itself) Newton's step, set by the water's slope, moved δ by
# 10⁻²² a time, below that volume's ulp and above the trace's round-off: it crept on
# without changing the water's pressure until the iterations ran out.
RELAXATION_ITERATIONS = 200
NEWTON_ITERATIONS = 50


@numba.njit(**KERNEL)
def relax_cells(kinds, parameters, left, right, m_a, m_b, va0, vb0, ea0, eb0, total, max_density_left,
                max_density_right, balance):  # pragma: no cover (compiled)
    """The pressure relaxation's root in every mixed cell (:meth:`PressureEquilibrium.relax`):
    the volume δ that α (material ``left``) takes from β (``right``), Newton bracketed by
    bisection (bisection alone after NEWTON_ITERATIONS), all cells iterated together until
    every one is balanced (|π_α − π_β| ≤
    ``balance`` × its scale) or stopped by round-off, then evaluated once more.  Returns
    (status, cell, V_α, V_β, p*, π_α, π_β): status RELAXED, or CANNOT_HOLD (the cell's
    volume cannot hold both materials below their compression limits) or NOT_CONVERGED
    (the cell farthest from balance) with that cell."""
    n = total.size
    lo, hi, delta = np.empty(n), np.empty(n), np.empty(n)
    va, vb, pressure = np.empty(n), np.empty(n), np.empty(n)
    pi_a, slope_a, coupling_a = np.empty(n), np.empty(n), np.empty(n)
    pi_b, slope_b, coupling_b = np.empty(n), np.empty(n), np.empty(n)
    h, scale, balanced = np.empty(n), np.empty(n), np.empty(n, dtype=np.bool_)
    for i in range(n):
        lo[i] = maximum(1e-12 * total[i], m_a[i] / max_density_left[i] * (1 + 1e-9)) - va0[i]
        hi[i] = vb0[i] - maximum(1e-12 * total[i], m_b[i] / max_density_right[i] * (1 + 1e-9))
    for i in range(n):
        if lo[i] >= hi[i]:
            return CANNOT_HOLD, i, va, vb, pressure, pi_a, pi_b
    for i in range(n):
        delta[i] = minimum(maximum(0.0, lo[i]), hi[i])
    finished, done = False, False
    for iteration in range(RELAXATION_ITERATIONS):
        all_balanced = True
        for i in range(n):
            va[i], vb[i] = va0[i] + delta[i], vb0[i] - delta[i]
            a, b = left[i], right[i]
            pi_a[i], slope_a[i], coupling_a[i] = relaxed_pressure(kinds[a], parameters, a, m_a[i], va[i], ea0[i],
                                                                  va0[i])
            pi_b[i], slope_b[i], coupling_b[i] = relaxed_pressure(kinds[b], parameters, b, m_b[i], vb[i], eb0[i],
                                                                  vb0[i])
            h[i] = pi_a[i] - pi_b[i]  # decreasing in δ
            # the pressures' scale: the larger of them, or the softer material's bulk modulus
            scale[i] = maximum(maximum(abs(pi_a[i]), abs(pi_b[i])),
                               minimum(abs(slope_a[i]) * va[i], abs(slope_b[i]) * vb[i]))
            balanced[i] = np.isfinite(h[i]) and abs(h[i]) <= balance * scale[i]
            all_balanced &= balanced[i]
        if finished or all_balanced:  # the values just computed are those of the result
            done = True
            break
        finished = True
        for i in range(n):
            if h[i] > 0:
                lo[i] = delta[i]
            if h[i] <= 0:
                hi[i] = delta[i]
            newton = delta[i] - h[i] / (slope_a[i] + slope_b[i])
            inside = np.isfinite(newton) and newton > lo[i] and newton < hi[i] and iteration < NEWTON_ITERATIONS
            new_delta = delta[i] if balanced[i] else (newton if inside else 0.5 * (lo[i] + hi[i]))
            # or round-off bounds what can still change (a few ulps of the smaller volume)
            resolution = 4e-16 * minimum(va[i], vb[i])
            finished &= balanced[i] or abs(new_delta - delta[i]) <= resolution or hi[i] - lo[i] <= resolution
            delta[i] = new_delta
    if not done:  # the cell farthest from balance (np.argmax: the first NaN, else the first largest)
        worst, largest = 0, -1.0
        for i in range(n):
            distance = abs(h[i]) / scale[i]
            if distance != distance:
                worst = i
                break
            if distance > largest:
                worst, largest = i, distance
        return NOT_CONVERGED, worst, va, vb, pressure, pi_a, pi_b
    # p* is the root of the material whose pressure depends most on it (|S| the larger):
    # its state is then exactly its own balance, the other's pressure within the
    # tolerance.  (The mean of the two left a near-vacuum trace of air in a cavity,
    # 10⁻¹⁹ of mass, at a negative energy: p_α = π_α + S_α (p* − π_α) with S_α ~ 1.)
    for i in range(n):
        pressure[i] = pi_a[i] if abs(coupling_a[i]) >= abs(coupling_b[i]) else pi_b[i]
    return RELAXED, 0, va, vb, pressure, pi_a, pi_b


NOT_FINITE = 4  # what relaxed_states returns besides RELAXED, CANNOT_HOLD and NOT_CONVERGED


@numba.njit(**KERNEL)
def balanced_cells(pa, pb, bulk_a, bulk_b, tolerance):  # pragma: no cover (compiled)
    """Whether every mixed cell's pressures agree within what the relaxation leaves alone:
    10 × ``tolerance`` relative to the larger pressure or the smaller ρc² (``bulk``)."""
    settled = True
    for i in range(pa.size):
        scale = maximum(maximum(abs(pa[i]), abs(pb[i])), minimum(bulk_a[i], bulk_b[i]))
        settled &= abs(pa[i] - pb[i]) <= 10.0 * tolerance * scale
    return settled


@numba.njit(**KERNEL)
def relaxed_states(kinds, parameters, left, right, m_a, m_b, va0, vb0, ea0, eb0, total, max_density_left,
                   max_density_right, balance):  # pragma: no cover (compiled)
    """The pressure relaxation at fixed cell volumes (:meth:`PressureEquilibrium.relax`):
    :func:`relax_cells`, then each material on its adiabat at the common pressure p*.
    Returns (status, cell, V_α, V_β, p*, details (8, n): e_α, e_β, p_α, p_β, ρ_α, ρ_β, c²_α,
    c²_β, and two figures for a failure's message): status RELAXED, or CANNOT_HOLD (the
    cell's volume), NOT_CONVERGED (its two pressures) or NOT_FINITE (its p*), the cell
    that failed."""
    n = total.size
    details = np.empty((8, n))
    status, cell, va, vb, pressure, pi_a, pi_b = relax_cells(kinds, parameters, left, right, m_a, m_b, va0, vb0,
                                                             ea0, eb0, total, max_density_left, max_density_right,
                                                             balance)
    if status == CANNOT_HOLD:
        return status, cell, va, vb, pressure, details, total[cell], np.nan
    if status == NOT_CONVERGED:
        return status, cell, va, vb, pressure, details, pi_a[cell], pi_b[cell]
    for i in range(n):
        if not abs(pressure[i]) < np.inf:
            return NOT_FINITE, i, va, vb, pressure, details, pressure[i], np.nan
    for i in range(n):
        a, b = left[i], right[i]
        details[2, i], _, details[0, i], details[4, i], details[6, i], _ = adiabat(
            kinds[a], parameters, a, m_a[i], va[i], ea0[i], va0[i], pressure[i])
        details[3, i], _, details[1, i], details[5, i], details[7, i], _ = adiabat(
            kinds[b], parameters, b, m_b[i], vb[i], eb0[i], vb0[i], pressure[i])
    return RELAXED, 0, va, vb, pressure, details, np.nan, np.nan

SOLVED, OUTSIDE_EOS = 0, 3  # what interface_solve returns as its status (besides CANNOT_HOLD, NOT_CONVERGED)


@numba.njit(**KERNEL)
def work_coupled_law(p, dp_dv, dp_dpi, pi):  # pragma: no cover (compiled)
    """The linearised law p + D (V − V^k) + E (π − π^k) = π as p' + D' (V − V^k) = π:
    (p', D') = ((p − E π^k)/(1 − E), D/(1 − E)), E held within ±½ (a preconditioner: the
    converged state is the same for any E)."""
    coupling = minimum(maximum(dp_dpi, -0.5), 0.5)
    keep = 1.0 - coupling
    return (p - coupling * pi) / keep, dp_dv / keep


@numba.njit(**KERNEL)
def linearised_laws(kinds, parameters, left, right, m_a, m_b, va0, vb0, ea0, eb0, va, vb, w0, w1, pi, values, first,
                    laws):  # pragma: no cover (compiled)
    """The predictor's law of each material linearised about the iterate (V_α, V_β, π),
    in V_α and in π through the work pressure W = w0 + w1 π of its energy (E_α = w1
    ∂p_α/∂W; leaving it out made the iteration converge only linearly, by a factor ~ΔV/V
    per iteration):  p_α ≈ p_α^k + D_α (V_α − V_α^k) + E_α (π − π^k), as
    :func:`work_coupled_law` writes it.  The materials' values at the iterate are
    evaluated (``first``) or those the corrector left in ``values`` ((6, 2, n), as
    :func:`split_cells` returns them).  Writes laws (4, n): p_α', D_α', p_β', D_β'."""
    for i in range(pi.size):
        if first:
            work = w0[i] + w1[i] * pi[i]
            a, b = left[i], right[i]
            pa, da, _, _, _, wa = adiabat(kinds[a], parameters, a, m_a[i], va[i], ea0[i], va0[i], work)
            pb, db, _, _, _, wb = adiabat(kinds[b], parameters, b, m_b[i], vb[i], eb0[i], vb0[i], work)
        else:
            pa, pb, da, db, wa, wb = values[0, 0, i], values[0, 1, i], values[1, 0, i], values[1, 1, i], \
                values[5, 0, i], values[5, 1, i]
        laws[0, i], laws[1, i] = work_coupled_law(pa, da, wa * w1[i], pi[i])
        laws[2, i], laws[3, i] = work_coupled_law(pb, db, wb * w1[i], pi[i])


@numba.njit(**KERNEL)
def corrector(kinds, parameters, left, right, m_a, m_b, va0, vb0, ea0, eb0, offset, slope, w0, w1, nonlinear,
              tolerance, max_density_left, max_density_right, laws, pi_new, va, vb, pi, values,
              progress):  # pragma: no cover (compiled)
    """The rest of an iteration of :func:`interface_solve`, once the predictor has given
    π_new: at the total volume V(π_new) = A + B π_new, the materials' split — the
    predictor's own, V_α^k + (π_new − p_α')/D_α' (``nonlinear`` false: the linearised solve
    ends there), or the corrector's, where both materials' pressures balance on their
    full equations of state (:func:`split_cells`) — becomes the new iterate (va, vb, pi;
    ``values``: the materials' values there).  Returns (status, cell, whether every cell
    has converged, details (8, n): e_α, e_β, p_α, p_β, ρ_α, ρ_β, c²_α, c²_β); ``progress``
    (4, n) keeps each cell's convergence (1/0), its change of π, |p_balanced − π_new| and
    the pressure scale, for :func:`unconverged`."""
    n = pi.size
    total, work, guess = np.empty(n), np.empty(n), np.empty(n)
    details = np.empty((8, n))
    for i in range(n):
        total[i] = offset[i] + slope[i] * pi_new[i]
        work[i] = w0[i] + w1[i] * pi_new[i]
        guess[i] = va[i] + (pi_new[i] - laws[0, i]) / laws[1, i]
    if not nonlinear:
        for i in range(n):
            va[i], vb[i], pi[i] = guess[i], total[i] - guess[i], pi_new[i]
            both_adiabats(kinds, parameters, left, right, total, m_a, m_b, va0, vb0, ea0, eb0, work, va, values, i)
    else:
        bad, _, v, split = split_cells(kinds, parameters, left, right, total, m_a, m_b, va0, vb0, ea0, eb0, work,
                                       guess, max_density_left, max_density_right, 1e-3 * tolerance)
        if bad >= 0:
            return CANNOT_HOLD, bad, False, details
        values[:] = split
    done = True
    for i in range(n):
        for side in range(2):
            details[side, i] = values[2, side, i]
            details[2 + side, i] = values[0, side, i]
            details[4 + side, i] = values[3, side, i]
            details[6 + side, i] = values[4, side, i]
        if not nonlinear:
            continue
        balanced = 0.5 * (values[0, 0, i] + values[0, 1, i])
        scale = maximum(abs(pi_new[i]), minimum(values[3, 0, i] * values[4, 0, i], values[3, 1, i] * values[4, 1, i]))
        converged = abs(balanced - pi_new[i]) <= tolerance * scale
        # With a stiff material against a soft one (water at 1e9 Pa against air at 1e5 Pa)
        # round-off in the corrector bounds the balance before the tolerance does: the
        # iterate then stops moving, which is convergence too.
        change = abs(pi_new[i] - pi[i])
        converged |= change <= _STALLED * maximum(abs(pi_new[i]), scale)
        va[i], vb[i], pi[i] = v[i], total[i] - v[i], pi_new[i]
        progress[0, i], progress[1, i] = 1.0 if converged else 0.0, change
        progress[2, i], progress[3, i] = abs(balanced - pi_new[i]), scale
        done &= converged
    return SOLVED, 0, done, details


@numba.njit(**KERNEL)
def admissible(iterations, pi, va, vb, details):  # pragma: no cover (compiled)
    """:func:`interface_solve`'s result once converged: a root outside a material's EOS
    domain (c² ≤ 0) is a failure (OUTSIDE_EOS, the first such cell)."""
    for i in range(pi.size):
        if not (details[6, i] > 0.0 and details[7, i] > 0.0):
            return OUTSIDE_EOS, i, iterations, pi, va, vb, details, 0.0
    return SOLVED, 0, iterations, pi, va, vb, details, 0.0


@numba.njit(**KERNEL)
def unconverged(iterations, pi, va, vb, details, progress):  # pragma: no cover (compiled)
    """:func:`interface_solve`'s result when its iterations ran out.  Round-off in a
    pressure is relative to the terms of its equation of state, as large as the stiffer
    material's ρc² (γ p∞ for water): an iterate that still moves, but by less than that,
    has stopped (a trace of near-vacuum air against water in tension moved by 1.7e-7 Pa on
    a scale of 100 Pa, the water's ρc² 2.6e9, and failed).  Only a solve that would
    otherwise fail is accepted on this scale: the iterations of every other stay those of
    the tolerance.  Else NOT_CONVERGED, the cell farthest from balance (np.argmax: the
    first NaN, else the first largest) with its pressure change."""
    accepted = True
    for i in range(pi.size):
        stiffer = maximum(details[4, i] * details[6, i], details[5, i] * details[7, i])
        accepted &= progress[0, i] == 1.0 or progress[1, i] <= _STALLED * maximum(abs(pi[i]), stiffer)
    if accepted:
        return admissible(iterations, pi, va, vb, details)
    worst, largest = 0, -1.0
    for i in range(pi.size):
        distance = progress[2, i] / progress[3, i]
        if distance != distance:
            worst = i
            break
        if distance > largest:
            worst, largest = i, distance
    return NOT_CONVERGED, worst, iterations, pi, va, vb, details, progress[2, worst]


@numba.njit(**KERNEL)
def interface_solve(kinds, parameters, left, right, m_a, m_b, va0, vb0, ea0, eb0, pressure0, offset, slope, w0, w1,
                    max_iterations, nonlinear, tolerance, max_density_left,
                    max_density_right):  # pragma: no cover (compiled)
    """The interface pressure π of every mixed cell with V(π) = A + Bπ (``offset``,
    ``slope``) and work pressure W = w0 + w1 π (:meth:`PressureEquilibrium.solve`; module
    docstring), all cells iterated together until every one has converged: each
    iteration the linearised laws (:func:`linearised_laws`), the predictor's pressure in
    closed form — V_α = V_α^k + (π − p_α')/D_α', V_β likewise, V_α + V_β = A + Bπ — and
    the corrector (:func:`corrector`).  Returns (status, cell, iterations, π, V_α, V_β,
    details (8, n), a figure for the failure's message: the volume that cannot hold the
    materials, or the unconverged pressure change)."""
    n = pressure0.size
    va, vb, pi = va0.copy(), vb0.copy(), pressure0.copy()
    laws, values, progress = np.empty((4, n)), np.empty((6, 2, n)), np.empty((4, n))
    pi_new, details = np.empty(n), np.empty((8, n))
    for iteration in range(1, max_iterations + 1):
        linearised_laws(kinds, parameters, left, right, m_a, m_b, va0, vb0, ea0, eb0, va, vb, w0, w1, pi, values,
                        iteration == 1, laws)
        for i in range(n):
            pa, da, pb, db = laws[0, i], laws[1, i], laws[2, i], laws[3, i]
            pi_new[i] = (offset[i] - va[i] - vb[i] + pa / da + pb / db) / (1.0 / da + 1.0 / db - slope[i])
        status, index, done, details = corrector(kinds, parameters, left, right, m_a, m_b, va0, vb0, ea0, eb0,
                                                 offset, slope, w0, w1, nonlinear, tolerance, max_density_left,
                                                 max_density_right, laws, pi_new, va, vb, pi, values, progress)
        if status == CANNOT_HOLD:
            return status, index, iteration, pi, va, vb, details, offset[index] + slope[index] * pi_new[index]
        if done:
            return admissible(iteration, pi, va, vb, details)
    return unconverged(max_iterations, pi, va, vb, details, progress)


class PressureEquilibrium:
    """The interface solve and the pressure relaxation of a set of mixed cells (module
    docstring), vectorised over them; the settings and statistics are those of ``mixed``."""

    def __init__(self, mixed: MixedCells):
        self.mixed = mixed
        # what the compiled loops take: the equations of state's codes and parameters, and
        # each side's material ids
        self.tables = kernel_tables(tuple(material.eos for material in mixed.materials))
        self.sides = tuple(np.ascontiguousarray(ids, dtype=np.int64)
                           for ids in (mixed.material_left, mixed.material_right))

    def all_sides(self):
        """Each side's material ids of the mixed cells the solves take: this set's, or on
        several MPI ranks all the ranks' (``MixedCells.across_ranks``)."""
        ranks = self.mixed.across_ranks
        return self.sides if ranks is None else ranks.sides

    def all_density_limits(self):
        """Each side's compression limit of the mixed cells the solves take (as
        :meth:`all_sides`)."""
        mixed = self.mixed
        ranks = mixed.across_ranks
        return (mixed.max_density_left, mixed.max_density_right) if ranks is None else ranks.density_limits

    def solve(self, state0, pressure0, volume_affine, work_affine, record: bool = True):
        """Find the interface pressure π with V(π) = A + Bπ, work pressure W = w0 + w1 π.

        state0: (m_α, m_β, V_α0, V_β0, e_α0, e_β0) at the start; pressure0: first iterate.
        Returns (π, V_α, V_β, details) with details the materials' energies, pressures,
        densities and c² at the end.  A root outside a material's EOS domain (c² ≤ 0: a gas
        at negative pressure) is a failure: at that time step the cell's nodes open faster
        than its materials can fill at an admissible pressure (the run retries the step
        with a smaller one).  Compiled (:func:`interface_solve`)."""
        mixed = self.mixed
        n = np.size(pressure0)
        arrays = cell_arrays((n,), *state0, pressure0, *volume_affine, *work_affine)
        ranks = mixed.across_ranks
        if ranks is not None:  # every rank solves all the ranks' mixed cells (MixedCells.across_ranks)
            arrays = ranks.whole(arrays)
        status, index, iterations, pi, va, vb, details, gap = interface_solve(
            *self.tables, *self.all_sides(), *arrays, mixed.max_iterations, mixed.nonlinear, mixed.tolerance,
            *self.all_density_limits())
        at, pi_at, details_at = index, pi, details  # the failing cell's figures, among the arrays solved
        if ranks is not None:
            index = ranks.local(index)
            pi, va, vb, details = ranks.mine((pi, va, vb, details))
        if status == CANNOT_HOLD:
            raise cannot_hold(mixed, index, gap)
        if status == NOT_CONVERGED:
            raise MixedCellFailure(mixed.cells, index, f"not converged after {mixed.max_iterations} iterations "
                                   f"(pressure change {gap:.3g})")
        if record:
            mixed.record_solve(iterations)
        if status == OUTSIDE_EOS:
            raise MixedCellFailure(mixed.cells, index, f"the root leaves the EOS domain (π = {pi_at[at]:.6g}, "
                                   f"c² = {details_at[6][at]:.3g} | {details_at[7][at]:.3g})")
        return pi, va, vb, tuple(details)

    def relax(self, volume, state0, pressure_guess=None):
        """Pressure relaxation at fixed cell volume: returns (p*, V_α, V_β, details).

        Each material's energy follows e_α = e_α^0 − p* (V_α − V_α^0)/m_α.  Every equation of
        state here is affine in e with ∂p/∂e a function of ρ alone, so at a given V_α the
        common pressure the material would reach is explicit,
        π_α(V_α) = p_α(ρ_α, e_α^0) / (1 − S_α),  S_α = −∂p/∂e (V_α − V_α^0)/m_α,
        and defined where 1 − S_α > 0: a gas compressed at its own pressure's work cannot go
        below (γ − 1)/γ of its volume (at that bound π_α → +∞, the continuation used beyond).
        The balance π_α(V_α) = π_β(V − V_α) is then a bracketed scalar root in δ below (Newton,
        bisection when it leaves the bracket), which cannot leave the admissible states.
        (Newton on p* with a corrector at fixed work pressure converged, for a trace of air
        against water in tension, to a spurious root of compressed air at negative energy:
        a water–air tube at 30° on an Eulerian mesh, the air squeezed to 10⁻¹² of its cell.)"""
        self.mixed.stats["relaxations"] += 1
        mixed = self.mixed
        # The unknown is the volume δ that α takes from β, V_α = V_α^0 + δ, V_β = V_β^0 − δ:
        # each volume then keeps its own precision (a trace's V_β is not the round-off of
        # V − V_α, which left 5e-11 between the pressures of a cell with a trace at rest).
        arrays = cell_arrays(np.shape(volume), *state0, volume)
        ranks = mixed.across_ranks
        if ranks is not None:  # every rank relaxes all the ranks' mixed cells (MixedCells.across_ranks)
            arrays = ranks.whole(arrays)
        status, cell, va, vb, pressure, details, figure_a, figure_b = relaxed_states(
            *self.tables, *self.all_sides(), *arrays, *self.all_density_limits(), 1e-3 * mixed.tolerance)
        if ranks is not None:
            cell = ranks.local(cell)
            va, vb, pressure, details = ranks.mine((va, vb, pressure, details))
        if status == CANNOT_HOLD:
            raise cannot_hold(mixed, cell, figure_a)
        if status == NOT_CONVERGED:
            raise MixedCellFailure(mixed.cells, cell, f"pressure relaxation not converged (pressures "
                                   f"{figure_a:.6g} and {figure_b:.6g})")
        if status == NOT_FINITE:
            raise MixedCellFailure(mixed.cells, cell, f"pressure relaxation = {figure_a:.6g}")
        return pressure, va, vb, tuple(details)
