"""``reachwise synth`` as a user runs it: outputs, JSON, Ctrl-C keeping finished runs."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from reachwise import load_robot, load_task
from reachwise.cli import app

runner = CliRunner()


def small_task(tmp_path: Path) -> Path:
    task = load_task("tunnel-87").subset(np.arange(0, 87, 9), name="tunnel-10")
    from reachwise.io.task_file import save_task

    path = tmp_path / "t.yaml"
    save_task(task, path)
    return path


def test_synth_writes_every_output(tmp_path: Path) -> None:
    out = tmp_path / "out"
    res = runner.invoke(
        app,
        ["synth", "--task", str(small_task(tmp_path)), "--robot", "sb60", "--runs", "2",
         "--out", str(out), "--json", "--no-figures"],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    data = json.loads(res.output)
    assert data["runs"] == 2 and data["task_points"] == 10
    for f in ("design.yaml", "design.urdf", "summary.json", "points.csv"):
        assert (out / f).is_file()
    robot = load_robot(str(out / "design.yaml"))
    rows = list(csv.DictReader(open(out / "points.csv")))
    assert len(rows) == 10
    # the written design and joints really reach the written points
    Q = np.array([[float(r[f"q{i}"]) for i in range(robot.n)] for r in rows])
    P = np.array([[float(r["x"]), float(r["y"]), float(r["z"])] for r in rows])
    err = np.linalg.norm(robot.fk(Q)[:, :3, 3] - P, axis=1)
    for r, e in zip(rows, err, strict=True):
        assert float(r["position_error_m"]) == pytest.approx(e, abs=1e-9)
    assert data["best"]["reached"] == sum(r["status"] == "full" for r in rows)
    # the HTML report (no figures asked): the best run's reached count in its runs table
    report = out / "report.html"
    assert data["report"] == str(report)
    text = report.read_text()
    assert "<img" not in text and 'id="table3"' in text
    assert f"<td>{data['best']['reached']}/10</td>" in text


def test_ctrl_c_keeps_finished_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import reachwise.synthesis.synthesize as synth_mod

    real = synth_mod.run_once
    calls = {"n": 0}

    def interrupt_second(*args, **kwargs):  # type: ignore[no-untyped-def]
        calls["n"] += 1
        if calls["n"] == 2:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(synth_mod, "run_once", interrupt_second)
    out = tmp_path / "out"
    res = runner.invoke(
        app,
        ["synth", "--task", str(small_task(tmp_path)), "--robot", "sb60", "--runs", "5",
         "--out", str(out), "--json", "--no-figures"],
    )  # fmt: skip
    assert res.exit_code == 130
    data = json.loads(res.output)
    assert data["interrupted"] and data["runs"] == 1
    assert (out / "design.yaml").is_file()


def test_bad_inputs_are_one_line_errors(tmp_path: Path) -> None:
    res = runner.invoke(app, ["synth", "--task", "tunnel-87", "--robot", "panda",
                              "--out", str(tmp_path)])  # fmt: skip
    assert res.exit_code != 0
    assert "no free design parameter" in str(res.exception) + res.output
