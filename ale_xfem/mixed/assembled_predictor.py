"""The enriched 1D closure's predictor as the assembled FE system, instead of its closed
form: the forms of the 2D enriched mixed cells (``forms/enriched_interface.py``) on
intervals, without stabilisation (in 1D the interface conditions hold strongly, and the
natural pair is stable).  The 1D mixed cell is thus the 1D case of the same forms; its
closed-form elimination (:mod:`ale_xfem.mixed.equilibrium`) is the fast path, tested equal
to this one.  The forms are compiled once per run; a remap that moves an interface only
rebinds them."""

from __future__ import annotations

import numpy as np

from ale_xfem.mixed.equilibrium import MixedCellFailure

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

    def predictor_for(self, mixed, state, predicted, mean_force, dt, mobility_a, mobility_b, start):
        """The predictor as the assembled FE system: returns a callable (iterate → material
        pressure π) for PressureEquilibrium.solve.

        Each mixed cell K = [x_a, x_b] holds α on [x_a, x_Γ] and β on [x_Γ, x_b]; node a is
        internal to α, b to β (the external nodes are massless: in 1D the system stays
        regular).  Rows: the doubled trapezoidal momentum of the internal nodes,
        (4M/dt)(ū − u^n) = 2F̄ ± (π^n + q*) (the explicit mean force holds the cell as a whole
        at π^n + q*), and the static equilibrium of the external ones; each material's
        pressure linearised about the iterate, P = π + D (V − V_iterate) + q*."""
        a, b = mixed.node_left, mixed.node_right
        x, u0, force = state.node_position[0], state.node_velocity[0], mean_force[0]
        # what the system takes of each mixed cell: its nodes' positions, velocities and mean
        # forces, their mobilities, π^n, q* and the start volumes
        inputs = (x[a], x[b], u0[a], u0[b], force[a], force[b], mobility_a, mobility_b, state.interface_pressure,
                  predicted.mixed_viscosity, start[2], start[3])
        cells, ranks = mixed, mixed.across_ranks
        if ranks is not None:  # all the ranks' mixed cells (serial numbers), each one's inputs from its owner
            inputs, cells = ranks.whole(inputs), ranks
        x_a, x_b, u_a, u_b, f_a, f_b, mobility_a, mobility_b, pi_n, q_star, va0, vb0 = inputs
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
        volumes = np.stack([va0, vb0])
        first = 0 if ranks is None else ranks.local(0)  # (a failure of the system is every cell's)

        def predict(va, vb, pa, pb, da, db):
            slope = np.stack([da, db])
            offsets = np.stack([pa + da * (va0 - va) + q_star, pb + db * (vb0 - vb) + q_star])
            system.set_materials(-1.0 / (slope * dt * volumes), offsets)
            try:
                out = system.solve(mass, rhs)
            except RuntimeError as error:  # the KSP failed (its options, or the system): all cells
                raise MixedCellFailure(mixed.cells, first, f"the assembled predictor's solve, over all mixed "
                                                           f"cells: {error}") from None
            return out["interface_pressure"] - q_star  # the interface stress less the viscosity: π

        return predict
