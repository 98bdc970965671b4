"""Benchmarks run by ``reachwise bench NAME``: our code and its baseline in one run.

Each module exposes ``run(quick: bool = False) -> BenchReport``. Register it in
``REGISTRY`` below. The harness in ``_harness`` times calls, summarizes medians and
tails, and renders the JSON shape of DESIGN.md or a rich table.
"""

from __future__ import annotations

REGISTRY: dict[str, str] = {
    "kinematics": "reachwise.benchmarks.kinematics",
    "distance": "reachwise.benchmarks.distance",
    "synthesis": "reachwise.benchmarks.synthesis",
    "sweep": "reachwise.benchmarks.sweep",
    "control": "reachwise.benchmarks.control",
    "pairs": "reachwise.benchmarks.pairs",
    "server": "reachwise.benchmarks.server",
    "realtime": "reachwise.benchmarks.realtime",
    "realtime-memory": "reachwise.benchmarks.realtime_memory",
    "replay": "reachwise.benchmarks.replay",
    "memory": "reachwise.benchmarks.memory",
    "server-memory": "reachwise.benchmarks.server_memory",
}
