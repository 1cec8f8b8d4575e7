"""The state of a run: node arrays and per-cell, per-material arrays.

Shapes (n_nodes, n_cells from the mesh; dim = mesh dimension; S = material slots per cell,
1 while materials never share a cell, 2 once mixed cells exist):

- ``node_position``, ``node_velocity``: (dim, n_nodes), component by component
- ``material_mass``, ``material_energy`` (specific internal energy): (S, n_cells)
- ``material_volume``, ``material_density``, ``material_pressure``,
  ``material_sound_speed``: (S, n_cells), derived from the above by :func:`thermodynamics`
- ``interface_pressure``, ``interface_velocity``: (n_mixed,), mixed cells only
- ``cell_material``: (S, n_cells) int, index into the run's material list, −1 for an
  empty slot (held by :class:`MaterialLayout`, which changes only when materials move
  between cells).

Units are the scene's (any consistent set: SI for solids, dimensionless for Toro's tests).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np


@dataclass(frozen=True)
class Material:
    name: str
    eos_name: str
    eos: object


class MaterialLayout:
    """Which material sits in which slot of which cell, grouped for EOS evaluation.

    ``groups`` holds, per material, the flat indices into an (S, n_cells) array (a slice
    when they are contiguous, which avoids a gather/scatter per evaluation)."""

    def __init__(self, cell_material: np.ndarray, n_materials: int):
        self.cell_material = np.ascontiguousarray(cell_material)
        flat = self.cell_material.ravel()
        self.groups = []
        for material in range(n_materials):
            where = np.flatnonzero(flat == material)
            if where.size == 0:
                continue
            if where[-1] - where[0] + 1 == where.size:
                where = slice(int(where[0]), int(where[-1]) + 1)
            self.groups.append((material, where))
        self.occupied = flat >= 0
        self.single = (self.groups[0][0] if len(self.groups) == 1 and bool(self.occupied.all())
                       else None)

    @property
    def slots(self) -> int:
        return self.cell_material.shape[0]


@dataclass(frozen=True)
class State:
    time: float
    node_position: np.ndarray
    node_velocity: np.ndarray
    material_mass: np.ndarray
    material_energy: np.ndarray
    material_volume: np.ndarray
    material_density: np.ndarray
    material_pressure: np.ndarray
    material_sound_speed: np.ndarray
    # Mixed cells (n_mixed,): the interface pressure p_Γ and the interface's mean velocity
    # over the last step (displacement of Γ / dt).  None when there are no mixed cells.
    interface_pressure: np.ndarray | None = None
    interface_velocity: np.ndarray | None = None

    def evolved(self, **changes) -> "State":
        return replace(self, **changes)


def thermodynamics(materials, layout: MaterialLayout, density, energy, out=None):
    """Pressure and sound speed (S, n_cells) from density and specific energy, material by
    material.  Empty slots get p = 0, c = 0.  ``out``: a (pressure, sound speed) pair of
    arrays shaped like density to fill instead of new ones."""
    if layout.single is not None:  # one material fills every slot: no gather or scatter
        eos = materials[layout.single].eos
        with np.errstate(invalid="ignore"):
            pressure, sound_speed = eos.pressure(density, energy), np.sqrt(eos.sound_speed_squared(density, energy))
        if out is None:
            return pressure, sound_speed
        out[0][...], out[1][...] = pressure, sound_speed
        return out
    if out is None:
        pressure, sound_speed = np.zeros_like(density), np.zeros_like(density)
    else:
        pressure, sound_speed = out
        if not layout.occupied.all():
            pressure.fill(0.0)
            sound_speed.fill(0.0)
    rho_flat, e_flat = density.reshape(-1), energy.reshape(-1)
    p_flat, c_flat = pressure.reshape(-1), sound_speed.reshape(-1)
    for material, where in layout.groups:
        eos = materials[material].eos
        rho, e = rho_flat[where], e_flat[where]
        p_flat[where] = eos.pressure(rho, e)
        # c² < 0 only outside the EOS's domain (e.g. a stiffened gas below p = −p∞): the
        # breakdown check reports it through the NaN it makes.
        with np.errstate(invalid="ignore"):
            c_flat[where] = np.sqrt(eos.sound_speed_squared(rho, e))
    return pressure, sound_speed


def totals(state: State, node_mass: np.ndarray) -> dict[str, float]:
    """Mass, momentum (per component) and total energy of a state."""
    kinetic = 0.5 * np.sum(node_mass * state.node_velocity**2)
    internal = np.sum(state.material_mass * state.material_energy)
    return {
        "mass": float(np.sum(state.material_mass)),
        "momentum": (node_mass * state.node_velocity).sum(axis=1),
        "kinetic_energy": float(kinetic),
        "internal_energy": float(internal),
        "total_energy": float(kinetic + internal),
    }
