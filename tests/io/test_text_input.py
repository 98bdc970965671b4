"""Robot, task (YAML, JSON, CSV) and scenario files that are not text, nest too deeply,
hold an oversized CSV cell or a non-ASCII digit: typed errors naming the file (and the
line where there is one), never a UnicodeDecodeError, RecursionError or csv.Error."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from reachwise.errors import InputError, RobotFileError, TaskError
from reachwise.io.robot_file import load_robot
from reachwise.io.task_file import load_task
from reachwise.io.text_input import MAX_NESTING, nesting_depth, parse_text, read_text
from reachwise.sim.scenarios import load_scenario

LOADERS: list[tuple[str, Callable[[str], Any], type[InputError]]] = [
    ("robot.yaml", load_robot, RobotFileError),
    ("task.yaml", load_task, TaskError),
    ("task.json", load_task, TaskError),
    ("task.csv", load_task, TaskError),
    ("scenario.yaml", load_scenario, InputError),
]
CSV = "x,y,z,dims\n1.0,0.0,0.0,3\n"


@pytest.mark.parametrize(("name", "load", "error"), LOADERS)
def test_non_utf8_bytes_name_file_and_line(
    tmp_path: Path, name: str, load: Callable[[str], Any], error: type[InputError]
) -> None:
    path = tmp_path / name
    path.write_bytes(b"name: a\n# comment\nx: \xff\xfe\n")
    with pytest.raises(error) as info:
        load(str(path))
    assert info.value.source == str(path)
    assert info.value.field == "line 3" and "not UTF-8" in info.value.reason


@pytest.mark.parametrize(("name", "load", "error"), [c for c in LOADERS if "csv" not in c[0]])
@pytest.mark.parametrize("depth", [MAX_NESTING + 1, 1000, 100_000])
def test_deep_nesting_is_refused(
    tmp_path: Path, name: str, load: Callable[[str], Any], error: type[InputError], depth: int
) -> None:
    path = tmp_path / name
    path.write_text('{"points": ' + "[" * depth + "]" * depth + "}")
    with pytest.raises(error, match="nested deeper than") as info:
        load(str(path))
    assert info.value.source == str(path)


def test_nesting_depth_counts_levels() -> None:
    assert nesting_depth(1) == 0
    assert nesting_depth({"a": [1, {"b": []}]}) == 4
    assert nesting_depth([[[[]]]]) == 4
    deepest = "a: " + "[" * (MAX_NESTING - 1) + "]" * (MAX_NESTING - 1)
    assert nesting_depth(parse_text(deepest, "f", "yaml")) == MAX_NESTING
    with pytest.raises(InputError, match="nested deeper"):
        parse_text("a: [" + deepest[3:] + "]", "f", "yaml")


def test_oversized_csv_cell_names_the_line(tmp_path: Path) -> None:
    path = tmp_path / "t.csv"
    path.write_text(CSV + "2.0,0.0,0.0," + "3" * 200_000 + "\n")
    with pytest.raises(TaskError) as info:
        load_task(str(path))
    assert info.value.source == str(path) and info.value.field == "line 3"


def test_csv_non_ascii_digit_in_dims(tmp_path: Path) -> None:
    path = tmp_path / "t.csv"
    path.write_text(CSV + "2.0,0.0,0.0,\u00b2\n")  # '²' is a digit to str.isdigit, not to int
    with pytest.raises(TaskError) as info:
        load_task(str(path))
    assert info.value.source == str(path) and "points[1].dims" in info.value.field
    assert "CSV line 3" in info.value.reason


def test_malformed_yaml_and_json_name_the_line(tmp_path: Path) -> None:
    bad_yaml = tmp_path / "r.yaml"
    bad_yaml.write_text("name: a\njoints: [unclosed\n")
    with pytest.raises(RobotFileError, match="not valid YAML") as info:
        load_robot(str(bad_yaml))
    assert info.value.field.startswith("line ")
    bad_json = tmp_path / "t.json"
    bad_json.write_text('{"name": "t",\n "points": [}\n')
    with pytest.raises(TaskError, match="not valid JSON") as info2:
        load_task(str(bad_json))
    assert info2.value.field == "line 2"


def test_file_larger_than_the_bound(tmp_path: Path) -> None:
    path = tmp_path / "big.yaml"
    path.write_text("a: 1\n" * 100)
    assert read_text(path, "big") == "a: 1\n" * 100
    with pytest.raises(InputError, match="larger than 100 bytes"):
        read_text(path, "big", max_bytes=100)


def test_yaml_alias_bomb_is_refused(tmp_path: Path) -> None:
    """Nine levels of ten aliases each: a few hundred bytes that expand to 10⁹ values."""
    text = "a: &a [1, 1, 1, 1, 1, 1, 1, 1, 1, 1]\n" + "".join(
        f"{chr(98 + i)}: &{chr(98 + i)} [{', '.join([f'*{chr(97 + i)}'] * 10)}]\n" for i in range(8)
    )
    path = tmp_path / "bomb.yaml"
    path.write_text(text)
    with pytest.raises(RobotFileError, match="aliases expanded") as info:
        load_robot(str(path))
    assert info.value.source == str(path)
