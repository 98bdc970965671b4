"""Ctrl-C during ``reachwise simulate``: a real SIGINT sent to the process at a seeded
tick (not a timed moment) ends the command with 130; the ticks finished before it are
written as a valid log, equal to the same ticks of an uninterrupted run."""

from __future__ import annotations

import json
import os
import signal
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

import reachwise.sim.scenarios as scenarios
import reachwise.sim.simulate as sim_mod
from reachwise.cli import app
from reachwise.sim.log import load_log
from tests.cli.sigint import restored_sigint

SCENARIO = "p3-self-collision"
DURATION = "1.5"


def _args(out: Path, *extra: str) -> list[str]:
    return ["simulate", SCENARIO, "--duration", DURATION, "--out", str(out), "--no-figures",
            "--json", *extra]  # fmt: skip


def _sigint_at(monkeypatch: pytest.MonkeyPatch, run: int, tick: int) -> None:
    """Send SIGINT to this process after ``tick`` ticks of run ``run`` (0: the first)."""
    real = sim_mod.simulate
    calls = [0]

    def wrapped(*args: Any, progress: Callable[[float, float], None], **kw: Any) -> Any:
        this, calls[0] = calls[0], calls[0] + 1
        ticks = [0]

        def progress_with_sigint(t: float, end: float) -> None:
            ticks[0] += 1
            if this == run and ticks[0] == tick:
                os.kill(os.getpid(), signal.SIGINT)  # recorded by the command's handler
            progress(t, end)

        return real(*args, progress=progress_with_sigint, **kw)

    monkeypatch.setattr(sim_mod, "simulate", wrapped)


def test_ctrl_c_keeps_the_finished_ticks_as_a_valid_log(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    whole = tmp_path / "whole"
    res = CliRunner().invoke(app, _args(whole, "--baseline"))
    assert res.exit_code == 0, res.output
    full = {k: load_log(whole / k) for k in ("avoidance", "baseline")}
    n_full = full["avoidance"].t.size
    rng = np.random.default_rng(32)
    # interrupt the avoidance run, then the baseline run (the avoidance run is complete)
    for run, label in ((0, "avoidance"), (1, "baseline")):
        tick = int(rng.integers(1, n_full - 1))
        out = tmp_path / f"int-{label}"
        with monkeypatch.context() as m, restored_sigint():
            _sigint_at(m, run, tick)
            res = CliRunner().invoke(app, _args(out, "--baseline"))
        assert res.exit_code == 130, res.output
        assert f"interrupted during the {label} run" in " ".join(res.stderr.split())
        assert "run the same command" in res.stderr
        summary = json.loads((out / "summary.json").read_text())
        assert summary["interrupted"] == label
        assert not (out / "report.html").exists()
        kept = load_log(out / label)
        assert kept.t.size == tick  # the tick that saw the SIGINT finished, none after
        assert kept.extras["interrupted"] is True
        ref = full[label]
        np.testing.assert_array_equal(kept.t, ref.t[:tick])
        np.testing.assert_array_equal(kept.distance, ref.distance[:tick])
        for r in ref.robots:
            np.testing.assert_array_equal(kept.q[r], ref.q[r][:tick])
            np.testing.assert_array_equal(kept.command[r], ref.command[r][:tick])
        if label == "baseline":  # the avoidance run finished before: kept whole
            done = load_log(out / "avoidance")
            np.testing.assert_array_equal(done.q[ref.robots[0]], full["avoidance"].q[ref.robots[0]])
            assert "interrupted" not in done.extras
        else:
            assert not (out / "baseline").exists()


def test_ctrl_c_before_the_first_tick_writes_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    real = scenarios.load_scenario

    def sigint_first(*args: Any, **kw: Any) -> Any:
        os.kill(os.getpid(), signal.SIGINT)  # while the scenario file is read
        return real(*args, **kw)

    monkeypatch.setattr(scenarios, "load_scenario", sigint_first)
    out = tmp_path / "none"
    with restored_sigint():
        res = CliRunner().invoke(app, _args(out))
    assert res.exit_code == 130, res.output
    assert "before its first tick: nothing written" in " ".join(res.stderr.split())
    assert not (out / "summary.json").exists()
