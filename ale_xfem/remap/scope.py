"""What a remap reaches beyond the cells and nodes it holds: sums over the whole mesh, the
verdict on a failure, and (on several MPI ranks) the values its neighbours' ranks own.

A serial run holds the whole mesh: :class:`WholeMesh` sums with numpy, raises a failure
at once and refreshes nothing.  On several MPI ranks each rank remaps its share of a 2D
mesh's cells and a ghost layer around it (``ale_xfem.parallel``), whose outer cells miss some of
their neighbours: a subclass there refreshes the ghost cells and nodes from their owners
at the points :class:`ale_xfem.remap.remapper_2d.Remapper2D` names, sums the ranks' own
entries in the serial order, and agrees on failures over the ranks.
"""

from __future__ import annotations

import numpy as np

from ale_xfem.remap.failure import RemapFailure


class WholeMesh:
    """The scope of a serial remap: the whole mesh."""

    # the nodes whose checks count (None: every node)
    owned_nodes = None

    def cells(self, *fields) -> None:
        """Refresh cell fields (each (rows, n_cells)) where another rank owns the cell: nothing
        to do on the whole mesh."""

    def nodes(self, *fields) -> None:
        """Refresh nodal fields (each (rows, n_nodes) or (n_nodes,)): as :meth:`cells`."""

    def totals(self, fields, over: str) -> list[float]:
        """Σ of each field over the whole mesh (``over`` "cells": (rows, n_cells), "nodes":
        (n_nodes,) or (rows, n_nodes)), in the serial order."""
        return [float(values.sum()) for values in fields]

    def summed(self, value):
        """Σ over the ranks of a value each rank found on its own cells or nodes (here: the
        value)."""
        return value

    def anywhere(self, flag: bool) -> bool:
        """Whether ``flag`` holds on any rank."""
        return bool(flag)

    def solved_mixed(self, mixed, options: dict):
        """The mixed cells a remap left (MixedCells or None), as the Lagrange step is to
        solve them: here the remap's own; on several ranks every rank's, as one set
        (``options``: the solver settings of new mixed cells)."""
        return mixed

    def cell_number(self, cell: int) -> int:
        """The serial number of a cell."""
        return int(cell)

    def verdict(self, failure: RemapFailure | None, order: int = 0) -> None:
        """Raise ``failure`` (on several ranks: the first any rank found, ``order`` ranking
        failures of one check — the serial cell number); nothing if there is none."""
        if failure is not None:
            raise failure


def first_cell(bad: np.ndarray) -> int:
    """The first cell where ``bad`` holds (-1: none)."""
    where = np.flatnonzero(bad)
    return int(where[0]) if where.size else -1
