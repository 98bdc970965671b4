"""The process settings of a 1 kHz loop: applied inside the block, restored after."""

from __future__ import annotations

import ctypes
import gc
import os
import platform
import sys

import pytest

from reachwise.runtime.realtime import keep_freed_memory, realtime_settings


def test_settings_apply_inside_the_block_and_are_restored() -> None:
    before = sys.getswitchinterval()
    gc.unfreeze()  # whatever an earlier test left frozen
    frozen = gc.get_freeze_count()
    with realtime_settings(switch_interval=2e-4):
        assert sys.getswitchinterval() == pytest.approx(2e-4)
        assert gc.get_freeze_count() > frozen
    assert sys.getswitchinterval() == before
    assert gc.get_freeze_count() == frozen
    with pytest.raises(ValueError, match="switch_interval"), realtime_settings(switch_interval=0):
        pass
    assert sys.getswitchinterval() == before
    with realtime_settings(freeze=False) as applied:  # by default: the interval as it is
        assert sys.getswitchinterval() == before == applied.switch_interval


@pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="mallopt is glibc's")
def test_memory_setting_applies_with_glibc() -> None:
    assert keep_freed_memory()


@pytest.mark.skipif(not hasattr(os, "sched_setscheduler"), reason="POSIX scheduling")
def test_priority_puts_the_thread_under_fifo_inside_the_block_or_says_why_not() -> None:
    policy, param = os.sched_getscheduler(0), os.sched_getparam(0).sched_priority
    with realtime_settings(priority=10, freeze=False) as applied:
        inside = os.sched_getscheduler(0), os.sched_getparam(0).sched_priority
    assert (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority) == (policy, param)
    if applied.priority is None:  # an unprivileged user: nothing changed, and why
        assert "not permitted" in applied.refused
        assert inside == (policy, param)
    else:
        assert applied.priority == 10 and applied.refused == ""
        assert inside == (os.SCHED_FIFO, 10)


@pytest.mark.skipif(not hasattr(os, "sched_setscheduler"), reason="POSIX scheduling")
def test_a_refused_priority_leaves_the_policy_and_says_so(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    def refuse(*_: object) -> None:
        raise PermissionError(1, "Operation not permitted")

    policy = os.sched_getscheduler(0)
    monkeypatch.setattr(os, "sched_setscheduler", refuse)
    with realtime_settings(priority=50, freeze=False) as applied:
        assert os.sched_getscheduler(0) == policy
    assert applied.priority is None
    assert "not permitted" in applied.refused


@pytest.mark.parametrize("bad", [0, 100, 1.5, True, "50"])
def test_a_priority_outside_1_to_99_is_refused_before_anything_changes(bad: object) -> None:
    before = sys.getswitchinterval()
    with pytest.raises(ValueError, match="priority must be an integer from 1 to 99"):
        with realtime_settings(priority=bad):  # type: ignore[arg-type]
            pass
    assert sys.getswitchinterval() == before


def test_objects_frozen_before_the_block_stay_frozen_after_it() -> None:
    gc.collect()
    gc.freeze()
    try:
        frozen = gc.get_freeze_count()
        assert frozen > 0
        with realtime_settings():
            pass
        assert gc.get_freeze_count() >= frozen
    finally:
        gc.unfreeze()


def _thp_enabled() -> int | None:
    """The kernel's own word on this process: ``THP_enabled`` in /proc/self/status."""
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith("THP_enabled:"):
                    return int(line.split()[1])
    except OSError:
        pass
    return None


needs_thp_on = pytest.mark.skipif(
    _thp_enabled() != 1,
    reason="no THP_enabled in /proc/self/status, or transparent huge pages off here",
)


@needs_thp_on
def test_huge_pages_are_off_for_the_process_inside_the_block_and_back_after() -> None:
    before = _thp_enabled()
    with realtime_settings(freeze=False) as applied:
        inside = _thp_enabled()
    assert applied.huge_pages_off
    assert inside == 0
    assert _thp_enabled() == before
    with realtime_settings(freeze=False, huge_pages=True) as kept:
        assert _thp_enabled() == before
    assert not kept.huge_pages_off


@needs_thp_on
def test_huge_pages_turned_off_before_the_block_stay_off_after_it() -> None:
    prctl = ctypes.CDLL(None).prctl
    assert prctl(41, 1, 0, 0, 0) == 0  # PR_SET_THP_DISABLE, as a caller might have
    try:
        with realtime_settings(freeze=False) as applied:
            assert _thp_enabled() == 0
        assert applied.huge_pages_off
        assert _thp_enabled() == 0
    finally:
        prctl(41, 0, 0, 0, 0)
    assert _thp_enabled() == 1


@needs_thp_on
def test_overlapping_blocks_keep_huge_pages_off_until_the_last_one_ends() -> None:
    # a loop's block and a server's in one process, on two threads: the first to
    # start ends first
    first, second = realtime_settings(freeze=False), realtime_settings(freeze=False)
    first.__enter__()
    applied = second.__enter__()
    first.__exit__(None, None, None)
    between = _thp_enabled()  # the second block still holds them off
    second.__exit__(None, None, None)
    assert applied.huge_pages_off
    assert between == 0
    assert _thp_enabled() == 1


@needs_thp_on
def test_huge_pages_off_except_where_advised_come_back_as_they_were() -> None:
    prctl = ctypes.CDLL(None).prctl
    # PR_SET_THP_DISABLE with PR_THP_DISABLE_EXCEPT_ADVISED (Linux 6.18 and on): numpy's
    # madvised arrays would still be collapsed, so the block turns them off completely
    if prctl(41, 1, 2, 0, 0) != 0:
        pytest.skip("no PR_THP_DISABLE_EXCEPT_ADVISED in this kernel")
    try:
        before = prctl(42, 0, 0, 0, 0)
        with realtime_settings(freeze=False) as applied:
            inside = prctl(42, 0, 0, 0, 0)
        after = prctl(42, 0, 0, 0, 0)
    finally:
        prctl(41, 0, 0, 0, 0)
    assert before == 3  # off (1), except where advised (2)
    assert applied.huge_pages_off
    assert inside == 1
    assert after == before
