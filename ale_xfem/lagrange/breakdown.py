"""The one failure the Lagrange phase reports: the state became unphysical."""

from __future__ import annotations

from ale_xfem.model.diagnostics import place


class Breakdown(RuntimeError):
    """The state became unphysical: a one-line diagnostic naming the cell, where it is, and
    the quantity (the run adds the step and the time).  ``detail``: what went wrong, in
    place of 'value, must be allowed' (a mixed-cell solve that did not converge)."""

    def __init__(self, quantity: str, cell: int, value: float, position, allowed: str = "",
                 materials: str = "", detail: str = ""):
        self.quantity, self.cell, self.value, self.position = quantity, cell, value, position
        self.allowed, self.materials, self.detail = allowed, materials, detail
        what = f": {detail}" if detail else f" = {value:.6g}, must be {allowed}"
        super().__init__(f"{place(cell, position, materials)}: {quantity}{what}")
