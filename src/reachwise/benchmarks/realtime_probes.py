"""What ``reachwise bench realtime`` (:mod:`reachwise.benchmarks.realtime`) reads about
its own threads and the machine: a thread's context switches and page faults
(:func:`thread_counters`), the slow ticks of the loop classed by them
(:func:`slow_tick_classes`), and the machine's stalls seen by a bare busy loop
(:func:`stall_gaps`)."""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["DT", "STALL_GAP", "slow_tick_classes", "stall_gaps", "thread_counters"]

#: The control period (s).
DT = 1e-3
#: A gap between two clock reads of the stall probe longer than this (s) is recorded.
STALL_GAP = 2e-4


def thread_counters() -> tuple[Any, bool]:
    """A function giving the calling thread's (voluntary, involuntary) context switches
    and page faults so far, and whether it counts them (Linux's ``RUSAGE_THREAD``;
    elsewhere (0, 0, 0))."""
    try:
        import resource

        who = resource.RUSAGE_THREAD  # type: ignore[attr-defined,unused-ignore]
    except (ImportError, AttributeError):
        return (lambda: (0, 0, 0)), False

    def switches() -> tuple[int, int, int]:
        r = resource.getrusage(who)
        return r.ru_nvcsw, r.ru_nivcsw, r.ru_minflt + r.ru_majflt

    return switches, True


def slow_tick_classes(
    tick_us: NDArray[np.float64],
    during: NDArray[np.bool_],
    switched: NDArray[np.int64],
    *,
    fifo: bool,
    counted: bool = True,
) -> dict[str, float]:
    """The loop's ticks over the period :data:`DT`, classed by what its thread did in
    them: ``tick_us`` (µs), ``during`` (a build was running), ``switched`` (per tick:
    voluntary and involuntary context switches and page faults, :func:`thread_counters`;
    ``counted`` False where the platform has none).

    ``ticks_waited_for_build``: the slow ticks during a build in which the thread was
    kept from running by something a build can cause — it blocked (a lock, the GIL, a
    page fault behind a write-locked memory map) or, at normal priority (``fifo``
    False), another thread took its core. Under ``SCHED_FIFO`` no normal thread (the
    build's worker is one) can take its core: only the kernel's own stop-class and
    real-time threads can (traced with ``perf sched`` in this loop: ``migration/1``
    alone, microseconds at a time), so such a preemption is counted apart
    (``slow_preempted_during_build``). Without counts every slow tick during a build
    counts as waited."""
    slow = tick_us > DT * 1e6
    vol, invol, faults = switched[:, 0] > 0, switched[:, 1] > 0, switched[:, 2] > 0
    if not counted:
        vol = invol = np.ones(len(tick_us), np.bool_)
    kept_off = vol | invol if not fifo else vol
    out: dict[str, Any] = {
        "slow_ticks": np.count_nonzero(slow),
        "slow_ticks_during_build": np.count_nonzero(slow & during),
        "ticks_waited_for_build": np.count_nonzero(slow & during & kept_off),
        "slow_preempted_during_build": np.count_nonzero(slow & during & invol & ~vol),
    }
    if counted:
        out |= {
            "slow.waited": np.count_nonzero(slow & vol),
            "slow.preempted": np.count_nonzero(slow & ~vol & invol),
            "slow.charged": np.count_nonzero(slow & ~vol & ~invol),
            "slow.faulted": np.count_nonzero(slow & faults),
            "page_faults": switched[:, 2].sum(),
            "ticks_faulted": np.count_nonzero(faults),
        }
    return {k: float(v) for k, v in out.items()}


def stall_gaps(seconds: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Run a bare busy loop of clock reads for ``seconds`` on this thread; every gap
    between two reads longer than :data:`STALL_GAP`: its wall time and the thread's
    CPU time over it (µs). A gap whose CPU time is (nearly) its wall time is a stall
    of the machine: the thread was charged for the time but ran none of its code (the
    hypervisor did not run the virtual CPU, or an interrupt took it); a gap with
    little CPU time is the scheduler running another thread."""
    wall_ns, cpu_ns = time.perf_counter_ns, time.thread_time_ns
    limit = int(STALL_GAP * 1e9)
    gaps: list[tuple[int, int]] = []
    t_prev, c_prev = wall_ns(), cpu_ns()
    c_before = c_prev
    end = t_prev + int(seconds * 1e9)
    while t_prev < end:
        t, c = wall_ns(), cpu_ns()
        if t - t_prev > limit:
            # the CPU clock over this gap and the one before it: a pause between the
            # previous wall and CPU reads falls in this wall gap but in the previous
            # CPU window (the two clocks cannot be read at one instant)
            gaps.append((t - t_prev, c - c_before))
        t_prev, c_before, c_prev = t, c_prev, c
    arr = np.array(gaps, dtype=np.float64).reshape(-1, 2) * 1e-3
    return arr[:, 0], arr[:, 1]
