"""Ctrl-C during ``reachwise demo``: a real SIGINT (once or twice) sent to the process
at a seeded step of a stage (not a timed moment) ends the demo with 130; the stages
finished before it stay complete and valid on disk, the interrupted one leaves no
marker, and the line says what was kept and how to resume."""

from __future__ import annotations

import json
import os
import signal
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from reachwise.cli import app
from reachwise.io.task_file import load_task
from reachwise.kinematics.robot import Robot
from tests.cli.sigint import restored_sigint


@pytest.mark.parametrize("signals", [1, 2])
def test_ctrl_c_in_a_stage_keeps_the_finished_stages(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, signals: int
) -> None:
    # the kinematics stage solves 5 IK targets on each of 4 robots: SIGINT at a seeded one
    at = int(np.random.default_rng(32 + signals).integers(1, 20))
    real = Robot.ik
    calls = [0]

    def ik(self: Robot, *args: Any, **kw: Any) -> Any:
        calls[0] += 1
        if calls[0] == at:
            for _ in range(signals):
                os.kill(os.getpid(), signal.SIGINT)  # recorded; the stage stops after it
        return real(self, *args, **kw)

    monkeypatch.setattr(Robot, "ik", ik)
    out = tmp_path / "demo"
    with restored_sigint():
        res = CliRunner().invoke(app, ["demo", "--quick", "--out", str(out), "--json"])
    assert res.exit_code == 130, res.output
    assert calls[0] == at  # honoured before the next IK call
    data = json.loads(res.stdout)
    assert data["interrupted"] == "kinematics"
    assert data["stages"] == {"task": "done"}
    text = " ".join(res.stderr.split()) + " ".join(res.stdout.split())
    assert "interrupted during kinematics: 1 finished stages kept" in text
    assert "run the same command to resume" in text
    # the finished stage is complete and valid: its task file loads, its marker names it
    marker = json.loads((out / "task.json").read_text())
    assert marker["files"] == ["tunnel-87.yaml"]
    assert len(load_task(out / "tunnel-87.yaml")) == 87
    assert not (out / "kinematics.json").exists()
    saved = json.loads((out / "demo.json").read_text())
    assert saved["interrupted"] == "kinematics"
