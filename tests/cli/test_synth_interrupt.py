"""Ctrl-C on a real ``reachwise synth`` process at random moments (start-up, runs,
writing), once or twice: it exits 130, and the runs it finished are written exactly as
an uninterrupted ``synth`` with that many runs writes them — or nothing is written."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from typer.testing import CliRunner

from reachwise import load_task
from reachwise.cli import app
from reachwise.io.task_file import save_task

FILES = ("design.urdf", "design.yaml", "points.csv", "report.html", "summary.json")
TRIALS = 20
#: Runs asked of an interrupted process: a few take the whole window the Ctrl-C is drawn
#: from, so the process is still running when it comes, even if the machine's load drops.
RUNS = 500


def _blocked_sigint() -> None:
    """``preexec_fn``: SIGINT at its default (a shell's background job ignores it) and
    blocked, so one sent before the interpreter runs reachwise's code waits for it."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})


def _args(task: Path, out: Path, runs: int) -> list[str]:
    return ["synth", "--task", str(task), "--robot", "sb60", "--runs", str(runs),
            "--out", str(out), "--json", "--no-figures"]  # fmt: skip


def _start(task: Path, out: Path, runs: int) -> subprocess.Popen[str]:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    return subprocess.Popen(
        [sys.executable, "-m", "reachwise", *_args(task, out, runs)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        preexec_fn=_blocked_sigint,
    )


def _files(folder: Path) -> dict[str, bytes]:
    """The files in ``folder``; the report's footer without the minute it was written."""
    if not folder.exists():
        return {}
    got = {p.name: p.read_bytes() for p in sorted(folder.iterdir())}
    if "report.html" in got:
        got["report.html"] = re.sub(
            rb" on \d{4}-\d\d-\d\d \d\d:\d\d UTC</footer>", b"</footer>", got["report.html"]
        )
    return got


def test_ctrl_c_at_random_moments_keeps_every_finished_run(tmp_path: Path) -> None:
    task = tmp_path / "task.yaml"
    save_task(load_task("tunnel-87").subset(np.arange(0, 87, 29), name="tunnel-3"), task)
    reference: dict[int, dict[str, bytes]] = {}

    def expected(k: int) -> dict[str, bytes]:
        if k not in reference:
            res = CliRunner().invoke(app, _args(task, tmp_path / f"ref-{k}", k))
            assert res.exit_code == 0, res.output
            reference[k] = _files(tmp_path / f"ref-{k}")
            assert sorted(reference[k]) == list(FILES)
        return reference[k]

    # an uninterrupted process: its files equal the in-process ones; its duration (start-up,
    # two runs, writing) is the window the interruptions are drawn from
    t0 = time.monotonic()
    proc = _start(task, tmp_path / "whole", 2)
    _, err = proc.communicate(timeout=600)
    window = time.monotonic() - t0
    assert proc.returncode == 0, err
    assert _files(tmp_path / "whole") == expected(2)

    rng = np.random.default_rng(32)
    kept = []
    for trial in range(TRIALS):
        out = tmp_path / f"trial-{trial}"
        delay = float(rng.uniform(0.0, window))
        second = float(rng.uniform(0.0, 0.5)) if rng.random() < 0.5 else None
        proc = _start(task, out, RUNS)  # far more runs than fit in the window
        try:
            time.sleep(delay)
            proc.send_signal(signal.SIGINT)
            if second is not None:
                time.sleep(second)
                if proc.poll() is None:
                    proc.send_signal(signal.SIGINT)
            _, err = proc.communicate(timeout=600)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        where = f"trial {trial}: Ctrl-C after {delay:.2f} s (second: {second})"
        assert proc.returncode == 130, f"{where}: exit {proc.returncode}\n{err}"
        assert "Traceback" not in err, f"{where}\n{err}"
        got = _files(out)
        if not got:
            kept.append(0)
            continue
        k = json.loads(got["summary.json"])["runs"]
        assert 1 <= k < RUNS, where
        assert got == expected(k), f"{where}: {k} runs differ from an uninterrupted run"
        kept.append(k)
    print("finished runs kept per trial:", kept)
