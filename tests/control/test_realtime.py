"""The process settings of a 1 kHz loop: applied inside the block, restored after."""

from __future__ import annotations

import gc
import platform
import sys

import pytest

from reachwise.control.realtime import keep_freed_memory, realtime_settings


def test_settings_apply_inside_the_block_and_are_restored() -> None:
    before = sys.getswitchinterval()
    frozen = gc.get_freeze_count()
    with realtime_settings(switch_interval=2e-4):
        assert sys.getswitchinterval() == pytest.approx(2e-4)
        assert gc.get_freeze_count() > frozen
    assert sys.getswitchinterval() == before
    assert gc.get_freeze_count() == frozen
    with pytest.raises(ValueError, match="switch_interval"), realtime_settings(switch_interval=0):
        pass
    assert sys.getswitchinterval() == before


@pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="mallopt is glibc's")
def test_memory_setting_applies_with_glibc() -> None:
    assert keep_freed_memory()
