"""Timing harness shared by the benchmarks (this layer may read the clock).

Times are in microseconds unless a key says otherwise (``..._s``).
"""

from __future__ import annotations

import json
import math
import os
import platform
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Target:
    """A figure and the limit it must stay at or below (``le``) or at or above."""

    value: float
    limit: float
    higher_is_better: bool = False

    @property
    def met(self) -> bool:
        if not np.isfinite(self.value):
            return False
        return self.value >= self.limit if self.higher_is_better else self.value <= self.limit


@dataclass
class BenchReport:
    """Figures of one benchmark run: metrics, ratios between methods and targets."""

    benchmark: str
    metrics: dict[str, float] = field(default_factory=dict)
    ratios: dict[str, float] = field(default_factory=dict)
    targets: dict[str, Target] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def add_samples(self, method: str, samples_us: np.ndarray) -> None:
        """Record median, p99 (and p99.9, mean, count) of per-call samples in µs."""
        s = np.asarray(samples_us, dtype=np.float64)
        self.metrics[f"{method}.median"] = float(np.median(s))
        self.metrics[f"{method}.p99"] = float(np.percentile(s, 99))
        self.metrics[f"{method}.p99_9"] = float(np.percentile(s, 99.9))
        self.metrics[f"{method}.mean"] = float(s.mean())
        self.metrics[f"{method}.count"] = float(s.size)

    def ratio(self, a: str, b: str, figure: str = "median") -> float:
        """Store and return metrics[a.figure] / metrics[b.figure] as ``a_over_b``."""
        r = self.metrics[f"{a}.{figure}"] / self.metrics[f"{b}.{figure}"]
        self.ratios[f"{a}_over_{b}"] = float(r)
        return float(r)

    def to_dict(self) -> dict[str, Any]:
        return {
            "benchmark": self.benchmark,
            "machine": machine_info(),
            "metrics": self.metrics,
            "ratios": self.ratios,
            "targets": {
                k: {"value": t.value, "limit": t.limit, "met": t.met}
                for k, t in self.targets.items()
            },
            "notes": self.notes,
        }

    def to_json(self) -> str:
        """:meth:`to_dict` as standard JSON: a figure that is not finite (NaN: not
        measured; inf: beyond the last bucket) is ``null``, which every parser reads
        (Python's ``NaN``/``Infinity`` extensions are not JSON)."""
        return json.dumps(_finite(self.to_dict()), indent=2, allow_nan=False)


def _finite(obj: Any) -> Any:
    """``obj`` with every non-finite float replaced by None (dicts and lists walked)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    return obj


def machine_info() -> dict[str, Any]:
    """What the figures were measured on."""
    import numba
    import scipy

    return {
        "python": platform.python_version(),
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "cpus": os.cpu_count(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "numba": numba.__version__,
    }


def time_calls(fn: Callable[[], object], repeat: int, warmup: int = 10) -> np.ndarray:
    """Per-call wall time of ``fn()`` in microseconds, ``repeat`` samples."""
    for _ in range(warmup):
        fn()
    out = np.empty(repeat)
    clock = time.perf_counter_ns
    for i in range(repeat):
        t0 = clock()
        fn()
        out[i] = (clock() - t0) * 1e-3
    return out


def time_interleaved(
    fns: dict[str, Callable[[int], object]], repeat: int, warmup: int = 5
) -> dict[str, np.ndarray]:
    """Time several methods query by query: for each i, every ``fn(i)`` in turn.

    Interleaving puts all methods under the same machine load at the same moment.
    """
    for i in range(warmup):
        for fn in fns.values():
            fn(i)
    out = {k: np.empty(repeat) for k in fns}
    clock = time.perf_counter_ns
    for i in range(repeat):
        for k, fn in fns.items():
            t0 = clock()
            fn(i)
            out[k][i] = (clock() - t0) * 1e-3
    return out
