"""A run's options as one typed group (``RunOptions``) or as keywords: the same run,
and a keyword given beside the group overrides its field."""

from __future__ import annotations

import pytest

import reachwise
from reachwise.sim.run_options import RunOptions
from tests.sim.test_stages import assert_same_log


def test_the_group_and_the_keywords_run_the_same() -> None:
    ticks: list[float] = []
    group = RunOptions(duration=0.05, progress=lambda t, _T: ticks.append(t))
    by_group = reachwise.simulate("p3-self-collision", options=group)
    by_keywords = reachwise.simulate("p3-self-collision", duration=0.05)
    assert_same_log(by_group, by_keywords)
    assert len(ticks) == len(by_group.t) == 6  # 0, 10, ..., 50 ms at dt = 10 ms


def test_a_keyword_overrides_the_groups_field() -> None:
    log = reachwise.simulate("p3-self-collision", options=RunOptions(duration=1.0), duration=0.02)
    assert len(log.t) == 3
    with pytest.raises(TypeError, match="no_such_option"):
        reachwise.simulate("p3-self-collision", no_such_option=1)  # type: ignore[call-arg]
