"""A scenario reads a MoveIt SRDF: ``self: {robot: arm, pairs: {srdf: FILE}}`` watches
every pair of link clouds the SRDF does not disable, and ``q0: NAME`` starts at its
``group_state``. Truth: the SRDF read independently with ElementTree; our own pairs
written to an SRDF and read back."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from reachwise.errors import InputError, UnknownName
from reachwise.io.srdf import write_srdf
from reachwise.sim.resolve import resolve_scenario
from reachwise.sim.scenarios import scenario_from_dict
from reachwise.sim.self_pairs import auto_self_pairs
from tests._real_arms import ERD, arm_path, needs_erd

pytestmark = needs_erd


def _scenario(arm: str, tip: str, q0: Any, pairs: Any, folder: Path) -> dict[str, Any]:
    return {
        "name": "srdf",
        "duration": 1.0,
        "robots": [{"name": "arm", "robot": {"file": str(arm_path(arm)), "tip": tip},
                    "q0": q0, "points": 200}],
        "watch": [{"self": {"robot": "arm", "pairs": pairs}, "margin": 0.02}],
    }  # fmt: skip


def _resolve(data: dict[str, Any], folder: Path) -> Any:
    return resolve_scenario(scenario_from_dict(data, str(folder / "s.yaml"), folder))


def test_panda_srdf_pairs_and_named_start(tmp_path: Path) -> None:
    assert ERD is not None
    srdf = ERD / "panda_description/srdf/panda.srdf"
    root = ET.parse(srdf).getroot()
    disabled = {
        frozenset((e.get("link1"), e.get("link2"))) for e in root.iter("disable_collisions")
    }
    state = {
        j.get("name"): float(str(j.get("value")))
        for g in root.iter("group_state")
        if g.get("name") == "default"
        for j in g.iter("joint")
    }
    res = _resolve(
        _scenario("panda", "panda_hand", "default", {"srdf": str(srdf)}, tmp_path), tmp_path
    )
    links = [k.split("/", 1)[1] for k in res.link_clouds]
    expected = {frozenset((a, b)) for i, a in enumerate(links) for b in links[i + 1 :]} - disabled
    got = res.self_pairs[0]
    assert got is not None and len(got) == len(expected) > 0
    assert {frozenset(p) for p in got} == expected
    q0 = res.scenario.spec.robots[0].q0
    assert q0 == pytest.approx([state[f"panda_joint{k}"] for k in range(1, 8)])


def test_our_pairs_round_trip_through_an_srdf(tmp_path: Path) -> None:
    q0 = [0.0, -1.57, 1.57, -1.57, -1.57, 0.0]
    auto = _scenario("ur5", "tool0", q0, "auto", tmp_path)
    auto["watch"][0]["self"]["samples"] = 300
    res = _resolve(auto, tmp_path)
    clouds = {k.split("/", 1)[1]: c for k, (c, _) in res.link_clouds.items()}
    ours = auto_self_pairs(res.robots["arm"], clouds, 0.02, home=np.array(q0), samples=300)
    assert res.self_pairs[0] == ours.watched
    write_srdf(ours, tmp_path / "ur5.srdf")
    back = _resolve(_scenario("ur5", "tool0", q0, {"srdf": "ur5.srdf"}, tmp_path), tmp_path)
    got = back.self_pairs[0]
    assert got is not None and {frozenset(p) for p in got} == {frozenset(p) for p in ours.watched}
    assert len(ours.excluded) > 0 and len(ours.watched) > 0


def test_an_unknown_pose_or_link_lists_the_valid_names(tmp_path: Path) -> None:
    assert ERD is not None
    srdf = str(ERD / "panda_description/srdf/panda.srdf")
    with pytest.raises(UnknownName) as info:
        _resolve(_scenario("panda", "panda_hand", "defualt", {"srdf": srdf}, tmp_path), tmp_path)
    assert info.value.suggestion == "default" and "robots.arm.q0" in str(info.value)
    bad = tmp_path / "bad.srdf"
    bad.write_text(
        '<robot name="panda"><disable_collisions link1="panda_link1" link2="panda_lnk2" '
        'reason="Adjacent"/></robot>'
    )
    with pytest.raises(UnknownName) as info:
        _resolve(
            _scenario("panda", "panda_hand", [0.0] * 7, {"srdf": "bad.srdf"}, tmp_path), tmp_path
        )
    assert info.value.suggestion == "panda_link2" and "watch[0].pairs.srdf" in str(info.value)


def test_a_named_start_needs_an_srdf_and_every_joint(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="names a pose"):
        _resolve(_scenario("panda", "panda_hand", "default", "auto", tmp_path), tmp_path)
    part = tmp_path / "part.srdf"
    part.write_text(
        '<robot name="panda"><group_state name="up" group="arm">'
        '<joint name="panda_joint1" value="0"/></group_state></robot>'
    )
    with pytest.raises(InputError, match="no value for joint"):
        _resolve(_scenario("panda", "panda_hand", "up", {"srdf": "part.srdf"}, tmp_path), tmp_path)
