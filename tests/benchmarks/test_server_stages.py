"""The stage breakdown of ``reachwise bench server`` runs on today's request path:
every stage of both paths and the server's whole tick are reported."""

from __future__ import annotations

import reachwise
from reachwise.benchmarks._harness import BenchReport
from reachwise.benchmarks.server_stages import STAGES, stage_costs


def test_every_stage_of_both_paths_is_reported() -> None:
    rep = BenchReport("stages")
    stage_costs(rep, reachwise.load_robot("hiab-xs033"), repeat=3)
    for path in ("full", "tick"):
        for stage in (*STAGES, "total"):
            assert f"stage.{path}.{stage}" in rep.metrics, (path, stage)
    for key in ("stage.tick.server_tick", "stage.tick.result_pairs", "stage.query_all"):
        assert key in rep.metrics
    assert rep.notes and "server_tick" in rep.notes[-1]
