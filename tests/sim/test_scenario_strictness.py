"""Nothing in a scenario is ignored without a word, and every problem names the file:
entries naming a link that does not exist or that is given no cloud, bounds on counts
(points, pixels, scanner beams), seeds, the controller's own checks."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml

from reachwise.errors import InputError, RobotFileError
from reachwise.io._builtin import builtin_text
from reachwise.io.robot_file import load_robot
from reachwise.sim.world import build_world

Edit = Callable[[dict[str, Any]], None]


def _robot0(**kw: Any) -> Edit:
    return lambda d: d["robots"][0].update(kw)


def _controller(**kw: Any) -> Edit:
    return lambda d: d["robots"][0]["controller"].update(kw)


CASES: list[tuple[str, str, Edit, str, str]] = [
    ("p3-self-collision", "unknown link_clouds link",
     _robot0(link_clouds={"link_99": {"mesh": "x.obj"}}),
     "robots.boom.link_clouds.link_99", "no link 'link_99'"),
    ("p3-self-collision", "link_clouds outside links (its missing mesh never read)",
     _robot0(link_clouds={"link_4": {"mesh": "missing.obj"}}),
     "robots.boom.link_clouds.link_4", "not among the links given clouds"),
    ("p3-self-collision", "self watch on an unknown link",
     lambda d: d["watch"][0].update(links=["link_99"]),
     "watch[0].links", "no cloud on 'link_99'"),
    ("p3-self-collision", "stop_ticks 0", _controller(stop_ticks=0),
     "robots[0].controller.stop_ticks", "greater than or equal to 1"),
    ("p3-self-collision", "kv negative", _controller(kv=-1.0),
     "robots.boom.controller.kv", "must be > 0"),
    ("p3-self-collision", "negative robot seed", _robot0(seed=-1),
     "robots[0].seed", "greater than or equal to 0"),
    ("p3-self-collision", "a billion points per link", _robot0(points=1_000_000_000),
     "robots[0].points", "at most 5000000 (size_limits.max_points)"),
    ("panda-person-camera", "camera a million pixels wide",
     lambda d: d["sensors"][0].update(width=1_000_000),
     "sensors[0].width", "at most 8192 (size_limits.max_image_side)"),
    ("panda-person-camera", "negative camera seed",
     lambda d: d["sensors"][0].update(seed=-5),
     "sensors[0].seed", "greater than or equal to 0"),
]  # fmt: skip


@pytest.mark.parametrize(
    ("scenario", "case", "edit", "field", "reason"), CASES, ids=[c[1] for c in CASES]
)
def test_scenario_problem_is_an_error_naming_file_and_field(
    tmp_path: Path, scenario: str, case: str, edit: Edit, field: str, reason: str
) -> None:
    data = yaml.safe_load(builtin_text("scenarios", scenario))
    edit(data)
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(InputError) as info:
        build_world(str(path))
    assert info.value.source == str(path)
    assert info.value.field == field and reason in info.value.reason


def test_unmodified_scenario_builds(tmp_path: Path) -> None:
    path = tmp_path / "s.yaml"
    path.write_text(builtin_text("scenarios", "p3-self-collision"))
    assert "boom/link_8" in build_world(str(path)).scene.objects


def test_robot_file_with_an_empty_name(tmp_path: Path) -> None:
    path = tmp_path / "r.yaml"
    path.write_text("name: ''\njoints: [{type: revolute, a: 0.5, limits: [-1, 1]}]\n")
    with pytest.raises(RobotFileError) as info:
        load_robot(str(path))
    assert info.value.source == str(path) and info.value.field == "name"


def test_robot_file_link_points_are_bounded(tmp_path: Path) -> None:
    path = tmp_path / "r.yaml"
    path.write_text(
        "name: r\njoints: [{type: revolute, a: 0.5, limits: [-1, 1]}]\n"
        "geometry: {link_0: {box: [0.1, 0.1, 0.1], points: 1000000000}}\n"
    )
    with pytest.raises(RobotFileError) as info:
        load_robot(str(path))
    assert info.value.source == str(path) and "points" in info.value.field
