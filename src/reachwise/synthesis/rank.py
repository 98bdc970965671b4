"""Ranking optimized topologies (P-II §5.1, Table 2; thesis §4.2).

After the dimensional synthesis of every topology, "all solutions (topologies) that were
able to reach all of the desired goal points should be organized into an ordered list"
by predefined criteria (P-II §2). P-II Table 2 ranks by the global conditioning index
``GCI = mean LCI`` (Eq. 38), the kinematic conditioning index ``KCI = min LCI``
(Eq. 39; reachwise's reading ``1 / max κ``, see ``kinematics.indices``) and their mean
``(GCI + KCI) / 2`` (Table 2's "Mean" column: e.g. Man1 (0.1043 + 0.0744)/2 = 0.0894).
The LCI is ``1/κ`` of the length-scaled Jacobian (P-I Eq. 34–37) at each task posture.

Further keys, as P-II §6 suggests ("different performance measures can be used"):

* ``manipulability`` — mean over the task of Yoshikawa's ``w = Π σᵢ`` of the same
  length-scaled Jacobian (higher is better; compare designs on the same task only);
* ``length`` — total link length ``Σ (|a_i| + |d_i|)`` over the DH rows (prismatic
  offsets included, strokes not), m (lower is better: a smaller, cheaper machine);
* ``prismatic`` — number of prismatic joints (lower is better);
* ``size``, ``limits``, ``bounds`` — the design objectives of ``objectives`` (lower is
  better): ``Σ |a| + Σ |d|`` of the free length parameters, the mean squared normalized
  distance of the joints from mid-range, and the bound-margin penalty. They need the
  synthesis problem, so ``measures`` leaves them NaN and the sweep fills them in;
* ``clearance`` — the smallest clearance of the design bodies over the task (m, higher is
  better), when the sweep keeps one (``SweepConfig.clearance``): a run that is less
  clear than that at a pose has not reached it, so its topology is rejected as one that
  does not reach; NaN without a clearance.

Only feasible candidates (the best run reaches every task point) are ranked; the others
are reported with ``rank = None`` (P-II Table 2's "−": "no solution for the problem").
Ties are broken deterministically: the selected key, then mean, GCI, KCI (higher
first), link length, prismatic joints (lower first), then the name; figures within a
relative :data:`SAME_FIGURE` count as equal (the rule that picks a topology's best run),
so rounding noise never orders two topologies while a later figure or the name can.
Pure math.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.errors import InputError, check_choice
from reachwise.kinematics.indices import (
    gci,
    inverse_condition,
    kci,
    manipulability,
    nominal_length,
    scaled_jacobian,
)
from reachwise.kinematics.robot import Robot

#: A ranking figure (P-II Table 2): the GCI/KCI mean, GCI, KCI, manipulability, link
#: length, number of prismatic joints, or a design objective (``size``, ``limits``,
#: ``bounds``; see ``objectives``).
RankKey = Literal[
    "mean", "gci", "kci", "manipulability", "length", "prismatic", "size", "limits", "bounds",
    "clearance",
]  # fmt: skip
# key -> +1 when higher is better, -1 when lower is better
RANK_KEYS: dict[RankKey, int] = {
    "mean": 1,
    "gci": 1,
    "kci": 1,
    "manipulability": 1,
    "length": -1,
    "prismatic": -1,
    "size": -1,
    "limits": -1,
    "bounds": -1,
    "clearance": 1,
}


@dataclass(frozen=True)
class Measures:
    """Performance figures of one design over its task (module docstring)."""

    gci: float
    kci: float
    mean: float
    manipulability: float
    length: float
    prismatic: int
    size: float = math.nan
    limits: float = math.nan
    bounds: float = math.nan
    clearance: float = math.nan

    def value(self, key: RankKey) -> float:
        return float(getattr(self, check_key(key)))


def check_key(key: object) -> RankKey:
    """``key`` as a :data:`RankKey`, or :class:`~reachwise.errors.UnknownName`."""
    return check_choice(key, get_args(RankKey), source="rank", kind="rank key")


def link_length(robot: Robot) -> float:
    """``Σ (|a_i| + |d_i|)`` over the DH rows (m); prismatic offsets, not strokes."""
    dh = robot.dh
    return float(np.abs(dh[:, 0]).sum() + np.abs(dh[:, 2]).sum())


def measures(robot: Robot, Q: ArrayLike) -> Measures:
    """GCI, KCI, their mean, mean manipulability, link length and prismatic joints of
    ``robot`` at the task configurations ``Q (m, n)`` (P-II Eq. 38–39, Table 2)."""
    from reachwise.kinematics.jacobian import jacobians

    Qa = np.atleast_2d(np.asarray(Q, dtype=np.float64))
    T, J, _ = jacobians(robot, Qa, params=False)
    Js = scaled_jacobian(J, nominal_length(robot, T))
    lcis = np.asarray(inverse_condition(Js), dtype=np.float64)
    g, k = gci(lcis), kci(lcis)
    w = np.asarray(manipulability(Js), dtype=np.float64)
    return Measures(
        gci=g,
        kci=k,
        mean=0.5 * (g + k),
        manipulability=float(np.mean(w)),
        length=link_length(robot),
        prismatic=int(np.sum(robot.prismatic)),
    )


@dataclass(frozen=True)
class Candidate:
    """One optimized topology to rank: its best run's figures on a task.

    ``n_reached`` of ``n_points`` task points reached; feasible when all are.
    ``measures`` is ``None`` when the synthesis failed outright (an error)."""

    name: str
    n_reached: int
    n_points: int
    measures: Measures | None
    e_obj: float = math.inf

    @property
    def feasible(self) -> bool:
        return self.measures is not None and self.n_reached == self.n_points


@dataclass(frozen=True)
class RankedRow:
    """A row of the ranked table: ``rank`` (1 = best) or ``None`` when infeasible."""

    rank: int | None
    candidate: Candidate


def order_figures(m: Measures, key: RankKey) -> tuple[float, ...]:
    """The figures designs are ordered by, each lower-is-better: the key (a value not
    taken, NaN or infinite, the worst), then mean, GCI, KCI (higher first), link length
    and prismatic joints (lower first)."""
    v = m.value(key)
    return (
        -RANK_KEYS[key] * (v if math.isfinite(v) else -RANK_KEYS[key] * math.inf),
        -m.mean,
        -m.gci,
        -m.kci,
        m.length,
        m.prismatic,
    )


def _figures(c: Candidate, key: RankKey) -> tuple[float, ...]:
    m = c.measures
    if m is None:  # pragma: no cover - infeasible ones are sorted separately
        raise InputError("rank", c.name, "no measures")
    return order_figures(m, key)


def rank(candidates: Sequence[Candidate], key: RankKey = "mean") -> tuple[RankedRow, ...]:
    """Feasible candidates ordered by ``key`` (ranks 1, 2, …), then the infeasible ones
    (``rank = None``; most points reached first, then by name). Figures compare as in
    :func:`first_best` (within :data:`SAME_FIGURE` equal: the next figure decides, finally
    the name): rank 1 is the candidate :func:`first_best` picks among all, rank 2 among
    the rest, and so on (:func:`best_first`). Deterministic."""
    key = check_key(key)
    names = [c.name for c in candidates]
    if len(set(names)) != len(names):
        raise InputError("rank", "candidates", "candidate names must be unique")
    feasible = sorted((c for c in candidates if c.feasible), key=lambda c: c.name)
    ok = [feasible[i] for i in best_first([_figures(c, key) for c in feasible])]
    bad = sorted((c for c in candidates if not c.feasible), key=lambda c: (-c.n_reached, c.name))
    return tuple(RankedRow(i + 1, c) for i, c in enumerate(ok)) + tuple(
        RankedRow(None, c) for c in bad
    )


#: Relative difference below which two figures of runs count as equal when the best
#: run is chosen (:func:`first_best`): rounding noise (a sum in another order, another
#: BLAS kernel) moves a figure by far less, a different design by far more.
SAME_FIGURE = 1e-9


def _same_as(values: NDArray[np.float64], ref: float) -> NDArray[np.bool_]:
    """Which ``values`` equal ``ref`` within a relative :data:`SAME_FIGURE` (non-finite
    ones only when identical)."""
    finite = np.isfinite(values) & math.isfinite(ref)
    with np.errstate(invalid="ignore"):
        near = np.abs(values - ref) <= SAME_FIGURE * np.maximum(np.abs(values), abs(ref))
    return np.where(finite, near, values == ref)


def same_figure(a: float, b: float) -> bool:
    """Whether two figures are equal within a relative :data:`SAME_FIGURE` (non-finite
    ones only when identical)."""
    return bool(_same_as(np.array([a], dtype=np.float64), b)[0])


def _figure_table(figures: Sequence[tuple[float, ...]]) -> NDArray[np.float64]:
    """``figures`` as rows of an array, a NaN (a figure not taken) the worst (+inf)."""
    table = np.array(figures, dtype=np.float64).reshape(len(figures), -1)
    table[np.isnan(table)] = math.inf
    return table


def _first_of(table: NDArray[np.float64], rows: NDArray[np.intp]) -> int:
    """The best of ``rows`` of ``table``: figure by figure, the rows within
    :data:`SAME_FIGURE` of the smallest stay; then the lowest row."""
    for j in range(table.shape[1]):
        if rows.size == 1:
            break
        col = table[rows, j]
        rows = rows[_same_as(col, float(col.min()))]
    return int(rows[0])


def first_best(figures: Sequence[tuple[float, ...]]) -> int:
    """Index of the smallest of ``figures`` (tuples of one length, each figure
    lower-is-better) compared figure by figure, figures within :data:`SAME_FIGURE`
    equal; a tie goes to the lowest index. So rounding noise in a figure never decides
    while a later figure can. A NaN figure is the worst."""
    if not figures:
        raise InputError("rank", "runs", "no run")
    table = _figure_table(figures)
    return _first_of(table, np.arange(len(table)))


def best_first(figures: Sequence[tuple[float, ...]]) -> list[int]:
    """Indices of ``figures`` best first: the :func:`first_best` of all, then of the
    rest, and so on. Equal to sorting the tuples when no two figures are within
    :data:`SAME_FIGURE` of each other without being equal; figures within it never
    decide while a later figure or the index can."""
    if not figures:
        return []
    table = _figure_table(figures)
    left = np.arange(len(table))
    out: list[int] = []
    while left.size:
        i = _first_of(table, left)
        out.append(i)
        left = left[left != i]
    return out


def best_run_index(
    n_reached: Sequence[int],
    e_obj: Sequence[float],
    objective: Sequence[float] | None = None,
    conditioning: Sequence[tuple[float, float]] | None = None,
    n_points: int | None = None,
) -> int:
    """The best of a set of runs (the rule of ``synthesize``): most points reached,
    then the smallest weighted design ``objective`` (when given), then the smallest pose
    error ``e_obj``, then the first. With ``conditioning`` ((GCI, KCI) per run, P-II
    Eq. 38–39) and ``n_points``, runs that reach all ``n_points`` compare GCI, then KCI
    (higher first) instead of ``e_obj``: a converged run's pose error is rounding noise
    (about 1e-13) that any change in summation order or library reorders. Figures
    within :data:`SAME_FIGURE` are equal (:func:`first_best`)."""
    if not n_reached:
        raise InputError("rank", "runs", "no run")
    obj = [0.0] * len(n_reached) if objective is None else list(objective)

    def figures(i: int) -> tuple[float, ...]:
        if conditioning is not None and n_reached[i] == n_points:
            g, k = (v if math.isfinite(v) else -math.inf for v in conditioning[i])
            return (-float(n_reached[i]), obj[i], 0.0, -g, -k)
        e = e_obj[i] if math.isfinite(e_obj[i]) else math.inf
        return (-float(n_reached[i]), obj[i], e, math.inf, math.inf)

    return first_best([figures(i) for i in range(len(n_reached))])
