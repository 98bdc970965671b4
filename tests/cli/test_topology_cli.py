"""``reachwise topology`` as a user runs it: reports, listing, errors, and a SIGKILL.

The command is tested through its own typer app (``reachwise.cli.topology.topology``)
and, for the kill, as a separate process (``python -m reachwise.cli.topology``), so the
tests do not depend on how the top-level app registers it.
"""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest
import typer
from typer.testing import CliRunner

from reachwise import load_robot
from reachwise.cli.topology import topology
from reachwise.errors import UnknownName
from reachwise.io.task_file import load_task, save_task
from reachwise.results.sweep_store import SweepStore
from reachwise.synthesis.sweep import SweepConfig, run_sweep
from reachwise.synthesis.topology import topologies_from_specs
from tests.conftest import sigint_default
from tests.synthesis.test_sweep import generated_task

runner = CliRunner()
app = typer.Typer()
app.command()(topology)

SPECS = ["RRPRRR", "RRPRRRP", "PRRRRR", "RRRRRR", "RRRPRR", "PRRPRR"]


def task_file(tmp_path: Path, k: int = 24) -> Path:
    path = tmp_path / f"gen{k}.yaml"
    save_task(generated_task(k)[0], path)
    return path


def test_topology_writes_ranked_tables_designs_and_figures(tmp_path: Path) -> None:
    out = tmp_path / "out"
    args = ["--task", str(task_file(tmp_path)), "--spec", "RRPRRR", "--spec", "PRRRRR",
            "--spec", "RRRRRR", "--subset", "8", "--top", "2", "--runs", "1", "--workers",
            "0", "--db", str(tmp_path / "s.db"), "--out", str(out), "--json"]  # fmt: skip
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    data = json.loads(res.output)
    assert data["subset"] is not None and len(data["subset"]) == 8
    assert len(data["round1"]) == 3 and len(data["final"]) == 2
    for f in ("ranking.md", "ranking.csv", "ranking.json"):
        assert (out / f).is_file()
    md = (out / "ranking.md").read_text()
    assert "| rank | topology |" in md and "GCI" in md and "Round 1" in md
    assert (out / "ranking.csv").read_text().splitlines()[0].startswith("rank,topology,round")
    assert json.loads((out / "ranking.json").read_text())["table"] == data["table"]
    assert data["designs"], "at least the generating topology is feasible"
    for d in data["designs"]:
        robot = load_robot(d["yaml"])
        assert robot.n == 6 and Path(d["urdf"]).is_file() and Path(d["figure"]).is_file()
    # the HTML report: the ranked topologies in order, the figures embedded
    report = Path(data["report"])
    assert report == out / "report.html"
    text = report.read_text()
    assert text.count("data:image/png;base64,") == 1 + len(data["designs"])
    ranked = [r["topology"] for r in data["final"] if r["rank"] is not None]
    assert [text.index(f">{n}<") for n in ranked] == sorted(text.index(f">{n}<") for n in ranked)
    # the same command again: everything is in the database
    res2 = runner.invoke(app, args)
    assert res2.exit_code == 0, res2.output
    again = json.loads(res2.output)
    assert again["new_items"] == 0 and again["stored_items"] == data["new_items"]
    assert again["table"] == data["table"]


def test_human_output_and_enumerate_list(tmp_path: Path) -> None:
    res = runner.invoke(
        app, ["--task", "tunnel-87", "--enumerate", "joints=6 first=vertical sample=5",
              "--db", str(tmp_path / "x.db"), "--out", str(tmp_path), "--list"],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    assert res.output.strip().endswith("5 topologies")
    res = runner.invoke(
        app, ["--task", str(task_file(tmp_path, 12)), "--spec", "RRPRRR", "--runs", "1",
              "--workers", "0", "--db", str(tmp_path / "h.db"), "--out", str(tmp_path / "o"),
              "--no-figures", "--rank", "gci"],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    assert "final ranking by gci" in res.output and "runs done now" in res.output
    assert f"report: {tmp_path / 'o' / 'report.html'}" in res.output.replace("\n", "")
    assert "<img" not in (tmp_path / "o" / "report.html").read_text()


def test_a_resume_says_how_many_stored_runs_of_other_code_it_runs_again(tmp_path: Path) -> None:
    """Runs stored by other code (here: versions without the source hash, as before it was
    kept) are run again; the progress output and the summary say how many."""
    db = tmp_path / "s.db"
    args = ["--task", str(task_file(tmp_path, 12)), "--spec", "RRPRRR", "--runs", "2",
            "--workers", "0", "--db", str(db), "--out", str(tmp_path / "o"),
            "--no-figures"]  # fmt: skip
    assert runner.invoke(app, args).exit_code == 0
    con = sqlite3.connect(db)
    with con:
        con.execute("""UPDATE items SET versions = '{"reachwise": "0.1.0"}' WHERE run = 1""")
    con.close()
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    text = " ".join(res.output.split())
    assert f"1 runs stored in {db} were computed by other code or libraries" in text
    assert "1 runs done now (1 of them replacing runs of other code), 1 found in" in text
    res = runner.invoke(app, [*args, "--json"])
    assert json.loads(res.output)["stale_items"] == 0 and "other code" not in res.output


@pytest.mark.parametrize(
    ("extra", "match"),
    [([], "exactly one"), (["--set", "p2", "--spec", "RRR"], "exactly one"),
     (["--set", "p2", "--lengths", "2:-2"], "LO > HI"),
     (["--set", "p2", "--stroke", "x"], "LO:HI")],
)  # fmt: skip
def test_bad_arguments(tmp_path: Path, extra: list[str], match: str) -> None:
    res = runner.invoke(
        app, ["--task", "tunnel-87", "--db", str(tmp_path / "e.db"), "--out", str(tmp_path),
              *extra],
    )  # fmt: skip
    assert res.exit_code == 2
    assert match in res.output


def test_an_unknown_rank_key_lists_the_valid_ones(tmp_path: Path) -> None:
    res = runner.invoke(
        app, ["--task", "tunnel-87", "--db", str(tmp_path / "e.db"), "--out", str(tmp_path),
              "--set", "p2", "--rank", "speed"],
    )  # fmt: skip
    assert isinstance(res.exception, UnknownName)  # `reachwise` exits 2 with this line
    assert (
        "unknown rank key 'speed'; valid: bounds, clearance, gci, kci, length, limits, "
        "manipulability, mean, prismatic, size" in str(res.exception)
    )
    assert not (tmp_path / "e.db").exists()


def test_ctrl_c_exits_130_keeping_finished_runs(tmp_path: Path) -> None:
    db = tmp_path / "int.db"
    args = [sys.executable, "-m", "reachwise.cli.topology", "--task",
            str(task_file(tmp_path, 40)), *(a for s in SPECS for a in ("--spec", s)),
            "--runs", "2", "--workers", "2", "--db", str(db), "--out", str(tmp_path / "o"),
            "--no-figures"]  # fmt: skip
    proc = subprocess.Popen(
        args,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        preexec_fn=sigint_default,
    )
    try:
        stored = 0
        deadline = time.monotonic() + 120
        while stored < 2 and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.02)
            stored = _count(db)
        assert proc.poll() is None, "the sweep ended before Ctrl-C"
        os.kill(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 130, err
    assert "run the same command to resume" in " ".join(err.split())
    with SweepStore(db) as st:
        assert st.integrity() == "ok"
        assert stored <= st.count() < len(SPECS) * 2


def _count(db: Path) -> int:
    if not db.exists():
        return 0
    con = sqlite3.connect(db)
    try:
        return int(con.execute("SELECT COUNT(*) FROM items").fetchone()[0])
    except sqlite3.OperationalError:  # schema not created yet
        return 0
    finally:
        con.close()


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:  # a zombie child of ours counts as gone
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().split(")")[-1].split()[0] != "Z"
    except OSError:
        return False


def test_sigkill_half_way_then_resume_runs_only_the_missing_items(tmp_path: Path) -> None:
    """Must show: kill -9 the sweep half-way; the rerun completes only the missing items,
    the database holds no duplicate or partial row, the table equals an uninterrupted
    run's, and the killed sweep's workers exit by themselves."""
    task_path = task_file(tmp_path, 40)
    db = tmp_path / "kill.db"
    runs = 2
    total = len(SPECS) * runs
    args = [sys.executable, "-m", "reachwise.cli.topology", "--task", str(task_path),
            *(a for s in SPECS for a in ("--spec", s)), "--runs", str(runs), "--workers", "2",
            "--db", str(db), "--out", str(tmp_path / "out"), "--json", "--no-figures"]  # fmt: skip
    proc = subprocess.Popen(
        args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
    )
    workers: set[int] = set()
    try:
        stored = 0
        deadline = time.monotonic() + 120
        while stored < total // 3 and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.02)
            stored = _count(db)
        assert proc.poll() is None, "the sweep ended before it could be killed"
        os.kill(proc.pid, signal.SIGKILL)  # the sweep's own process, like kill -9
        proc.wait(timeout=30)
        with SweepStore(db) as st:
            workers = {
                int(r.worker.rsplit(":", 1)[1]) for r in st.results(st.sweeps()[0]["sweep_id"])
            }
        deadline = time.monotonic() + 15
        while any(_alive(p) for p in workers) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not any(_alive(p) for p in workers), "orphaned workers kept running"
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)  # clean up our process group if anything is left
        except ProcessLookupError:
            pass
    with SweepStore(db) as st:
        assert st.integrity() == "ok"
        sid = st.sweeps()[0]["sweep_id"]
        killed_rows = st.results(sid)
        after_kill = len(killed_rows)
        assert 0 < after_kill < total
    res = subprocess.run(args, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    data = json.loads(res.stdout)
    assert data["stored_items"] == after_kill
    assert data["new_items"] == total - after_kill
    con = sqlite3.connect(db)
    n, distinct = con.execute(
        "SELECT COUNT(*), COUNT(DISTINCT sweep_id || topology || round || '/' || run) FROM items"
    ).fetchone()
    con.close()
    assert n == distinct == total
    with SweepStore(db) as st:
        rows = {r.key: r for r in st.results(sid)}
        for r in killed_rows:  # nothing finished before the kill was redone or changed
            assert rows[r.key].same_outcome(r) and rows[r.key].worker == r.worker
    reference = run_sweep(
        load_task(str(task_path)), topologies_from_specs(SPECS), SweepConfig(runs=runs),
        workers=0,
    )  # fmt: skip
    assert data["table"] == json.loads(json.dumps(reference.table()))
