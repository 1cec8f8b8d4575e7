"""The binding of the UFL forms of ``forms/mixed_cell.py`` to the current mixed cells: the
enriched closure's predictor as the assembled FE system (PETSc), instead of its closed form.
The forms are compiled once per run; a remap that moves an interface only rebinds them."""

from __future__ import annotations

import numpy as np


class AssembledPredictor:
    """The compiled forms of the predictor on the current mixed cells."""

    def __init__(self, dolfinx_mesh, cells):
        from forms.mixed_cell import MixedCellForms

        self.mesh = dolfinx_mesh
        self.forms = MixedCellForms(dolfinx_mesh.comm, dolfinx_mesh.topology.cell_name(),
                                    dolfinx_mesh.geometry.dim)  # compiled once per run
        self.rebuild(cells)

    def rebuild(self, cells):
        """Bind the compiled forms to the current mixed cells (no compilation)."""
        from forms.mixed_cell import MixedCellPredictor

        self.cells = cells
        self.predictor = MixedCellPredictor(self.mesh, cells, self.forms)

    def predictor_for(self, mixed, state, predicted, mean_force, dt, mobility_a, mobility_b, start):
        """The predictor as the assembled FE system of forms/mixed_cell.py: returns a
        callable (iterate → material pressure π) for PressureEquilibrium.solve."""
        forms = self
        if not np.array_equal(forms.cells, mixed.cells):  # a remap moved an interface: new submesh
            forms.rebuild(mixed.cells)
        a, b = mixed.node_left, mixed.node_right
        forms.predictor.move(state.node_position)
        pi_n = state.interface_pressure
        q_star = predicted.mixed_viscosity
        n_nodes = state.node_position.shape[1]
        held = 1e30  # a held node: its row fixes ū to its prescribed value
        mass = [np.zeros(n_nodes), np.zeros(n_nodes)]
        rhs = [np.zeros((1, n_nodes)), np.zeros((1, n_nodes))]
        u0 = state.node_velocity[0]
        for k, node, mobility, sign in ((0, a, mobility_a, 1.0), (1, b, mobility_b, -1.0)):
            m4 = np.where(mobility > 0, 4.0 / np.where(mobility > 0, mobility, 1.0), held)  # 4M/dt
            mass[k][node] = m4
            # 4M u^n/dt + 2F̄ + F^n: the doubled trapezoidal row (module docstring there)
            explicit = np.where(mobility > 0, 2.0 * mean_force[0, node] + sign * (pi_n + q_star), 0.0)
            rhs[k][0, node] = m4 * u0[node] + explicit
        m_a, m_b, va0, vb0, _, _ = start
        volume = va0 + vb0
        x_gamma = state.node_position[0, a] + va0

        def predict(va, vb, pa, pb, da, db):
            offsets = [pa + da * (va0 - va) + q_star, pb + db * (vb0 - vb) + q_star]
            pressure, _ = forms.predictor.solve(mass, rhs, [va0 / volume, vb0 / volume], [da * dt, db * dt],
                                                offsets, np.ones((a.size, 1)), x_gamma[:, None],
                                                np.ones(a.size))
            return pressure - q_star  # the interface stress less the viscosity: π

        return predict
