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


def held_arrays(boundaries: list[Boundary], dim: int):
    """The walls and pistons among ``boundaries``, in their order, as the compiled loops
    take them (ale_xfem.lagrange.kernels.hold): kinds (0 wall, 1 piston), offsets into the
    nodes, the nodes, each one's normal and prescribed velocity (n_boundaries, dim)."""
    held = [b for b in boundaries if b.kind != "free"]
    kinds = np.array([0 if b.kind == "wall" else 1 for b in held], dtype=np.int64)
    offsets = np.zeros(len(held) + 1, dtype=np.int64)
    offsets[1:] = np.cumsum([b.nodes.size for b in held])
    nodes = (np.concatenate([b.nodes for b in held]).astype(np.int64) if held else np.zeros(0, dtype=np.int64))
    normals, velocities = np.zeros((len(held), dim)), np.zeros((len(held), dim))
    for row, b in enumerate(held):
        if b.normal is not None:
            normals[row] = b.normal[:dim]
        if b.velocity is not None:
            velocities[row] = b.velocity[:dim]
    return kinds, offsets, nodes, normals, velocities
