"""The per-tick counters that class ``reachwise bench realtime``'s slow ticks judge the
loop's thread: each must count a blocking call and a page fault it is known to make."""

from __future__ import annotations

import mmap
import sys
import time

import pytest

from reachwise.benchmarks.realtime import thread_counters

pytestmark = pytest.mark.skipif(sys.platform != "linux", reason="RUSAGE_THREAD is Linux's")

PAGES = 64


def test_a_sleep_counts_as_a_voluntary_switch() -> None:
    counter, counted = thread_counters()
    assert counted
    before = counter()
    time.sleep(0.005)  # the thread blocks: it gives its core up of its own accord
    after = counter()
    assert after[0] - before[0] >= 1


def test_touching_fresh_pages_counts_their_faults() -> None:
    counter, _ = thread_counters()
    size = mmap.PAGESIZE * PAGES
    with mmap.mmap(-1, size) as fresh:  # anonymous: no page there until touched
        before = counter()
        for page in range(PAGES):
            fresh[page * mmap.PAGESIZE] = 1
        after = counter()
    assert after[2] - before[2] >= PAGES
