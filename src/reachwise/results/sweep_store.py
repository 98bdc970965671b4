"""The SQLite results store of topology sweeps (``synthesis.sweep.store.ResultStore``; item 7).

One database holds any number of sweeps, each identified by its fingerprint
(``sweep.sweep_fingerprint``). Tables:

* ``sweeps`` — one row per sweep: id, task name, configuration and subset (JSON),
  versions, creation time;
* ``topologies`` — per sweep, each topology's name, canonical spec and template hash
  (a resumed sweep whose template under a name changed is refused);
* ``items`` — one row per finished run ``(sweep, topology, round, run)`` (the primary
  key: a run can never be stored twice; a run computed by other code, i.e. stored with
  other ``versions``, is replaced when this code writes it): seed, reach, objective,
  iterations, GCI, KCI, mean, manipulability, link length, prismatic joints, the
  size/limits/bounds objectives
  (schema 2; a schema-1 database is upgraded in place), design (JSON), per-point status
  (JSON), the joint values of every task point (float64 BLOB), wall time, worker,
  versions, finish time, and the error text of a run that raised.

Durability: WAL journal, ``synchronous=FULL``, one transaction per row, so a killed
process (SIGKILL, power loss after the commit) loses nothing that was written and
never leaves a partial row; a run written twice by the same code (two sweeps on one
database) is kept once, and a run of other code is replaced (``ON CONFLICT DO UPDATE
… WHERE`` the versions differ). Floats are stored as IEEE doubles (REAL, or JSON
with round-trip ``repr``), so results read back bit-identical.
"""

from __future__ import annotations

import json
import math
import sqlite3
from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from reachwise.errors import InputError
from reachwise.synthesis.rank import Measures
from reachwise.synthesis.sweep.items import ItemResult

SCHEMA_VERSION = 3
# v2 adds the design-objective measures (``rank.Measures.size/limits/bounds``), v3 the
# clearance (``rank.Measures.clearance``); an older database is upgraded in place (the
# new columns read NULL, i.e. NaN, for old rows).
_NEW_COLUMNS = {2: ("size", "limits", "bounds"), 3: ("clearance",)}
_SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (
  key TEXT PRIMARY KEY,
  value TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS sweeps (
  sweep_id TEXT PRIMARY KEY,
  task TEXT NOT NULL,
  meta TEXT NOT NULL,
  created TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS topologies (
  sweep_id TEXT NOT NULL REFERENCES sweeps(sweep_id),
  name TEXT NOT NULL,
  spec TEXT NOT NULL,
  template_sha TEXT NOT NULL,
  position INTEGER NOT NULL,
  PRIMARY KEY (sweep_id, name)
);
CREATE TABLE IF NOT EXISTS items (
  sweep_id TEXT NOT NULL,
  topology TEXT NOT NULL,
  round INTEGER NOT NULL CHECK (round IN (1, 2)),
  run INTEGER NOT NULL CHECK (run >= 0),
  seed INTEGER NOT NULL,
  n_points INTEGER NOT NULL,
  n_reached INTEGER NOT NULL,
  feasible INTEGER NOT NULL CHECK (feasible IN (0, 1)),
  e_obj REAL,
  iterations INTEGER NOT NULL,
  converged INTEGER NOT NULL CHECK (converged IN (0, 1)),
  gci REAL,
  kci REAL,
  mean REAL,
  manipulability REAL,
  length REAL,
  prismatic INTEGER,
  size REAL,
  limits REAL,
  bounds REAL,
  clearance REAL,
  max_position_error REAL,
  max_orientation_error REAL,
  design_names TEXT NOT NULL,
  design TEXT NOT NULL,
  status TEXT NOT NULL,
  q BLOB NOT NULL,
  q_rows INTEGER NOT NULL,
  q_cols INTEGER NOT NULL,
  error TEXT NOT NULL,
  wall_s REAL NOT NULL,
  worker TEXT NOT NULL,
  versions TEXT NOT NULL,
  finished_at TEXT NOT NULL,
  PRIMARY KEY (sweep_id, topology, round, run),
  FOREIGN KEY (sweep_id, topology) REFERENCES topologies(sweep_id, name),
  CHECK (length(q) = 8 * q_rows * q_cols)
);
"""
_COLUMNS = (
    "sweep_id", "topology", "round", "run", "seed", "n_points", "n_reached", "feasible",
    "e_obj", "iterations", "converged", "gci", "kci", "mean", "manipulability", "length",
    "prismatic", "size", "limits", "bounds", "clearance", "max_position_error",
    "max_orientation_error",
    "design_names", "design", "status", "q", "q_rows", "q_cols", "error", "wall_s", "worker",
    "versions", "finished_at",
)  # fmt: skip


def _real(v: float) -> float | None:
    return None if math.isnan(v) else float(v)


def _float(v: Any) -> float:
    return math.nan if v is None else float(v)


class SweepStore:
    """A sweep results database (module docstring). ``path`` ``":memory:"`` keeps it in
    memory. Use as a context manager or call ``close``."""

    def __init__(self, path: str | Path = ":memory:") -> None:
        self.path = str(path)
        if self.path != ":memory:":
            Path(self.path).parent.mkdir(parents=True, exist_ok=True)
        self._db = sqlite3.connect(self.path, timeout=30.0, isolation_level=None)
        self._db.execute("PRAGMA busy_timeout = 30000")
        if self.path != ":memory:":
            mode = self._db.execute("PRAGMA journal_mode = WAL").fetchone()[0]
            if str(mode).lower() != "wal":  # pragma: no cover - filesystem without WAL
                raise InputError(self.path, "journal_mode", f"WAL unavailable ({mode})")
        self._db.execute("PRAGMA synchronous = FULL")
        self._db.execute("PRAGMA foreign_keys = ON")
        with self._tx():
            for stmt in _SCHEMA.split(";"):
                if stmt.strip():
                    self._db.execute(stmt)
            row = self._db.execute("SELECT value FROM meta WHERE key='schema'").fetchone()
            if row is None:
                self._db.execute(
                    "INSERT INTO meta(key, value) VALUES ('schema', ?)", (str(SCHEMA_VERSION),)
                )
            elif 1 <= int(row[0]) < SCHEMA_VERSION:
                for version in range(int(row[0]) + 1, SCHEMA_VERSION + 1):
                    for c in _NEW_COLUMNS[version]:
                        self._db.execute(f"ALTER TABLE items ADD COLUMN {c} REAL")
                self._db.execute("UPDATE meta SET value = ? WHERE key = 'schema'",
                                 (str(SCHEMA_VERSION),))  # fmt: skip
            elif int(row[0]) != SCHEMA_VERSION:
                raise InputError(self.path, "schema", f"version {row[0]}, expected "
                                 f"{SCHEMA_VERSION}")  # fmt: skip

    # ---- plumbing --------------------------------------------------------------------------
    def _tx(self) -> _Transaction:
        return _Transaction(self._db)

    def close(self) -> None:
        self._db.close()

    def __enter__(self) -> SweepStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---- sweeps ----------------------------------------------------------------------------
    def open_sweep(
        self, sweep_id: str, meta: dict[str, Any], topologies: Sequence[tuple[str, str, str]]
    ) -> None:
        """Register a sweep and its topologies ``(name, spec, template hash)``; on a
        resume, check that no topology's template changed under its name."""
        now = datetime.now(UTC).isoformat()
        with self._tx():
            self._db.execute(
                "INSERT INTO sweeps(sweep_id, task, meta, created) VALUES (?, ?, ?, ?) "
                "ON CONFLICT(sweep_id) DO NOTHING",
                (sweep_id, str(meta.get("task", "")), json.dumps(meta, sort_keys=True), now),
            )
            known = {
                n: sha
                for n, sha in self._db.execute(
                    "SELECT name, template_sha FROM topologies WHERE sweep_id = ?", (sweep_id,)
                )
            }
            pos = len(known)
            for name, spec, sha in topologies:
                if name in known:
                    if known[name] != sha:
                        raise InputError(
                            self.path,
                            f"topology {name!r}",
                            "its template changed since this sweep was stored; use a new database",
                        )
                    continue
                self._db.execute(
                    "INSERT INTO topologies(sweep_id, name, spec, template_sha, position) "
                    "VALUES (?, ?, ?, ?, ?)",
                    (sweep_id, name, spec, sha, pos),
                )
                known[name] = sha
                pos += 1

    def sweeps(self) -> list[dict[str, Any]]:
        """Every sweep in the database: id, task, creation time, meta and item count."""
        rows = self._db.execute(
            "SELECT s.sweep_id, s.task, s.created, s.meta, "
            "(SELECT COUNT(*) FROM items i WHERE i.sweep_id = s.sweep_id) "
            "FROM sweeps s ORDER BY s.created, s.sweep_id"
        ).fetchall()
        return [
            {"sweep_id": r[0], "task": r[1], "created": r[2], "meta": json.loads(r[3]),
             "items": r[4]}
            for r in rows
        ]  # fmt: skip

    def topologies(self, sweep_id: str) -> list[tuple[str, str]]:
        """``(name, spec)`` of a sweep's topologies in registration order."""
        return [
            (n, s)
            for n, s in self._db.execute(
                "SELECT name, spec FROM topologies WHERE sweep_id = ? ORDER BY position",
                (sweep_id,),
            )
        ]

    # ---- items -----------------------------------------------------------------------------
    def done(self, sweep_id: str, round: int) -> set[tuple[str, int]]:
        """``(topology, run)`` of every stored item of a round."""
        return {
            (t, int(r))
            for t, r in self._db.execute(
                "SELECT topology, run FROM items WHERE sweep_id = ? AND round = ?",
                (sweep_id, round),
            )
        }

    def write(self, sweep_id: str, result: ItemResult) -> bool:
        """Store one finished run in its own transaction; False if it was already there
        with the same versions (a row of other versions is replaced)."""
        q = np.ascontiguousarray(result.q, dtype="<f8")
        if q.ndim != 2:
            q = q.reshape(0, 0)
        m = result.measures
        row = (
            sweep_id, result.topology, int(result.round), int(result.run), int(result.seed),
            int(result.n_points), int(result.n_reached), int(result.feasible),
            _real(result.e_obj), int(result.iterations), int(bool(result.converged)),
            None if m is None else m.gci, None if m is None else m.kci,
            None if m is None else m.mean, None if m is None else m.manipulability,
            None if m is None else m.length, None if m is None else int(m.prismatic),
            None if m is None else _real(m.size), None if m is None else _real(m.limits),
            None if m is None else _real(m.bounds),
            None if m is None else _real(m.clearance),
            _real(result.max_position_error), _real(result.max_orientation_error),
            json.dumps(list(result.design_names)), json.dumps(list(result.design)),
            json.dumps(list(result.status)), q.tobytes(), int(q.shape[0]), int(q.shape[1]),
            result.error, float(result.wall_s), result.worker,
            json.dumps(result.versions, sort_keys=True),
            datetime.now(UTC).isoformat(),
        )  # fmt: skip
        sql = (
            f"INSERT INTO items({', '.join(_COLUMNS)}) VALUES ({', '.join('?' * len(_COLUMNS))}) "
            "ON CONFLICT(sweep_id, topology, round, run) DO UPDATE SET "
            + ", ".join(f"{c} = excluded.{c}" for c in _COLUMNS[4:])
            + " WHERE items.versions != excluded.versions"
        )
        with self._tx():
            cur = self._db.execute(sql, row)
            return cur.rowcount == 1

    def results(self, sweep_id: str, round: int | None = None) -> list[ItemResult]:
        """Stored items of a sweep (one round or all), ordered by round, topology, run."""
        where = "sweep_id = ?" + ("" if round is None else " AND round = ?")
        args: tuple[Any, ...] = (sweep_id,) if round is None else (sweep_id, round)
        cur = self._db.execute(
            f"SELECT {', '.join(_COLUMNS)} FROM items WHERE {where} ORDER BY round, topology, run",
            args,
        )
        return [self._item(dict(zip(_COLUMNS, r, strict=True))) for r in cur]

    @staticmethod
    def _item(r: dict[str, Any]) -> ItemResult:
        measures = None
        if r["gci"] is not None:
            measures = Measures(
                gci=float(r["gci"]), kci=float(r["kci"]), mean=float(r["mean"]),
                manipulability=float(r["manipulability"]), length=float(r["length"]),
                prismatic=int(r["prismatic"]), size=_float(r["size"]),
                limits=_float(r["limits"]), bounds=_float(r["bounds"]),
                clearance=_float(r["clearance"]),
            )  # fmt: skip
        q = np.frombuffer(r["q"], dtype="<f8").reshape(r["q_rows"], r["q_cols"]).copy()
        return ItemResult(
            topology=r["topology"],
            round=int(r["round"]),
            run=int(r["run"]),
            seed=int(r["seed"]),
            n_points=int(r["n_points"]),
            n_reached=int(r["n_reached"]),
            e_obj=_float(r["e_obj"]),
            iterations=int(r["iterations"]),
            converged=bool(r["converged"]),
            measures=measures,
            design_names=tuple(json.loads(r["design_names"])),
            design=tuple(float(v) for v in json.loads(r["design"])),
            q=q,
            status=tuple(json.loads(r["status"])),
            max_position_error=_float(r["max_position_error"]),
            max_orientation_error=_float(r["max_orientation_error"]),
            error=r["error"],
            wall_s=float(r["wall_s"]),
            worker=r["worker"],
            versions=json.loads(r["versions"]),
        )

    def count(self, sweep_id: str | None = None) -> int:
        """Number of stored items (of one sweep, or all)."""
        if sweep_id is None:
            return int(self._db.execute("SELECT COUNT(*) FROM items").fetchone()[0])
        return int(
            self._db.execute(
                "SELECT COUNT(*) FROM items WHERE sweep_id = ?", (sweep_id,)
            ).fetchone()[0]
        )

    def integrity(self) -> str:
        """``PRAGMA integrity_check`` (``"ok"`` for a sound database)."""
        return str(self._db.execute("PRAGMA integrity_check").fetchone()[0])


class _Transaction:
    """``BEGIN IMMEDIATE`` … ``COMMIT`` (``ROLLBACK`` on error) on an autocommit connection."""

    def __init__(self, db: sqlite3.Connection) -> None:
        self._db = db

    def __enter__(self) -> None:
        self._db.execute("BEGIN IMMEDIATE")

    def __exit__(self, typ: object, exc: object, tb: object) -> None:
        if typ is None:
            self._db.execute("COMMIT")
        else:
            self._db.execute("ROLLBACK")
