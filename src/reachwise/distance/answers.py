"""Every watched pair's answer of one scene query, kept as one array of numbers.

A 1 kHz loop reads a few numbers per pair; it should not pay for a Python object per
pair it never looks at. :class:`PairAnswers` is the sequence
:attr:`~reachwise.distance.scene.SceneResult.pairs` holds for the in-process scene: it
wraps the (P, :data:`ROW_COLUMNS`) array the compiled query wrote (read-only, one per
query, never reused) and makes a :class:`~reachwise.distance.scene.PairResult` only when
one is asked for (then keeps it). Code that wants the numbers reads :attr:`PairAnswers.rows`
directly — the controller's converter does — in the collision server's wire layout:

=====  =====================================================================
col    meaning
=====  =====================================================================
0      distance (m; inf for "no risk")
1–3    point on a (world)
4–6    point on b (world)
7–9    direction, unit vector from b to a
10–11  input rows of the two points in their clouds (-1 for "no risk")
12     1.0 for "no risk" (beyond the margin), else 0.0
=====  =====================================================================
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from typing import overload

import numpy as np
from numpy.typing import NDArray

from reachwise.distance._batch import ROW_COLUMNS
from reachwise.distance._common import NO_RISK, DistanceResult
from reachwise.distance.pairs import PairResult, WatchedPair

__all__ = ["ROW_COLUMNS", "PairAnswers", "pair_row", "rows_of", "write_row"]


class PairAnswers(Sequence[PairResult]):
    """The answers of one query (see the module docstring): ``layout`` the watched
    pairs in order, ``rows`` their numbers, ``versions`` the cloud version per object.
    Behaves as the tuple of :class:`PairResult` it stands for (equal to it, too)."""

    __slots__ = ("_built", "_layout", "_rows", "_versions")

    def __init__(
        self,
        layout: tuple[WatchedPair, ...],
        rows: NDArray[np.float64],
        versions: Mapping[str, int],
    ) -> None:
        self._layout = layout
        self._rows = rows
        self._versions = versions
        self._built: list[PairResult | None] = [None] * len(layout)

    @property
    def rows(self) -> NDArray[np.float64]:
        """(P, 13) read-only numbers of every pair (see the module docstring)."""
        return self._rows

    @property
    def layout(self) -> tuple[WatchedPair, ...]:
        """The watched pairs, in the order of the rows."""
        return self._layout

    def __len__(self) -> int:
        return len(self._layout)

    @overload
    def __getitem__(self, i: int) -> PairResult: ...

    @overload
    def __getitem__(self, i: slice) -> tuple[PairResult, ...]: ...

    def __getitem__(self, i: int | slice) -> PairResult | tuple[PairResult, ...]:
        if isinstance(i, slice):
            return tuple(self[k] for k in range(*i.indices(len(self))))
        k = i + len(self) if i < 0 else i
        if not 0 <= k < len(self):
            raise IndexError("pair index out of range")
        got = self._built[k]
        if got is None:
            got = self._make(k)
            self._built[k] = got
        return got

    def __iter__(self) -> Iterator[PairResult]:
        for k in range(len(self)):
            yield self[k]

    def __eq__(self, other: object) -> bool:
        if isinstance(other, PairAnswers | tuple | list):
            return tuple(self) == tuple(other)
        return NotImplemented

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        return f"PairAnswers({list(self)!r})"

    def _make(self, k: int) -> PairResult:
        w = self._layout[k]
        v = self._versions
        return PairResult(
            w.a, w.b, w.margin, w.kind, pair_row(self._rows[k]), (v.get(w.a, 0), v.get(w.b, 0))
        )


def pair_row(row: NDArray[np.float64]) -> DistanceResult:
    """The :class:`DistanceResult` of one answer row (its vectors are views of it)."""
    if row[12] != 0.0:
        return NO_RISK
    return DistanceResult(
        float(row[0]), row[1:4], row[4:7], row[7:10], int(row[10]), int(row[11]), False
    )


def write_row(row: NDArray[np.float64], r: DistanceResult) -> None:
    """Write the answer ``r`` into ``row``, one row of the layout in the module
    docstring (the one place that layout is written from a result)."""
    if r.no_risk:
        row[0] = math.inf
        row[1:10] = math.nan
        row[10:12] = -1.0
        row[12] = 1.0
    else:
        row[0] = r.distance
        row[1:4] = r.point_a
        row[4:7] = r.point_b
        row[7:10] = r.direction
        row[10] = r.index_a
        row[11] = r.index_b
        row[12] = 0.0


def rows_of(pairs: Sequence[PairResult]) -> NDArray[np.float64]:
    """The (P, 13) rows of answers given as :class:`PairResult` values (read-only)."""
    out = np.empty((len(pairs), ROW_COLUMNS))
    for k, p in enumerate(pairs):
        write_row(out[k], p.result)
    out.setflags(write=False)
    return out
