"""The one failure the Lagrange phase reports: the state became unphysical."""

from __future__ import annotations

import numpy as np


class Breakdown(RuntimeError):
    """The state became unphysical: a one-line diagnostic (step, time, cell, quantity)."""

    def __init__(self, quantity: str, cell: int, value: float, position, allowed: str):
        self.quantity, self.cell, self.value, self.position = quantity, cell, value, position
        where = ", ".join(f"{v:.6g}" for v in np.atleast_1d(position))
        super().__init__(f"cell {cell} (x = {where}): {quantity} = {value:.6g}, must be {allowed}")
