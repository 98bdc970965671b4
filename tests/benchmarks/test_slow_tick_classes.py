"""``bench realtime`` judges its loop's slow ticks with :func:`slow_tick_classes`: each
class must take the ticks it is known to hold and no others."""

from __future__ import annotations

import numpy as np

from reachwise.benchmarks.realtime import slow_tick_classes

# per tick: wall (µs), during a build, (voluntary, involuntary, faults)
TICKS = [
    (150.0, True, (0, 0, 0)),  # fast: never counted, whatever it did
    (900.0, True, (1, 1, 1)),  # fast, switched and faulted
    (2500.0, True, (1, 0, 1)),  # slow, during a build, blocked in a fault
    (1800.0, True, (0, 1, 0)),  # slow, during a build, preempted only
    (4000.0, True, (0, 0, 0)),  # slow, during a build, never switched out (charged)
    (3000.0, False, (2, 0, 0)),  # slow, blocked, no build running
]


def _classes(*, fifo: bool, counted: bool = True) -> dict[str, float]:
    tick_us = np.array([t[0] for t in TICKS])
    during = np.array([t[1] for t in TICKS])
    switched = np.array([t[2] for t in TICKS], dtype=np.int64)
    return slow_tick_classes(tick_us, during, switched, fifo=fifo, counted=counted)


def test_under_fifo_only_a_blocked_tick_waited_for_the_build() -> None:
    got = _classes(fifo=True)
    assert got["slow_ticks"] == 4
    assert got["slow_ticks_during_build"] == 3
    assert got["ticks_waited_for_build"] == 1  # the fault; no normal thread preempts FIFO
    assert got["slow_preempted_during_build"] == 1
    assert (got["slow.waited"], got["slow.preempted"], got["slow.charged"]) == (2, 1, 1)
    assert got["slow.faulted"] == 1
    assert (got["page_faults"], got["ticks_faulted"]) == (2, 2)


def test_at_normal_priority_a_preempted_tick_waited_too() -> None:
    got = _classes(fifo=False)
    assert got["ticks_waited_for_build"] == 2  # the worker may have taken the core


def test_without_switch_counts_every_slow_tick_during_a_build_counts() -> None:
    got = _classes(fifo=True, counted=False)
    assert got["ticks_waited_for_build"] == 3
    assert "slow.charged" not in got
