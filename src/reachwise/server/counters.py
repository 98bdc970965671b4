"""The collision server's counters: request, error and latency metrics, and the
sequence numbers that stamp every query and health reply (never repeated, also across
restarts with a state directory)."""

from __future__ import annotations

import math
import threading
from collections import Counter

import numpy as np

import reachwise.server.protocol as P
from reachwise.server.state import StateStore

#: Sequence numbers reserved in the state directory at a time.
SEQUENCE_BLOCK = 1_000_000
#: Upper bucket edges of the latency histograms, microseconds (1-2-5 series).
LATENCY_EDGES_US: tuple[float, ...] = tuple(
    float(m * 10**e) for e in range(0, 7) for m in (1, 2, 5) if m * 10**e <= 1_000_000
)
_EDGES = np.asarray(LATENCY_EDGES_US)
#: Query times are binned into the histograms in batches of this many.
BIN_EVERY = 256


class Metrics:
    """Request and error counts and the query latency histograms (thread-safe).

    A query's times are appended to a list (the cheapest thing to do per tick) and
    binned into the histograms in batches of :data:`BIN_EVERY`, and whenever a
    snapshot is taken."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._requests: Counter[str] = Counter()
        self._errors: Counter[str] = Counter()
        n = len(LATENCY_EDGES_US) + 1
        self._compute = np.zeros(n, dtype=np.int64)
        self._handling = np.zeros(n, dtype=np.int64)
        self._pending: list[tuple[float, float]] = []
        self._ticks = 0  # queries that came as binary ticks, counted apart (no lock)

    def request(self, op: str) -> None:
        with self._lock:
            self._requests[op] += 1

    def tick(self) -> None:
        """Count one query that came as a binary tick. Without a lock (the per-tick
        path): call it under one lock that every caller holds (the service's)."""
        self._ticks += 1

    def error(self, code: P.ErrorCode) -> None:
        with self._lock:
            self._errors[code.value] += 1

    def query(self, compute_s: float, handling_s: float) -> None:
        """Record one query: its computation and its handling from receipt to reply (s)."""
        pending = self._pending
        pending.append((compute_s, handling_s))  # atomic: no lock per tick
        if len(pending) >= BIN_EVERY:
            self._bin()

    def _bin(self) -> None:
        with self._lock:
            pending, self._pending = self._pending, []
            if not pending:
                return
            t = np.asarray(pending, dtype=np.float64) * 1e6
            n = self._compute.size
            for hist, col in ((self._compute, t[:, 0]), (self._handling, t[:, 1])):
                idx = np.searchsorted(_EDGES, col, side="right")
                hist += np.bincount(idx, minlength=n)

    def snapshot(self, uptime: float, sequence: int) -> P.MetricsReply:
        self._bin()
        with self._lock:
            return P.MetricsReply(
                uptime,
                sequence,
                _with_ticks(self._requests, self._ticks),
                dict(self._errors),
                LATENCY_EDGES_US,
                tuple(int(c) for c in self._compute),
                tuple(int(c) for c in self._handling),
            )


def _with_ticks(requests: Counter[str], ticks: int) -> dict[str, int]:
    """The request counts, binary ticks counted as queries."""
    out = dict(requests)
    if ticks:
        out["query"] = out.get("query", 0) + ticks
    return out


class SequenceCounter:
    """Numbers 1, 2, 3 … for query and health replies; with a store, reserved in blocks
    so that a restarted server continues above everything it may have handed out."""

    def __init__(self, store: StateStore | None, block: int = SEQUENCE_BLOCK) -> None:
        self._store = store
        self._block = block
        self._lock = threading.Lock()
        self._last = 0
        self._reserved = math.inf
        if store is not None:
            self._last = store.read_reserved()
            self._reserved = self._last + block
            store.write_reserved(int(self._reserved))

    @property
    def last(self) -> int:
        """The last number handed out (0 before the first)."""
        return self._last

    def take(self) -> int:
        with self._lock:
            self._last += 1
            if self._last > self._reserved:  # the writer thread fell far behind
                self._extend_locked()
            return self._last

    @property
    def wants_extension(self) -> bool:
        return self._last > self._reserved - self._block // 2

    def extend(self) -> None:
        with self._lock:
            self._extend_locked()

    def _extend_locked(self) -> None:
        if self._store is not None:
            self._reserved = max(self._reserved, self._last) + self._block
            self._store.write_reserved(int(self._reserved))
