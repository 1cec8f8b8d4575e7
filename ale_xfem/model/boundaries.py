"""Boundary conditions held on the nodes of a side: walls, pistons (prescribed velocity),
free ends."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Boundary:
    """Nodes held by one boundary condition.

    kind ``wall``: no normal velocity (unit outward normal, free tangential slip);
    kind ``velocity``: the whole velocity prescribed (a piston);  ``free``: no constraint."""

    side: str
    kind: str
    nodes: np.ndarray
    normal: np.ndarray | None = None  # (dim,)
    velocity: np.ndarray | None = None  # (dim,)

    def apply(self, node_velocity: np.ndarray) -> None:
        """Impose the condition on node_velocity (components, n_nodes), in place.  In 1D a
        second (transverse) component is tangential to the wall and left free."""
        dim = self.normal.size
        if self.kind == "wall":
            u = node_velocity[:dim, self.nodes]
            normal_part = self.normal @ u
            node_velocity[:dim, self.nodes] = u - self.normal[:, None] * normal_part
        elif self.kind == "velocity":
            node_velocity[:dim, self.nodes] = self.velocity[:dim, None]
