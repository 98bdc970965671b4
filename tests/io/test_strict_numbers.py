"""A YAML boolean is not a number in any file: robot, task and scenario fields that mean
a number refuse ``true``/``false`` (pydantic would take them as 1/0) with an error that
names the file and the field; boolean fields still take booleans."""

from __future__ import annotations

import copy
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml

from reachwise.errors import InputError, RobotFileError, TaskError
from reachwise.io._builtin import builtin_text
from reachwise.io.robot_file import load_robot
from reachwise.io.task_file import load_task
from reachwise.sim.scenarios import load_scenario

ROBOT = {
    "name": "two",
    "joints": [
        {"type": "revolute", "a": 0.5, "theta": 0.0, "limits": [-1.0, 1.0]},
        {"type": "revolute", "a": 0.4, "limits": [-1.0, 1.0]},
    ],
    "base": {"xyz": [0.0, 0.0, 0.0]},
}
TASK = {"name": "t", "points": [{"xyz": [1.0, 0.0, 0.0], "dims": 3}]}


def _set(data: dict[str, Any], path: tuple[Any, ...], value: Any) -> dict[str, Any]:
    out = copy.deepcopy(data)
    at: Any = out
    for key in path[:-1]:
        at = at[key]
    at[path[-1]] = value
    return out


def _write(tmp_path: Path, data: dict[str, Any], name: str) -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data))
    return path


def _scenario(name: str) -> dict[str, Any]:
    return yaml.safe_load(builtin_text("scenarios", name))


CASES: list[tuple[str, Callable[[], dict[str, Any]], tuple[Any, ...], str]] = [
    ("robot", lambda: ROBOT, ("joints", 0, "a"), "joints[0].a"),
    ("robot", lambda: ROBOT, ("joints", 0, "theta"), "joints[0].theta"),
    ("robot", lambda: ROBOT, ("base", "xyz", 0), "base.xyz"),
    ("robot", lambda: ROBOT, ("joints", 1, "limits", 1), "joints[1].limits"),
    ("task", lambda: TASK, ("points", 0, "xyz", 0), "points[0].xyz"),
    ("task", lambda: TASK, ("points", 0, "dims"), "points[0].dims"),
    ("scenario", lambda: _scenario("p3-self-collision"), ("robots", 0, "q0", 7), "q0"),
    ("scenario", lambda: _scenario("p3-self-collision"), ("robots", 0, "controller", "kv"), "kv"),
    ("scenario", lambda: _scenario("p3-self-collision"), ("dt",), "dt"),
    ("scenario", lambda: _scenario("panda-person-camera"), ("sensors", 0, "width"), "width"),
    ("scenario", lambda: _scenario("panda-person-camera"), ("sensors", 0, "rate"), "rate"),
]
LOADERS: dict[str, tuple[Callable[[str], Any], type[InputError]]] = {
    "robot": (load_robot, RobotFileError),
    "task": (load_task, TaskError),
    "scenario": (load_scenario, InputError),
}


@pytest.mark.parametrize(("kind", "base", "path", "field"), CASES)
@pytest.mark.parametrize("flag", [True, False])
def test_a_boolean_where_a_number_is_meant_is_an_error(
    tmp_path: Path, kind: str, base: Callable[[], dict[str, Any]], path: tuple[Any, ...],
    field: str, flag: bool,
) -> None:  # fmt: skip
    load, error = LOADERS[kind]
    good = _write(tmp_path, base(), f"good-{kind}.yaml")
    load(str(good))  # the unmodified file is valid
    bad = _write(tmp_path, _set(base(), path, flag), f"bad-{kind}.yaml")
    with pytest.raises(error) as info:
        load(str(bad))
    assert str(bad) in str(info.value)
    assert field in info.value.field and "boolean is not a number" in str(info.value)


def test_boolean_fields_still_take_booleans(tmp_path: Path) -> None:
    data = _scenario("p3-self-collision")
    assert data["robots"][0]["goals"][0]["mirror_y"] is True
    load_scenario(str(_write(tmp_path, data, "s.yaml")))
