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

Slot 1 is zero wherever a cell holds one material.  The (2, n_cells) arrays a Lagrange
step makes come from :class:`TwoSlotArrays`, which reuses the memory of the states a run
has dropped; a state is not changed once handed on (``evolved`` makes a new one).

Units are the scene's (any consistent set: SI for solids, dimensionless for Toro's tests).
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass, fields

import numpy as np

from ale_xfem.eos import kernel_tables
from ale_xfem.eos.kernels import fill_pressure_sound_speed
from ale_xfem.model.cell_kernels import same_slots, slot_densities


@dataclass(frozen=True)
class Material:
    name: str
    eos_name: str
    eos: object


class MaterialLayout:
    """Which material sits in which slot of which cell: ``cell_material`` (S, n_cells), −1
    for an empty slot."""

    def __init__(self, cell_material: np.ndarray, n_materials: int):
        self.cell_material = np.ascontiguousarray(cell_material)
        self.n_materials = n_materials

    @property
    def slots(self) -> int:
        return self.cell_material.shape[0]

    def updated(self, cell_material: np.ndarray) -> "MaterialLayout":
        """The layout of ``cell_material``: this one when no material entered or left a
        cell (a remap of pure regions), else a new one."""
        cell_material = np.ascontiguousarray(cell_material)
        if cell_material.shape == self.cell_material.shape and same_slots(cell_material, self.cell_material):
            return self
        return MaterialLayout(cell_material, self.n_materials)

    def first_slot(self) -> "MaterialLayout":
        """The layout of slot 0 alone (the explicit loop's view of a mixed layout)."""
        if self.slots == 1:
            return self
        return MaterialLayout(self.cell_material[:1], self.n_materials)


def ranked_materials(values, count: int = 2) -> np.ndarray:
    """Per cell, the materials of its ``count`` largest ``values`` ((n_materials, n_cells),
    finite, e.g. volumes): (count, n_cells), the largest first and of equal values the
    lower material first — np.argsort(-values, axis=0, kind="stable")[:count], without a
    sort along the strided axis (a loop over the materials).  Slot 0 of a cell holds its
    largest material, slot 1 of a mixed cell the next one."""
    values = np.array(values, dtype=float)  # a copy: the ranked entries are masked
    count = min(count, values.shape[0])
    ranked = np.empty((count, values.shape[1]), dtype=np.int64)
    for rank in range(count):
        best, row = values[0].copy(), ranked[rank]
        row.fill(0)
        for m in range(1, values.shape[0]):
            larger = values[m] > best
            row[larger] = m
            np.maximum(best, values[m], out=best)
        if rank + 1 < count:
            values[row, np.arange(values.shape[1])] = -np.inf
    return ranked


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
    # 2D enriched mixed cells (one velocity per material on their nodes): each material's
    # nodal velocity (2, dim, n_nodes; the mesh's node_velocity where the node is not in a
    # mixed cell), its nodal masses (2, n_nodes) and corner masses (2, k, n_cells), both
    # condensed in the mixed cells.  None otherwise.
    material_node_velocity: np.ndarray | None = None
    material_node_mass: np.ndarray | None = None
    material_corner_mass: np.ndarray | None = None
    # (2, n_nodes) bool: the material's mass sits on the node (an internal node); at its
    # external nodes a material's velocity is only the extension of its field into the cut cell
    material_node_internal: np.ndarray | None = None
    # 2D enriched mixed cells, in a Lagrangian state a remap reads: what each cell gained of
    # each material that crossed the mesh's moving edges in the step (a node moves with the
    # material it lies in, so an edge between nodes of two materials moves with neither):
    # (mass (2, n_cells), internal energy (2, n_cells), momentum (2 components, 2, n_cells),
    # kinetic energy (2, n_cells)), by material.  The remap adds it before its own fluxes.
    # None otherwise.
    material_crossing: tuple | None = None

    def evolved(self, **changes) -> "State":
        """A copy with ``changes`` (field names) replaced: dataclasses.replace without its
        re-run of __init__ (40 µs, a step makes one)."""
        unknown = changes.keys() - _STATE_FIELDS
        if unknown:
            raise TypeError(f"State has no field {sorted(unknown)[0]!r}")
        new = object.__new__(State)
        new.__dict__.update(self.__dict__)
        new.__dict__.update(changes)
        return new


_STATE_FIELDS = frozenset(field.name for field in fields(State))


class TwoSlotArrays:
    """(2, n_cells) arrays for the states a run makes, slot 1 zero but at the mixed cells.

    Zeroing slot 1 of a new array is a pass over every cell, for a few mixed cells: five
    arrays a step cost about 0.5 ms, 7 % of a 10⁵-cell step with one mixed cell.  The
    memory of an array the run has dropped is handed out again instead, with only the
    slot-1 entries it held zeroed.
    Safety rests on numpy, not on bookkeeping: the arrays are made over buffers this object
    owns, so every view of one refers to that array itself (numpy does not look past it to
    a base that is not an array), and the array is freed only when no state, evaluation or
    view uses its memory any more; only then does a weak reference's callback take its
    buffer back.  The holder of an array writes slot 1 only at the cells it was taken for."""

    # Below this many cells a new array's row of zeros costs less than the bookkeeping of a
    # recycled one (measured: 2 µs against 4 at 10³ cells, 4.6 against 4 at 10⁴, 30 against
    # 4 at 10⁵), and new arrays are made.
    RECYCLE_FROM = 10_000

    def __init__(self, n_cells: int):
        self.n_cells = n_cells
        self.free = []  # (buffer, the cells whose slot 1 it may hold nonzero)
        # id of a weak reference to an array handed out → (the reference, which must live
        # for its callback to run; the array's buffer; its cells)
        self.lent = {}

    def take(self, cells) -> np.ndarray:
        """A (2, n_cells) array: slot 0 undefined, slot 1 zero except at ``cells`` (the
        mixed cells, whose entries are undefined too)."""
        if self.n_cells < self.RECYCLE_FROM:
            array = np.empty((2, self.n_cells))
            array[1].fill(0.0)
            return array
        if self.free:
            buffer, written = self.free.pop()
            array = np.ndarray((2, self.n_cells), buffer=buffer)
            array[1, written] = 0.0
        else:
            buffer = bytearray(2 * self.n_cells * np.dtype(float).itemsize)
            array = np.ndarray((2, self.n_cells), buffer=buffer)
            array[1].fill(0.0)
        reference = weakref.ref(array, self._returned)
        self.lent[id(reference)] = (reference, buffer, np.array(cells, copy=True))
        return array

    def _returned(self, reference):
        """The array is gone, and with it every view of its memory: take the buffer back."""
        _, buffer, cells = self.lent.pop(id(reference))
        self.free.append((buffer, cells))


def density_of(mass, volume):
    """ρ = m / V per slot, 0 in empty slots (V = 0)."""
    density = np.empty_like(mass)
    slot_densities(mass, volume, density)
    return density


def thermodynamics(materials, layout: MaterialLayout, density, energy, out=None):
    """Pressure and sound speed (S, n_cells) from density and specific energy, each slot by
    the equation of state of its material (one compiled pass, ale_xfem.eos.kernels).
    Empty slots get p = 0, c = 0; c is NaN where c² < 0, outside the EOS's domain (e.g. a
    stiffened gas below p = −p∞): the breakdown check reports it.  ``out``: a (pressure,
    sound speed) pair of arrays shaped like density to fill instead of new ones."""
    pressure, sound_speed = (np.empty_like(density), np.empty_like(density)) if out is None else out
    kinds, parameters = kernel_tables(tuple(material.eos for material in materials))
    fill_pressure_sound_speed(kinds, parameters, layout.cell_material[:density.shape[0]], density, energy,
                              pressure, sound_speed)
    return pressure, sound_speed


def material_masses(state: State, layout: MaterialLayout) -> np.ndarray:
    """The mass of each material (n_materials,), each summed pairwise as np.sum does (a
    running sum, as np.bincount's, drifts by up to n ε: 4 × 10⁻¹⁴ of Sedov's one material
    on 60², where the total mass agreed to 2 × 10⁻¹⁶)."""
    return np.array([state.material_mass[layout.cell_material == m].sum() for m in range(layout.n_materials)])


def material_angular_momenta(state: State, layout: MaterialLayout, cell_nodes: np.ndarray, centroids: np.ndarray,
                             center) -> np.ndarray:
    """Each material's angular momentum about ``center`` (2D, per unit length; (n_materials,)):
    Σ_K m_α,K (x_K − c) × ū_K, x_K the cell's centroid (n_cells, 2) and ū_K the mean
    velocity of its nodes (``cell_nodes`` (n_cells, k)).  With one velocity field a mixed
    cell's materials move alike: what this measures is how much of a spinning material's
    angular momentum its cells still hold.  Where the state carries one velocity per
    material (2D enriched mixed cells) each material's own nodal masses and velocities
    give it, Σ_i M_α,i (x_i − c) × u_α,i: the momentum the run conserves."""
    if state.material_node_velocity is not None:
        arm = state.node_position - np.asarray(center, dtype=float)[:, None]
        u = state.material_node_velocity
        return np.sum(state.material_node_mass * (arm[0] * u[:, 1] - arm[1] * u[:, 0]), axis=1)
    velocity = _cells_mean_velocity(state, cell_nodes)
    arm = centroids - np.asarray(center, dtype=float)
    moment = arm[:, 0] * velocity[1] - arm[:, 1] * velocity[0]
    return np.array([_material_sum(state, layout, m, moment) for m in range(layout.n_materials)])


def material_momenta(state: State, layout: MaterialLayout, cell_nodes: np.ndarray) -> np.ndarray:
    """Each material's momentum (2D, per unit length; (n_materials, 2)): Σ_K m_α,K ū_K, ū_K
    the mean velocity of the cell's nodes (``cell_nodes`` (n_cells, k)) — with one velocity
    field what a material's cells carry; where the state carries one velocity per material
    (2D enriched mixed cells), Σ_i M_α,i u_α,i over its own nodal masses: the momentum the
    run conserves."""
    if state.material_node_velocity is not None:
        return np.einsum("mn,mdn->md", state.material_node_mass, state.material_node_velocity)
    velocity = _cells_mean_velocity(state, cell_nodes)
    return np.array([[_material_sum(state, layout, m, velocity[d]) for d in range(2)]
                     for m in range(layout.n_materials)])


def _cells_mean_velocity(state: State, cell_nodes: np.ndarray) -> np.ndarray:
    """(2, n_cells): the mean velocity of each cell's nodes (one velocity field)."""
    return state.node_velocity[:2, cell_nodes].mean(axis=2)


def _material_sum(state: State, layout: MaterialLayout, m: int, per_cell: np.ndarray) -> float:
    """Σ_K m_m,K f_K: material m's masses in its cells (every slot) times a cell field."""
    return np.sum(np.where(layout.cell_material == m, state.material_mass, 0.0) * per_cell)


def totals(state: State, node_mass: np.ndarray) -> dict[str, float]:
    """Mass, momentum (per component) and total energy of a state (with one velocity per
    material on the nodes of enriched 2D mixed cells: of each material's velocities with
    its own nodal masses)."""
    if state.material_node_velocity is not None:
        mass, velocity = state.material_node_mass[:, None, :], state.material_node_velocity
        momentum = (mass * velocity).sum(axis=(0, 2))
    else:
        mass, velocity = node_mass, state.node_velocity
        momentum = (node_mass * velocity).sum(axis=1)
    kinetic = 0.5 * np.sum(mass * velocity**2)
    internal = np.sum(state.material_mass * state.material_energy)
    return {
        "mass": float(np.sum(state.material_mass)),
        "momentum": momentum,
        "kinetic_energy": float(kinetic),
        "internal_energy": float(internal),
        "total_energy": float(kinetic + internal),
    }
