"""The stall probe of ``reachwise bench realtime`` judges the machine: it must find a
gap it is known to contain and not charge the thread for a gap it slept through.
(A test with a CPU-spinning signal handler was dropped: in 1 of 6 runs on the
development VM the thread's CPU clock did not advance over the 4 ms spin — unexplained,
see the closing note of issue 17.)"""

from __future__ import annotations

import signal
import sys
import time

import pytest

from reachwise.benchmarks.realtime import stall_gaps

GAP = 0.004  # s, the injected gap


def _probe_with(handler: object) -> list[tuple[float, float]]:
    """The probe's gaps (wall, CPU; µs) while a timer runs ``handler`` once (on a busy
    machine other gaps come with it: the tests look for the injected one)."""
    previous = signal.signal(signal.SIGALRM, handler)  # type: ignore[arg-type]
    try:
        signal.setitimer(signal.ITIMER_REAL, 0.05)
        wall, cpu = stall_gaps(0.3)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, previous)
    return list(zip(wall.tolist(), cpu.tolist(), strict=True))


@pytest.mark.skipif(sys.platform == "win32", reason="SIGALRM")
def test_a_gap_the_thread_slept_through_is_not_charged_cpu() -> None:
    def nap(*_: object) -> None:
        time.sleep(GAP)

    gaps = _probe_with(nap)
    assert any(wall >= GAP * 1e6 and cpu < 0.5 * wall for wall, cpu in gaps), gaps
