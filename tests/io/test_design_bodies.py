"""The ``design: bodies:`` section of robot files: load, errors, round trip."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from reachwise import load_robot, save_robot
from reachwise.errors import RobotFileError
from reachwise.io.robot_file import robot_from_dict, robot_to_dict

_CAP = {"along": ["a"], "radius": 0.1}
_SHORT = {"start": [0, 0, 0], "end": [0, 0, 1], "radius": 0.1, "contact": 2.0}


def _sb60_dict() -> dict:
    return robot_to_dict(load_robot("sb60"))


def test_bodies_round_trip_through_a_file(tmp_path: Path) -> None:
    robot = load_robot("sb60")
    assert {b.name for b in robot.design.bodies} >= {"boom", "feed"}
    data = robot_to_dict(robot)
    data["design"]["clearance"] = 0.12
    data["design"]["bodies"]["bracket"] = {
        "link": "link_0",
        "box": {"size": [0.5, 0.6, 0.7], "xyz": [-0.35, 0.0, 0.0], "rpy": [0.0, 0.0, 0.3]},
    }
    again = robot_from_dict(data, "x.yaml")
    path = tmp_path / "r.yaml"
    save_robot(again, path)
    back = load_robot(path)
    assert back.design.clearance == 0.12
    a = {b.name: b for b in again.design.bodies}
    b = {b.name: b for b in back.design.bodies}
    assert a.keys() == b.keys()
    for name in a:
        x, y = a[name], b[name]
        assert (x.link, x.shape, x.along, x.radius, x.contact) == (
            y.link, y.shape, y.along, y.radius, y.contact,
        )  # fmt: skip
        assert x.start == pytest.approx(y.start) and x.end == pytest.approx(y.end)
        assert x.size == pytest.approx(y.size)
        for r1, r2 in zip(x.origin, y.origin, strict=True):
            assert r1 == pytest.approx(r2, abs=1e-12)


def test_a_joint_name_places_the_body_on_the_link_it_ends_at() -> None:
    robot = load_robot("sb60")
    boom = next(b for b in robot.design.bodies if b.name == "boom")
    assert boom.link == "link_3"  # written as `link: boom_extension`, joint 3


@pytest.mark.parametrize(
    ("body", "field", "reason"),
    [
        ({"link": "link_9", "capsule": {"along": ["a"], "radius": 0.1}}, "bad", "no link"),
        ({"link": "link_2", "capsule": {"along": ["a"], "radius": -1}}, "bad", "greater than 0"),
        ({"link": "link_2", "capsule": {"radius": 0.1}}, "bad", "start and end"),
        ({"link": "link_2", "capsule": {"along": ["q"], "radius": 0.1}}, "bad", "'a' or 'd'"),
        ({"link": "tool", "capsule": {"along": ["d"], "radius": 0.1}}, "bad", "no DH row"),
        (
            {
                "link": "link_2",
                "box": {"size": [1, 1, 1]},
                "capsule": {"along": ["a"], "radius": 0.1},
            },
            "bad",
            "exactly one shape",
        ),
        (
            {
                "link": "link_8",
                "capsule": {"start": [0, 0, 0], "end": [0, 0, 1], "radius": 0.1, "contact": 2.0},
            },
            "bad",
            "whole",
        ),
    ],
)
def test_bad_bodies_name_the_file_field_and_reason(body: dict, field: str, reason: str) -> None:
    data = _sb60_dict()
    data["design"]["bodies"] = {field: body}
    with pytest.raises(RobotFileError, match=reason) as info:
        robot_from_dict(yaml.safe_load(yaml.safe_dump(data)), "robot.yaml")
    assert "robot.yaml" in str(info.value) and "bodies" in str(info.value)
