"""``reachwise synth --pareto`` as a user runs it: the front's files and report, one
progress line per solve of the sweep, and Ctrl-C during the sweep keeping its designs."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from reachwise import load_robot
from reachwise.cli import app
from reachwise.cli.interrupts import Interrupts
from tests.cli.sigint import restored_sigint

from .test_synth_cli import small_task

runner = CliRunner()
#: A progress line of the sweep: solves done/budget, stage, front so far, last values.
LINE = re.compile(
    r"^pareto (\d+)/(\d+) (end|level|polish|gap|settle): (\d+) on the front; "
    r"last gci (\S+), size (\S+) \(\d+:\d\d\)$",
    re.M,
)


def _args(task: Path, out: Path, *extra: str) -> list[str]:
    return ["synth", "--task", str(task), "--robot", "sb60", "--runs", "1", "--pareto",
            "gci,size", "--points", "3", "--out", str(out), "--no-figures", *extra]  # fmt: skip


def test_pareto_writes_the_front_and_links_every_design(tmp_path: Path) -> None:
    """The front's files and report, and on stderr one progress line per design of the
    sweep, in order, whose values are the written designs' (4 significant digits)."""
    out = tmp_path / "front"
    res = runner.invoke(app, _args(small_task(tmp_path), out))
    assert res.exit_code == 0, res.output
    front = json.loads((out / "pareto" / "front.json").read_text())
    assert front["objectives"] == ["gci", "size"] and len(front["points"]) >= 3
    assert front["front_size"] == sum(p["front"] for p in front["points"]) >= 1
    assert front["partial"] is False
    html = (out / "report.html").read_text()
    assert 'id="pareto-table"' in html and "Partial front" not in html
    for p in front["points"]:
        assert p["all_reached"]
        for key in ("design_yaml", "design_urdf"):
            assert (out / p[key]).is_file() and f'href="{p[key]}"' in html
        load_robot(str(out / p["design_yaml"]))
    assert (out / "pareto" / "front.csv").is_file()
    lines = LINE.findall(res.stderr)
    assert len(lines) == len(front["points"])
    for k, (line, p) in enumerate(zip(lines, front["points"], strict=True)):
        solves, budget, _, on_front, gci, size = line
        assert int(solves) == k + 1 and int(solves) <= int(budget)
        assert 1 <= int(on_front) <= k + 1
        assert float(gci) == pytest.approx(p["values"]["gci"], rel=1e-3)
        assert float(size) == pytest.approx(p["values"]["size"], rel=1e-3)
    assert int(lines[-1][3]) == front["front_size"]
    assert "partial front" not in res.stdout


def test_ctrl_c_during_the_sweep_writes_the_designs_found(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A Ctrl-C recorded before the sweep's fourth solve (the command checks between
    solves): exit 130, the runs written, and the three designs found written as a
    partial front, in the summary, the files and the report."""
    real = Interrupts.check
    calls = {"n": 0}

    def ctrl_c_at_fourth(self: Interrupts) -> None:
        calls["n"] += 1
        if calls["n"] == 4:
            self.received += 1  # what the SIGINT handler records
        real(self)

    monkeypatch.setattr(Interrupts, "check", ctrl_c_at_fourth)
    out = tmp_path / "front"
    with restored_sigint():  # the interrupted command leaves SIGINT blocked
        res = runner.invoke(app, _args(small_task(tmp_path), out, "--json"))
    assert res.exit_code == 130, res.output
    data = json.loads(res.stdout)
    assert data["interrupted"] and data["runs"] == 1
    assert (out / "design.yaml").is_file()
    front = json.loads((out / "pareto" / "front.json").read_text())
    assert front["partial"] is True and data["pareto"]["partial"] is True
    assert [p["index"] for p in front["points"]] == [0, 1, 2]
    assert front["front_size"] >= 1
    for p in front["points"]:
        assert p["all_reached"]
        load_robot(str(out / p["design_yaml"]))
    assert sorted(d.name for d in (out / "pareto").iterdir() if d.is_dir()) == [
        "point-0", "point-1", "point-2",
    ]  # fmt: skip
    assert "Partial front" in (out / "report.html").read_text()
