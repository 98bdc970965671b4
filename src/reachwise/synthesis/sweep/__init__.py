"""The topology sweep: two rounds of dimensional synthesis over many topologies (P-II Fig. 1).

P-II §2 and Fig. 1 (thesis §4.2, §5.1): define the task and a descriptive subset of it;
run the dimensional synthesis of every candidate topology on the subset (round 1);
order the feasible ones — those reaching every subset point — by the chosen measure;
run the best ``K`` on the complete task (round 2) and rank them again (P-II Table 2).
Without a subset (``SweepConfig.subset = None``) every topology goes straight to the
complete task, P-II's "somewhat simplified process".

One concept per module:

- ``config`` — ``SweepConfig`` (subset, top, runs, seed, solver, rank key);
- ``items`` — a ``WorkItem`` is one multi-start run ``(topology, round, run)`` with seed
  ``config.seed + run`` (the same seeds for every topology, as in ``synthesize``):
  picklable and pure, ``run_item`` → ``ItemResult``;
- ``fingerprint`` — the sweep id (task, subset, seed, solver settings) items are keyed by;
- ``store`` — the ``ResultStore`` interface every finished item is written to at once,
  and ``MemoryStore``; the persistent SQLite store is ``reachwise.results.sweep_store``;
- ``executors`` — a local process pool (default) or a Dask cluster (``dask_executor``);
- ``tables`` — ``RoundTable`` (P-II Table 2 of one round) and ``SweepResult``;
- ``run`` — ``run_sweep``: items go to any ``concurrent.futures.Executor`` in batches of
  ``config.batch_size``; items already stored are skipped (resume); Ctrl-C keeps what
  finished (``SweepInterrupted``).

Results do not depend on the executor, the number of workers or the batch size: a fixed
seed gives identical results.
"""

from __future__ import annotations

from reachwise.synthesis.sweep.config import ROUND_FULL, ROUND_SUBSET, SweepConfig
from reachwise.synthesis.sweep.executors import dask_executor, process_pool
from reachwise.synthesis.sweep.fingerprint import (
    sweep_fingerprint,
    task_fingerprint,
    template_fingerprint,
)
from reachwise.synthesis.sweep.items import ItemResult, WorkItem, run_batch, run_item, versions
from reachwise.synthesis.sweep.run import SweepEvent, SweepInterrupted, run_sweep
from reachwise.synthesis.sweep.store import MemoryStore, ResultStore
from reachwise.synthesis.sweep.tables import RoundTable, SweepResult, round_table

__all__ = [
    "ROUND_FULL",
    "ROUND_SUBSET",
    "ItemResult",
    "MemoryStore",
    "ResultStore",
    "RoundTable",
    "SweepConfig",
    "SweepEvent",
    "SweepInterrupted",
    "SweepResult",
    "WorkItem",
    "dask_executor",
    "process_pool",
    "round_table",
    "run_batch",
    "run_item",
    "run_sweep",
    "sweep_fingerprint",
    "task_fingerprint",
    "template_fingerprint",
    "versions",
]
