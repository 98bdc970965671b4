"""Process settings for a control loop that runs at 1 kHz in Python (issue 17).

A tick of :class:`~reachwise.distance.scene.Scene.query_all`, the converter and
:meth:`~reachwise.control.controller.Controller.step` allocates a few small objects and
no cycles, and its compiled parts hold the GIL. What still costs milliseconds now and
then is the interpreter and the C library around it:

- **the cyclic garbage collector**: a full collection walks every object the process
  holds — numba's, scipy's, the scene's — and takes milliseconds. ``gc.freeze()``
  after the setup moves those objects out of its sight, so the collections the tick's
  few allocations trigger are short;
- **the GIL's switch interval**: a thread that wants the GIL (the camera thread
  handing over a frame, the ingestion worker between two compiled passes) waits for
  the running thread to give it up, forcibly after ``sys.getswitchinterval()``, 5 ms
  by default. 0.1 ms bounds how long the loop thread and a hand-over wait for each
  other (their own Python is a few microseconds at a time);
- **the C library's memory**: glibc returns freed blocks of more than 128 kB (up to
  32 MB, adaptively) to the kernel, so the next cloud's arrays are new pages, each
  zeroed by the kernel on first touch — 20 000 page faults, a third of the time of a
  million-point build. ``mallopt`` thresholds of 1 GiB keep freed memory for reuse
  (the process's resident size then stays at its peak).

:func:`realtime_settings` applies the three for the duration of a ``with`` block
(memory settings stay: they are process-wide and harmless to keep);
``reachwise bench realtime`` runs its loop inside it.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import gc
import sys
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["keep_freed_memory", "realtime_settings"]

_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
_KEEP = 1 << 30  # bytes


def keep_freed_memory() -> bool:
    """Ask the C library to keep freed memory for reuse (glibc ``mallopt``: trim and
    mmap thresholds of 1 GiB). Returns False where that is not available."""
    name = ctypes.util.find_library("c")
    if name is None:
        return False
    try:
        libc = ctypes.CDLL(name)
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    ok = mallopt(_M_MMAP_THRESHOLD, _KEEP) == 1
    return bool(mallopt(_M_TRIM_THRESHOLD, _KEEP) == 1 and ok)


@contextmanager
def realtime_settings(
    *, switch_interval: float = 1e-4, freeze: bool = True, keep_memory: bool = True
) -> Iterator[None]:
    """Within the block: the garbage collector's existing objects frozen
    (``gc.freeze()`` after a collection), the GIL switch interval at
    ``switch_interval`` seconds, freed memory kept (:func:`keep_freed_memory`). On exit
    the switch interval is restored and the frozen objects are handed back to the
    collector. Enter it after the setup (robots, scene, clouds, controller) and a
    first tick, so that everything made once is frozen."""
    if not switch_interval > 0:
        raise ValueError(f"switch_interval must be > 0 s, got {switch_interval!r}")
    if keep_memory:
        keep_freed_memory()
    if freeze:
        gc.collect()
        gc.freeze()
    previous = sys.getswitchinterval()
    sys.setswitchinterval(switch_interval)
    try:
        yield
    finally:
        sys.setswitchinterval(previous)
        if freeze:
            gc.unfreeze()
