"""The SQLite sweep store: exact round trips, unique rows, resumable, kill-safe."""

from __future__ import annotations

import math
import os
import signal
import sqlite3
import subprocess
import sys
import textwrap
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from reachwise.errors import InputError
from reachwise.results.sweep_store import SweepStore
from reachwise.synthesis.rank import Measures
from reachwise.synthesis.sweep import ItemResult, WorkItem, run_item
from reachwise.synthesis.topology import to_template
from reachwise.tasks.task import Task


def _item(topology: str = "t", round: int = 1, run: int = 0, seed: int = 0) -> ItemResult:
    rng = np.random.default_rng(seed + 100 * run)
    q = rng.normal(size=(5, 6))
    return ItemResult(
        topology=topology,
        round=round,
        run=run,
        seed=seed,
        n_points=5,
        n_reached=4,
        e_obj=float(rng.random()) / 3.0,
        iterations=17,
        converged=False,
        measures=Measures(0.1 / 3, 0.2 / 7, 0.5 * (0.1 / 3 + 0.2 / 7), 1e3 / 3, 9.0 / 7, 2),
        design_names=("a1", "d2", "base.x"),
        design=(1 / 3, -2 / 7, math.pi),
        q=q,
        status=("full", "full", "position", "full", "full"),
        max_position_error=1e-4 / 3,
        max_orientation_error=2e-3 / 3,
        wall_s=0.123,
        worker="host:1",
        versions={"reachwise": "x"},
    )


def _open(path: Path | str) -> SweepStore:
    s = SweepStore(path)
    s.open_sweep("sid", {"task": "demo"}, [("t", "R R", "h1"), ("u", "P R", "h2")])
    return s


def test_round_trip_is_bit_exact(tmp_path: Path) -> None:
    with _open(tmp_path / "s.db") as st:
        a = _item()
        assert st.write("sid", a)
        (b,) = st.results("sid")
        assert b.same_outcome(a)
        assert b.q.tobytes() == a.q.tobytes()
        assert b.design == a.design and b.measures == a.measures
        assert b.wall_s == a.wall_s and b.worker == a.worker and b.versions == a.versions
        assert st.done("sid", 1) == {("t", 0)} and st.done("sid", 2) == set()


def test_error_rows_round_trip(tmp_path: Path) -> None:
    err = replace(
        _item(run=1), measures=None, e_obj=math.inf, q=np.zeros((0, 0)), design=(),
        status=(), n_reached=0, error="ValueError: bad", max_position_error=math.nan,
    )  # fmt: skip
    with _open(tmp_path / "s.db") as st:
        st.write("sid", err)
        (b,) = st.results("sid")
        assert b.error == "ValueError: bad" and b.measures is None
        assert b.e_obj == math.inf and math.isnan(b.max_position_error)
        assert not b.feasible


def test_a_run_is_stored_once(tmp_path: Path) -> None:
    with _open(tmp_path / "s.db") as st:
        assert st.write("sid", _item())
        assert not st.write("sid", replace(_item(), e_obj=99.0))
        assert st.count("sid") == 1
        assert st.results("sid")[0].e_obj != 99.0
        st.write("sid", _item(round=2))
        st.write("sid", _item("u", run=3))
        assert st.count() == 3
        assert [r.key for r in st.results("sid")] == [("t", 1, 0), ("u", 1, 3), ("t", 2, 0)]
        assert [r.key for r in st.results("sid", 2)] == [("t", 2, 0)]


def test_reopen_resumes_and_checks_templates(tmp_path: Path) -> None:
    path = tmp_path / "s.db"
    with _open(path) as st:
        st.write("sid", _item())
    with _open(path) as st:  # same sweep again: nothing lost, nothing duplicated
        assert st.done("sid", 1) == {("t", 0)}
        assert st.topologies("sid") == [("t", "R R"), ("u", "P R")]
        assert st.sweeps()[0]["items"] == 1
        with pytest.raises(InputError, match="template changed"):
            st.open_sweep("sid", {}, [("t", "R R", "other-hash")])


def test_wal_mode_and_constraints(tmp_path: Path) -> None:
    path = tmp_path / "s.db"
    with _open(path) as st:
        st.write("sid", _item())
    db = sqlite3.connect(path)
    assert db.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    pk = [r[1] for r in db.execute("PRAGMA table_info(items)") if r[5]]
    assert pk == ["sweep_id", "topology", "round", "run"]
    with pytest.raises(sqlite3.IntegrityError):  # a q blob of the wrong size is refused
        db.execute("UPDATE items SET q = x'00'")
    db.close()


def test_a_failed_write_leaves_no_row(tmp_path: Path) -> None:
    with _open(tmp_path / "s.db") as st:
        bad = replace(_item(), topology="unregistered")  # foreign key fails
        with pytest.raises(sqlite3.IntegrityError):
            st.write("sid", bad)
        assert st.count() == 0
        assert st.write("sid", _item())


def test_store_of_a_real_run(tmp_path: Path, rng: np.random.Generator) -> None:
    tmpl = to_template("R(0) R(90) P(90) R(90) R(90) R(90)")
    P = rng.uniform(-1, 1, (4, 3)) + np.array([3.0, 0.0, 1.0])
    task = Task.from_arrays("tiny", P, dims=3)
    res = run_item(WorkItem("t", 1, 0, 7, tmpl, task))
    assert not res.error and res.q.shape == (4, 6)
    with _open(tmp_path / "s.db") as st:
        st.write("sid", res)
        assert st.results("sid")[0].same_outcome(res)


def test_sigkill_during_writes_leaves_a_sound_database(tmp_path: Path) -> None:
    """A writer killed at a random moment: every stored row is complete and unique."""
    path = tmp_path / "kill.db"
    code = textwrap.dedent(
        f"""
        import sys
        sys.path.insert(0, {str(Path(__file__).parent)!r})
        from test_sweep_store import _item, _open
        st = _open({str(path)!r})
        print("ready", flush=True)
        for i in range(100000):
            st.write("sid", _item(run=i))
        """
    )
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE)
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == b"ready"
        reader = SweepStore(path)
        give_up = time.monotonic() + 120.0  # a hang guard, not a pass/fail clock
        while reader.count() < 50 and proc.poll() is None and time.monotonic() < give_up:
            time.sleep(0.001)
        assert reader.count() >= 50, f"the writer stopped early (exit {proc.poll()})"
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
        reader.close()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    with SweepStore(path) as st:
        assert st.integrity() == "ok"
        rows = st.results("sid")
        runs = [r.run for r in rows]
        assert len(runs) == len(set(runs)) >= 50
        assert runs == list(range(len(runs)))  # each write committed in order, none partial
        for r in rows:
            assert r.same_outcome(_item(run=r.run))
        assert st.write("sid", _item(run=len(runs)))  # and the sweep can go on


@pytest.mark.parametrize("version", [1, 2])
def test_an_older_schema_is_upgraded_in_place(tmp_path: Path, version: int) -> None:
    """A store written before the design objectives (schema 1: no size/limits/bounds
    columns) or before the clearance (schema 2: no clearance column) opens, keeps its
    rows (the new measures read NaN) and takes new ones."""
    from reachwise.results import sweep_store

    path = tmp_path / f"v{version}.db"
    old_schema = sweep_store._SCHEMA
    later = {1: ("size", "limits", "bounds", "clearance"), 2: ("clearance",)}[version]
    for c in later:
        old_schema = old_schema.replace(f"  {c} REAL,\n", "")
    db = sqlite3.connect(path)
    db.executescript(old_schema)
    db.execute("INSERT INTO meta(key, value) VALUES ('schema', ?)", (str(version),))
    db.commit()
    db.close()
    old = _item(run=0)
    with SweepStore(path) as st:
        st.open_sweep("sid", {"task": "demo"}, [("t", "R R", "h1")])
        assert st.write("sid", old)
    db = sqlite3.connect(path)
    db.execute(f"UPDATE items SET {', '.join(f'{c} = NULL' for c in later)}")
    db.commit()
    db.close()
    new = replace(
        _item(run=1),
        measures=replace(_item().measures, size=3.5, limits=0.25, bounds=0.0, clearance=0.125),
    )
    with SweepStore(path) as st:
        assert st.write("sid", new)
        got = {r.run: r for r in st.results("sid")}
    assert got[0].same_outcome(old) and math.isnan(got[0].measures.clearance)
    assert got[1].measures.size == 3.5 and got[1].measures.clearance == 0.125
    assert got[1].same_outcome(new)
    with SweepStore(path) as st:  # opening again is a no-op
        assert len(st.results("sid")) == 2
