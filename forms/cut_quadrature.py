"""Integrals over a material's part of cut cells in DOLFINx forms compiled once: fixed
reference quadrature points, per-cell weights fitted to exact moments (the first route of the
cut-cell integrals in docs/design.md).

A quadrature-element Function ``ratio`` holds, at the points of the measure's rule, the
ratio of each cell's fitted weight to the rule's own (w_q |det J|): ``ratio * f * measure``
then integrates f over the part — 1 on a cell the part covers, 0 where it is absent, and on
a cut cell the weights w'_q with Σ_q w'_q x_q^a y_q^b = ∫_part x^a y^b dA for the monomials
of total degree ≤ ``exact_degree``.  Moving the part refills ``ratio``: nothing compiles.

Triangles only: their map is affine, so a P1 integrand of degree k in the reference cell is
a polynomial of degree k in x, y and the physical moments make it exact.  On a
non-affine quadrilateral the integrands (Q1 products over |det J|) are not polynomials in
x, y: that needs moments in the reference cell over the preimage of the cut.

With the default rule (degree 4: six points) and exact_degree 2 (six monomials) the
system is square; its weights can be negative (on a straight cut about 1.3 a cut cell,
the least −2.4 % of the cell's area on 8² to 256²; ``stats``): the integrals stay exact,
which is what the forms need; a lumped mass built from such weights would not be positive.
"""

from __future__ import annotations

import basix
import basix.ufl
import dolfinx_solver  # noqa: F401  (before dolfinx: it loads MPI and PETSc)
import dolfinx
import numpy as np
import ufl


class CutQuadrature:
    """The measure ``ratio * measure`` of one material's part of the cells of ``mesh``, or
    of the interface segments in them (:meth:`set_interface`)."""

    def __init__(self, mesh, rule_degree: int = 4, exact_degree: int = 2):
        if mesh.topology.cell_name() != "triangle":
            raise ValueError(f"cut-cell quadrature on {mesh.topology.cell_name()} cells: built for triangles "
                             "only (an affine map; see the module docstring)")
        self.mesh, self.exact_degree = mesh, exact_degree
        element = basix.ufl.quadrature_element("triangle", value_shape=(), scheme="default", degree=rule_degree)
        self.space = dolfinx.fem.functionspace(mesh, element)
        self.ratio = dolfinx.fem.Function(self.space)
        self.measure = ufl.Measure("dx", domain=mesh, metadata={"quadrature_degree": rule_degree,
                                                                "quadrature_scheme": "default"})
        self.points, self.weights = basix.make_quadrature(basix.CellType.triangle, rule_degree)
        self.exponents = [(total - b, b) for total in range(exact_degree + 1) for b in range(total + 1)]
        if len(self.exponents) > self.weights.size:
            raise ValueError(f"exact_degree {exact_degree} needs {len(self.exponents)} points; the rule of degree "
                             f"{rule_degree} has {self.weights.size}")
        self.stats = {"min_weight": 1.0, "negative_weights": 0}
        self._dofs = np.asarray(self.space.dofmap.list)  # (cells, points)
        self._nodes = np.asarray(mesh.geometry.dofmaps[0])

    def local_frames(self, cut_cells):
        """(origin (n, 2), scale (n,)) of each cell's local coordinates ξ = (x − origin) /
        scale: its first node, and √|det J| (a length of the cell), which keep the fitting
        well conditioned on small cells far from the origin."""
        corner = self.mesh.geometry.x[self._nodes[np.asarray(cut_cells, dtype=np.int64)], :2]
        axes = corner[:, 1:] - corner[:, :1]
        return corner[:, 0], np.sqrt(np.abs(axes[:, 0, 0] * axes[:, 1, 1] - axes[:, 0, 1] * axes[:, 1, 0]))

    def set_interface(self, cut_cells, moments) -> None:
        """The measure of the interface Γ instead of a part: the segment Γ_K of each cut
        cell, given by its moments ∫_Γ ξ^a η^b ds in the cell's local coordinates (a line
        integral carried by the cell's interior points, exact for the same monomials)."""
        self.set_part(np.zeros(0, dtype=np.int64), cut_cells, moments, record=False)

    def set_part(self, full_cells, cut_cells, moments, record: bool = True) -> None:
        """The part covers ``full_cells``, and of each of ``cut_cells`` the region whose
        moments ∫ ξ^a η^b dA are given — ξ, η the cell's local coordinates
        (:meth:`local_frames`), dA the physical area, (len(cut_cells), monomials of
        exact_degree in the order (a, b) = (d − j, j), d = 0 … exact_degree, j = 0 … d); it is
        absent from every other cell."""
        values = self.ratio.x.array
        values[:] = 0.0
        values[self._dofs[np.asarray(full_cells, dtype=np.int64)]] = 1.0
        cut_cells = np.asarray(cut_cells, dtype=np.int64)
        if cut_cells.size:
            corner = self.mesh.geometry.x[self._nodes[cut_cells], :2]  # (n, 3, 2)
            axes = corner[:, 1:] - corner[:, :1]  # (n, 2, 2): rows x1 − x0, x2 − x0
            area = np.abs(axes[:, 0, 0] * axes[:, 1, 1] - axes[:, 0, 1] * axes[:, 1, 0])
            # the rule's points in the cells' local coordinates
            points = np.einsum("qk,nkd->nqd", self.points, axes) / np.sqrt(area)[:, None, None]
            vandermonde = np.stack([points[..., 0] ** a * points[..., 1] ** b for a, b in self.exponents], axis=1)
            # least-norm weights: Σ_q w'_q x_q^a y_q^b = moment (square here, so exact)
            weights = np.einsum("nqk,nk->nq", np.linalg.pinv(vandermonde), np.asarray(moments, dtype=float))
            values[self._dofs[cut_cells]] = weights / (self.weights * area[:, None])
            if record:  # (a part's weights, relative to the cell's area; not Γ's, which are lengths)
                relative = weights / (0.5 * area[:, None])
                self.stats["min_weight"] = float(min(self.stats["min_weight"], relative.min()))
                self.stats["negative_weights"] += int(np.sum(weights < 0))
        self.ratio.x.scatter_forward()
