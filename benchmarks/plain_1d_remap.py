"""What does an Eulerian remap cost against the Lagrange step, stripped to its arithmetic?

Evidence for BENCHMARKS.md ("What the unmet speed targets would take"), not part of the
package.  On Sod's tube (ideal gas, γ = 1.4):

- the *Lagrange step* of ale_xfem.lagrange stripped to its arithmetic: the compatible
  two-stage predictor–corrector, quadratic + linear artificial viscosity, walls;
- the *Eulerian remap* back to the initial nodes, stripped likewise: swept-region fluxes
  of mass and total internal energy with minmod slopes of ρ and ρε, the nodes' momentum
  through the moving middles of the cells (the dual faces) with the upwind node's velocity
  and its minmod slope, the kinetic energy change reported (not deposited), and the force
  evaluation of the remapped state (which the step then does not make).

No interfaces, mixed cells, windows, breakdown checks or CFL.  It prints the pure
Lagrangian step, the Eulerian cycle and what the remap adds to a step, relative to the
pure step (the quantity of issue 3's target, ≤ 2×).

    python benchmarks/plain_1d_remap.py --kernel numpy --cells 100000
    python benchmarks/plain_1d_remap.py --kernel loops --cells 100000   # needs numba

``numba`` is not a dependency of ale_xfem: install it into a throw-away virtualenv to run
the loops (they are serial, as numpy's element-wise kernels are).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

GAMMA, Q_QUADRATIC, Q_LINEAR = 1.4, 2.0, 1.0


def sod_tube(n_cells: int):
    x = np.linspace(0.0, 1.0, n_cells + 1)
    centre = 0.5 * (x[1:] + x[:-1])
    left = centre < 0.5
    mass = np.where(left, 1.0, 0.125) / n_cells
    energy = np.where(left, 2.5, 2.0)
    node_mass = np.zeros_like(x)
    node_mass[:-1] += 0.5 * mass
    node_mass[1:] += 0.5 * mass
    return x, np.zeros_like(x), mass, energy, node_mass


def numpy_kernels():
    def forces(x, u, mass, e):
        """Cell stresses P = p + q and nodal forces F_i = Σ_K P_K ∂V_K/∂x_i (walls: 0 at the ends)."""
        width = x[1:] - x[:-1]
        density = mass / width
        jump = np.minimum(u[1:] - u[:-1], 0.0)
        stress = (GAMMA - 1.0) * density * e
        stress += density * jump * (Q_QUADRATIC * jump - Q_LINEAR * np.sqrt(GAMMA * (GAMMA - 1.0) * e))
        force = np.zeros_like(x)
        force[1:-1] = stress[:-1] - stress[1:]
        return force, stress

    def minmod_slopes(value, inverse_spacing):
        slope = np.zeros_like(value)
        gradient = np.diff(value) * inverse_spacing
        right = gradient[1:]
        np.clip(gradient[:-1], np.minimum(right, 0.0), np.maximum(right, 0.0), out=slope[1:-1])
        return slope

    def remap(x, target, u, mass, e, node_mass):
        """Back onto ``target``: new masses, energies, node masses and velocities, and the
        kinetic energy change."""
        width = x[1:] - x[:-1]
        centre = x[:-1] + 0.5 * width
        rho, eps = mass / width, mass * e / width
        inverse_spacing = 1.0 / np.diff(centre)
        srho, seps = minmod_slopes(rho, inverse_spacing), minmod_slopes(eps, inverse_spacing)
        d = target[1:-1] - x[1:-1]
        right = d > 0.0  # the node sweeps part of its right cell
        offset = x[1:-1] + 0.5 * d - np.where(right, centre[1:], centre[:-1])
        flux_mass = -d * (np.where(right, rho[1:], rho[:-1]) + np.where(right, srho[1:], srho[:-1]) * offset)
        flux_energy = -d * (np.where(right, eps[1:], eps[:-1]) + np.where(right, seps[1:], seps[:-1]) * offset)
        new_mass, new_energy = mass.copy(), mass * e
        new_mass[1:] += flux_mass
        new_mass[:-1] -= flux_mass
        new_energy[1:] += flux_energy
        new_energy[:-1] -= flux_energy
        # nodes: the middle of cell j moves by δ = (d_j + d_{j+1})/2, sweeping mass between
        # nodes j and j + 1 (> 0: rightward) with the upwind node's velocity and slope
        delta = np.zeros_like(width)
        delta[1:-1] = 0.5 * (d[:-1] + d[1:])
        delta[0], delta[-1] = 0.5 * d[0], 0.5 * d[-1]
        swept = -delta * (rho + 0.5 * delta * srho)
        from_left = delta < 0.0
        node_slope = minmod_slopes(u, 1.0 / width)
        upwind = np.where(from_left, u[:-1], u[1:])
        upwind += np.where(from_left, node_slope[:-1], node_slope[1:]) * (0.5 * delta
                                                                         + np.copysign(0.25 * width, delta))
        moved = swept * upwind
        new_node_mass, momentum = node_mass.copy(), node_mass * u
        new_node_mass[:-1] -= swept
        new_node_mass[1:] += swept
        momentum[:-1] -= moved
        momentum[1:] += moved
        new_u = momentum / new_node_mass
        kinetic_change = 0.5 * (np.dot(new_node_mass * new_u, new_u) - np.dot(node_mass * u, u))
        return new_mass, new_energy / new_mass, new_node_mass, new_u, kinetic_change

    return forces, remap


def loop_kernels():
    import numba

    @numba.njit(cache=False)
    def forces(x, u, mass, e):
        n = e.size
        stress = np.empty(n)
        force = np.zeros(n + 1)
        for j in range(n):
            density = mass[j] / (x[j + 1] - x[j])
            jump = min(u[j + 1] - u[j], 0.0)
            stress[j] = (GAMMA - 1.0) * density * e[j] + density * jump * (
                Q_QUADRATIC * jump - Q_LINEAR * np.sqrt(GAMMA * (GAMMA - 1.0) * e[j]))
        for k in range(1, n):
            force[k] = stress[k - 1] - stress[k]
        return force, stress

    @numba.njit(cache=False)
    def minmod(a, b):
        if a * b <= 0.0:
            return 0.0
        return a if abs(a) < abs(b) else b

    @numba.njit(cache=False)
    def remap(x, target, u, mass, e, node_mass):
        n = e.size
        rho, eps, centre, srho, seps = np.empty(n), np.empty(n), np.empty(n), np.zeros(n), np.zeros(n)
        for j in range(n):
            width = x[j + 1] - x[j]
            centre[j] = x[j] + 0.5 * width
            rho[j], eps[j] = mass[j] / width, mass[j] * e[j] / width
        for j in range(1, n - 1):
            left, right = 1.0 / (centre[j] - centre[j - 1]), 1.0 / (centre[j + 1] - centre[j])
            srho[j] = minmod((rho[j] - rho[j - 1]) * left, (rho[j + 1] - rho[j]) * right)
            seps[j] = minmod((eps[j] - eps[j - 1]) * left, (eps[j + 1] - eps[j]) * right)
        new_mass, new_energy = mass.copy(), mass * e
        d = np.zeros(n + 1)
        for k in range(1, n):
            d[k] = target[k] - x[k]
            donor = k if d[k] > 0.0 else k - 1
            offset = x[k] + 0.5 * d[k] - centre[donor]
            flux_mass = -d[k] * (rho[donor] + srho[donor] * offset)
            flux_energy = -d[k] * (eps[donor] + seps[donor] * offset)
            new_mass[k] += flux_mass
            new_mass[k - 1] -= flux_mass
            new_energy[k] += flux_energy
            new_energy[k - 1] -= flux_energy
        node_slope = np.zeros(n + 1)
        for k in range(1, n):
            node_slope[k] = minmod((u[k] - u[k - 1]) / (x[k] - x[k - 1]), (u[k + 1] - u[k]) / (x[k + 1] - x[k]))
        new_node_mass, momentum = node_mass.copy(), node_mass * u
        for j in range(n):
            width = x[j + 1] - x[j]
            delta = 0.5 * (d[j] + d[j + 1])
            swept = -delta * (rho[j] + 0.5 * delta * srho[j])
            node = j if delta < 0.0 else j + 1
            upwind = u[node] + node_slope[node] * (0.5 * delta + np.copysign(0.25 * width, delta))
            new_node_mass[j] -= swept
            new_node_mass[j + 1] += swept
            momentum[j] -= swept * upwind
            momentum[j + 1] += swept * upwind
        new_u = momentum / new_node_mass
        kinetic_change = 0.0
        for k in range(n + 1):
            kinetic_change += 0.5 * (new_node_mass[k] * new_u[k] ** 2 - node_mass[k] * u[k] ** 2)
        return new_mass, new_energy / new_mass, new_node_mass, new_u, kinetic_change

    return forces, remap


KERNELS = {"numpy": numpy_kernels, "loops": loop_kernels}


def cycle_seconds(kernel: str = "numpy", cells: int = 100000, steps: int = 50, repeats: int = 3,
                  eulerian: bool = True) -> dict:
    """Seconds a step of the pure Lagrangian loop ("pure") and (``eulerian``) of the
    Eulerian cycle ("eulerian"), each the best of ``repeats`` timings of ``steps`` steps
    after a warm-up (``ale-xfem bench`` calls it for the numpy reference)."""
    forces, remap = KERNELS[kernel]()
    dt = 0.1 / cells

    def lagrange(x, u, mass, e, node_mass, start, evaluate_end: bool):
        force, stress = start
        dt_over_node_mass = dt / node_mass
        u_pred = u + dt_over_node_mass * force
        us = u + u_pred
        e_pred = e - (0.5 * dt) * stress * (us[1:] - us[:-1]) / mass
        force_pred, stress_pred = forces(x + 0.5 * dt * us, u_pred, mass, e_pred)
        u_new = u + dt_over_node_mass * 0.5 * (force + force_pred)
        us = u + u_new
        e_new = e - (0.25 * dt) * (stress + stress_pred) * (us[1:] - us[:-1]) / mass
        x_new = x + 0.5 * dt * us
        return x_new, u_new, e_new, (forces(x_new, u_new, mass, e_new) if evaluate_end else None)

    def pure(count):
        x, u, mass, e, node_mass = sod_tube(cells)
        start = forces(x, u, mass, e)
        for _ in range(count):
            x, u, e, start = lagrange(x, u, mass, e, node_mass, start, True)

    def eulerian_cycle(count):
        x0, u, mass, e, node_mass = sod_tube(cells)
        start = forces(x0, u, mass, e)
        for _ in range(count):
            x, u, e, _ = lagrange(x0, u, mass, e, node_mass, start, False)
            mass, e, node_mass, u, _ = remap(x, x0, u, mass, e, node_mass)
            start = forces(x0, u, mass, e)

    seconds = {}
    for name, run in (("pure", pure), ("eulerian", eulerian_cycle))[:2 if eulerian else 1]:
        run(3)  # warm-up (and numba's compilation)
        best = np.inf
        for _ in range(repeats):
            clock = time.perf_counter()
            run(steps)
            best = min(best, (time.perf_counter() - clock) / steps)
        seconds[name] = best
    return seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--kernel", choices=sorted(KERNELS), default="numpy")
    parser.add_argument("--cells", type=int, default=100000)
    parser.add_argument("--steps", type=int, default=50)
    args = parser.parse_args()
    try:
        seconds = cycle_seconds(args.kernel, args.cells, args.steps)
    except ImportError as missing:
        parser.error(f"--kernel {args.kernel} needs {missing.name}, which ale_xfem does not depend on: "
                     f"pip install {missing.name} into a throw-away virtualenv")
    pure_step, cycle = seconds["pure"], seconds["eulerian"]
    print(f"{args.kernel}: {args.cells} cells, pure Lagrangian step {pure_step * 1e3:.3f} ms, Eulerian cycle "
          f"{cycle * 1e3:.3f} ms: the remap adds {(cycle - pure_step) / pure_step:.2f}× the pure step")


if __name__ == "__main__":
    main()
