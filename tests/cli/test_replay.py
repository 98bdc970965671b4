"""``reachwise replay``: a recording of a UR5 cell in, the result files out; a bad
recording ends it with exit code 2 and one line naming the topic and time."""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path
from typing import Any

import pytest

import reachwise.cli as cli
from tests._real_arms import arm_path, needs_erd
from tests.io.ros import _cell

UR5 = [
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
]


def _main(argv: list[str], monkeypatch: pytest.MonkeyPatch, capsys: Any) -> tuple[int, str]:
    monkeypatch.setattr(sys, "argv", ["reachwise", *argv])
    try:
        cli.main()
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 1
    else:
        code = 0
    return code, capsys.readouterr().err


@needs_erd
def test_replay_writes_the_results(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: Any
) -> None:
    bag = _cell.write_cell(tmp_path / "cell.mcap", seconds=0.3, joints=UR5)
    out = tmp_path / "replay"
    argv = [
        "replay", str(bag), "--robot", str(arm_path("ur5")), "--tip", "tool0",
        "--joints", "/joint_states", "--clouds", "/points", "--clouds", "/depth/image",
        "--margin", "0.5", "--points", "100", "--block", "--out", str(out), "--json",
    ]  # fmt: skip
    code, err = _main(argv, monkeypatch, capsys)
    assert code == 0, err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["frames"] == 31
    assert summary["clouds_handed_over"] == {"/points": 3, "/depth/image": 3}
    rows = list(csv.DictReader((out / "distances.csv").open()))
    assert {r["pair"].split("|")[1] for r in rows} == {"/points", "/depth/image"}
    assert min(float(r["distance"]) for r in rows) == pytest.approx(summary["min_distance"])
    for name in ("near.csv", "report.html", "results.mcap"):
        assert (out / name).exists()


@needs_erd
def test_bad_recording_exits_2_naming_topic_and_time(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: Any
) -> None:
    bag = _cell.write_cell(tmp_path / "cell.mcap", seconds=0.2, joints=UR5[:5])
    argv = [
        "replay", str(bag), "--robot", str(arm_path("ur5")), "--tip", "tool0",
        "--clouds", "/points", "--points", "50", "--out", str(tmp_path / "o"),
    ]  # fmt: skip
    code, err = _main(argv, monkeypatch, capsys)
    assert code == 2
    assert "topic /joint_states" in err and "wrist_3_joint" in err and "t = 0.000000000 s" in err


def test_a_bad_memory_box_exits_2(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: Any
) -> None:
    argv = ["replay", str(tmp_path / "x.mcap"), "--robot", "panda", "--clouds", "/d",
            "--memory", "0.05", "--memory-box", "1,2,3"]  # fmt: skip
    code, err = _main(argv, monkeypatch, capsys)
    assert code == 2 and "six numbers" in err
