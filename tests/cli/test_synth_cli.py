"""``reachwise synth`` as a user runs it: outputs, JSON, Ctrl-C keeping finished runs."""

from __future__ import annotations

import csv
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from reachwise import load_robot, load_task
from reachwise.cli import app
from reachwise.errors import InputError
from reachwise.io.ros.joint_state import robot_joint_names

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
    joints = robot_joint_names(robot)  # the joint columns are named after the joints
    Q = np.array([[float(r[j]) for j in joints] for r in rows])
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


def test_objective_improves_the_reaching_design_and_reports_it(tmp_path: Path) -> None:
    out = tmp_path / "obj"
    res = runner.invoke(
        app,
        ["synth", "--task", str(small_task(tmp_path)), "--robot", "sb60", "--runs", "1",
         "--objective", "gci:1,size:0.2", "--min-length", "0.05", "--out", str(out),
         "--json", "--no-figures"],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    data = json.loads(res.output)
    b = data["best"]
    assert data["objective"] == {"gci": 1.0, "size": 0.2}
    assert b["all_reached"]
    before, after = b["reach_only"], b["objective_values"]
    # the weighted sum of relative changes improved (gci up counts, size down counts)
    gain = (after["gci"] / before["gci"] - 1) - 0.2 * (after["size"] / before["size"] - 1)
    assert gain > 0
    # every flagged parameter really sits within 1 % of its range from a kept bound
    robot = load_robot("sb60")
    for h in data["bound_hits"]:
        assert h["side"] in ("lower", "upper", "min_length")
        assert h["parameter"] in robot.design_names
        assert abs(h["value"] - h["bound"]) <= 0.01 * 5.0 + 1e-12
    names = {h["parameter"] for h in data["bound_hits"]}
    for r in data["table3"]:  # and no parameter clear of its bounds is flagged
        if 0.011 < r["optimized"] < 0.989 and r["parameter"][0] not in "ad":
            assert r["parameter"] not in names
    html = (out / "report.html").read_text()
    assert 'id="objectives"' in html and 'id="bound-hits"' in html
    assert "bound flag" in html


def test_pareto_without_a_reaching_run_says_why_and_fails(tmp_path: Path) -> None:
    """A pose 6 m beyond the others: no run reaches every pose, so no sweep can start.
    The runs are written, the command names the pose the best run missed and what it
    missed, the report says the same, and the exit code is 1."""
    from reachwise.io.task_file import save_task
    from reachwise.tasks.task import Task

    task = load_task("tunnel-87").subset(np.arange(0, 87, 9), name="tunnel-10")
    P = task.positions.copy()
    P[-1] += np.array([6.0, 0.0, 0.0])
    far = Task.from_arrays("far", P, rotations=task.rotations, dims=6, names=task.names)
    path = tmp_path / "far.yaml"
    save_task(far, path)
    out = tmp_path / "out"
    res = runner.invoke(
        app,
        ["synth", "--task", str(path), "--robot", "sb60", "--runs", "1", "--no-tunnel",
         "--pareto", "gci,size", "--points", "3", "--out", str(out), "--no-figures"],
    )  # fmt: skip
    assert res.exit_code == 1, res.output
    text = " ".join(res.output.split())  # the console wraps long lines
    best = json.loads((out / "summary.json").read_text())["best"]
    assert "no Pareto sweep" in text and f"serves {best['reached']}/10" in text
    assert best["reached"] < 10 and f"{far.names[-1]} (position" in text
    assert (out / "design.yaml").is_file() and not (out / "pareto").exists()
    html = (out / "report.html").read_text()
    assert 'id="pareto"' in html and "no Pareto sweep" in html


def test_front_clearance_needs_a_sweep_and_a_clearance_it_keeps(tmp_path: Path) -> None:
    """--front-clearance is refused before any run: without --pareto, without bodies
    kept clear, at 0, or above --clearance (the start design would not keep it)."""
    task = str(small_task(tmp_path))
    for args, words in (
        (["--clearance", "0.1", "--front-clearance", "0.05"], "needs --pareto"),
        (["--clearance", "0", "--pareto", "gci,size", "--front-clearance", "0.05"], "--clearance"),
        (["--clearance", "0.1", "--pareto", "clearance,size", "--front-clearance", "0"], "> 0"),
        (["--clearance", "0.1", "--pareto", "clearance,size", "--front-clearance", "0.2"],
         "at most --clearance 0.1"),
    ):  # fmt: skip
        out = tmp_path / "x"
        res = runner.invoke(
            app, ["synth", "--task", task, "--robot", "sb60", "--out", str(out), *args]
        )
        text = " ".join((res.output + str(res.exception or "")).split())
        assert res.exit_code == 2, (args, text)
        assert words in text and "front-clearance" in text, (args, text)
        assert not out.exists()


def test_bad_objectives_are_input_errors(tmp_path: Path) -> None:
    task = str(small_task(tmp_path))
    for args, words in (
        (["--objective", "speed:1"], "speed"),
        (["--objective", "gci:-1"], ">= 0"),
        (["--pareto", "gci"], "two different objectives"),
        (["--pareto", "gci,speed"], "speed"),
    ):
        res = runner.invoke(
            app, ["synth", "--task", task, "--robot", "sb60", "--out", str(tmp_path / "x"), *args]
        )
        # a usage error exits 2 here; an InputError reaches ``main``, which exits 2
        text = res.output + str(res.exception or "")
        assert res.exit_code == 2 or isinstance(res.exception, InputError), (args, text)
        assert words in text, (args, text)


def test_clearance_reports_left_out_poses_and_each_pose_clearance(tmp_path: Path) -> None:
    """--clearance: the poses no design can serve are named in the summary and left out
    of the count; summary.json and points.csv give each pose's smallest clearance and
    its pair, each at least the clearance when every pose is reached."""
    task = load_task("tunnel-87")
    idx = [i for i, n in enumerate(task.names) if n.startswith(("P01/", "P02/"))]
    from reachwise.io.task_file import save_task

    path = tmp_path / "t.yaml"
    save_task(task.subset(idx, name="tunnel-p12"), path)
    out = tmp_path / "out"
    res = runner.invoke(
        app,
        ["synth", "--task", str(path), "--robot", "sb60", "--runs", "1", "--clearance", "0.1",
         "--out", str(out), "--json", "--no-figures"],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    data = json.loads(res.output)
    c = data["clearance"]
    left = {u["name"] for u in c["unservable"]}
    assert {"P01/lifter01", "P02/lifter01"} <= left
    assert data["task_points"] == len(idx) - len(left)
    assert data["best"]["all_reached"]
    assert c["smallest_m"] >= 0.1 and len(c["per_pose"]) == data["task_points"]
    with (out / "points.csv").open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert all(float(r["clearance_m"]) >= 0.1 and " ~ " in r["clearance_pair"] for r in rows)
    assert {r["name"] for r in rows}.isdisjoint(left)


def test_a_task_that_leaves_the_design_free_is_warned_about(tmp_path: Path) -> None:
    """Two poses: joint motion alone reaches them from the random start, every design
    parameter stays where it started, and the command says so by name."""
    task = load_task("tunnel-87").subset(np.array([0, 40]), name="tunnel-2")
    from reachwise.io.task_file import save_task

    path = tmp_path / "t2.yaml"
    save_task(task, path)
    out = tmp_path / "out"
    args = ["synth", "--task", str(path), "--robot", "sb60", "--runs", "1", "--out", str(out)]
    res = runner.invoke(app, [*args, "--no-figures"])
    assert res.exit_code == 0, res.output
    data = json.loads((out / "summary.json").read_text())
    free = data["unconstrained"]
    assert free and set(free) <= set(data["design_parameters"])
    assert "unconstrained" in res.output and free[0] in res.output
    # the rule on the result itself: a parameter that a reaching run moved is not free
    import reachwise

    result = reachwise.synthesize(task, reachwise.load_robot("sb60"), runs=1, seed=0)
    names = result.unconstrained()
    assert names
    run = result.best
    moved = run.design.copy()
    k = result.problem.design_names.index(names[0])
    lo, hi = result.problem.declared_bounds
    moved[k] += 0.01 * (hi[k] - lo[k])
    runs = (replace(run, design=moved, reach_design=None),)
    other = replace(result, runs=runs, best_index=0)
    assert names[0] not in other.unconstrained() and set(other.unconstrained()) < set(names)


def test_clearance_starts_reach_every_run_and_bad_values_are_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """--clearance-starts N is each run's SolverOptions.clearance_starts (the solves a
    clearance run may take); below 1 it is refused before any run."""
    import reachwise.synthesis.synthesize as synthesize

    task = load_task("tunnel-87")
    idx = [i for i, n in enumerate(task.names) if n.startswith("P01/")]
    from reachwise.io.task_file import save_task

    path = tmp_path / "t.yaml"
    save_task(task.subset(idx, name="tunnel-p1"), path)
    args = ["synth", "--task", str(path), "--robot", "sb60", "--clearance", "0.1",
            "--no-figures", "--json"]  # fmt: skip
    bad = runner.invoke(app, [*args, "--out", str(tmp_path / "x"), "--clearance-starts", "0"])
    assert bad.exit_code == 2 and not (tmp_path / "x").exists(), bad.output
    seen: list[int] = []
    real = synthesize.run_once

    def recording(*a: object, **kw: object) -> object:
        options = kw.get("options")
        seen.append(getattr(options, "clearance_starts", 1))
        return real(*a, **kw)  # type: ignore[arg-type]

    monkeypatch.setattr(synthesize, "run_once", recording)
    out = tmp_path / "out"
    res = runner.invoke(app, [*args, "--out", str(out), "--runs", "2", "--clearance-starts", "3"])
    assert res.exit_code == 0, res.output
    assert seen == [3, 3]
    assert json.loads(res.output)["task_points"] > 0
