"""One pydantic-error translation and one built-in-name-or-path resolver, shared by the
robot, task, scenario and server-state loaders."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import pytest
from pydantic import BaseModel, ConfigDict, ValidationError, field_validator

from reachwise.errors import InputError, RobotFileError, UnknownName
from reachwise.io._builtin import Builtin, builtin_names, load_named
from reachwise.io.validation import field_path, input_error


class _Joint(BaseModel):
    model_config = ConfigDict(extra="forbid")
    type: Literal["revolute", "prismatic"]
    limits: tuple[float, float] | None = None

    @field_validator("limits")
    @classmethod
    def _ordered(cls, v: tuple[float, float] | None) -> tuple[float, float] | None:
        if v is not None and v[0] > v[1]:
            raise ValueError("lower limit above upper limit")
        return v


class _Robot(BaseModel):
    model_config = ConfigDict(extra="forbid")
    name: str
    joints: list[_Joint]


def _error(data: object, **kw: object) -> InputError:
    with pytest.raises(ValidationError) as info:
        _Robot.model_validate(data)
    return input_error(info.value, "arm.yaml", **kw)  # type: ignore[arg-type]


def test_field_path_is_written_as_in_the_file() -> None:
    assert field_path(("joints", 2, "limits")) == "joints[2].limits"
    assert field_path((0, "xyz")) == "[0].xyz"
    assert field_path(()) == ""


def test_the_error_names_file_field_and_reason() -> None:
    joints = [{"type": "revolute"}, {"type": "revolute"}, {"type": "revolute", "limits": [2, 1]}]
    err = _error({"name": "a", "joints": joints})
    assert type(err) is InputError
    assert (err.source, err.field, err.reason) == (
        "arm.yaml",
        "joints[2].limits",
        "lower limit above upper limit",  # "Value error, " of pydantic dropped
    )
    assert str(err) == "arm.yaml: joints[2].limits: lower limit above upper limit"


def test_an_unknown_key_is_reported_first_then_every_other_problem() -> None:
    err = _error({"joints": [{"type": "screw", "limts": [0, 1]}]}, error=RobotFileError)
    assert isinstance(err, RobotFileError)
    assert err.field == "joints[0].limts"
    assert err.reason.startswith("Extra inputs are not permitted; 2 more problems: ")
    assert "more)" not in err.reason
    # both other problems are named with their fields, none hidden behind a count
    assert "joints[0].type: Input should be 'revolute' or 'prismatic'" in err.reason
    assert "name: Field required" in err.reason


def test_an_unknown_key_names_the_closest_valid_key() -> None:
    err = _error({"name": "a", "joints": [{"type": "revolute", "limts": [0, 1]}]}, model=_Robot)
    assert err.field == "joints[0].limts"
    assert err.reason == "Extra inputs are not permitted (did you mean 'limits'?)"
    err = _error({"nam": "a", "joints": []}, model=_Robot)
    assert err.field == "nam"
    assert err.reason == (
        "Extra inputs are not permitted (did you mean 'name'?); "
        "1 more problem: name: Field required"
    )
    # nothing close: no guess
    err = _error({"name": "a", "joints": [], "zzzzzz": 1}, model=_Robot)
    assert err.reason == "Extra inputs are not permitted"


def test_valid_keys_follow_lists_unions_and_mappings() -> None:
    from reachwise.io.validation import closest_key, valid_keys

    class _Box(BaseModel):
        size: float

    class _Mesh(BaseModel):
        mesh: str
        scale: float = 1.0

    class _Scene(BaseModel):
        objects: dict[str, _Box | _Mesh]
        robots: list[_Robot] | None = None

    assert valid_keys(_Scene, ()) == ["objects", "robots"]
    assert valid_keys(_Scene, ("objects", "table")) == ["size", "mesh", "scale"]
    assert valid_keys(_Scene, ("objects", "table", "_Mesh")) == ["mesh", "scale"]
    assert valid_keys(_Scene, ("robots", 0, "joints", 3)) == ["type", "limits"]
    assert valid_keys(_Scene, ("robots", 0, "name")) == []
    assert closest_key("scael", ["mesh", "scale"]) == "scale"
    assert closest_key("colour", ["mesh", "scale"]) is None


def test_a_short_tuple_names_the_tuple_and_its_length() -> None:
    err = _error({"name": "a", "joints": [{"type": "revolute", "limits": [0]}]})
    assert (err.field, err.reason) == ("joints[0].limits", "too few values")
    err = _error(
        {"name": "a", "joints": [{"type": "revolute", "limits": [0]}]}, lengths={"limits": 2}
    )
    assert err.reason == "expected 2 values"


def test_builtins_files_and_unknown_names(tmp_path: Path) -> None:
    def load(x: str | Path) -> tuple[str, str]:
        return load_named(
            "robots",
            x,
            from_builtin=lambda b: ("builtin", b.label),
            from_file=lambda p: ("file", str(p)),
            suffixes=(".yaml",),
        )

    assert "sb60" in builtin_names("robots")
    assert load("sb60") == ("builtin", "built-in robot sb60")
    assert Builtin("robots", "sb60").text().lstrip().startswith(("#", "name"))
    assert (Builtin("scenarios", "trap").folder / "trap.yaml").is_file()
    # a path that looks like a file goes to the file loader, which reports it missing
    assert load(tmp_path / "none.yaml")[0] == "file"
    assert load("sub/none")[0] == "file"
    plain = tmp_path / "plainfile"
    plain.write_text("x")
    assert load(plain) == ("file", str(plain))
    with pytest.raises(UnknownName) as info:
        load("sb61")
    err = info.value
    assert isinstance(err, InputError) and isinstance(err, KeyError)
    assert err.name == "sb61" and err.valid == tuple(builtin_names("robots"))
    assert "unknown built-in robot 'sb61'; valid: hiab-xs033, p2-man1" in str(err)
    assert str(err).endswith("; did you mean 'sb60'?") and err.suggestion == "sb60"
    with pytest.raises(UnknownName) as info:
        load("zzzz")
    assert info.value.suggestion is None and "did you mean" not in str(info.value)
