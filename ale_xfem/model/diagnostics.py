"""How a diagnostic names a cell: its index, where it is, and the materials of a mixed cell."""

from __future__ import annotations

import numpy as np


def place(cell: int, position, materials: str = "") -> str:
    """'cell 12 (x = 0.5)' in 1D, 'cell 12 (x, y = 0.5, 0.25)' in 2D; with the materials of a
    mixed cell, left | right."""
    coordinates = np.atleast_1d(position)
    names = "x" if coordinates.size == 1 else "x, y"
    where = ", ".join(f"{v:.6g}" for v in coordinates)
    return f"cell {cell} ({names} = {where}{'; ' + materials if materials else ''})"
