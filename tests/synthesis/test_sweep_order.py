"""The sweep's tables do not depend on the order its runs arrive in, on which process ran
them, or on rounding noise in their figures.

A process pool hands finished runs back in completion order, and a run computed in another
process (another summation order, another BLAS kernel) may differ in its last bits. The
best run of a topology is chosen from its stored runs, so these tests feed the collector
(the stores and ``round_table``) the same runs in every order and with their figures moved
by rounding noise, and check the table is the same. The figures are those of two runs of
p2-man6 on tunnel-87 whose order flipped between two sweeps at one commit.
"""

from __future__ import annotations

import itertools
import json
import math
import re
import threading
from collections.abc import Callable
from concurrent.futures import Executor, Future
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from reachwise._version import source_fingerprint, tree_fingerprint
from reachwise.errors import InputError
from reachwise.results.sweep_store import SweepStore
from reachwise.synthesis.rank import SAME_FIGURE, Measures, RankKey
from reachwise.synthesis.sweep import (
    ROUND_FULL,
    ItemResult,
    MemoryStore,
    SweepConfig,
    SweepEvent,
    WorkItem,
    round_table,
    run_sweep,
)
from reachwise.synthesis.sweep.tables import best_run
from reachwise.synthesis.topology import Topology, topologies_from_specs
from reachwise.tasks.task import Task


def _run(
    topology: str,
    run: int,
    *,
    reached: int = 20,
    points: int = 20,
    e_obj: float = 1.2e-13,
    gci: float = 0.05,
    kci: float = 0.01,
    length: float = 9.0,
) -> ItemResult:
    """One stored run with the given figures (a run of a 2-parameter design, 20 poses)."""
    m = Measures(
        gci=gci, kci=kci, mean=0.5 * (gci + kci), manipulability=0.01, length=length,
        prismatic=1, size=length, limits=0.1, bounds=0.0,
    )  # fmt: skip
    return ItemResult(
        topology=topology, round=1, run=run, seed=run, n_points=points, n_reached=reached,
        e_obj=e_obj, iterations=100 + run, converged=reached == points, measures=m,
        design_names=("a2", "d4"), design=(0.5 + run, 1.0 + run),
        q=np.full((points, 6), 0.1 * run), status=("ok",) * points,
        max_position_error=1e-7, max_orientation_error=1e-7,
    )  # fmt: skip


def _failed(r: ItemResult) -> ItemResult:
    """``r`` as a run whose synthesis raised."""
    return replace(r, n_reached=0, e_obj=math.inf, measures=None, error="InputError: no")


def _records(results: list[ItemResult], key: RankKey = "mean") -> list[dict[str, Any]]:
    rows: list[dict[str, Any]] = json.loads(json.dumps(round_table(results, 1, key).records()))
    return rows


def _p2_man6(e0: float, e1: float) -> list[ItemResult]:
    """p2-man6's two runs as measured: run 0 GCI 0.05693, mean 0.02986; run 1 GCI 0.05489,
    mean 0.03033; both reach every pose, their pose errors at rounding level."""
    return [
        _run("p2-man6", 0, e_obj=e0, gci=0.05693, kci=2 * 0.02986 - 0.05693),
        _run("p2-man6", 1, e_obj=e1, gci=0.05489, kci=2 * 0.03033 - 0.05489),
    ]


@pytest.mark.parametrize("e0, e1", [(1.2e-13, 1.6e-13), (1.6e-13, 1.2e-13)])
def test_best_of_runs_that_reach_every_pose_is_by_the_rank_figures_not_the_noise(
    e0: float, e1: float
) -> None:
    """Converged pose errors are rounding noise: whichever is smaller, the run with the
    better mean is the topology's row."""
    rows = _records(_p2_man6(e0, e1))
    assert rows[0]["best_run"] == 1
    assert rows[0]["gci"] == 0.05489 and rows[0]["mean"] == pytest.approx(0.03033)
    (ref,) = _records(_p2_man6(1.2e-13, 1.6e-13))
    assert {**rows[0], "e_obj": None} == {**ref, "e_obj": None}


def test_runs_equal_up_to_rounding_tie_to_the_first_run() -> None:
    """Two runs that found the same design (figures equal within rounding) report the
    first run, whichever of them rounding made slightly better."""
    for sign in (1.0, -1.0):
        gci = 0.05 * (1 + sign * 10 * np.finfo(float).eps)
        a = _run("t", 0, gci=0.05, e_obj=3e-13)
        b = _run("t", 1, gci=gci, e_obj=1e-13)
        assert best_run([a, b], "mean") == 0
        assert best_run([b, a], "mean") == 1  # the index of run 0 in the given order
    # a real difference, far above SAME_FIGURE, is not a tie
    better = _run("t", 1, gci=0.05 * (1 + 1e3 * SAME_FIGURE))
    assert best_run([_run("t", 0), better], "mean") == 1


def test_most_poses_reached_first_then_the_pose_error() -> None:
    full = _run("t", 2, gci=0.01, e_obj=2e-13)
    near = _run("t", 0, reached=19, gci=0.09, e_obj=0.02)
    assert best_run([near, full], "mean") == 1  # every pose beats better figures
    far = _run("t", 1, reached=19, gci=0.09, e_obj=0.01)
    assert best_run([near, far], "mean") == 1  # short of a pose: the smaller error
    failed = _failed(_run("t", 3))
    assert best_run([failed, near], "gci") == 1


def test_rank_key_decides_between_runs_that_reach_every_pose() -> None:
    small = _run("t", 0, gci=0.04, length=6.0)
    good = _run("t", 1, gci=0.06, length=9.0)
    assert best_run([small, good], "mean") == 1
    assert best_run([small, good], "length") == 0
    assert best_run([small, good], "size") == 0
    nan = _run("t", 2, gci=math.nan)  # a figure not taken is the worst
    assert best_run([nan, small], "gci") == 1


def _mixed() -> list[ItemResult]:
    """Three topologies, three runs each: reaching, infeasible and failed runs."""
    out = _p2_man6(1.6e-13, 1.2e-13)
    out.append(_run("p2-man6", 2, reached=17, gci=0.08, e_obj=0.3))
    out += [_run("p2-man1", r, gci=0.07 - 0.01 * r, e_obj=(3 - r) * 1e-13) for r in range(3)]
    out += [
        _run("p2-man4", 0, reached=18, e_obj=0.16),
        _run("p2-man4", 1, reached=19, e_obj=0.4),
        _failed(_run("p2-man4", 2)),
    ]
    return out


def test_round_table_is_the_same_for_every_arrival_order() -> None:
    runs = _mixed()
    ref = _records(runs)
    assert [r["topology"] for r in ref] == ["p2-man1", "p2-man6", "p2-man4"]
    assert [r["best_run"] for r in ref] == [0, 1, 1]
    rng = np.random.default_rng(7)
    orders = [runs[::-1]] + [[runs[i] for i in rng.permutation(len(runs))] for _ in range(30)]
    for order in orders:
        assert _records(order) == ref


@pytest.mark.parametrize("kind", ["memory", "sqlite"])
def test_stores_written_in_any_order_give_the_same_table(kind: str, tmp_path: Path) -> None:
    """Runs written to a store in completion order (any order) read back, and rank, the
    same: the store orders by round, topology and run."""
    runs = _mixed()
    ref = _records(runs)
    for i, order in enumerate(itertools.islice(itertools.permutations(runs), 0, None, 40000)):
        store = MemoryStore() if kind == "memory" else SweepStore(tmp_path / f"{i}.db")
        store.open_sweep("s", {}, [(n, n, n) for n in ("p2-man1", "p2-man4", "p2-man6")])
        for r in order:
            assert store.write("s", r)
        back = store.results("s", 1)
        assert [r.key for r in back] == sorted(r.key for r in runs)
        assert _records(back) == ref
        if isinstance(store, SweepStore):
            store.close()


# ---- a pool that hands runs back in a forced order ----------------------------------------------
class ForcedOrder(Executor):
    """An executor that hands each round's runs back in a chosen order, one at a time.

    It computes nothing: a submitted batch is answered with the stored results of a
    reference sweep (the same runs). Once all ``rounds[i]`` batches of a round are
    submitted, a feeder thread completes them in ``order(n)``, each only after the sweep
    has stored the previous one (its ``item`` events, passed to :meth:`stored`): the
    arrival order is exactly the forced one, by synchronization alone.
    """

    def __init__(
        self,
        reference: dict[tuple[str, int, int], ItemResult],
        rounds: list[int],
        order: Callable[[int], list[int]],
    ) -> None:
        self._ref = reference
        self._rounds = rounds
        self._order = order
        self._submitted: list[tuple[Future[list[ItemResult]], list[WorkItem]]] = []
        self._cond = threading.Condition()
        self._stored = 0
        self._closed = False
        self.arrivals: list[tuple[str, int, int]] = []  # as the sweep stored them
        self.handed: list[tuple[str, int, int]] = []  # as this executor handed them back
        threading.Thread(target=self._feed, daemon=True).start()

    def submit(self, fn: Any, /, *args: Any, **kwargs: Any) -> Future[Any]:
        f: Future[list[ItemResult]] = Future()
        with self._cond:
            self._submitted.append((f, list(args[0])))
            self._cond.notify_all()
        return f

    def stored(self, e: SweepEvent) -> None:
        if e.kind == "item" and e.result is not None:
            with self._cond:
                self.arrivals.append(e.result.key)
                self._stored += 1
                self._cond.notify_all()

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        """Let the feeder end (a sweep that stopped early stores nothing more)."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()

    def _wait(self, ready: Callable[[], bool]) -> bool:
        """Wait for ``ready``; ``False`` when shut down first."""
        with self._cond:
            self._cond.wait_for(lambda: self._closed or ready())
            return not self._closed

    def _feed(self) -> None:
        start = 0
        for n in self._rounds:
            if not self._wait(lambda k=start + n: len(self._submitted) >= k):  # type: ignore[misc]
                return
            for i in self._order(n):
                f, items = self._submitted[start + i]
                with self._cond:
                    after = self._stored + len(items)
                    self.handed += [(it.topology, it.round, it.run) for it in items]
                f.set_result([self._ref[(it.topology, it.round, it.run)] for it in items])
                if not self._wait(lambda k=after: self._stored >= k):  # type: ignore[misc]
                    return
            start += n


def _tasks() -> tuple[Task, list[Topology]]:
    from tests.synthesis.test_sweep import generated_task

    return generated_task(k=12)[0], topologies_from_specs(["RRPRRR", "RRRRRR", "PRRRRR"])


def test_a_pool_handing_runs_back_in_any_order_gives_the_same_sweep() -> None:
    """A two-round sweep whose runs arrive reversed, interleaved or shuffled gives the
    in-process sweep's tables (both rounds, which topologies advanced, best runs)."""
    task, topos = _tasks()
    cfg = SweepConfig(subset=6, top=2, runs=2)
    ref_store = MemoryStore()
    ref = run_sweep(task, topos, cfg, workers=0, store=ref_store)
    assert ref.round1 is not None
    stored = {r.key: r for r in ref_store.results(ref.sweep_id)}
    rounds = [len(topos) * cfg.runs, len(ref.advanced) * cfg.runs]
    rng = np.random.default_rng(3)
    orders: list[Callable[[int], list[int]]] = [
        lambda n: list(range(n))[::-1],
        lambda n: list(range(1, n, 2)) + list(range(0, n, 2)),  # every run 1 before run 0
        lambda n: [int(i) for i in rng.permutation(n)],
    ]
    for order in orders:
        ex = ForcedOrder(stored, rounds, order)
        res = run_sweep(task, topos, cfg, executor=ex, on_event=ex.stored)
        assert ex.arrivals == ex.handed and len(ex.arrivals) == sum(rounds)
        assert res.advanced == ref.advanced
        assert res.final.best == ref.final.best and res.round1 is not None
        assert res.round1.best == ref.round1.best
        assert json.dumps(res.table()) == json.dumps(ref.table())


def test_a_run_from_other_code_is_refused_not_stored() -> None:
    """A worker that imported another checkout (or other libraries) is named with what
    differs, and its run is not stored: the sweep would not be reproducible."""
    task, topos = _tasks()
    cfg = SweepConfig(runs=1)
    ref_store = MemoryStore()
    ref = run_sweep(task, topos[:2], cfg, workers=0, store=ref_store)
    stored = {r.key: r for r in ref_store.results(ref.sweep_id)}
    assert {r.versions["source"] for r in stored.values()} == {source_fingerprint()}
    odd = (topos[0].name, ROUND_FULL, 0)  # the first run submitted, and handed back
    stored[odd] = replace(stored[odd], versions={**stored[odd].versions, "source": "0" * 16})
    ex = ForcedOrder(stored, [len(stored)], lambda n: list(range(n)))
    store = MemoryStore()
    with pytest.raises(
        InputError, match=re.escape(f"run 0 of '{odd[0]}'") + ".*source 0{16}"
    ) as err:
        run_sweep(task, topos[:2], cfg, executor=ex, store=store, on_event=ex.stored)
    ex.shutdown()
    assert source_fingerprint() in str(err.value)
    assert store.results(ref.sweep_id) == []


def test_the_source_fingerprint_follows_every_file(tmp_path: Path) -> None:
    """An edit, a new file or a rename changes the fingerprint; other files do not."""
    import reachwise

    (tmp_path / "sub").mkdir()
    (tmp_path / "a.py").write_text("x = 1\n")
    (tmp_path / "sub" / "b.py").write_text("y = 2\n")
    (tmp_path / "notes.txt").write_text("not code")
    base = tree_fingerprint(tmp_path)
    (tmp_path / "notes.txt").write_text("changed")
    assert tree_fingerprint(tmp_path) == base
    (tmp_path / "sub" / "b.py").write_text("y = 3\n")
    edited = tree_fingerprint(tmp_path)
    assert edited != base
    (tmp_path / "sub" / "b.py").rename(tmp_path / "sub" / "c.py")
    assert tree_fingerprint(tmp_path) not in (base, edited)
    assert source_fingerprint() == tree_fingerprint(Path(reachwise.__file__).parent)
