"""The enriched 1D closure's step as the assembled FE system, instead of its closed form:
the forms of the 2D enriched mixed cells (``forms/enriched_interface.py``) on intervals,
without stabilisation (in 1D the interface conditions hold strongly, and the natural pair
is stable), solved by the 2D cells' predictor/corrector
(:class:`ale_xfem.mixed.implicit_step.ImplicitStep`).  The 1D mixed cell is thus the 1D
case of the same forms, solver and iteration; its closed-form elimination
(:mod:`ale_xfem.mixed.equilibrium`) is the fast path, tested equal to this one to the
iterations' tolerance.  The forms are compiled once per run; a remap that moves an
interface only rebinds them."""

from __future__ import annotations

import functools

import numpy as np

from ale_xfem.mixed.equilibrium import MixedCellFailure
from ale_xfem.mixed.implicit_step import ImplicitStep, MaterialStart
from ale_xfem.model.mixed_cells import MaterialGroups

# a held node: its row fixes the velocity to its prescribed value
HELD_INERTIA = 1e30


class AssembledPredictor:
    """The compiled forms of the predictor on the current mixed cells.  On several MPI
    ranks every rank assembles and solves it over all the ranks' mixed cells, on the serial
    mesh (``MixedCells.across_ranks``: the solves iterate the whole set), each cell's
    inputs from the rank that owns it: the serial run's system, to the bit — or, bound by a
    ``system`` shared out over the ranks (``ale-xfem run --interface-solve distributed``),
    assembled and factorised over them: the serial run's to round-off."""

    def __init__(self, dolfinx_mesh, cells, n_nodes: int, petsc_options: dict | None = None, system=None):
        """``n_nodes``: the mesh's nodes (the forms' nodal arrays); ``system``: what binds
        the forms to the cells (InterfaceSystem's arguments; None: InterfaceSystem)."""
        from forms.enriched_interface import InterfaceForms, InterfaceSystem

        self.mesh, self.n_nodes, self.petsc_options = dolfinx_mesh, n_nodes, petsc_options
        self.bound_system = InterfaceSystem if system is None else system
        self.forms = InterfaceForms(dolfinx_mesh.comm, "none", "free", "interval")  # compiled once per run
        self.rebuild(cells)

    def rebuild(self, cells):
        """Bind the compiled forms to the current mixed cells (no compilation)."""
        self.cells = cells
        if getattr(self, "system", None) is not None:  # (its PETSc objects freed now: InterfaceSystem.destroy)
            self.system.destroy()
        self.system = self.bound_system(self.mesh, cells, self.forms, self.petsc_options)

    def solve(self, mixed, state, predicted, mean_force, dt, mobility_a, mobility_b, start, start_stress):
        """The implicit step of the mixed cells on the assembled FE system: returns
        (π, V_α, V_β, details) of ``mixed`` as :meth:`PressureEquilibrium.solve` does
        (details: e_α, e_β, p_α, p_β, ρ_α, ρ_β, c²_α, c²_β) and counts the iterations.

        Each mixed cell K = [x_a, x_b] holds α on [x_a, x_Γ] and β on [x_Γ, x_b]; node a is
        internal to α, b to β (the external nodes are massless: in 1D the system stays
        regular).  Rows: the doubled trapezoidal momentum of the internal nodes,
        (4M/dt)(ū − u^n) = 2F̄ ± (π^n + q*) (the explicit mean force holds the cell as a whole
        at π^n + q*), and the static equilibrium of the external ones; each material's
        pressure linearised about the iterate, P = p + D (V − V_iterate) + q*, and its
        energy working against ½(W^n + p), W^n = ``start_stress`` (π^n + q^n + q*)."""
        a, b = mixed.node_left, mixed.node_right
        x, u0, force = state.node_position[0], state.node_velocity[0], mean_force[0]
        # what the system takes of each mixed cell: its nodes' positions, velocities and mean
        # forces, their mobilities, π^n, q*, W^n and the start masses, volumes and energies
        inputs = (x[a], x[b], u0[a], u0[b], force[a], force[b], mobility_a, mobility_b, state.interface_pressure,
                  predicted.mixed_viscosity, start_stress, *start)
        cells, ranks = mixed, mixed.across_ranks
        if ranks is not None:  # all the ranks' mixed cells (serial numbers), each one's inputs from its owner
            inputs, cells = ranks.whole(inputs), ranks
        x_a, x_b, u_a, u_b, f_a, f_b, mobility_a, mobility_b, pi_n, q_star, start_stress, m_a, m_b, va0, vb0, \
            ea0, eb0 = inputs
        a, b = cells.node_left, cells.node_right
        if not np.array_equal(self.cells, cells.cells):  # a remap moved an interface: new submesh
            self.rebuild(cells.cells)
        system = self.system
        position = np.zeros((1, self.n_nodes))  # (the system reads its cells' nodes only)
        position[0, a], position[0, b] = x_a, x_b
        system.move(position)
        system.vertex_order(np.stack([a, b], axis=1))
        mass = [np.zeros((1, self.n_nodes)), np.zeros((1, self.n_nodes))]
        rhs = [np.zeros((1, self.n_nodes)), np.zeros((1, self.n_nodes))]
        for k, node, u, f, mobility, sign in ((0, a, u_a, f_a, mobility_a, 1.0), (1, b, u_b, f_b, mobility_b, -1.0)):
            inertia = np.where(mobility > 0, 4.0 / np.where(mobility > 0, mobility, 1.0), HELD_INERTIA)  # 4M/dt
            mass[k][0, node] = inertia
            explicit = np.where(mobility > 0, 2.0 * f + sign * (pi_n + q_star), 0.0)
            rhs[k][0, node] = inertia * u + explicit
        x_gamma = x_a + va0
        parts = (np.stack([x_a, x_gamma], axis=1)[..., None], np.stack([x_gamma, x_b], axis=1)[..., None])
        # G: α's part ends at node a (outward normal −1), β's at node b (+1)
        edge_flux = np.zeros((2, a.size, 2, 1))
        edge_flux[0, :, 0, 0], edge_flux[1, :, 1, 0] = -1.0, 1.0
        system.set_geometry(parts, x_gamma[:, None], x_gamma[:, None], edge_flux, np.ones((a.size, 1)))
        sides = (mixed.left_groups, mixed.right_groups) if ranks is None else map(MaterialGroups, ranks.sides)
        eos = [functools.partial(groups.eos_values, mixed.materials) for groups in sides]
        step = ImplicitStep(system, cells.cells, eos, None, tolerance=mixed.tolerance,
                            max_iterations=mixed.max_iterations, nonlinear=mixed.nonlinear)
        begin = MaterialStart(np.stack([m_a, m_b]), np.stack([va0, vb0]), np.stack([ea0, eb0]), np.stack([pi_n, pi_n]))
        try:
            out = step.solve(dt, begin, mass, rhs, viscosity=q_star, start_stress=start_stress)
        except MixedCellFailure as failure:  # (its cell among all the ranks': this rank's, or -1)
            index = failure.index if ranks is None else ranks.local(failure.index)
            raise MixedCellFailure(mixed.cells, index, failure.detail) from None
        except RuntimeError as error:  # the KSP failed (its options, or the system): all cells
            first = 0 if ranks is None else ranks.local(0)
            raise MixedCellFailure(mixed.cells, first, f"the assembled predictor's solve, over all mixed "
                                                       f"cells: {error}") from None
        volume, energy, pressure, density = out["volume"], out["energy"], out["pressure"], out["density"]
        results = (out["interface_pressure"] - q_star, volume[0], volume[1],  # π: the interface stress less q*
                   energy[0], energy[1], pressure[0], pressure[1], density[0], density[1],
                   *out["sound_speed_squared"])
        if ranks is not None:
            results = ranks.mine(results)
        mixed.record_solve(out["iterations"])
        pi, va, vb, *details = results
        return pi, va, vb, tuple(details)

