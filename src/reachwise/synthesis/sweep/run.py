"""``run_sweep``: the two-round loop of P-II Fig. 1 over an executor and a store."""

from __future__ import annotations

from collections.abc import Callable, Collection, Sequence
from concurrent.futures import FIRST_COMPLETED, Executor, Future, wait
from dataclasses import asdict, dataclass
from typing import Any

from reachwise.errors import InputError
from reachwise.synthesis.rank import RankedRow
from reachwise.synthesis.sweep.config import ROUND_FULL, ROUND_SUBSET, SweepConfig
from reachwise.synthesis.sweep.executors import process_pool
from reachwise.synthesis.sweep.fingerprint import sweep_fingerprint, template_fingerprint
from reachwise.synthesis.sweep.items import ItemResult, WorkItem, run_batch, versions
from reachwise.synthesis.sweep.store import MemoryStore, ResultStore
from reachwise.synthesis.sweep.tables import RoundTable, SweepResult, round_table
from reachwise.synthesis.topology.sets import Topology
from reachwise.tasks.task import Task


@dataclass(frozen=True)
class SweepEvent:
    """Progress: ``kind`` is ``round`` (a round starts: ``total`` topologies, ``done``
    already finished in the store, ``stale`` stored runs computed by other code or
    libraries that this round runs again), ``topology`` (a topology finished all its runs
    in ``round``) or ``item`` (one run finished; ``result`` set)."""

    kind: str
    round: int
    total: int = 0
    done: int = 0
    topology: str = ""
    result: ItemResult | None = None
    stale: int = 0


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C during a sweep: what finished is stored; run the same sweep to resume."""


def run_sweep(
    task: Task,
    topologies: Sequence[Topology],
    config: SweepConfig | None = None,
    *,
    executor: Executor | None = None,
    workers: int | None = None,
    store: ResultStore | None = None,
    on_event: Callable[[SweepEvent], None] | None = None,
) -> SweepResult:
    """Run (or resume) the two-round sweep of P-II Fig. 1 and return its tables.

    ``executor``: any ``concurrent.futures.Executor`` (not shut down here); without one a
    ``process_pool(workers)`` is made and closed, and ``workers=0`` runs every item in
    this process. ``store``: where finished items go and are skipped from: any
    ``ResultStore`` (the CLI passes ``reachwise.results.sweep_store.SweepStore``, a resumable
    SQLite file); default a ``MemoryStore`` that lives as long as this call. Ctrl-C:
    pending items are cancelled, running ones are awaited and stored, then
    ``SweepInterrupted`` is raised.

    Resuming keeps the stored runs computed by this code and these libraries (their
    ``versions`` equal :func:`~reachwise.synthesis.sweep.items.versions` of this process)
    and runs the others again, replacing their rows: a store written by another checkout,
    another numpy or scipy, or before runs recorded their source hash gives the table this
    code computes. The ``round`` event and ``SweepResult.stale_items`` say how many.
    """
    from reachwise.tasks.select import descriptive_subset

    cfg = config or SweepConfig()
    topos = list(topologies)
    if not topos:
        raise InputError("sweep", "topologies", "no topology to sweep")
    names = [t.name for t in topos]
    if len(set(names)) != len(names):
        raise InputError("sweep", "topologies", "topology names must be unique")
    by_name = {t.name: t for t in topos}
    subset = None
    if cfg.subset is not None and cfg.subset < len(task):
        subset = descriptive_subset(task, cfg.subset)
    sid = sweep_fingerprint(task, subset, cfg)
    if store is None:
        store = MemoryStore()
    meta = {
        "task": task.name,
        "task_points": len(task),
        "subset": None if subset is None else [int(i) for i in subset],
        "config": _config_json(cfg),
        "versions": versions(),
    }
    store.open_sweep(
        sid, meta, [(t.name, str(t.spec), template_fingerprint(t.template)) for t in topos]
    )
    emit = on_event or (lambda e: None)

    owned = executor is None and workers != 0
    ex = process_pool(workers) if owned else executor
    counts = [0, 0, 0]  # items run now, items found in the store, stale items run again
    try:
        round1: RoundTable | None = None
        if subset is not None:
            sub_task = task.subset(subset, name=f"{task.name}[subset {len(subset)}]")
            _run_round(store, sid, sub_task, ROUND_SUBSET, topos, cfg, ex, emit, counts)
            round1 = _restrict(_table(store, sid, ROUND_SUBSET, cfg), names)
            advanced = tuple(r.candidate.name for r in round1.rows if r.rank is not None)[: cfg.top]
        else:
            advanced = tuple(names)
        adv = [by_name[n] for n in advanced]
        _run_round(store, sid, task, ROUND_FULL, adv, cfg, ex, emit, counts)
        final = _restrict(_table(store, sid, ROUND_FULL, cfg), advanced)
    finally:
        if owned and ex is not None:
            ex.shutdown(wait=True, cancel_futures=True)
    return SweepResult(sid, task, subset, cfg, by_name, round1, final, advanced, *counts)


def _table(store: ResultStore, sid: str, round: int, cfg: SweepConfig) -> RoundTable:
    """A round's table from the store, over runs ``0 … cfg.runs − 1`` only (a store may
    hold more runs from an earlier, longer sweep)."""
    res = [r for r in store.results(sid, round) if r.run < cfg.runs]
    return round_table(res, round, cfg.rank_key)


def _restrict(table: RoundTable, names: Sequence[str]) -> RoundTable:
    """The table limited to the topologies of this sweep (a store may hold more), ranks
    renumbered."""
    keep = set(names)
    runs = {k: v for k, v in table.runs.items() if k in keep}
    best = {k: v for k, v in table.best.items() if k in keep}
    rows = tuple(r for r in table.rows if r.candidate.name in keep)
    ranked = [r for r in rows if r.rank is not None]
    rows = tuple(RankedRow(i + 1, r.candidate) for i, r in enumerate(ranked)) + tuple(
        r for r in rows if r.rank is None
    )
    return RoundTable(table.round, table.task_points, table.rank_key, rows, runs, best)


def _config_json(cfg: SweepConfig) -> dict[str, Any]:
    return asdict(cfg)


def _work_items(
    done: Collection[tuple[str, int]],
    task: Task,
    round: int,
    topologies: Sequence[Topology],
    cfg: SweepConfig,
) -> tuple[list[WorkItem], dict[str, int]]:
    """The round's runs not in ``done`` (``(topology, run)`` pairs already stored), in
    order, and how many each topology has left."""
    todo: list[WorkItem] = []
    left: dict[str, int] = {}
    for t in topologies:
        for run in range(cfg.runs):
            if (t.name, run) in done:
                continue
            todo.append(
                WorkItem(
                    topology=t.name,
                    round=round,
                    run=run,
                    seed=cfg.seed + run,
                    template=t.template,
                    task=task,
                    solver=cfg.solver,
                    init_sets=cfg.init_sets,
                    options=cfg.options,
                    workspace=cfg.workspace,
                    objective=cfg.objective,
                    clearance=cfg.clearance,
                )
            )
            left[t.name] = left.get(t.name, 0) + 1
    return todo, left


def _stale_runs(
    store: ResultStore,
    sid: str,
    round: int,
    topologies: Sequence[Topology],
    cfg: SweepConfig,
    own: dict[str, str],
) -> set[tuple[str, int]]:
    """``(topology, run)`` of the round's stored runs computed with other code or libraries
    than this process's (``versions`` differ, or lack the source hash, as in stores written
    before it was kept): their designs need not be the ones this code finds."""
    names = {t.name for t in topologies}
    return {
        (r.topology, r.run)
        for r in store.results(sid, round)
        if r.topology in names and r.run < cfg.runs and r.versions != own
    }


def _check_versions(res: ItemResult, own: dict[str, str]) -> None:
    """Refuse a run computed with other code or libraries than this sweep's process (a
    checkout changed while the workers started, a cluster worker with another numpy):
    its design would differ from the one this sweep reproduces. Nothing of it is stored."""
    if res.versions == own:
        return
    diff = ", ".join(
        f"{k} {res.versions.get(k, '?')} (sweep: {own.get(k, '?')})"
        for k in sorted(set(own) | set(res.versions))
        if res.versions.get(k) != own.get(k)
    )
    raise InputError(
        "sweep",
        f"run {res.run} of {res.topology!r} (round {res.round}) from {res.worker or '?'}",
        f"computed with other code or libraries than this sweep: {diff}; its result would "
        "not be reproducible. Rerun the sweep on one checkout (finished runs are stored)",
    )


def _run_round(
    store: ResultStore,
    sid: str,
    task: Task,
    round: int,
    topologies: Sequence[Topology],
    cfg: SweepConfig,
    ex: Executor | None,
    emit: Callable[[SweepEvent], None],
    counts: list[int],
) -> None:
    own = versions()
    stale = _stale_runs(store, sid, round, topologies, cfg, own)
    todo, left = _work_items(store.done(sid, round) - stale, task, round, topologies, cfg)
    finished = len(topologies) - len(left)
    counts[1] += len(topologies) * cfg.runs - len(todo)
    counts[2] += len(stale)
    emit(SweepEvent("round", round, total=len(topologies), done=finished, stale=len(stale)))

    def accept(res: ItemResult) -> None:
        nonlocal finished
        _check_versions(res, own)
        store.write(sid, res)
        counts[0] += 1
        emit(SweepEvent("item", round, topology=res.topology, result=res))
        left[res.topology] -= 1
        if left[res.topology] == 0:
            finished += 1
            emit(SweepEvent("topology", round, len(topologies), finished, res.topology))

    batches = [todo[i : i + cfg.batch_size] for i in range(0, len(todo), cfg.batch_size)]
    if ex is None:
        try:
            for b in batches:
                for res in run_batch(b):
                    accept(res)
        except KeyboardInterrupt:
            raise SweepInterrupted() from None
        return
    pending: set[Future[list[ItemResult]]] = {ex.submit(run_batch, b) for b in batches}
    try:
        while pending:
            ready, pending = wait(pending, return_when=FIRST_COMPLETED)
            for f in ready:
                for res in f.result():
                    accept(res)
    except KeyboardInterrupt:
        running = {f for f in pending if not f.cancel()}
        try:
            while running:
                ready, running = wait(running, return_when=FIRST_COMPLETED)
                for f in ready:
                    if not f.cancelled() and f.exception() is None:
                        for res in f.result():
                            accept(res)
        except KeyboardInterrupt:
            pass
        raise SweepInterrupted() from None
    except BaseException:
        for f in pending:
            f.cancel()
        raise
