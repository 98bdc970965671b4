"""SRDF in and out: our excluded pairs round-trip through MoveIt's format, and reading
example-robot-data's SRDFs gives exactly the pairs they list (counted independently
with ElementTree)."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from reachwise.distance.self_pairs import PairRule, SelfPairs
from reachwise.errors import InputError
from reachwise.io.srdf import read_srdf, write_srdf
from tests._real_arms import ERD, needs_erd


def test_round_trip_of_our_pairs(tmp_path: Path) -> None:
    rules = (
        PairRule("a", "b", "adjacent", "joined by one joint"),
        PairRule("a", "c", "watched", "close", 0.1),
        PairRule("b", "d", "never", "never within 0.05 m"),
        PairRule("c", "d", "always", "always within 0.05 m"),
    )
    pairs = SelfPairs("arm", 0.05, 100, 0, np.zeros(3), rules)
    back = read_srdf(write_srdf(pairs, tmp_path / "arm.srdf"))
    assert back.robot == "arm"
    assert [(p.link1, p.link2, p.reason) for p in back.disabled] == [
        ("a", "b", "Adjacent"),
        ("b", "d", "Never"),
        ("c", "d", "Always"),
    ]
    assert frozenset(("a", "c")) not in back.disabled_pairs()  # watched: MoveIt checks it


@needs_erd
@pytest.mark.parametrize(
    "srdf",
    ["panda_description/srdf/panda.srdf", "ur_description/srdf/ur5.srdf",
     "baxter_description/srdf/baxter_manipulation.srdf"],
)  # fmt: skip
def test_example_robot_data_srdfs_give_the_pairs_they_list(srdf: str) -> None:
    assert ERD is not None
    path = ERD / srdf
    if not path.is_file():
        pytest.skip(f"{srdf} is not in this example-robot-data")
    listed = {
        frozenset((e.get("link1"), e.get("link2")))
        for e in ET.parse(path).getroot().iter("disable_collisions")
    }
    got = read_srdf(path)
    assert got.disabled_pairs() == listed and len(got.disabled) == len(listed) > 0


@pytest.mark.parametrize(
    ("body", "words"),
    [
        ('<disable_collisions link1="a" reason="Never"/>', "link1 and link2"),
        ('<disable_collisions link1="a" link2="a" reason="Never"/>', "itself"),
        ('<disable_collisions link1="a" link2="b" reason="Sometimes"/>', "unknown reason"),
        ('<group_state name="home" group="arm"><joint name="j1" value="x"/></group_state>',
         "not a number"),
    ],
)  # fmt: skip
def test_a_bad_srdf_is_an_input_error_naming_the_file(
    tmp_path: Path, body: str, words: str
) -> None:
    path = tmp_path / "r.srdf"
    path.write_text(f'<?xml version="1.0"?>\n<robot name="r">\n{body}\n</robot>\n')
    with pytest.raises(InputError, match=words) as info:
        read_srdf(path)
    assert str(path) in str(info.value) and "line 3" in str(info.value)


def test_group_states_are_named_poses(tmp_path: Path) -> None:
    path = tmp_path / "r.srdf"
    path.write_text(
        '<robot name="r"><group_state name="home" group="arm">'
        '<joint name="j1" value="0.5"/><joint name="j2" value="-1"/></group_state></robot>'
    )
    assert read_srdf(path).poses == {"home": {"j1": 0.5, "j2": -1.0}}


def test_robot_pairs_writes_an_srdf_of_its_excluded_pairs(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from reachwise.cli import app
    from reachwise.io.pairs_file import load_pairs

    out, srdf = tmp_path / "p.yaml", tmp_path / "p.srdf"
    args = ["robot", "pairs", "sb60", "--out", str(out), "--srdf", str(srdf),
            "--samples", "300", "--points", "100"]  # fmt: skip
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    pairs, _ = load_pairs(out)
    got = read_srdf(srdf)
    assert got.disabled_pairs() == {frozenset((p.a, p.b)) for p in pairs.excluded}
    assert not got.disabled_pairs() & {frozenset(w) for w in pairs.watched}
