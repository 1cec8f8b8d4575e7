"""How fast can a bare quadrilateral Lagrange step go on this machine, and with what tools?

Evidence for BENCHMARKS.md ("What the unmet speed targets would take"), not part of the
package.  One step of the scheme of ale_xfem.lagrange stripped to its arithmetic: the
compatible two-stage predictor–corrector (two force evaluations, energy from the
time-centred corner forces), an ideal gas (γ = 1.4), the quadratic + linear artificial
viscosity with L = √A; no hourglass control, CFL, boundary conditions or checks.  Sod's
states on an √n × √n grid of the unit square; nodes numbered row by row, corner c of
every cell a slice of the (ny + 1, nx + 1) node plane.

    python benchmarks/plain_quad_step.py --kernel numpy   --cells 100000
    python benchmarks/plain_quad_step.py --kernel numexpr --cells 100000   # needs numexpr
    python benchmarks/plain_quad_step.py --kernel loops   --cells 100000   # needs numba
    python benchmarks/plain_quad_step.py --stages 1       --cells 100000   # one evaluation a step

``--stages 1``: the classical staggered leapfrog instead (velocities at half steps, one
force evaluation a step, each zone's energy changed by the work of the step's forces on
the half-step velocity): the step a plain explicit code takes, but its total energy is
not conserved to round-off (the drift is printed), which is why ale_xfem takes two.

``numexpr`` and ``numba`` are not dependencies of ale_xfem: install them into a
throw-away virtualenv to run those kernels (numexpr is held to one thread and numba's
loops are serial, as numpy's element-wise kernels are).  Every kernel prints ms a step,
zone-cycles a second and the relative change of total energy (round-off: the same
compatible scheme).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

GAMMA, Q_QUADRATIC, Q_LINEAR = 1.4, 2.0, 1.0
# corner c of every cell as a slice of the node plane: (i, j), (i+1, j), (i+1, j+1), (i, j+1)
CORNERS = ((slice(None, -1), slice(None, -1)), (slice(None, -1), slice(1, None)),
           (slice(1, None), slice(1, None)), (slice(1, None), slice(None, -1)))


def sod_grid(n_cells: int):
    """Node positions, velocities, cell masses and energies, lumped node masses."""
    side = int(round(np.sqrt(n_cells)))
    x, y = np.meshgrid(np.linspace(0.0, 1.0, side + 1), np.linspace(0.0, 1.0, side + 1))
    left = x[:-1, :-1] < 0.5
    mass = np.where(left, 1.0, 0.125) / side**2
    energy = np.where(left, 2.5, 2.0)
    node_mass = np.zeros_like(x)
    for corner in CORNERS:
        node_mass[corner] += 0.25 * mass
    return x, y, np.zeros_like(x), np.zeros_like(x), mass, energy, node_mass


def numpy_kernels(mass):
    """Force evaluation and corner work as whole-array numpy expressions."""

    def forces(x, y, u, v, e):
        px, rx = x[CORNERS[0]] - x[CORNERS[2]], x[CORNERS[1]] - x[CORNERS[3]]
        py, ry = y[CORNERS[0]] - y[CORNERS[2]], y[CORNERS[1]] - y[CORNERS[3]]
        area = 0.5 * (px * ry - py * rx)
        density = mass / area
        pressure = (GAMMA - 1.0) * density * e
        sound = np.sqrt(GAMMA * pressure / density)
        ax, bx = u[CORNERS[0]] - u[CORNERS[2]], u[CORNERS[1]] - u[CORNERS[3]]
        ay, by = v[CORNERS[0]] - v[CORNERS[2]], v[CORNERS[1]] - v[CORNERS[3]]
        jump = np.minimum(0.5 * (ry * ax - rx * ay - py * bx + px * by) / np.sqrt(area), 0.0)
        stress = pressure + density * jump * (Q_QUADRATIC * jump - Q_LINEAR * sound)
        g = (0.5 * ry * stress, -0.5 * rx * stress, -0.5 * py * stress, 0.5 * px * stress)
        return _scatter(x, g), g

    def work(g, us, vs):
        return (g[0] * (us[CORNERS[0]] - us[CORNERS[2]]) + g[1] * (vs[CORNERS[0]] - vs[CORNERS[2]])
                + g[2] * (us[CORNERS[1]] - us[CORNERS[3]]) + g[3] * (vs[CORNERS[1]] - vs[CORNERS[3]]))

    return forces, work


def _scatter(x, g):
    """F_Ki = P ∂A/∂x_i summed onto the nodes (∂A/∂x_2 = −∂A/∂x_0, ∂A/∂x_3 = −∂A/∂x_1)."""
    fx, fy = np.zeros_like(x), np.zeros_like(x)
    fx[CORNERS[0]] += g[0]
    fx[CORNERS[2]] -= g[0]
    fx[CORNERS[1]] += g[2]
    fx[CORNERS[3]] -= g[2]
    fy[CORNERS[0]] += g[1]
    fy[CORNERS[2]] -= g[1]
    fy[CORNERS[1]] += g[3]
    fy[CORNERS[3]] -= g[3]
    return fx, fy


def numexpr_kernels(mass):
    """The same expressions, each evaluated by numexpr in one fused pass."""
    import numexpr

    numexpr.set_num_threads(1)
    evaluate = numexpr.evaluate

    def forces(x, y, u, v, e):
        x0, x1, x2, x3 = (x[c] for c in CORNERS)
        y0, y1, y2, y3 = (y[c] for c in CORNERS)
        u0, u1, u2, u3 = (u[c] for c in CORNERS)
        v0, v1, v2, v3 = (v[c] for c in CORNERS)
        px, rx, py, ry = evaluate("x0 - x2"), evaluate("x1 - x3"), evaluate("y0 - y2"), evaluate("y1 - y3")
        area = evaluate("0.5 * (px * ry - py * rx)")
        density = evaluate("mass / area", dict(mass=mass, area=area))
        jump = evaluate("where(rate < 0, rate, 0)", dict(rate=evaluate(
            "0.5 * (ry * (u0 - u2) - rx * (v0 - v2) - py * (u1 - u3) + px * (v1 - v3)) / sqrt(area)")))
        stress = evaluate("(g - 1) * density * e + density * jump * (qq * jump - ql * sqrt(g * (g - 1) * e))",
                          dict(g=GAMMA, qq=Q_QUADRATIC, ql=Q_LINEAR, density=density, e=e, jump=jump))
        g = (evaluate("0.5 * ry * stress"), evaluate("-0.5 * rx * stress"),
             evaluate("-0.5 * py * stress"), evaluate("0.5 * px * stress"))
        return _scatter(x, g), g

    def work(g, us, vs):
        g0, g1, g2, g3 = g
        u0, u1, u2, u3 = (us[c] for c in CORNERS)
        v0, v1, v2, v3 = (vs[c] for c in CORNERS)
        return evaluate("g0 * (u0 - u2) + g1 * (v0 - v2) + g2 * (u1 - u3) + g3 * (v1 - v3)")

    return forces, work


def loop_kernels(mass):
    """The same arithmetic as compiled loops over the cells (numba)."""
    import numba

    @numba.njit(cache=False)
    def forces_into(x, y, u, v, e, mass, g, fx, fy):
        fx[:] = 0.0
        fy[:] = 0.0
        for j in range(e.shape[0]):
            for i in range(e.shape[1]):
                px, rx = x[j, i] - x[j + 1, i + 1], x[j, i + 1] - x[j + 1, i]
                py, ry = y[j, i] - y[j + 1, i + 1], y[j, i + 1] - y[j + 1, i]
                area = 0.5 * (px * ry - py * rx)
                density = mass[j, i] / area
                pressure = (GAMMA - 1.0) * density * e[j, i]
                sound = np.sqrt(GAMMA * pressure / density)
                ax, bx = u[j, i] - u[j + 1, i + 1], u[j, i + 1] - u[j + 1, i]
                ay, by = v[j, i] - v[j + 1, i + 1], v[j, i + 1] - v[j + 1, i]
                jump = min(0.5 * (ry * ax - rx * ay - py * bx + px * by) / np.sqrt(area), 0.0)
                stress = pressure + density * jump * (Q_QUADRATIC * jump - Q_LINEAR * sound)
                g0, g1, g2, g3 = 0.5 * ry * stress, -0.5 * rx * stress, -0.5 * py * stress, 0.5 * px * stress
                g[0, j, i], g[1, j, i], g[2, j, i], g[3, j, i] = g0, g1, g2, g3
                fx[j, i] += g0
                fx[j + 1, i + 1] -= g0
                fx[j, i + 1] += g2
                fx[j + 1, i] -= g2
                fy[j, i] += g1
                fy[j + 1, i + 1] -= g1
                fy[j, i + 1] += g3
                fy[j + 1, i] -= g3

    @numba.njit(cache=False)
    def work_into(g, us, vs, out):
        for j in range(out.shape[0]):
            for i in range(out.shape[1]):
                out[j, i] = (g[0, j, i] * (us[j, i] - us[j + 1, i + 1]) + g[1, j, i] * (vs[j, i] - vs[j + 1, i + 1])
                             + g[2, j, i] * (us[j, i + 1] - us[j + 1, i]) + g[3, j, i] * (vs[j, i + 1] - vs[j + 1, i]))

    def forces(x, y, u, v, e):
        g = np.empty((4, *e.shape))
        fx, fy = np.empty_like(x), np.empty_like(x)
        forces_into(x, y, u, v, e, mass, g, fx, fy)
        return (fx, fy), g

    def work(g, us, vs):
        out = np.empty(g.shape[1:])
        work_into(g, us, vs, out)
        return out

    return forces, work


KERNELS = {"numpy": numpy_kernels, "numexpr": numexpr_kernels, "loops": loop_kernels}


def step_seconds(kernel: str = "numpy", cells: int = 100000, steps: int = 20, stages: int = 2,
                 repeats: int = 3) -> tuple[float, int, float]:
    """(seconds a step, the best of ``repeats`` timings of ``steps`` steps after a warm-up;
    the number of cells; the relative change of total energy) (``ale-xfem bench
    --dimension 2`` calls it for the numpy reference)."""
    x, y, u, v, mass, e, node_mass = sod_grid(cells)
    forces, work = KERNELS[kernel](mass)
    dt = 1e-4
    dt_over_node_mass = dt / node_mass

    def total_energy(u, v, e):
        return float(np.sum(mass * e) + 0.5 * np.sum(node_mass * (u * u + v * v)))

    def step(x, y, u, v, e, start):
        (fx, fy), g = start
        u_pred, v_pred = u + dt_over_node_mass * fx, v + dt_over_node_mass * fy
        us, vs = u + u_pred, v + v_pred
        e_pred = e - (0.5 * dt) * work(g, us, vs) / mass
        (fx_pred, fy_pred), g_pred = forces(x + 0.5 * dt * us, y + 0.5 * dt * vs, u_pred, v_pred, e_pred)
        u_new = u + dt_over_node_mass * 0.5 * (fx + fx_pred)
        v_new = v + dt_over_node_mass * 0.5 * (fy + fy_pred)
        us, vs = u + u_new, v + v_new
        e_new = e - (0.25 * dt) * (work(g, us, vs) + work(g_pred, us, vs)) / mass
        x_new, y_new = x + 0.5 * dt * us, y + 0.5 * dt * vs
        return x_new, y_new, u_new, v_new, e_new, forces(x_new, y_new, u_new, v_new, e_new)

    def leapfrog(x, y, u, v, e, start):
        """u, v at the half step before x, y, e; one force evaluation."""
        (fx, fy), g = start
        u_new, v_new = u + dt_over_node_mass * fx, v + dt_over_node_mass * fy
        e_new = e - dt * work(g, u_new, v_new) / mass
        x_new, y_new = x + dt * u_new, y + dt * v_new
        return x_new, y_new, u_new, v_new, e_new, forces(x_new, y_new, u_new, v_new, e_new)

    if stages == 1:
        step = leapfrog  # noqa: F811
    start = forces(x, y, u, v, e)
    energy_before = total_energy(u, v, e)
    for _ in range(3):  # warm-up (and numba's compilation)
        x, y, u, v, e, start = step(x, y, u, v, e, start)
    best = np.inf
    for _ in range(repeats):
        clock = time.perf_counter()
        for _ in range(steps):
            x, y, u, v, e, start = step(x, y, u, v, e, start)
        best = min(best, (time.perf_counter() - clock) / steps)
    return best, e.size, abs(total_energy(u, v, e) - energy_before) / energy_before


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--kernel", choices=sorted(KERNELS), default="numpy")
    parser.add_argument("--cells", type=int, default=100000)
    parser.add_argument("--steps", type=int, default=20)
    parser.add_argument("--stages", type=int, choices=(1, 2), default=2,
                        help="force evaluations a step: 2 compatible predictor–corrector (default), 1 leapfrog")
    args = parser.parse_args()
    try:
        best, cells, drift = step_seconds(args.kernel, args.cells, args.steps, args.stages)
    except ImportError as missing:
        parser.error(f"--kernel {args.kernel} needs {missing.name}, which ale_xfem does not depend on: "
                     f"pip install {missing.name} into a throw-away virtualenv")
    print(f"{args.kernel}, {args.stages} evaluation{'s' if args.stages == 2 else ''} a step: {cells} cells, "
          f"{best * 1e3:.2f} ms a step (best of 3 × {args.steps}), {cells / best:.3g} zone-cycles/s, relative "
          f"change of total energy {drift:.1e}")


if __name__ == "__main__":
    main()
