"""Process settings for a control loop that runs at 1 kHz in Python.

A tick of :class:`~reachwise.distance.scene.Scene.query_all`, the converter and
:meth:`~reachwise.control.controller.Controller.step` allocates a few small objects and
no cycles, and its compiled parts hold the GIL. What still costs milliseconds now and
then is the interpreter and the C library around it:

- **the cyclic garbage collector**: a full collection walks every object the process
  holds — numba's, scipy's, the scene's — and takes milliseconds. ``gc.freeze()``
  after the setup moves those objects out of its sight, so the collections the tick's
  few allocations trigger are short;
- **the GIL's switch interval** (left at Python's 5 ms by default): a thread that
  wants the GIL asks the running one to give it up after ``sys.getswitchinterval()``.
  The loop's tick (0.1–0.5 ms) is shorter than 5 ms and it sleeps between ticks, so
  the other threads (a camera handing over a frame, the ingestion worker between two
  compiled passes: microseconds of Python each) take the GIL while it sleeps and it
  is never made to give the GIL away mid-tick. A short interval does just that:
  measured in ``bench realtime``'s loop under ``SCHED_FIFO``, 0.1 ms had the loop
  switched out mid-tick in 14–21 ticks of 10 000 (p99.9 0.43–0.48 ms), 5 ms in 1–3
  (0.38–0.40 ms). ``switch_interval`` sets it for the block if wanted;
- **the scheduler**: a loop thread woken by its timer waits on the run queue while both
  cores run other threads (the ingestion worker's builds, another process) — measured
  in ``reachwise bench realtime``, up to 5 ms inside one tick at normal priority. Real
  1 kHz loops (libfranka, ros2_control) run their control thread under ``SCHED_FIFO``:
  it then takes a core from any normal thread at once. ``priority`` (1–99) asks Linux
  for that for the calling thread; it needs the right to (root, ``CAP_SYS_NICE`` or an
  ``rtprio`` limit): without it the thread keeps its policy and the block says so;
- **the C library's memory**: glibc returns freed blocks of more than 128 kB (up to
  32 MB, adaptively) to the kernel, so the next cloud's arrays are new pages, each
  zeroed by the kernel on first touch — 20 000 page faults, a third of the time of a
  million-point build. ``mallopt`` thresholds of 1 GiB keep freed memory for reuse
  (the process's resident size then stays at its peak);
- **the kernel's huge-page collapsing**: numpy asks for transparent huge pages on
  arrays of 4 MB and more (a cloud, its index), and Linux's ``khugepaged`` then
  collapses their pages into huge ones now and then, holding the process's memory
  map write-locked for milliseconds. A page fault of the loop at that moment waits:
  traced with ``perf sched`` in ``bench realtime``'s loop, one tick blocked twice for
  5 ms in a fault behind ``collapse_huge_page`` (a 10.6 ms tick, the loop's only one
  over 1 ms in 20 s). ``huge_pages=False`` (the default) turns transparent huge pages
  off for the process for the block (``prctl(PR_SET_THP_DISABLE)``, as real-time
  Linux guides advise): ``khugepaged`` then leaves its memory alone. Measured side by
  side, a 300 000- or 1 000 000-point build is as fast without them.

:func:`realtime_settings` applies them for the duration of a ``with`` block (memory
settings stay: they are process-wide and harmless to keep) and yields what took effect
(:class:`RealtimeApplied`);
``reachwise bench realtime`` runs its loop inside it.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import gc
import os
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import cast

__all__ = ["RealtimeApplied", "fifo_refusal", "keep_freed_memory", "realtime_settings"]

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


@dataclass(frozen=True)
class RealtimeApplied:
    """What :func:`realtime_settings` could apply: ``priority``, the ``SCHED_FIFO``
    priority the calling thread runs at (None: its policy is unchanged, ``refused``
    says why when one was asked for), ``memory_kept`` (glibc ``mallopt``),
    ``frozen`` (the collector's objects), the GIL ``switch_interval`` (s) and
    ``huge_pages_off``."""

    priority: int | None
    memory_kept: bool
    frozen: bool
    switch_interval: float
    refused: str = ""
    #: Whether transparent huge pages are off for the process in the block (by the
    #: block or before it); False where the OS has no such setting or it was kept.
    huge_pages_off: bool = False


_NOT_PERMITTED = "not permitted (needs root, CAP_SYS_NICE or an rtprio limit)"


def _check_priority(priority: object) -> None:
    if not (isinstance(priority, int) and not isinstance(priority, bool) and 1 <= priority <= 99):
        raise ValueError(f"priority must be an integer from 1 to 99, got {priority!r}")


def _fifo(priority: int) -> tuple[tuple[int, int] | None, str]:
    """Put the calling thread under ``SCHED_FIFO`` at ``priority``: the policy and
    priority to restore, or None and why it was not possible."""
    if not hasattr(os, "sched_setscheduler"):
        return None, f"SCHED_FIFO is not available on {sys.platform}"
    policy = os.sched_getscheduler(0)
    param = os.sched_getparam(0)
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except PermissionError:
        return None, _NOT_PERMITTED
    return (policy, param.sched_priority), ""


_PR_SET_THP_DISABLE = 41
_PR_GET_THP_DISABLE = 42


class _HugePages:
    """Transparent huge pages off for this process (Linux ``prctl``) while at least
    one :func:`realtime_settings` block holds them off — the setting is the process's,
    and blocks may overlap (a server and a client loop in one process) — and back as
    they were after the last one."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._holders = 0
        self._restore: int | None = None  # the PR_GET_THP_DISABLE value before

    def hold_off(self) -> bool:
        """Hold them off; whether they are off (False: no such setting here)."""
        with self._lock:
            if self._holders == 0:
                prctl = _prctl()
                if prctl is None:  # not Linux
                    return False
                before = prctl(_PR_GET_THP_DISABLE, 0, 0, 0, 0)
                if before < 0:  # a kernel without the setting
                    return False
                if before != 1:  # on, or off except where madvised (Linux 6.18 and on)
                    if prctl(_PR_SET_THP_DISABLE, 1, 0, 0, 0) != 0:
                        return False
                    self._restore = before
            self._holders += 1
            return True

    def release(self) -> None:
        """Let go of one :meth:`hold_off` that returned True."""
        with self._lock:
            self._holders -= 1
            prctl = _prctl()
            if self._holders == 0 and self._restore is not None and prctl is not None:
                # the value read is the flag (bit 0) or'ed with the mode's flags
                # (PR_THP_DISABLE_EXCEPT_ADVISED), as setting it takes them
                prctl(_PR_SET_THP_DISABLE, self._restore & 1, self._restore & ~1, 0, 0)
                self._restore = None


def _prctl() -> Callable[..., int] | None:
    """Linux's ``prctl(option, arg2, arg3, arg4, arg5)`` (None elsewhere)."""
    if sys.platform != "linux":
        return None
    try:
        prctl = ctypes.CDLL(None).prctl
    except (OSError, AttributeError):
        return None
    prctl.argtypes = [ctypes.c_int] + [ctypes.c_ulong] * 4
    prctl.restype = ctypes.c_int
    return cast("Callable[..., int]", prctl)


_HUGE_PAGES = _HugePages()


def fifo_refusal(priority: int) -> str:
    """Why a thread of this process may not run under ``SCHED_FIFO`` at ``priority``
    ("" when it may), found by trying in a short-lived thread of its own (the caller's
    policy is untouched). For threads that cannot be asked afterwards: libzmq's I/O
    threads take their policy when they start and abort the process if it is refused."""
    _check_priority(priority)
    out: list[str] = []

    def probe() -> None:
        out.append(_fifo(priority)[1])  # the policy dies with this thread

    thread = threading.Thread(target=probe, name="reachwise-fifo-probe")
    thread.start()
    thread.join()
    return out[0]


@contextmanager
def realtime_settings(
    *,
    switch_interval: float | None = None,
    freeze: bool = True,
    keep_memory: bool = True,
    priority: int | None = None,
    huge_pages: bool = False,
) -> Iterator[RealtimeApplied]:
    """Within the block: the garbage collector's existing objects frozen
    (``gc.freeze()`` after a collection), the GIL switch interval at ``switch_interval``
    seconds (None: as it is), freed memory kept (:func:`keep_freed_memory`), with
    ``priority`` (1–99) the calling thread under ``SCHED_FIFO`` at that priority where
    the OS permits it, and (unless ``huge_pages``) transparent huge pages off for the
    process on Linux. On exit the switch interval, the thread's scheduling policy and
    (after the last of overlapping blocks) the huge-page setting are restored, and the
    frozen objects are handed back to the collector (unless objects were frozen before
    the block: those stay frozen, and so do these).
    Enter it after the setup (robots, scene, clouds, controller) and a first tick, so
    that everything made once is frozen; run the loop in the thread that enters it.
    Yields :class:`RealtimeApplied`."""
    if switch_interval is not None and not switch_interval > 0:
        raise ValueError(f"switch_interval must be > 0 s, got {switch_interval!r}")
    if priority is not None:
        _check_priority(priority)
    kept = keep_freed_memory() if keep_memory else False
    # objects frozen by someone else before the block stay frozen after it (the
    # collector can only unfreeze everything at once)
    unfreeze = freeze and gc.get_freeze_count() == 0
    if freeze:
        gc.collect()
        gc.freeze()
    previous = sys.getswitchinterval()
    interval = previous if switch_interval is None else switch_interval
    sys.setswitchinterval(interval)
    restore, refused = _fifo(priority) if priority is not None else (None, "")
    pages_off = False if huge_pages else _HUGE_PAGES.hold_off()
    try:
        yield RealtimeApplied(
            priority if restore is not None else None,
            kept,
            freeze,
            interval,
            refused,
            pages_off,
        )
    finally:
        if pages_off:
            _HUGE_PAGES.release()
        if restore is not None:
            os.sched_setscheduler(0, restore[0], os.sched_param(restore[1]))
        sys.setswitchinterval(previous)
        if unfreeze:
            gc.unfreeze()
