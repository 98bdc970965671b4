"""The server's scheduling options: ZeroMQ I/O threads under SCHED_FIFO when asked and
permitted, a clear error when not (libzmq itself would abort the process), and the
``--priority`` option of ``reachwise serve`` falling back to normal priority with a
warning."""

from __future__ import annotations

import gc
import os
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import reachwise.runtime.realtime as RT
import reachwise.server.transport as T
from reachwise.cli.serve import app
from reachwise.errors import InputError
from reachwise.server.client import SceneClient
from reachwise.server.transport import CollisionServer

linux_fifo = pytest.mark.skipif(
    sys.platform != "linux" or RT.fifo_refusal(10) != "", reason="SCHED_FIFO not permitted"
)


def _zmq_io_threads() -> dict[int, int]:
    """This process's ZeroMQ I/O threads: native id -> scheduling policy."""
    out = {}
    for tid in os.listdir("/proc/self/task"):
        name = Path(f"/proc/self/task/{tid}/comm").read_text().strip()
        if name.startswith("ZMQbg/IO"):
            out[int(tid)] = os.sched_getscheduler(int(tid))
    return out


@linux_fifo
def test_io_priority_puts_the_servers_io_threads_under_fifo() -> None:
    before = set(_zmq_io_threads())
    srv = CollisionServer("tcp://127.0.0.1:*", io_threads=2, io_priority=10)
    with srv.background() as endpoint, SceneClient(endpoint) as c:
        assert c.health().ready
        c.add_object("box", np.random.default_rng(0).normal(size=(100, 3)))
        mine = {t: p for t, p in _zmq_io_threads().items() if t not in before}
        servers = [p for t, p in mine.items() if os.sched_getparam(t).sched_priority == 10]
    assert len(servers) == 2 and set(servers) == {os.SCHED_FIFO}


def test_a_refused_io_priority_is_a_clear_error_before_anything_starts(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(T, "fifo_refusal", lambda _p: "not permitted (test)")
    with pytest.raises(InputError, match=r"io_priority.*not permitted"):
        CollisionServer("tcp://127.0.0.1:*", io_priority=50)
    with pytest.raises(InputError, match="io_threads"):
        CollisionServer("tcp://127.0.0.1:*", io_threads=0)


def test_fifo_refusal_says_why_and_leaves_the_caller_alone() -> None:
    policy = os.sched_getscheduler(0) if hasattr(os, "sched_getscheduler") else None
    why = RT.fifo_refusal(10)
    assert why == "" or "not" in why
    if policy is not None:
        assert os.sched_getscheduler(0) == policy
    with pytest.raises(ValueError, match="priority"):
        RT.fifo_refusal(0)


def test_serve_priority_refused_falls_back_to_normal_priority_with_a_warning(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(RT, "fifo_refusal", lambda _p: "not permitted (test)")
    gc.unfreeze()
    runner = CliRunner()
    got = runner.invoke(
        app, ["--bind", "tcp://127.0.0.1:*", "--priority", "50", "--max-runtime", "0.3"]
    )
    assert got.exit_code == 0, got.output
    assert "SCHED_FIFO not permitted (test); serving at normal priority" in got.output
    assert "normal priority)" in got.output
    assert gc.get_freeze_count() == 0  # serve hands back what it froze, in process too
