"""The closures' per-mixed-cell formulas, compiled once and called both by the staged step
(the closures of :mod:`ale_xfem.mixed.common` and :mod:`ale_xfem.mixed.enriched`, on the
arrays of the mixed cells) and by a 1D enriched run's compiled chunks
(:mod:`ale_xfem.mixed.enriched_steps`): one implementation of each."""

from __future__ import annotations

import numba
import numpy as np

from ale_xfem.eos.kernels import state_derivatives
from ale_xfem.geometry.polygon_kernels import KERNEL, maximum, minimum
from ale_xfem.lagrange.kernels import artificial_viscosity


@numba.njit(**KERNEL)
def viscosity_media(kinds, parameters, right, cells, volume, density, sound_speed, volume_left, volume_right,
                    mass_right, energy_right, mixed_density, mixed_sound_speed):  # pragma: no cover (compiled)
    """The medium a mixed cell's viscosity sees (SharedClosure.viscosity_medium): the
    volume-weighted harmonic mean density 1/ρ = Σ f_α/ρ_α and the larger sound speed of its
    materials.  ``cells``: the mixed cells; ``volume``, ``density`` and ``sound_speed``
    (n_cells,): the cells' volumes and slot 0's (α's) density and sound speed; the other
    arrays (n_mixed,): α's and β's volumes, β's mass and energy, β's material (``right``),
    and the results."""
    for j in range(cells.size):
        k, material = cells[j], right[j]
        rho_right = mass_right[j] / volume_right[j]
        c2_right = state_derivatives(kinds[material], parameters, material, rho_right, energy_right[j])[3]
        mixed_density[j] = volume[k] / (volume_left[j] / density[k] + volume_right[j] / rho_right)
        mixed_sound_speed[j] = maximum(sound_speed[k], np.sqrt(maximum(c2_right, 0.0)))


@numba.njit(**KERNEL)
def add_viscosity(q_quadratic, q_linear, jump, density, sound_speed, weight, q):  # pragma: no cover (compiled)
    """q += weight · the artificial viscosity of each mixed cell (the explicit step's
    :func:`ale_xfem.lagrange.kernels.artificial_viscosity`) at the velocity jump ``jump``,
    density and sound speed given, all (n_mixed,) (EnrichedClosure2D._own_viscosity)."""
    for j in range(q.size):
        q[j] += weight * artificial_viscosity(q_quadratic, q_linear, jump[j], density[j], sound_speed[j])


@numba.njit(**KERNEL)
def cap_by_internal_nodes(cells, volume, node_mass, node_a, node_b, mixed_density):  # pragma: no cover
    """An enriched 1D mixed cell's viscosity density capped at 2 / (L (1/M_a + 1/M_b))
    (EnrichedClosure.viscosity_medium: the rate at which q relaxes the velocity jump of its
    internal nodes is then a pure cell's)."""
    for j in range(cells.size):
        compliance = 1.0 / node_mass[node_a[j]] + 1.0 / node_mass[node_b[j]]
        mixed_density[j] = minimum(mixed_density[j], 2.0 / (volume[cells[j]] * compliance))


@numba.njit(**KERNEL)
def interface_affine(dt, inverse_node_mass, free_nodes, cells, node_a, node_b, velocity, mean_force, volume,
                     interface_pressure, viscosity_start, viscosity_predicted, mobility, offset, slope,
                     work_offset):  # pragma: no cover (compiled)
    """The coefficients of an enriched 1D mixed cell's interface solve
    (EnrichedClosure.implicit_solve; paper §2.2.1): its volume at n+1 as V(π) = A + Bπ, the
    internal nodes moving with the trapezoidal force ½(F^n + F*) − ½(π − π^n) ∂V/∂x_i, and
    the work pressure ½(π^n + q^n + q*) + ½π of its energy update.  ``velocity``,
    ``mean_force``: u^n and ½(F^n + F*) (component 0 along the tube); writes each cell's
    mobilities dt/M of its internal nodes (held nodes: 0) into ``mobility`` (2, n_mixed),
    and A, B and the work pressure's offset."""
    for j in range(cells.size):
        a, b = node_a[j], node_b[j]
        mobility_a = dt * inverse_node_mass[a] * free_nodes[a]
        mobility_b = dt * inverse_node_mass[b] * free_nodes[b]
        centred = (velocity[0, b] - velocity[0, a]) + 0.5 * (mobility_b * mean_force[0, b]
                                                             - mobility_a * mean_force[0, a])
        slope[j] = 0.25 * dt * (mobility_a + mobility_b)
        offset[j] = volume[cells[j]] + dt * centred - slope[j] * interface_pressure[j]
        work_offset[j] = 0.5 * (interface_pressure[j] + viscosity_start[j] + viscosity_predicted[j])
        mobility[0, j], mobility[1, j] = mobility_a, mobility_b


@numba.njit(**KERNEL)
def pure_cell_forces(nodes, first, cell, corner, cell_material, force_n, force_predicted,
                     out):  # pragma: no cover (compiled)
    """Each material's time-centred force F̄ = ½(F^n + F*) of its pure cells at ``nodes``
    (EnrichedClosure2D._pure_forces), into ``out`` (2 materials, 2 components, n_nodes):
    ``force_n``, ``force_predicted`` (2, k, n_cells) every cell's corner forces,
    ``cell_material`` (n_cells,) each cell's material (−1: mixed; the other material's cells
    and the mixed cells add nothing).  The gather of ale_xfem.model.cell_kernels.node_area_sums,
    in its order (ale_xfem.model.mesh.Corners.scatter's bits), written for these four sums as
    remap.swept_kernels_2d.corner_shares_at is for its five: corner by corner, each corner's
    cells in order, each corner's sum (from +0) then added (``first``, ``cell``, ``corner``:
    ale_xfem.model.mesh.node_corners, by corner then by cell)."""
    for n in range(nodes.size):
        node = nodes[n]
        t00, t01, t10, t11 = 0.0, 0.0, 0.0, 0.0  # (material, component)
        j, end = first[node], first[node + 1]
        while j < end:
            i = corner[j]
            p00, p01, p10, p11 = 0.0, 0.0, 0.0, 0.0
            while j < end and corner[j] == i:
                c = cell[j]
                fx = (force_n[0, i, c] + force_predicted[0, i, c]) * 0.5
                fy = (force_n[1, i, c] + force_predicted[1, i, c]) * 0.5
                if cell_material[c] == 0:
                    p00 += fx
                    p01 += fy
                elif cell_material[c] == 1:
                    p10 += fx
                    p11 += fy
                j += 1
            t00 += p00
            t01 += p01
            t10 += p10
            t11 += p11
        out[0, 0, node], out[0, 1, node], out[1, 0, node], out[1, 1, node] = t00, t01, t10, t11
