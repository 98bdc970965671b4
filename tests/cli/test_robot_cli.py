"""The robot and demo commands as a user runs them."""

from __future__ import annotations

import json
from pathlib import Path

from typer.testing import CliRunner

from reachwise import __version__, load_robot, save_robot
from reachwise.cli import app

runner = CliRunner()


def test_version() -> None:
    res = runner.invoke(app, ["--version"])
    assert res.exit_code == 0 and __version__ in res.output


def test_robot_show_json_reports_reach_and_conditioning() -> None:
    res = runner.invoke(app, ["robot", "show", "puma560", "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.output)
    assert data["dof"] == 6 and data["name"] == "puma560"
    # Craig's PUMA reaches at most a2 + sqrt(a3² + d4²) + |d3| offset ≈ 0.86 m
    assert 0.7 < data["sampled"]["reach_max_m"] < 0.9
    assert 0.0 <= data["sampled"]["lci_min"] <= data["sampled"]["lci_mean"] <= 1.0


def test_robot_check_good_and_bad(tmp_path: Path) -> None:
    good = tmp_path / "panda.yaml"
    save_robot(load_robot("panda"), good)
    res = runner.invoke(app, ["robot", "check", str(good)])
    assert res.exit_code == 0 and "ok" in res.output
    bad = tmp_path / "bad.yaml"
    bad.write_text(good.read_text().replace("type: revolute", "type: screw", 1))
    res = runner.invoke(app, ["robot", "check", str(bad), "--json"])
    assert res.exit_code == 2
    err = json.loads(res.output)
    assert not err["ok"] and "bad.yaml" in err["error"] and "joints[0].type" in err["error"]
