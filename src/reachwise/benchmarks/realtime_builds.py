"""The index builds of ``reachwise bench realtime`` (:mod:`reachwise.benchmarks.realtime`,
part 1): what the ingestion worker does per hand-over against the baseline path."""

from __future__ import annotations

import gc
import time

import numpy as np

from reachwise.benchmarks._baseline_build import ingest_baseline
from reachwise.benchmarks._harness import BenchReport, Target
from reachwise.benchmarks.realtime_room import camera_frame, room_points
from reachwise.distance.ingest import ready_cloud

__all__ = ["index_builds"]


def index_builds(rep: BenchReport, quick: bool) -> None:
    """Part 1 of ``reachwise bench realtime``: the ingestion worker's build of a
    300 000-point camera frame and of the 1 000 000-point room against the baseline
    path (:mod:`reachwise.benchmarks._baseline_build`), interleaved rep by rep, wall
    and thread CPU time (µs)."""
    reps = 3 if quick else 9
    camera = camera_frame(0).astype(np.float64)
    clouds = {"300k": camera[:300_000], "1M": room_points()}
    for name, pts in clouds.items():
        ready_cloud("warm", 1, pts[:1000], 0.0)
        ingest_baseline(pts[:1000])
        wall: dict[str, list[float]] = {"new": [], "old": []}
        cpu: dict[str, list[float]] = {"new": [], "old": []}
        for _ in range(reps):
            for method in ("new", "old"):
                w0, c0 = time.perf_counter(), time.thread_time()
                if method == "new":
                    ready_cloud("cloud", 1, pts, 0.0)
                else:
                    ingest_baseline(pts)
                wall[method].append((time.perf_counter() - w0) * 1e6)
                cpu[method].append((time.thread_time() - c0) * 1e6)
                gc.collect()
        for method in ("new", "old"):
            rep.add_samples(f"build.{name}.{method}", np.array(wall[method]))
            rep.metrics[f"build.{name}.{method}_cpu.median"] = float(np.median(cpu[method]))
            rep.metrics[f"build.{name}.{method}.min"] = float(np.min(wall[method]))
        rep.ratio(f"build.{name}.old", f"build.{name}.new")
    rep.targets["build_300k"] = Target(rep.metrics["build.300k.new.median"], 20_000.0)
    rep.targets["build_1M"] = Target(rep.metrics["build.1M.new.median"], 80_000.0)
