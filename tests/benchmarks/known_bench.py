"""A benchmark module with known samples instead of timings, for the harness tests
(registered under the name ``known`` by the tests only)."""

from __future__ import annotations

import numpy as np

from reachwise.benchmarks._harness import BenchReport, Target


def run(quick: bool = False) -> BenchReport:
    report = BenchReport("known")
    report.add_samples("ours.query", np.arange(1.0, 101.0)[::-1])  # 100 .. 1
    report.add_samples("baseline.query", np.array([10.0] * 99 + [1000.0]))
    report.ratio("baseline.query", "ours.query")
    report.targets["ours.query.median"] = Target(report.metrics["ours.query.median"], 60.0)
    report.notes.append("quick" if quick else "full")
    return report
