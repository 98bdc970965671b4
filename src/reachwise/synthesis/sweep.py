"""The topology sweep: two rounds of dimensional synthesis over many topologies (P-II Fig. 1).

P-II §2 and Fig. 1 (thesis §4.2, §5.1): define the task and a descriptive subset of it;
run the dimensional synthesis of every candidate topology on the subset (round 1);
order the feasible ones — those reaching every subset point — by the chosen measure;
run the best ``K`` on the complete task (round 2) and rank them again (P-II Table 2).
Without a subset (``SweepConfig.subset = None``) every topology goes straight to the
complete task, P-II's "somewhat simplified process".

**Work items.** One item is one multi-start run ``(topology, round, run)`` with seed
``config.seed + run`` (the same seeds for every topology, as in ``synthesize``): a
picklable, pure ``WorkItem`` → ``ItemResult`` (``run_item``). Items go to any
``concurrent.futures.Executor`` in batches of ``config.batch_size`` (``run_batch``):
by default a local ``ProcessPoolExecutor`` on all cores (spawned workers that ignore
Ctrl-C and exit when the sweep's process dies), or a Dask cluster through
``dask_executor`` (``client.get_executor()``; the ``cluster`` extra). A batch of 1
(default) hands every finished run to the store at once; larger batches cut the
per-submission overhead of a remote cluster when runs are short, at the price of
re-running a killed batch.

**Results store.** Every finished item is written to the store in one transaction as
soon as it arrives (``reachwise.io.sweep_store.SweepStore``, SQLite; any object with the
``ResultStore`` methods works). Items already in the store are skipped, so running the
same sweep again resumes it; the tables are always built from the store, so a resumed
sweep gives the table of an uninterrupted one. Items are keyed by the sweep's
fingerprint (task, subset, seed, solver settings — not ``runs``, ``top`` or the rank
key, so more runs or a larger ``K`` reuse what is done).

Timing: ``run_item`` records each run's wall time (``ItemResult.wall_s``); nothing
below this layer reads a clock. Results do not depend on the executor, the number of
workers or the batch size: a fixed seed gives identical results.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import platform
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Executor, Future, wait
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field, replace
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import InputError, MissingDependency, ReachwiseError, check_choice
from reachwise.kinematics.robot import Robot
from reachwise.synthesis.problem import SynthesisProblem
from reachwise.synthesis.rank import (
    Candidate,
    Measures,
    RankedRow,
    RankKey,
    best_run_index,
    check_key,
)
from reachwise.synthesis.rank import measures as design_measures
from reachwise.synthesis.rank import rank as rank_candidates
from reachwise.synthesis.solvers import SolverOptions
from reachwise.synthesis.synthesize import SOLVERS, SolverName, run_once
from reachwise.synthesis.topology import Topology
from reachwise.tasks.task import Task

Array = NDArray[np.float64]
ROUND_SUBSET = 1
ROUND_FULL = 2


# ---- configuration and work items --------------------------------------------------------
@dataclass(frozen=True)
class SweepConfig:
    """How a sweep runs (P-II Fig. 1).

    ``subset``: size of the descriptive subset for round 1 (``tasks.select``), ``None``
    for one round on the complete task; ``top``: how many feasible topologies go on to
    the complete task; ``runs``: multi-start runs per topology and round (seeds
    ``seed … seed + runs − 1``); ``rank_key``: one of ``rank.RANK_KEYS``; ``workspace``:
    keep the links inside the task's envelope (the tunnel); ``batch_size``: runs per
    submitted batch.
    """

    subset: int | None = None
    top: int = 3
    runs: int = 3
    seed: int = 0
    solver: SolverName = "dls"
    init_sets: int = 8
    rank_key: RankKey = "mean"
    workspace: bool = True
    options: SolverOptions | None = None
    batch_size: int = 1

    def __post_init__(self) -> None:
        if self.subset is not None and self.subset < 1:
            raise InputError("sweep", "subset", "must be >= 1 (or None for no subset)")
        if self.top < 1:
            raise InputError("sweep", "top", "must be >= 1")
        if self.runs < 1:
            raise InputError("sweep", "runs", "must be >= 1")
        check_choice(self.solver, SOLVERS, source="sweep", kind="solver")
        if self.init_sets < 1:
            raise InputError("sweep", "init_sets", "must be >= 1")
        if self.batch_size < 1:
            raise InputError("sweep", "batch_size", "must be >= 1")
        check_key(self.rank_key)


@dataclass(frozen=True, eq=False)
class WorkItem:
    """One run to do: picklable and self-contained (template and task travel with it)."""

    topology: str
    round: int
    run: int
    seed: int
    template: Robot
    task: Task
    solver: SolverName = "dls"
    init_sets: int = 8
    options: SolverOptions | None = None
    workspace: bool = True


@dataclass(frozen=True, eq=False)
class ItemResult:
    """What one run produced (stored as one row). ``error`` is non-empty when the
    synthesis raised; then ``measures`` is ``None`` and nothing is reached."""

    topology: str
    round: int
    run: int
    seed: int
    n_points: int
    n_reached: int
    e_obj: float
    iterations: int
    converged: bool
    measures: Measures | None
    design_names: tuple[str, ...]
    design: tuple[float, ...]
    q: Array
    status: tuple[str, ...]
    max_position_error: float
    max_orientation_error: float
    error: str = ""
    wall_s: float = 0.0
    worker: str = ""
    versions: dict[str, str] = field(default_factory=dict)

    @property
    def feasible(self) -> bool:
        return not self.error and self.n_reached == self.n_points

    @property
    def key(self) -> tuple[str, int, int]:
        return (self.topology, self.round, self.run)

    def same_outcome(self, other: ItemResult) -> bool:
        """Equal apart from timing, worker and versions (the deterministic part)."""
        return (
            self.key == other.key
            and self.seed == other.seed
            and self.n_reached == other.n_reached
            and _same_float(self.e_obj, other.e_obj)
            and self.iterations == other.iterations
            and self.converged == other.converged
            and self.measures == other.measures
            and self.design_names == other.design_names
            and self.design == other.design
            and self.status == other.status
            and np.array_equal(self.q, other.q)
            and self.error == other.error
        )


def _same_float(a: float, b: float) -> bool:
    return a == b or (math.isnan(a) and math.isnan(b))


def versions() -> dict[str, str]:
    """Versions the results were computed with (stored per item)."""
    import scipy

    from reachwise._version import __version__

    return {
        "reachwise": __version__,
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "python": platform.python_version(),
    }


def run_item(item: WorkItem) -> ItemResult:
    """One synthesis run of one topology (``synthesize.run_once``) and its measures
    (P-II Eq. 38–39, ``rank.measures``). Pure apart from its wall-time record."""
    t0 = time.perf_counter()
    problem: SynthesisProblem | None = None
    try:
        problem = SynthesisProblem(item.template, item.task)
        ws = item.task.envelope if item.workspace else None
        r = run_once(problem, item.seed, item.solver, item.init_sets, item.options, ws)
        m = design_measures(r.robot, r.q)
        res = ItemResult(
            topology=item.topology,
            round=item.round,
            run=item.run,
            seed=item.seed,
            n_points=problem.K,
            n_reached=r.n_reached,
            e_obj=r.e_obj,
            iterations=r.iterations,
            converged=r.converged,
            measures=m,
            design_names=problem.design_names,
            design=tuple(float(v) for v in r.design),
            q=np.asarray(r.q, dtype=np.float64),
            status=r.status,
            max_position_error=float(np.max(r.position_error)),
            max_orientation_error=float(np.max(r.orientation_error)),
        )
    except (ReachwiseError, ValueError, ArithmeticError) as exc:
        res = ItemResult(
            topology=item.topology,
            round=item.round,
            run=item.run,
            seed=item.seed,
            n_points=len(item.task),
            n_reached=0,
            e_obj=math.inf,
            iterations=0,
            converged=False,
            measures=None,
            design_names=() if problem is None else problem.design_names,
            design=(),
            q=np.zeros((0, 0)),
            status=(),
            max_position_error=math.inf,
            max_orientation_error=math.inf,
            error=f"{type(exc).__name__}: {exc}",
        )
    wall = time.perf_counter() - t0
    return replace(res, wall_s=wall, worker=f"{platform.node()}:{os.getpid()}", versions=versions())


def run_batch(items: Sequence[WorkItem]) -> list[ItemResult]:
    """Run a batch of items in order (the unit submitted to an executor)."""
    return [run_item(it) for it in items]


# ---- fingerprints ---------------------------------------------------------------------------
def _h(*parts: bytes) -> str:
    h = hashlib.sha256()
    for p in parts:
        h.update(len(p).to_bytes(8, "little"))
        h.update(p)
    return h.hexdigest()


def task_fingerprint(task: Task) -> str:
    """Hash of everything about a task that changes a synthesis."""
    return _h(
        np.ascontiguousarray(task.poses, dtype="<f8").tobytes(),
        np.ascontiguousarray(task.dims, dtype="<i8").tobytes(),
        np.ascontiguousarray(task.tol_position, dtype="<f8").tobytes(),
        np.ascontiguousarray(task.tol_orientation, dtype="<f8").tobytes(),
        repr(task.envelope).encode(),
    )


def template_fingerprint(robot: Robot) -> str:
    """Hash of a template's kinematics, limits and design space."""
    joints = [(j.type, j.a, j.alpha, j.d, j.theta, j.limits, j.passive) for j in robot.joints]
    d = robot.design
    design = (
        [(j, sorted(d.joints[j].items())) for j in sorted(d.joints)],
        sorted(d.base.items()),
    )
    return _h(
        repr((robot.convention, joints, design)).encode(),
        np.ascontiguousarray(robot.base, dtype="<f8").tobytes(),
        np.ascontiguousarray(robot.tool, dtype="<f8").tobytes(),
    )


def sweep_fingerprint(task: Task, subset: NDArray[np.intp] | None, config: SweepConfig) -> str:
    """The sweep id: task, subset, seed and solver settings (not runs, top, rank key)."""
    opts = None if config.options is None else asdict(config.options)
    spec = {
        "task": task_fingerprint(task),
        "subset": None if subset is None else [int(i) for i in subset],
        "seed": config.seed,
        "solver": config.solver,
        "init_sets": config.init_sets,
        "workspace": config.workspace,
        "options": opts,
    }
    return _h(json.dumps(spec, sort_keys=True).encode())[:16]


# ---- the store interface ------------------------------------------------------------------
class ResultStore(Protocol):
    """What the sweep needs from a results store (``io.sweep_store.SweepStore``)."""

    def open_sweep(
        self, sweep_id: str, meta: dict[str, Any], topologies: Sequence[tuple[str, str, str]]
    ) -> None: ...

    def done(self, sweep_id: str, round: int) -> set[tuple[str, int]]: ...

    def write(self, sweep_id: str, result: ItemResult) -> bool: ...

    def results(self, sweep_id: str, round: int | None = None) -> list[ItemResult]: ...


# ---- tables ---------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class RoundTable:
    """The ranked table of one round: rows (``rank.RankedRow``) and, per topology, its
    runs and the index of its best run (``rank.best_run_index``)."""

    round: int
    task_points: int
    rank_key: RankKey
    rows: tuple[RankedRow, ...]
    runs: dict[str, tuple[ItemResult, ...]]
    best: dict[str, int]

    def best_result(self, name: str) -> ItemResult:
        return self.runs[name][self.best[name]]

    def records(self) -> list[dict[str, Any]]:
        """Plain rows (rank, topology, feasibility, GCI, KCI, mean, …) for reports."""
        out = []
        for row in self.rows:
            c = row.candidate
            b = self.best_result(c.name)
            m = c.measures
            runs = self.runs[c.name]
            out.append(
                {
                    "rank": row.rank,
                    "topology": c.name,
                    "round": self.round,
                    "feasible": c.feasible,
                    "reached": c.n_reached,
                    "points": c.n_points,
                    "gci": None if m is None else m.gci,
                    "kci": None if m is None else m.kci,
                    "mean": None if m is None else m.mean,
                    "manipulability": None if m is None else m.manipulability,
                    "length": None if m is None else m.length,
                    "prismatic": None if m is None else m.prismatic,
                    "e_obj": c.e_obj,
                    "best_run": b.run,
                    "best_seed": b.seed,
                    "runs": len(runs),
                    "runs_feasible": sum(r.feasible for r in runs),
                    "error": b.error,
                    "note": "" if c.feasible else "error" if b.error else "infeasible",
                }
            )
        return out


def round_table(results: Sequence[ItemResult], round: int, key: RankKey) -> RoundTable:
    """Rank the topologies of one round from their runs (best run per topology)."""
    by: dict[str, list[ItemResult]] = {}
    for r in results:
        if r.round == round:
            by.setdefault(r.topology, []).append(r)
    runs = {k: tuple(sorted(v, key=lambda r: r.run)) for k, v in sorted(by.items())}
    best = {
        k: best_run_index([r.n_reached for r in v], [r.e_obj for r in v]) for k, v in runs.items()
    }
    cands = []
    points = 0
    for k, v in runs.items():
        b = v[best[k]]
        points = max(points, b.n_points)
        cands.append(Candidate(k, b.n_reached, b.n_points, b.measures, b.e_obj))
    return RoundTable(round, points, key, rank_candidates(cands, key), runs, best)


@dataclass(frozen=True, eq=False)
class SweepResult:
    """A finished sweep: the tables of both rounds, which topologies advanced, and the
    final table (round 2, the complete task)."""

    sweep_id: str
    task: Task
    subset: NDArray[np.intp] | None
    config: SweepConfig
    topologies: dict[str, Topology]
    round1: RoundTable | None
    final: RoundTable
    advanced: tuple[str, ...]
    new_items: int = 0
    stored_items: int = 0

    def ranked(self) -> list[str]:
        """Names of the feasible topologies of the final table, best first."""
        return [r.candidate.name for r in self.final.rows if r.rank is not None]

    def robot(self, name: str, round: int = ROUND_FULL) -> Robot:
        """The optimized design of a topology's best run (base frame included)."""
        table = self.final if round == ROUND_FULL else self.round1
        if table is None or name not in table.runs:
            raise InputError("sweep", "topology", f"{name!r} has no result in round {round}")
        best = table.best_result(name)
        if best.error:
            raise InputError("sweep", "topology", f"{name!r} failed: {best.error}")
        template = self.topologies[name].template
        probe = SynthesisProblem(template, self.task)
        if probe.design_names != best.design_names:
            raise InputError("sweep", "topology", f"{name!r}: stored design does not fit")
        return probe.robot_at(np.array(best.design), name=f"{template.name}-synth")

    def table(self) -> list[dict[str, Any]]:
        """The final ranked table (ranked, then infeasible), plus round-1 rows of the
        topologies that did not advance (``round`` 1, ``rank`` None, ``note`` "not
        advanced" when feasible on the subset but outside the top ``K``)."""
        rows = self.final.records()
        if self.round1 is not None:
            adv = set(self.advanced)
            for r in self.round1.records():
                if r["topology"] not in adv:
                    note = r["note"] or "not advanced"
                    rows.append({**r, "rank": None, "note": note})
        return rows


# ---- events (progress) ----------------------------------------------------------------------
@dataclass(frozen=True)
class SweepEvent:
    """Progress: ``kind`` is ``round`` (a round starts: ``total`` topologies, ``done``
    already finished in the store), ``topology`` (a topology finished all its runs in
    ``round``) or ``item`` (one run finished; ``result`` set)."""

    kind: str
    round: int
    total: int = 0
    done: int = 0
    topology: str = ""
    result: ItemResult | None = None


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C during a sweep: what finished is stored; run the same sweep to resume."""


# ---- executors --------------------------------------------------------------------------------
def _watch_parent(parent: int) -> None:  # pragma: no cover - runs in worker processes
    while True:
        time.sleep(1.0)
        if os.getppid() != parent:
            os._exit(1)


def _worker_init(parent: int) -> None:  # pragma: no cover - runs in worker processes
    """Process-pool worker: leave Ctrl-C to the sweep (it stops submitting and waits for
    the running items); exit when the sweep's process is gone (killed)."""
    import signal
    import threading

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threading.Thread(target=_watch_parent, args=(parent,), daemon=True).start()


def process_pool(workers: int | None = None) -> Executor:
    """A local process pool (spawned workers, ``workers`` defaults to all cores)."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    n = workers or os.cpu_count() or 1
    return ProcessPoolExecutor(
        max_workers=n,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=_worker_init,
        initargs=(os.getpid(),),
    )


@contextmanager
def dask_executor(address: str, workers: int | None = None) -> Iterator[Executor]:
    """A ``concurrent.futures`` executor on a Dask cluster (``client.get_executor()``).

    ``address`` ``tcp://HOST:8786`` connects to a running scheduler; ``local`` starts a
    ``LocalCluster`` of ``workers`` single-threaded worker processes bound to 127.0.0.1
    with the dashboard off, and closes it afterwards. Needs the ``cluster`` extra
    (``pip install "reachwise[cluster]"``, i.e. ``dask[distributed]``).
    """
    try:
        from distributed import Client, LocalCluster
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise MissingDependency("distributed", "cluster", "a sweep on a Dask cluster") from exc
    if address == "local":
        n = workers or os.cpu_count() or 1
        cluster = LocalCluster(
            n_workers=n,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
        )
        client = Client(cluster)
        try:
            yield client.get_executor(pure=False)
        finally:
            client.close()
            cluster.close()
    else:
        client = Client(address)
        try:
            yield client.get_executor(pure=False)
        finally:
            client.close()


# ---- the sweep --------------------------------------------------------------------------------
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
    this process. ``store``: where finished items go and are skipped from (default an
    in-memory SQLite store). Ctrl-C: pending items are cancelled, running ones are
    awaited and stored, then ``SweepInterrupted`` is raised.
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
        from reachwise.io.sweep_store import SweepStore

        store = SweepStore(":memory:")
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
    counts = [0, 0]  # items run now, items found in the store
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
    return SweepResult(
        sid, task, subset, cfg, by_name, round1, final, advanced, counts[0], counts[1]
    )


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
    done = store.done(sid, round)
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
                )
            )
            left[t.name] = left.get(t.name, 0) + 1
    finished = len(topologies) - len(left)
    counts[1] += len(topologies) * cfg.runs - len(todo)
    emit(SweepEvent("round", round, total=len(topologies), done=finished))

    def accept(res: ItemResult) -> None:
        nonlocal finished
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
