"""``reachwise bench sweep``: the topology sweep (P-II Fig. 1, Table 2) and its scaling.

Three figures:

* ``p2`` — the six P-II topologies (``p2-man1`` … ``p2-man6``) × 3 runs on the complete
  ``tunnel-87`` task (one round, as in P-II §5: every topology on all 87 points), on all
  cores; target ≤ 10 min on the 2-core machine. The resulting table (GCI, KCI, mean,
  feasibility) is in the notes.
* ``enum`` — enumeration throughput: topologies from ``enumerate_topologies`` (6 joints,
  default rules, an evenly spaced sample) optimized once each on the 16-point
  descriptive subset of ``tunnel-87`` (the first round of a real sweep), in topologies
  per minute, with 1 and with 2 worker processes.
* ``speedup_2_over_1`` — wall time with 1 worker over wall time with 2 on the ``enum``
  workload (many independent runs, the bulk of any sweep); target ≥ 1.7. The two are
  measured alternately (1, 2, 1, 2 …) and the best of each kept, since other load on a
  shared machine only ever slows a measurement down. Wall times include starting the
  process pool. Quick mode: 1 run per P-II topology, a smaller sample, one repeat.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from functools import partial

from reachwise.benchmarks._harness import BenchReport, Target
from reachwise.io.robot_file import load_robot
from reachwise.io.task_file import load_task
from reachwise.synthesis.sweep import SweepConfig, SweepResult, run_sweep
from reachwise.synthesis.topology import (
    EnumerationRules,
    builtin_set,
    enumerate_topologies,
    topologies_from_specs,
)
from reachwise.tasks.select import descriptive_subset

P2_RUNS = 3
SUBSET = 16


def _timed(fn: Callable[[], SweepResult]) -> tuple[float, SweepResult]:
    t0 = time.perf_counter()
    res = fn()
    return time.perf_counter() - t0, res


def run(quick: bool = False) -> BenchReport:
    rep = BenchReport("sweep")
    task = load_task("tunnel-87")
    cores = os.cpu_count() or 1
    workers = min(2, cores)

    # -- P-II: six topologies x 3 runs on the complete task, all cores
    runs = 1 if quick else P2_RUNS
    p2 = builtin_set("p2", load_robot)
    t_p2, res = _timed(partial(run_sweep, task, p2, SweepConfig(runs=runs), workers=cores))
    rep.metrics["p2.topologies"] = float(len(p2))
    rep.metrics["p2.runs_per_topology"] = float(runs)
    rep.metrics["p2.workers"] = float(cores)
    rep.metrics["p2.wall_s"] = t_p2
    rep.metrics["p2.feasible"] = float(len(res.ranked()))
    walls = [r.wall_s for v in res.final.runs.values() for r in v]
    rep.metrics["p2.run_median_s"] = float(sorted(walls)[len(walls) // 2])
    rep.targets["p2_wall_s"] = Target(t_p2, 600.0)
    for row in res.table():
        if row["feasible"]:
            rep.notes.append(
                f"P-II {row['topology']}: rank {row['rank']}, GCI {row['gci']:.4f}, "
                f"KCI {row['kci']:.4f}, mean {row['mean']:.4f}, "
                f"{row['runs_feasible']}/{row['runs']} runs reach all 87"
            )
        else:
            rep.notes.append(
                f"P-II {row['topology']}: infeasible, best run reaches "
                f"{row['reached']}/{row['points']} ({row['runs_feasible']}/{row['runs']} runs)"
            )

    # -- enumeration throughput on the subset, 1 and 2 workers, best of alternating repeats
    sample = 12 if quick else 40
    repeats = 1 if quick else 2
    topos = topologies_from_specs(enumerate_topologies(EnumerationRules(sample=sample)))
    sub = task.subset(descriptive_subset(task, SUBSET), name=f"tunnel-87[{SUBSET}]")
    cfg = SweepConfig(runs=1)
    best: dict[int, float] = {}
    feasible = 0
    for _ in range(repeats):
        for w in (1, workers):
            t, r = _timed(partial(run_sweep, sub, topos, cfg, workers=w))
            best[w] = min(best.get(w, float("inf")), t)
            feasible = len(r.ranked())
    rep.metrics["enum.topologies"] = float(len(topos))
    rep.metrics["enum.subset_points"] = float(SUBSET)
    rep.metrics["enum.feasible"] = float(feasible)
    rep.metrics["enum.1_worker_s"] = best[1]
    rep.metrics[f"enum.{workers}_workers_s"] = best[workers]
    rep.metrics["enum.topologies_per_min_1_worker"] = 60.0 * len(topos) / best[1]
    rep.metrics[f"enum.topologies_per_min_{workers}_workers"] = 60.0 * len(topos) / best[workers]
    speed = best[1] / best[workers]
    rep.ratios[f"{workers}_workers_over_1"] = speed
    rep.targets["speedup_2_over_1"] = Target(speed if workers == 2 else float("nan"), 1.7, True)
    rep.notes.append(
        f"enum: {len(topos)} enumerated 6-joint topologies (evenly spaced sample of "
        f"{len(enumerate_topologies(EnumerationRules()))}), 1 run each on the {SUBSET}-point "
        f"descriptive subset; best of {repeats} alternating repeats; {cores} cores"
    )
    return rep
