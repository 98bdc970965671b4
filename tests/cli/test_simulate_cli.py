"""``reachwise simulate`` command (the lead registers it; tested through its function)."""

from __future__ import annotations

import json
from pathlib import Path

import typer
from typer.testing import CliRunner

from reachwise.cli.simulate import simulate


def test_simulate_cli_writes_logs_figures_summary(tmp_path: Path) -> None:
    app = typer.Typer()
    app.command()(simulate)
    res = CliRunner().invoke(
        app,
        ["p5-crane-obstacle", "--baseline", "--duration", "3", "--out", str(tmp_path), "--json"],
    )
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    assert data["baseline"]["first_collision"] is not None
    for f in ("summary.json", "joints.png", "tool_path.png", "min_distance.png",
              "avoidance/log.npz", "avoidance/log.csv", "baseline/log.npz"):  # fmt: skip
        assert (tmp_path / f).is_file(), f
    # the HTML report embeds the three figures and states the baseline's collision
    assert data["report"] == str(tmp_path / "report.html")
    text = (tmp_path / "report.html").read_text()
    assert text.count("data:image/png;base64,") == 3
    assert f"{data['baseline']['first_collision']:.2f} s (" in text
