"""Ranked tables of a sweep: one per round (P-II Table 2) and the finished sweep."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import InputError
from reachwise.kinematics.robot import Robot
from reachwise.synthesis.problem import SynthesisProblem
from reachwise.synthesis.rank import (
    Candidate,
    RankedRow,
    RankKey,
    first_best,
    order_figures,
)
from reachwise.synthesis.rank import rank as rank_candidates
from reachwise.synthesis.sweep.config import ROUND_FULL, SweepConfig
from reachwise.synthesis.sweep.items import ItemResult
from reachwise.synthesis.topology.sets import Topology
from reachwise.tasks.task import Task


@dataclass(frozen=True, eq=False)
class RoundTable:
    """The ranked table of one round: rows (``rank.RankedRow``) and, per topology, its
    runs and the index of its best run (:func:`best_run`)."""

    round: int
    task_points: int
    rank_key: RankKey
    rows: tuple[RankedRow, ...]
    runs: dict[str, tuple[ItemResult, ...]]
    best: dict[str, int]

    def best_result(self, name: str) -> ItemResult:
        return self.runs[name][self.best[name]]

    def records(self) -> list[dict[str, Any]]:
        """Plain rows (rank, topology, feasibility, GCI, KCI, mean, …) for reports."""
        out = []
        for row in self.rows:
            c = row.candidate
            b = self.best_result(c.name)
            m = c.measures
            runs = self.runs[c.name]
            out.append(
                {
                    "rank": row.rank,
                    "topology": c.name,
                    "round": self.round,
                    "feasible": c.feasible,
                    "reached": c.n_reached,
                    "points": c.n_points,
                    "gci": None if m is None else m.gci,
                    "kci": None if m is None else m.kci,
                    "mean": None if m is None else m.mean,
                    "manipulability": None if m is None else m.manipulability,
                    "length": None if m is None else m.length,
                    "prismatic": None if m is None else m.prismatic,
                    "clearance": None if m is None else _finite_or_none(m.clearance),
                    "e_obj": c.e_obj,
                    "best_run": b.run,
                    "best_seed": b.seed,
                    "runs": len(runs),
                    "runs_feasible": sum(r.feasible for r in runs),
                    "error": b.error,
                    "note": "" if c.feasible else "error" if b.error else "infeasible",
                }
            )
        return out


def _finite_or_none(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


def _figures(r: ItemResult, key: RankKey, feasible: bool) -> tuple[float, ...]:
    if feasible and r.measures is not None:
        return order_figures(r.measures, key)
    return (r.e_obj if math.isfinite(r.e_obj) else math.inf,)


def best_run(runs: Sequence[ItemResult], key: RankKey) -> int:
    """Index of a topology's best run (the run its row reports), independent of the order
    the runs arrived in and of rounding noise in their figures.

    Most task points reached first. Among runs that reach every point, the best by the
    rank key, then mean, GCI, KCI (higher first), link length and prismatic joints
    (lower first): the figures the sweep ranks topologies by (``rank.order_figures``).
    The pose error ``e_obj`` is not compared there: a converged run's error is rounding
    noise (about 1e-13) that any change in summation order reorders. Among runs that
    miss points, the smallest ``e_obj``. Figures within a relative
    :data:`~reachwise.synthesis.rank.SAME_FIGURE` are equal; a tie goes to the lowest
    run number (:func:`~reachwise.synthesis.rank.first_best`).
    """
    if not runs:
        raise InputError("sweep", "runs", "no run")
    most = max(r.n_reached for r in runs)
    tied = sorted((r for r in runs if r.n_reached == most), key=lambda r: r.run)
    feasible = all(r.feasible for r in tied)
    return runs.index(tied[first_best([_figures(r, key, feasible) for r in tied])])


def round_table(results: Sequence[ItemResult], round: int, key: RankKey) -> RoundTable:
    """Rank the topologies of one round from their runs (best run per topology)."""
    by: dict[str, list[ItemResult]] = {}
    for r in results:
        if r.round == round:
            by.setdefault(r.topology, []).append(r)
    runs = {k: tuple(sorted(v, key=lambda r: r.run)) for k, v in sorted(by.items())}
    best = {k: best_run(v, key) for k, v in runs.items()}
    cands = []
    points = 0
    for k, v in runs.items():
        b = v[best[k]]
        points = max(points, b.n_points)
        cands.append(Candidate(k, b.n_reached, b.n_points, b.measures, b.e_obj))
    return RoundTable(round, points, key, rank_candidates(cands, key), runs, best)


@dataclass(frozen=True, eq=False)
class SweepResult:
    """A finished sweep: the tables of both rounds, which topologies advanced, and the
    final table (round 2, the complete task). ``new_items`` runs were done by this call,
    ``stored_items`` were found in the store and kept, ``stale_items`` (of the new ones)
    were in the store computed by other code or libraries and were run again."""

    sweep_id: str
    task: Task
    subset: NDArray[np.intp] | None
    config: SweepConfig
    topologies: dict[str, Topology]
    round1: RoundTable | None
    final: RoundTable
    advanced: tuple[str, ...]
    new_items: int = 0
    stored_items: int = 0
    stale_items: int = 0

    def ranked(self) -> list[str]:
        """Names of the feasible topologies of the final table, best first."""
        return [r.candidate.name for r in self.final.rows if r.rank is not None]

    def robot(self, name: str, round: int = ROUND_FULL) -> Robot:
        """The optimized design of a topology's best run (base frame included)."""
        table = self.final if round == ROUND_FULL else self.round1
        if table is None or name not in table.runs:
            raise InputError("sweep", "topology", f"{name!r} has no result in round {round}")
        best = table.best_result(name)
        if best.error:
            raise InputError("sweep", "topology", f"{name!r} failed: {best.error}")
        template = self.topologies[name].template
        probe = SynthesisProblem(template, self.task)
        if probe.design_names != best.design_names:
            raise InputError("sweep", "topology", f"{name!r}: stored design does not fit")
        return probe.robot_at(np.array(best.design), name=f"{template.name}-synth")

    def table(self) -> list[dict[str, Any]]:
        """The final ranked table (ranked, then infeasible), plus round-1 rows of the
        topologies that did not advance (``round`` 1, ``rank`` None, ``note`` "not
        advanced" when feasible on the subset but outside the top ``K``)."""
        rows = self.final.records()
        if self.round1 is not None:
            adv = set(self.advanced)
            for r in self.round1.records():
                if r["topology"] not in adv:
                    note = r["note"] or "not advanced"
                    rows.append({**r, "rank": None, "note": note})
        return rows
