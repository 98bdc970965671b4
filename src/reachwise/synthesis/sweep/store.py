"""Where a sweep's finished runs go: the ``ResultStore`` interface and ``MemoryStore``.

Every finished item is handed to the store as soon as it arrives; items already in the
store are skipped, so running the same sweep again on a persistent store resumes it, and
the tables are always built from the store (a resumed sweep gives the table of an
uninterrupted one). The synthesis layer writes no files: a persistent store is passed
in by the caller — ``reachwise.results.sweep_store.SweepStore`` (SQLite, one transaction
per item) is the one the CLI and the demo use. ``MemoryStore`` keeps the items of one
process and is the default of ``run_sweep``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol

from reachwise.errors import InputError
from reachwise.synthesis.sweep.items import ItemResult


class ResultStore(Protocol):
    """What the sweep needs from a results store.

    ``open_sweep`` registers a sweep and its topologies ``(name, spec, template hash)``
    and refuses a topology whose template changed under its name; ``done`` lists the
    stored ``(topology, run)`` of a round; ``write`` stores one item (``False`` if it
    was already there with the same ``versions``; a run is never stored twice: a run
    stored with other versions, i.e. computed by other code, is replaced); ``results``
    returns the stored items of a sweep, one round or all, ordered by round, topology, run.
    """

    def open_sweep(
        self, sweep_id: str, meta: dict[str, Any], topologies: Sequence[tuple[str, str, str]]
    ) -> None: ...

    def done(self, sweep_id: str, round: int) -> set[tuple[str, int]]: ...

    def write(self, sweep_id: str, result: ItemResult) -> bool: ...

    def results(self, sweep_id: str, round: int | None = None) -> list[ItemResult]: ...


class MemoryStore:
    """A ``ResultStore`` in memory (nothing survives the process)."""

    def __init__(self) -> None:
        self._meta: dict[str, dict[str, Any]] = {}
        self._templates: dict[str, dict[str, str]] = {}
        self._items: dict[tuple[str, str, int, int], ItemResult] = {}

    def open_sweep(
        self, sweep_id: str, meta: dict[str, Any], topologies: Sequence[tuple[str, str, str]]
    ) -> None:
        self._meta.setdefault(sweep_id, dict(meta))
        known = self._templates.setdefault(sweep_id, {})
        for name, _spec, sha in topologies:
            if known.setdefault(name, sha) != sha:
                raise InputError(
                    "sweep store", f"topology {name!r}", "its template changed in this sweep"
                )

    def done(self, sweep_id: str, round: int) -> set[tuple[str, int]]:
        return {(t, r) for s, t, rd, r in self._items if s == sweep_id and rd == round}

    def write(self, sweep_id: str, result: ItemResult) -> bool:
        key = (sweep_id, result.topology, int(result.round), int(result.run))
        if key in self._items and self._items[key].versions == result.versions:
            return False
        self._items[key] = result
        return True

    def results(self, sweep_id: str, round: int | None = None) -> list[ItemResult]:
        keys = [k for k in self._items if k[0] == sweep_id and (round is None or k[2] == round)]
        return [self._items[k] for k in sorted(keys, key=lambda k: (k[2], k[1], k[3]))]
