"""The seconds a process spends loading or compiling its compiled (numba) kernels, which a
run's timings leave out: they are paid once per kernel signature in a process, from numba's
cache in about 0.3 s for all of them, and cold (a fresh install, or another cache folder)
in seconds per kernel set — not the run's own time.  numba announces each compilation,
loading from its cache included, as a "numba:compile" event; one listener, registered when
this module is first imported, adds up their durations (a compilation inside another counted
once)."""

from __future__ import annotations

from numba.core import event

_LISTENER = event.TimingListener()
event.register("numba:compile", _LISTENER)


def compile_seconds() -> float:
    """Seconds this process has spent so far loading or compiling compiled kernels."""
    return _LISTENER.duration if _LISTENER.done else 0.0
