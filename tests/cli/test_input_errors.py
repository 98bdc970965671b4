"""Bad scenario, robot and task files on the command line: one line that names every
problem and, for a misspelt key, the key meant."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
import yaml

from reachwise import cli
from reachwise.io._builtin import builtin_text


def _run(
    argv: list[str], monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> str:
    """``reachwise ARGV`` as the console script runs it: its stderr, after checking it
    exits with code 2 (bad input) and says why in one line."""
    monkeypatch.setattr(sys, "argv", ["reachwise", *argv])
    with pytest.raises(SystemExit) as info:
        cli.main()
    assert info.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err and "\n" not in err
    return err


def _builtin(kind: str, name: str) -> dict:
    data = yaml.safe_load(builtin_text(kind, name))  # type: ignore[arg-type]
    assert isinstance(data, dict)
    return data


def _write(tmp_path: Path, name: str, data: dict) -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data))
    return path


def test_a_misspelt_scenario_key_is_named_with_every_problem(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    data = _builtin("scenarios", "p3-self-collision")
    data["watch"][0]["margn"] = data["watch"][0].pop("margin")
    path = _write(tmp_path, "typo.yaml", data)
    out = _run(["simulate", str(path)], monkeypatch, capsys)
    assert "watch[0].margn: Extra inputs are not permitted (did you mean 'margin'?)" in out
    assert "watch[0].margin: Field required" in out
    assert "more)" not in out


def test_a_misspelt_robot_key_is_named(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    data = _builtin("robots", "puma560")
    data["joints"][1]["limts_deg"] = data["joints"][1].pop("limits_deg")
    path = _write(tmp_path, "arm.yaml", data)
    out = _run(["robot", "check", str(path)], monkeypatch, capsys)
    assert "joints[1].limts_deg: Extra inputs are not permitted (did you mean 'limits_deg'?)" in out


def test_a_misspelt_task_key_is_named(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _write(tmp_path, "t.yaml", {"pionts": [{"xyz": [0, 0, 0]}]})
    out = _run(["task", "show", str(path)], monkeypatch, capsys)
    assert "pionts: Extra inputs are not permitted (did you mean 'points'?)" in out
    assert "points: Field required" in out
