"""What both remaps do with the kinetic energy the momentum remap changes, when it must not
be given back node by node: the gains of some nodes are not taken from the cells around
them (cold gas must not be cooled below zero by a neighbour's gain).  The 2D remap always
works this way; the 1D remap when its local deposit would leave a material outside its
equation of state's domain (``deposit_kinetic_loss(..., positive_only=True)``)."""

from __future__ import annotations

import numpy as np


def losses_only(loss, totals=None):
    """The nodes' kinetic-energy losses (n_nodes,) with the gains left out and the rest
    scaled to the same sum, for a remap that lost kinetic energy overall (loss.sum() > 0):
    deposited as heat, total energy is conserved.  ``totals``: (Σ loss, Σ max(loss, 0)) over
    the whole mesh, when ``loss`` is one MPI rank's share (:mod:`ale_xfem.remap.scope`)."""
    positive = np.maximum(loss, 0.0)
    total, positive_total = (loss.sum(), positive.sum()) if totals is None else totals
    return positive * (total / positive_total)


def made_kinetic_energy_factor(loss_sum, internal_energy_sum):
    """For a remap that made kinetic energy overall (loss_sum < 0): the factor every internal
    energy is scaled by so that they pay for it in proportion (none goes below 0)."""
    return 1.0 + loss_sum / internal_energy_sum
