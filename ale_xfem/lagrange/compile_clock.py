"""The seconds a process spends compiling its compiled (numba) kernels, which a run's
timings leave out: numba compiles a kernel at its first call with a signature that its
cache (a folder named after the kernels' sources) does not hold — every kernel on a fresh
install, seconds per kernel set — and announces each compilation as a "numba:compile"
event; one listener, registered when this module is first imported, adds up their
durations (a compilation inside another counted once).  Loading a kernel from the cache
is no such event (numba returns the cached one before it), so the first run in a process
still counts that loading: a few hundredths of a second for a 1D scene's kernels, about a
tenth for a 2D enriched scene's."""

from __future__ import annotations

import time

from numba.core import event

_LISTENER = event.TimingListener()
event.register("numba:compile", _LISTENER)


def compile_seconds() -> float:
    """Seconds this process has spent so far compiling compiled kernels."""
    return _LISTENER.duration if _LISTENER.done else 0.0


def own_clock() -> float:
    """Seconds of wall-clock time less those spent compiling so far: the difference of two
    readings is the time between them that was not compiling kernels."""
    return time.perf_counter() - compile_seconds()
