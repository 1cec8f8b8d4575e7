"""The one failure a remap reports: the remapped state would not be physical."""

from __future__ import annotations


class RemapFailure(RuntimeError):
    """The remap would leave a material without mass, a node without mass, or a cell
    without a material: a one-line diagnostic."""
