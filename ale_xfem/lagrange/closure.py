"""The one interface through which the explicit step knows its mixed cells.

A Lagrange step (:mod:`ale_xfem.lagrange.wilkins`) advances every cell as a pure cell of
stress P = p + q.  A mixed cell holds two materials: what its stress is, how its materials
share its deformation and its work, and when that is decided (explicitly, or by an
implicit interface solve) is the *closure* of the mixed cells, a class of
:mod:`ale_xfem.mixed` (enriched: the paper's doubled velocities with an interface pressure;
single-velocity: the equal-strain baseline).  The step calls it at fixed points of the
compatible predictor–corrector, and nowhere else:

1. ``relax_start``       the pressure relaxation of the start state (paper §3);
2. ``viscosity_medium``  the density and sound speed the viscosity of a mixed cell sees;
3. ``predicted_view``    the mixed cells' materials at the predicted positions (for q*);
4. ``implicit_solve``    the n+1 stress of the mixed cells, added to the mean forces
                         (enriched: the interface solve; single-velocity: nothing to do);
5. ``end_of_step``       the materials' volumes and energies at n+1;
6. ``finish`` / ``state_for_remap``  the new state's mixed-cell entries.

What the closure needs of the step it receives as the ``step`` argument: ``evaluate``
(forces of a state), ``two_slots`` (the (2, n_cells) arrays of new states), ``free_nodes``
and ``relax_end_state``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from ale_xfem.model.mixed_cells import MixedCells
from ale_xfem.model.state import State


@dataclass
class MixedView:
    """What the force evaluation needs of the mixed cells (n_mixed,): the materials'
    volumes, β's mass and energy (α's sit in slot 0), and the interface pressure."""

    volume_left: np.ndarray
    volume_right: np.ndarray
    mass_right: np.ndarray
    energy_right: np.ndarray
    interface_pressure: np.ndarray

    @classmethod
    def of(cls, state: State, cells) -> "MixedView":
        return cls(state.material_volume[0, cells], state.material_volume[1, cells],
                   state.material_mass[1, cells], state.material_energy[1, cells],
                   state.interface_pressure)


class MixedCellClosure(ABC):
    """The mixed cells of a step (module docstring).  ``mixed``: the current mixed cells."""

    mixed: MixedCells
    #: whether the mixed cells' n+1 stress comes from an implicit solve (timed by the step)
    implicit: bool

    def compiles_steps(self, step) -> bool:
        """Whether :meth:`steps` can take this run's steps in compiled chunks."""
        return False

    def steps(self, step, state: State, evaluation, clock: dict, boundary_impulse):
        """Steps in one compiled call, as ExplicitWilkins.pure_steps takes those of pure
        cells (its ``clock`` and results); only where :meth:`compiles_steps`."""
        raise NotImplementedError(f"{type(self).__name__} takes its steps one by one")

    def hold_predictor(self, u0, u_pred) -> None:
        """Change the explicit predictor's velocities ``u_pred`` (in place; ``u0`` the
        start's) where the closure's own solve moves the nodes; by default nowhere."""

    @abstractmethod
    def bind(self, mixed: MixedCells) -> None:
        """Take the mixed cells a remap left (no compilation: the forms stay)."""

    @abstractmethod
    def relax_start(self, state: State, in_place: bool = False) -> tuple[State, bool]:
        """The start state with its mixed cells' pressures relaxed, and whether it changed."""

    @abstractmethod
    def viscosity_medium(self, view: MixedView, volume, density, sound_speed, node_mass):
        """(density, sound speed) of each mixed cell as its artificial viscosity sees it
        (``node_mass``: the lumped nodal masses the viscosity pushes)."""

    @abstractmethod
    def predicted_view(self, state: State, first, x_pred, e_pred) -> MixedView:
        """The mixed cells at the predicted positions; sets their entries of e_pred."""

    @abstractmethod
    def implicit_solve(self, step, state: State, first, predicted, mean_force, dt, dt_over_node_mass):
        """Add the mixed cells' n+1 stress to mean_force; returns the solution or None."""

    @abstractmethod
    def end_of_step(self, state: State, first, predicted, x_new, e_new, solution):
        """(V_α, V_β, details) at n+1, details the materials' energies, pressures, densities
        and c²."""

    @abstractmethod
    def finish(self, step, state: State, solution, x_new, u_new, e_new, dt):
        """(new state, its force evaluation) with the mixed cells' entries filled."""

    @abstractmethod
    def state_for_remap(self, step, state: State, solution, x_new, u_new, cell_volume, e_new, dt):
        """(the (2, n_cells) material volumes, the interface fields) of a state the remap
        reads; fills the mixed cells' entries of e_new."""
