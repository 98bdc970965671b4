"""``reachwise demo`` (reduced with the hidden ``--quick``): folder layout, reports and
their links, resuming after Ctrl-C without redoing finished stages, ``--fresh``,
``--view``."""

from __future__ import annotations

import json
import sys
import types
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from reachwise.cli import app, demo_stages
from reachwise.cli import demo as demo_mod

FOLDERS = (
    "synthesis-sb60-tunnel-87",
    "topology-p2-tunnel-87",
    "simulate-p3-self-collision",
    "simulate-p5-crane-obstacle",
)
STAGES = ("task", "kinematics", "synthesis", "topology", "p3", "p5", "distance")


class Links(HTMLParser):
    def __init__(self, text: str) -> None:
        super().__init__()
        self.hrefs: list[str] = []
        self.feed(text)

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        if tag == "a":
            self.hrefs += [v or "" for k, v in attrs if k == "href"]


def run(out: Path, *extra: str) -> Any:
    return CliRunner().invoke(app, ["demo", "--quick", "--out", str(out), "--json", *extra])


def figures(res: Any) -> dict[str, Any]:
    assert res.stdout.strip(), res.output
    return dict(json.loads(res.stdout))


def test_demo_interrupted_resumes_and_writes_every_report(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    out = tmp_path / "reachwise-demo"

    # Ctrl-C during the first simulation: the stages before it stay complete on disk
    def interrupt(*args: Any) -> dict[str, Any]:
        raise KeyboardInterrupt

    with monkeypatch.context() as m:
        m.setattr(demo_stages, "simulate", interrupt)
        res = run(out)
    assert res.exit_code == 130, res.output
    first = figures(res)
    assert first["interrupted"] == "p3"
    assert list(first["stages"]) == ["task", "kinematics", "synthesis", "topology"]
    assert set(first["stages"].values()) == {"done"}
    for f in FOLDERS[:2]:
        assert (out / f / "stage.json").is_file() and (out / f / "report.html").is_file()
    assert not (out / FOLDERS[2] / "stage.json").exists()
    assert '<td class="l">interrupted</td>' in (out / "report.html").read_text()
    syn_marker = (out / FOLDERS[0] / "stage.json").stat().st_mtime_ns

    # the rerun reuses them and does the rest
    res = run(out)
    assert res.exit_code == 0, res.output
    data = figures(res)
    assert data["interrupted"] is None
    assert data["stages"] == {
        "task": "reused",
        "kinematics": "reused",
        "synthesis": "reused",
        "topology": "reused",
        "p3": "done",
        "p5": "done",
        "distance": "done",
    }
    assert (out / FOLDERS[0] / "stage.json").stat().st_mtime_ns == syn_marker
    assert data["synthesis"] == first["synthesis"]

    # layout: each stage's outputs and report in its folder
    assert (out / "tunnel-87.yaml").is_file() and (out / "demo.json").is_file()
    syn = out / FOLDERS[0]
    for f in ("design.yaml", "design.urdf", "points.csv", "summary.json", "task.yaml"):
        assert (syn / f).is_file(), f
    topo = out / FOLDERS[1]
    for f in ("sweep.db", "ranking.md", "ranking.json"):
        assert (topo / f).is_file(), f
    assert list((topo / "designs").glob("01-*.yaml"))
    for f in FOLDERS[2:]:
        for name in (
            "avoidance/log.npz",
            "baseline/log.npz",
            "summary.json",
            "joints.png",
            "tool_path.png",
            "min_distance.png",
            "report.html",
            "stage.json",
        ):
            assert (out / f / name).is_file(), (f, name)

    # the key figures are the stage outputs' own
    summ = json.loads((syn / "summary.json").read_text())
    assert data["synthesis"]["runs_reaching_all"] == summ["runs_reaching_all"]
    assert data["synthesis"]["task_points"] == 8
    sim = json.loads((out / FOLDERS[3] / "summary.json").read_text())
    assert data["p5"]["baseline"]["first_collision_s"] == sim["baseline"]["first_collision"]
    assert data["p5"]["avoidance"]["min_distance_m"] == sim["avoidance"]["min_distance"]
    panda = data["kinematics"]["panda"]
    assert panda["solved"] == panda["targets"] and panda["max_position_error_m"] <= 1e-6
    dist = data["distance"]
    assert dist["agree_with_brute"] == dist["queries"] > 0
    ranking = json.loads((topo / "ranking.json").read_text())
    assert data["topology"]["ranked"] == [r["topology"] for r in ranking["final"] if r["rank"]]

    # the top-level report links every per-run report, and the links resolve
    top = out / "report.html"
    assert data["report"] == str(top.resolve())
    hrefs = Links(top.read_text()).hrefs
    assert sorted(hrefs) == sorted(f"{f}/report.html" for f in FOLDERS)
    assert all((out / h).is_file() for h in hrefs)
    assert '<td class="l">interrupted</td>' not in top.read_text()

    # a third run redoes nothing; --view hands the folder to the viewer
    calls: list[tuple[Path, bool]] = []
    viewer = types.ModuleType("reachwise.viz.viewer")
    viewer.serve_results = lambda folder, block=False: calls.append((folder, block))  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "reachwise.viz.viewer", viewer)
    res = run(out, "--view")
    assert res.exit_code == 0, res.output
    assert set(figures(res)["stages"].values()) == {"reused"}
    assert calls == [(out, True)]

    # --fresh clears every stage before running (interrupted at once here: nothing left)
    with monkeypatch.context() as m:
        m.setattr(demo_stages, "task", interrupt)
        res = run(out, "--fresh")
    assert res.exit_code == 130
    assert figures(res)["stages"] == {}
    for f in FOLDERS:
        assert not (out / f).exists()
    assert not (out / "tunnel-87.yaml").exists()


def test_changed_options_redo_only_their_stage(tmp_path: Path) -> None:
    st = {s.key: s for s in demo_mod._stages(_ctx(tmp_path, runs=10))}
    other = {s.key: s for s in demo_mod._stages(_ctx(tmp_path, runs=4))}
    assert st["synthesis"].params != other["synthesis"].params
    assert all(st[k].params == other[k].params for k in STAGES if k != "synthesis")
    # a marker with other parameters is not reused
    ctx = _ctx(tmp_path, runs=10)
    marker = st["synthesis"].marker(tmp_path)
    marker.parent.mkdir(parents=True)
    marker.write_text(json.dumps({"params": other["synthesis"].params, "files": []}))
    assert demo_mod._reusable(ctx, st["synthesis"]) is None
    marker.write_text(json.dumps({"params": st["synthesis"].params, "files": ["missing.html"]}))
    assert demo_mod._reusable(ctx, st["synthesis"]) is None
    marker.write_text(json.dumps({"params": st["synthesis"].params, "files": []}))
    assert demo_mod._reusable(ctx, st["synthesis"]) is not None


def _ctx(out: Path, runs: int) -> Any:
    from rich.console import Console

    quiet = Console(quiet=True)
    return demo_mod.Ctx(out, 0, False, runs, 2, 20, 3, None, quiet, quiet, True)


def test_each_gci_figure_names_the_design_it_starts_from() -> None:
    """The run's random start and the first reaching design are two different starts: each
    line says which one its GCI figures go from, both to the same final design."""
    from reachwise.cli.demo_stages import best_line, objective_lines

    d = {
        "best_seed": 3,
        "task_points": 87,
        "bound_hits": [],
        "best": {
            "reached": 87,
            "gci_initial": 0.0711,
            "gci": 0.0721,
            "kci_initial": 0.01,
            "kci": 0.02,
            "reach_only": {"gci": 0.0667, "kci": 0.015},
            "objective_values": {"gci": 0.0721, "kci": 0.02},
        },
    }
    best = best_line(d)
    assert "from its random start design to the final design: GCI 0.0711 → 0.0721" in best
    (obj,) = objective_lines(d)
    assert "from the first design that reaches every point to the improved final design" in obj
    assert "GCI 0.0667 → 0.0721" in obj
