"""Ctrl-C during ``reachwise topology`` in process (``--workers 0``, the compiled runs
in this process): a real SIGINT, once or twice, sent at a seeded stored run (not a
timed moment) ends the sweep with 130 after that run; the database holds exactly the
finished runs, intact, and the same command resumes with only the missing ones."""

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
from reachwise.results.sweep_store import SweepStore
from tests.cli.sigint import restored_sigint
from tests.cli.test_topology_cli import task_file

SPECS = ["RRPRRR", "PRRRRR", "RRRRRR"]
RUNS = 2


@pytest.mark.parametrize("signals", [1, 2])
def test_ctrl_c_keeps_every_stored_run_and_resumes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, signals: int
) -> None:
    db = tmp_path / "sweep.db"
    args = ["topology", "--task", str(task_file(tmp_path)),
            *(a for s in SPECS for a in ("--spec", s)), "--runs", str(RUNS), "--workers", "0",
            "--db", str(db), "--out", str(tmp_path / "out"), "--json", "--no-figures"]  # fmt: skip
    total = len(SPECS) * RUNS
    at = int(np.random.default_rng(32 + signals).integers(1, total))
    real = SweepStore.write
    writes = [0]

    def write(self: SweepStore, *a: Any, **kw: Any) -> bool:
        stored = real(self, *a, **kw)
        writes[0] += 1
        if writes[0] == at:
            for _ in range(signals):
                os.kill(os.getpid(), signal.SIGINT)  # recorded; honoured after this run
        return stored

    with monkeypatch.context() as m, restored_sigint():
        m.setattr(SweepStore, "write", write)
        res = CliRunner().invoke(app, args)
    assert res.exit_code == 130, res.output
    line = " ".join(res.stderr.split())
    assert f"interrupted: {at} finished runs are stored in" in line
    assert "run the same command to resume" in line
    with SweepStore(db) as st:
        assert st.integrity() == "ok"
        assert st.count() == at
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    assert data["stored_items"] == at
    assert data["new_items"] + at == total
