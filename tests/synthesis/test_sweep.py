"""The two-round topology sweep (P-II Fig. 1, Table 2): ranking, resume, executors.

Affordability: the P-II test runs one run per topology on the complete ``tunnel-87``;
``reachwise bench sweep`` runs the full six topologies × 3 runs. The other tests use a
task generated from a known RRPRRR design (P-II's recovery idea, P-I §4).
"""

from __future__ import annotations

import json
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from reachwise import load_robot, load_task
from reachwise.errors import InputError
from reachwise.kinematics.robot import DesignSpace
from reachwise.results.sweep_store import SweepStore
from reachwise.synthesis.problem import SynthesisProblem
from reachwise.synthesis.sweep import (
    MemoryStore,
    SweepConfig,
    SweepEvent,
    SweepInterrupted,
    SweepResult,
    run_sweep,
    template_fingerprint,
    versions,
)
from reachwise.synthesis.topology import Topology, builtin_set, to_template, topologies_from_specs
from reachwise.tasks.task import Task

SPECS = ["RRPRRR", "RRPRRRP", "PRRRRR", "RRRRRR"]


def generated_task(k: int = 24, seed: int = 5) -> tuple[Task, np.ndarray]:
    """6-D poses of a random RRPRRR design (default twists) inside its bounds."""
    tmpl = to_template("RRPRRR")
    rng = np.random.default_rng(seed)
    probe = SynthesisProblem(tmpl, Task.from_arrays("probe", np.zeros((1, 3)), dims=3))
    lo, hi = probe.bounds
    p = probe.p
    design = lo[:p] + (hi[:p] - lo[:p]) * rng.uniform(0.15, 0.85, p)
    robot = probe.robot_at(design)
    Q = rng.uniform(0.9 * robot.lower, 0.9 * robot.upper, (k, robot.n))
    T = robot.fk(Q)
    task = Task.from_arrays(f"rrprrr-{k}", T[:, :3, 3], rotations=T[:, :3, :3], dims=6)
    return task, design


def _table(res: SweepResult) -> list[dict[str, Any]]:
    rows: list[dict[str, Any]] = json.loads(json.dumps(res.table()))
    return rows


@pytest.fixture(scope="module")
def gen() -> Task:
    return generated_task()[0]


@pytest.fixture(scope="module")
def two_round_reference(gen: Task) -> SweepResult:
    """An uninterrupted two-round sweep, in process."""
    cfg = SweepConfig(subset=8, top=2, runs=1)
    return run_sweep(gen, topologies_from_specs(SPECS), cfg, workers=0)


# ---- must show: P-II on tunnel-87 -----------------------------------------------------------
def test_p2_on_tunnel_87_ranked_with_gci_kci_mean_and_reproducible() -> None:
    task = load_task("tunnel-87")
    p2 = builtin_set("p2", load_robot)
    cfg = SweepConfig(runs=1)  # one round on the complete task, like P-II §5
    res = run_sweep(task, p2, cfg, workers=2)
    table = res.table()
    assert len(table) == 6 and {r["topology"] for r in table} == {t.name for t in p2}
    ranked = [r for r in table if r["rank"] is not None]
    infeasible = [r for r in table if r["rank"] is None]
    assert ranked and infeasible  # some reach all 87 points, some cannot
    assert [r["rank"] for r in ranked] == list(range(1, len(ranked) + 1))
    for r in ranked:
        assert r["feasible"] and r["reached"] == r["points"] == 87
        assert 0 < r["kci"] <= r["gci"] < 1
        assert r["mean"] == pytest.approx(0.5 * (r["gci"] + r["kci"]))
    assert [r["mean"] for r in ranked] == sorted((r["mean"] for r in ranked), reverse=True)
    for r in infeasible:
        assert not r["feasible"] and r["reached"] < 87 and r["note"] == "infeasible"
    assert table[: len(ranked)] == ranked  # infeasible rows come last
    # same seed, same table: a second sweep (new store, in this process) agrees exactly
    again = run_sweep(task, p2, cfg, workers=0)
    assert _table(again) == _table(res)


# ---- must show: recovery ---------------------------------------------------------------------
def test_recovery_finds_the_generating_topology_feasible() -> None:
    task, _ = generated_task()
    topos = topologies_from_specs(SPECS)
    res = run_sweep(task, topos, SweepConfig(runs=2), workers=0)
    gen_name = str(topos[0].spec)
    row = next(r for r in res.table() if r["topology"] == gen_name)
    assert row["feasible"] and row["rank"] is not None and row["reached"] == len(task)
    robot = res.robot(gen_name)
    best = res.final.best_result(gen_name)
    T = robot.fk(best.q)
    assert np.abs(T[:, :3, 3] - task.positions).max() < 1e-3


# ---- two rounds, resume, Ctrl-C ---------------------------------------------------------------
def test_two_rounds_rank_the_subset_then_the_best_k(
    gen: Task, two_round_reference: SweepResult
) -> None:
    res = two_round_reference
    assert res.subset is not None and len(res.subset) == 8
    assert res.round1 is not None and len(res.round1.rows) == 4
    r1_ranked = [r.candidate.name for r in res.round1.rows if r.rank is not None]
    assert res.advanced == tuple(r1_ranked[:2])
    assert set(res.final.runs) == set(res.advanced)
    assert res.final.task_points == len(gen) and res.round1.task_points == 8
    rows = res.table()
    assert [r["round"] for r in rows[:2]] == [2, 2]
    assert {r["note"] for r in rows if r["round"] == 1} <= {"not advanced", "infeasible"}
    assert len(rows) == 4


def test_rerun_resumes_from_the_store(
    gen: Task, two_round_reference: SweepResult, tmp_path: Path
) -> None:
    topos = topologies_from_specs(SPECS)
    cfg = SweepConfig(subset=8, top=2, runs=1)
    with SweepStore(tmp_path / "s.db") as st:
        first = run_sweep(gen, topos, cfg, workers=0, store=st)
        assert first.new_items == 4 + 2 and first.stored_items == 0
    with SweepStore(tmp_path / "s.db") as st:
        again = run_sweep(gen, topos, cfg, workers=0, store=st)
        assert again.new_items == 0 and again.stored_items == 6
        assert _table(again) == _table(first) == _table(two_round_reference)
        more = run_sweep(gen, topos, replace(cfg, top=3), workers=0, store=st)
        assert more.stored_items == 6 and more.new_items == len(more.advanced) - 2
        assert st.count() == 6 + more.new_items


def test_ctrl_c_stores_what_finished_and_resume_completes(
    gen: Task, two_round_reference: SweepResult, tmp_path: Path
) -> None:
    topos = topologies_from_specs(SPECS)
    cfg = SweepConfig(subset=8, top=2, runs=1)
    seen: list[str] = []

    def interrupt(e: SweepEvent) -> None:
        if e.kind == "item":
            seen.append(e.topology)
            if len(seen) == 2:
                raise KeyboardInterrupt

    with SweepStore(tmp_path / "c.db") as st:
        with ThreadPoolExecutor(2) as ex, pytest.raises(SweepInterrupted):
            run_sweep(gen, topos, cfg, executor=ex, store=st, on_event=interrupt)
        stored = st.count()
        assert 2 <= stored < 6
        assert st.integrity() == "ok"
        res = run_sweep(gen, topos, cfg, workers=0, store=st)
        assert res.stored_items == stored and res.new_items == 6 - stored
        assert _table(res) == _table(two_round_reference)


@pytest.mark.parametrize("kind", ["memory", "sqlite"])
def test_resume_runs_again_the_runs_of_other_code_and_keeps_the_rest(
    kind: str, tmp_path: Path
) -> None:
    """A store resumed at other sources (an edit, a landing), or written before runs kept
    their source hash, holds runs this code need not reproduce: those are run again and
    their rows replaced, the round's progress event says how many, and the runs of this
    code are kept as stored. The stale rows carry a wrong design: the table is the one
    this code computes."""
    task = generated_task(k=12)[0]
    topos = topologies_from_specs(["RRPRRR", "RRRRRR"])
    cfg = SweepConfig(runs=2)
    ref_store = MemoryStore()
    ref = run_sweep(task, topos, cfg, workers=0, store=ref_store)
    runs = [replace(r, worker="kept") for r in ref_store.results(ref.sweep_id)]
    own = versions()
    assert len(runs) == 4 and all(r.versions == own for r in runs)
    older = {k: v for k, v in own.items() if k != "source"}
    stale = {
        runs[0].key: {**own, "source": "0" * 16},  # another checkout
        runs[3].key: older,  # a store from before the source hash
    }
    store = MemoryStore() if kind == "memory" else SweepStore(tmp_path / "s.db")
    store.open_sweep(
        ref.sweep_id, {}, [(t.name, str(t.spec), template_fingerprint(t.template)) for t in topos]
    )
    for r in runs:
        if r.key in stale:
            r = replace(r, versions=stale[r.key], design=tuple(v + 1 for v in r.design))
        assert store.write(ref.sweep_id, r)
    events: list[SweepEvent] = []
    res = run_sweep(task, topos, cfg, workers=0, store=store, on_event=events.append)
    assert [e.stale for e in events if e.kind == "round"] == [2]
    assert (res.new_items, res.stored_items, res.stale_items) == (2, 2, 2)
    assert sorted(e.result.key for e in events if e.result is not None) == sorted(stale)
    assert sorted(e.topology for e in events if e.kind == "topology") == sorted(
        {k[0] for k in stale}
    )
    back = {r.key: r for r in store.results(ref.sweep_id)}
    assert len(back) == 4 and all(r.versions == own for r in back.values())
    for r in runs:
        assert back[r.key].same_outcome(r)
        assert (back[r.key].worker == "kept") == (r.key not in stale)
    assert _table(res) == _table(ref)
    again = run_sweep(task, topos, cfg, workers=0, store=store)
    assert (again.new_items, again.stored_items, again.stale_items) == (0, 4, 0)
    if isinstance(store, SweepStore):
        store.close()


# ---- executors ----------------------------------------------------------------------------------
def test_any_executor_and_batches_give_the_same_table(
    gen: Task, two_round_reference: SweepResult
) -> None:
    topos = topologies_from_specs(SPECS)
    cfg = SweepConfig(subset=8, top=2, runs=1, batch_size=3)
    with ThreadPoolExecutor(2) as ex:
        res = run_sweep(gen, topos, cfg, executor=ex)
    assert _table(res) == _table(two_round_reference)


def test_dask_local_cluster_equals_the_process_pool(two_round_reference: SweepResult) -> None:
    pytest.importorskip("distributed", reason="dask[distributed] (the cluster extra) missing")
    from reachwise.synthesis.sweep import dask_executor

    task = two_round_reference.task
    topos = topologies_from_specs(SPECS)
    cfg = SweepConfig(subset=8, top=2, runs=1)
    pool = run_sweep(task, topos, cfg, workers=2)
    with dask_executor("local", workers=2) as ex:
        dask = run_sweep(task, topos, cfg, executor=ex)
    assert _table(dask) == _table(pool) == _table(two_round_reference)
    for name, runs in pool.final.runs.items():
        for a, b in zip(runs, dask.final.runs[name], strict=True):
            assert a.same_outcome(b)


# ---- errors -------------------------------------------------------------------------------------
def test_a_failing_topology_is_reported_not_ranked(gen: Task) -> None:
    good = topologies_from_specs(["RRPRRR"])[0]
    fixed = replace(good.template, design=DesignSpace())  # no free design parameter
    bad = Topology("no-design", fixed, good.spec)
    res = run_sweep(gen, [good, bad], SweepConfig(runs=1), workers=0)
    row = next(r for r in res.table() if r["topology"] == "no-design")
    assert row["rank"] is None and row["note"] == "error" and "design" in row["error"]
    with pytest.raises(InputError, match="failed"):
        res.robot("no-design")


def test_config_and_input_errors(gen: Task) -> None:
    for kw, field in [({"top": 0}, "top"), ({"runs": 0}, "runs"), ({"subset": 0}, "subset"),
                      ({"solver": "x"}, "solver"), ({"rank_key": "speed"}, "key"),
                      ({"batch_size": 0}, "batch_size")]:  # fmt: skip
        with pytest.raises(InputError, match=field):
            SweepConfig(**kw)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="no topology"):
        run_sweep(gen, [], workers=0)
    t = topologies_from_specs(["RRPRRR"])
    with pytest.raises(InputError, match="unique"):
        run_sweep(gen, t + t, workers=0)


# ---- design objectives in the sweep ------------------------------------------------------------
def test_sweep_improves_for_an_objective_and_ranks_by_it(gen: Task) -> None:
    topos = topologies_from_specs(SPECS[:2])
    plain = run_sweep(gen, topos, SweepConfig(runs=1, rank_key="size"), workers=0)
    small = SweepConfig(runs=1, rank_key="size", objective={"size": 1.0})
    res = run_sweep(gen, topos, small, workers=0)
    assert res.sweep_id != plain.sweep_id  # the objective is part of the sweep's id
    ranked = [r for r in res.table() if r["rank"] is not None]
    sizes = [res.final.best_result(r["topology"]).measures.size for r in ranked]  # type: ignore[union-attr]
    assert ranked and sizes == sorted(sizes)  # lower size ranks first
    for r in ranked:
        before = plain.final.best_result(r["topology"])
        after = res.final.best_result(r["topology"])
        if before.feasible:  # the same reaching run, then improved for size
            assert after.feasible
            assert after.measures.size <= before.measures.size + 1e-9  # type: ignore[union-attr]
