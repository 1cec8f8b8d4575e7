"""The mixed cells of a mesh, as data: which cells hold two materials, their internal nodes
(1D), the materials on each side, and the settings of their solver (scene keys
``numerics.interface_*`` and ``[interface]``).  The solver itself is
:mod:`ale_xfem.mixed.equilibrium`; the closures that step them, :mod:`ale_xfem.mixed`."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class MaterialGroups:
    """Per-material index groups of a 1D array of material ids (one entry per mixed cell)."""

    ids: np.ndarray

    def __post_init__(self):
        self.groups = [(int(m), np.flatnonzero(self.ids == m)) for m in np.unique(self.ids)]

    def eos_values(self, materials, rho, e):
        """Pressure, ∂p/∂ρ|_e, ∂p/∂e|_ρ, c² for each entry."""
        if len(self.groups) == 1:
            return list(materials[self.groups[0][0]].eos.state(rho, e))
        out = [np.empty_like(rho) for _ in range(4)]
        for material, where in self.groups:
            values = materials[material].eos.state(rho[where], e[where])
            for target, value in zip(out, values):
                target[where] = value
        return out

    def max_density(self, materials):
        limit = np.empty(self.ids.size)
        for material, where in self.groups:
            limit[where] = materials[material].eos.max_density
        return limit


@dataclass
class MixedCells:
    """The static description of the mixed cells (1D: with their internal nodes a, b; 2D:
    node_left = node_right = None) and the settings of their solver."""

    cells: np.ndarray  # (n_mixed,) cell index
    node_left: np.ndarray  # (n_mixed,) node a, internal to α (slot 0)
    node_right: np.ndarray  # (n_mixed,) node b, internal to β (slot 1)
    material_left: np.ndarray  # (n_mixed,) material id of α
    material_right: np.ndarray  # (n_mixed,) material id of β
    materials: list
    tolerance: float = 1e-10
    max_iterations: int = 50
    nonlinear: bool = True
    model: str = "enriched"  # or "single_velocity": one velocity field, equal strain + relaxation
    relaxation: bool = True  # pressure relaxation at the start of every step
    stats: dict = field(default_factory=lambda: {"steps": 0, "iterations": 0, "max_iterations": 0,
                                                 "relaxations": 0})
    # On several MPI ranks (ale_xfem.parallel): the mixed cells of all the ranks as one set
    # (whole(arrays), mine(arrays), local(index)), which every rank solves whole — the
    # solves iterate all their cells until every one is done, and relax all or none: the
    # serial run's iterations.  None on one rank.
    across_ranks: object = None

    def __post_init__(self):
        self.left_groups = MaterialGroups(self.material_left)
        self.right_groups = MaterialGroups(self.material_right)
        self.count = self.cells.size
        # the densities each side's equation of state allows (its compression limit)
        self.max_density_left = self.left_groups.max_density(self.materials)
        self.max_density_right = self.right_groups.max_density(self.materials)

    def record_solve(self, iterations: int) -> None:
        """Count one interface solve of ``iterations`` predictor/corrector iterations."""
        self.stats["steps"] += 1
        self.stats["iterations"] += iterations
        self.stats["max_iterations"] = max(self.stats["max_iterations"], iterations)


def material_names(mixed: MixedCells, index: int) -> str:
    """'α | β' of mixed cell ``index`` (slot 0 | slot 1; in 1D left | right), for diagnostics."""
    return " | ".join(mixed.materials[int(m[index])].name for m in (mixed.material_left, mixed.material_right))


def with_mixed_state(state, cells, va, vb, details, interface_velocity, in_place: bool = False):
    """A copy of state with the mixed cells' material arrays replaced (``in_place``: the
    state's own arrays are changed, for a state nothing else refers to yet)."""
    ea, eb, pa, pb, rho_a, rho_b, c2a, c2b = details
    arrays = {k: getattr(state, k) if in_place else getattr(state, k).copy() for k in (
        "material_volume", "material_energy", "material_density", "material_pressure",
        "material_sound_speed")}
    for slot, values in enumerate(((va, ea, rho_a, pa, c2a), (vb, eb, rho_b, pb, c2b))):
        v, e, rho, p, c2 = values
        arrays["material_volume"][slot, cells] = v
        arrays["material_energy"][slot, cells] = e
        arrays["material_density"][slot, cells] = rho
        arrays["material_pressure"][slot, cells] = p
        arrays["material_sound_speed"][slot, cells] = np.sqrt(np.maximum(c2, 0.0))
    return state.evolved(**arrays, interface_pressure=0.5 * (pa + pb),
                         interface_velocity=interface_velocity)
