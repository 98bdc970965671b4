"""Robot YAML files: round trips and clear errors for every kind of mistake."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from reachwise import load_robot, save_robot
from reachwise.errors import RobotFileError, UnknownName
from reachwise.io.robot_file import builtin_robots, load_robot_file, robot_to_dict

GOOD = {
    "name": "demo-arm",
    "convention": "modified",
    "joints": [
        {"type": "revolute", "a": 0.0, "alpha": 0.0, "d": 0.4, "limits": [-2.8, 2.8], "vmax": 1.0},
        {"type": "prismatic", "a": 0.5, "alpha": 1.5708, "d": 0.2, "limits": [0.0, 3.0]},
        {"type": "revolute", "a": 0.1, "alpha_deg": -90, "limits_deg": [-170, 170]},
        {"type": "passive", "a": 0.0, "alpha": 0.0, "d": 0.1},
        {"type": "fixed", "a": 0.0, "alpha": -1.5708, "d": 0.3},
    ],
    "base": {"xyz": [1, 2, 0.5], "rpy_deg": [0, 0, 30]},
    "tool": {"xyz": [0, 0, 0.2], "rpy": [0.1, 0.2, 0.3]},
    "geometry": {"link_2": {"box": [1.0, 0.2, 0.2], "points": 500, "xyz": [0.5, 0, 0]}},
    "design": {"joints": {1: {"a": [-2, 2]}, 2: {"d": [-2, 2]}}, "base": {"x": [-5, 5]}},
}


def write(tmp_path: Path, data: object, name: str = "arm.yaml") -> Path:
    p = tmp_path / name
    p.write_text(yaml.safe_dump(data, sort_keys=False))
    return p


def test_load_and_round_trip(tmp_path: Path, rng: np.random.Generator) -> None:
    robot = load_robot_file(write(tmp_path, GOOD))
    assert robot.n == 4 and list(robot.actuated) == [True, True, True, False]
    assert robot.joints[2].alpha == pytest.approx(-np.pi / 2)
    assert robot.design.size == 3
    out = tmp_path / "again.yaml"
    save_robot(robot, out)
    again = load_robot(str(out))
    Q = rng.uniform(robot.lower, robot.upper, (20, robot.n))
    np.testing.assert_allclose(again.fk_all(Q), robot.fk_all(Q), atol=1e-12)
    a, b = robot_to_dict(again), robot_to_dict(robot)
    assert a["joints"] == b["joints"]  # DH rows, limits, vmax: exact
    np.testing.assert_allclose(again.base, robot.base, atol=1e-15)
    np.testing.assert_allclose(again.tool, robot.tool, atol=1e-15)
    assert again.geometry.keys() == robot.geometry.keys()
    (g,), (h,) = again.geometry["link_2"], robot.geometry["link_2"]
    assert (g.shape, g.size, g.points) == (h.shape, h.size, h.points)
    np.testing.assert_allclose(g.origin_matrix, h.origin_matrix, atol=1e-15)
    assert again.design == robot.design


@pytest.mark.parametrize("name", builtin_robots())
def test_every_builtin_round_trips(name: str, tmp_path: Path, rng: np.random.Generator) -> None:
    robot = load_robot(name)
    save_robot(robot, tmp_path / "r.yaml")
    again = load_robot(str(tmp_path / "r.yaml"))
    Q = rng.uniform(robot.lower, robot.upper, (10, robot.n))
    np.testing.assert_allclose(again.fk(Q), robot.fk(Q), atol=1e-12)


def mutate(joint: int, **change: object) -> dict:
    data = yaml.safe_load(yaml.safe_dump(GOOD))
    data["joints"][joint].update(change)
    return data


BAD = [
    (mutate(1, colour="red"), r"joints\[1\]\.colour", "Extra inputs"),
    (mutate(0, a="long"), r"joints\[0\]\.a", "number"),
    (mutate(2, limits=[1.0, -1.0], limits_deg=None), r"joints\[2\]", "lower 1.0 > upper -1.0"),
    (mutate(1, limits=[0.0, float("nan")]), r"joints\[1\]", "limits: NaN"),
    (mutate(0, d=float("nan")), r"joints\[0\]\.d", "finite"),
    (mutate(0, type="spherical"), r"joints\[0\]\.type", "revolute"),
    (mutate(1, limits=None), r"joints\[1\]", "prismatic joint needs limits"),
    (mutate(0, vmax=-1.0), r"joints\[0\]\.vmax", "greater than 0"),
    ({k: v for k, v in GOOD.items() if k != "name"}, r"name", "Field required"),
    ({**GOOD, "joints": []}, r"joints", "at least 1"),
    ({**GOOD, "geometry": {"link_9": {"box": [1, 1, 1]}}}, r"geometry\.link_9", "no such link"),
    ({**GOOD, "design": {"joints": {7: {"a": [0, 1]}}}}, r"design\.joints\.7", "no such joint"),
    ({**GOOD, "design": {"joints": {1: {"a": [2, 1]}}}}, r"joints\.1\.a", "lower bound"),
]


@pytest.mark.parametrize(("data", "field", "reason"), BAD)
def test_bad_files_name_file_field_and_reason(
    tmp_path: Path, data: dict, field: str, reason: str
) -> None:
    path = write(tmp_path, data, "broken.yaml")
    with pytest.raises(RobotFileError, match=field) as info:
        load_robot(str(path))
    msg = str(info.value)
    assert "broken.yaml" in msg
    assert reason in msg


def test_unbounded_joint_round_trips(tmp_path: Path) -> None:
    from reachwise.kinematics.robot import Joint, Robot

    robot = Robot("free", (Joint("revolute", limits=(-np.inf, np.inf)), Joint("prismatic", a=1)))
    assert robot.joints[1].limits == (-np.inf, np.inf)  # prismatic default: unbounded
    save_robot(robot, tmp_path / "free.yaml")
    again = load_robot(str(tmp_path / "free.yaml"))
    assert again.joints[0].limits == (-np.inf, np.inf)
    assert again.joints[1].limits == (-np.inf, np.inf)


def test_not_yaml_and_missing_file(tmp_path: Path) -> None:
    p = tmp_path / "x.yaml"
    p.write_text("joints: [unclosed")
    with pytest.raises(RobotFileError, match="not valid YAML"):
        load_robot(str(p))
    with pytest.raises(RobotFileError, match="no such file"):
        load_robot(str(tmp_path / "missing.yaml"))
    with pytest.raises(UnknownName, match=r"unknown built-in robot 'no-such-robot'; valid: .*sb60"):
        load_robot("no-such-robot")


def test_design_objectives_in_the_robot_file() -> None:
    """``design:`` holds min_length, margin and the objective weights; they round-trip,
    and an unknown objective or a bad value names the field."""
    from dataclasses import replace

    from reachwise.io.robot_file import robot_from_dict

    robot = load_robot("sb60")
    design = replace(robot.design, min_length=0.1, margin=0.1, objective={"gci": 1.0, "size": 0.2})
    data = robot_to_dict(replace(robot, design=design))
    assert data["design"]["objective"] == {"gci": 1.0, "size": 0.2}
    back = robot_from_dict(data, "boom.yaml")
    assert back.design.min_length == 0.1 and back.design.margin == 0.1
    assert dict(back.design.objective) == {"gci": 1.0, "size": 0.2}
    for field, value, words in (
        ("objective", {"speed": 1.0}, "unknown objective 'speed'"),
        ("objective", {"gci": -1.0}, ">= 0"),
        ("min_length", -0.1, "design.min_length"),
        ("margin", 0.7, "design.margin"),
    ):
        bad = robot_to_dict(robot)
        bad["design"][field] = value
        with pytest.raises(RobotFileError, match=r"boom\.yaml") as err:
            robot_from_dict(bad, "boom.yaml")
        assert words in str(err.value), str(err.value)
