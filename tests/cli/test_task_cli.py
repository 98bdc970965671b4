"""``reachwise task generate|show`` as a user runs them (the typer app of cli/task.py)."""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

import numpy as np
from typer.testing import CliRunner

from reachwise.cli.task import app
from reachwise.errors import TaskError
from reachwise.io.task_file import load_task

runner = CliRunner()


def test_generate_one_tunnel_plan(tmp_path: Path) -> None:
    out = tmp_path / "plan.yaml"
    args = ["generate", "tunnel", "--width", "7", "--height", "6.5", "--arch", "2",
            "--face-x", "6.5", "--lookout-deg", "4", "--out", str(out), "--json"]  # fmt: skip
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    data = json.loads(res.output)
    assert data["written"] == str(out)
    assert set(data["groups"]) == {"cut", "stoping", "contour", "lifter"}
    assert data["dims"] == {"5": data["points"]}
    assert np.isclose(data["groups"]["contour"]["axis_angle_from_x_min_deg"], 4.0)
    t = load_task(out)
    assert len(t) == data["points"] and np.allclose(t.positions[:, 0], 6.5)
    assert t.envelope is not None and t.envelope.profile.width == 7.0


def test_generate_combined_plans_as_csv(tmp_path: Path) -> None:
    out = tmp_path / "plans.csv"
    args = ["generate", "tunnel", "--plans", "3", "--points", "25", "--dims", "6",
            "--seed", "3", "--out", str(out)]  # fmt: skip
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    assert "wrote" in res.output and "25 points" in res.output
    t = load_task(out)
    assert len(t) == 25 and (t.dims == 6).all()
    assert {n.split("/")[0] for n in t.names} == {"P01", "P02", "P03"}


def test_generate_tunnel_87_writes_the_builtin(tmp_path: Path) -> None:
    out = tmp_path / "t87.yaml"
    res = runner.invoke(app, ["generate", "tunnel-87", "--out", str(out)])
    assert res.exit_code == 0, res.output
    shipped = (resources.files("reachwise.data") / "tasks" / "tunnel-87.yaml").read_text()
    assert out.read_text() == shipped
    res = runner.invoke(app, ["generate", "tunnel-87", "--out", str(tmp_path / "t.json")])
    assert res.exit_code == 0 and len(load_task(tmp_path / "t.json")) == 87


def test_show_builtin_json_and_table(tmp_path: Path) -> None:
    res = runner.invoke(app, ["show", "tunnel-87", "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.output)
    assert data["points"] == 87 and data["dims"] == {"6": 87}
    assert sum(g["points"] for g in data["groups"].values()) == 87
    cut, contour = data["groups"]["cut"], data["groups"]["contour"]
    assert cut["axis_spread_deg"] > contour["axis_spread_deg"]
    lo, hi = data["bounding_box_m"]["min"], data["bounding_box_m"]["max"]
    assert 5.5 <= lo[0] <= hi[0] <= 8.5 and hi[2] > 6.5
    assert data["envelope"]["min_clearance_m"] > 0
    res = runner.invoke(app, ["show", "tunnel-87"])
    assert res.exit_code == 0 and "cut" in res.output and "87 points" in res.output


def test_show_a_file_without_groups(tmp_path: Path) -> None:
    p = tmp_path / "pts.csv"
    p.write_text("x,y,z\n1,2,3\n4,5,6\n")
    res = runner.invoke(app, ["show", str(p), "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.output)
    assert data["groups"] == {"": {"points": 2}} and "axes" not in data


def test_bad_input_raises_a_task_error(tmp_path: Path) -> None:
    res = runner.invoke(
        app, ["generate", "tunnel", "--arch", "9", "--out", str(tmp_path / "x.yaml")]
    )
    assert isinstance(res.exception, TaskError) and "arch_height" in str(res.exception)
    res = runner.invoke(app, ["generate", "tunnel", "--plans", "3", "--face-x", "6",
                              "--out", str(tmp_path / "x.yaml")])  # fmt: skip
    assert isinstance(res.exception, TaskError)
    res = runner.invoke(app, ["show", str(tmp_path / "nope.yaml")])
    assert isinstance(res.exception, TaskError) and "no such file" in str(res.exception)
