"""Pareto fronts of two design objectives (beyond the thesis).

Real design trades reach margin, conditioning, size and joint travel; one weighted sum
gives one design. The front here is built from one design that reaches every pose (the
reach-only best run); every design of it is improved in the null space of the task
(``improve``) from a design that reaches every pose, so every design reaches every pose.
With ``a`` the first objective and ``b`` the second:

1. **the two ends**: the design improved for ``a`` alone and for ``b`` alone;
2. **fixed levels**: ``points − 2`` designs that improve ``a`` while ``b`` is held at
   evenly spaced levels between its values at the two ends (the ε-constraint method,
   the level enforced by a penalty, ``objectives.Objective.levels``), each starting from
   the previous one (a continuation from the ``a`` end). A sweep of the weights alone
   would reach only the convex hull of the front — on the SB60 family it jumps from one
   end to the other — while the levels spread the designs along it;
3. **ends polished**: each end once more from the best design for its objective that
   the sweep found (a local method's first end can land short of what the continuation
   reached), then improved for the other objective with its own held at the value
   reached (a lexicographic end: of the designs as good in ``a``, the best in ``b``);
4. **adaptive levels**: while the front has fewer than ``points`` designs, a new level
   of ``b`` halfway across the largest gap between adjacent front designs (the distance
   in objective space normalized by the front's extent), solved from each of the two
   neighbours (warm starts); a gap that gave no new design is not tried again. The
   sweep stops when the front has ``points`` designs, when no untried gap is wider than
   two tolerances (none can hold a distinct design), or after ``max_solves``
   improvements;
5. **settling** (``pareto_settle``): every end and level solved again from the best
   design known at it and at the levels next to it, pass after pass, until no level's
   scalarised cost improves or ``ParetoOptions.settle`` more improvements are spent. Each design of
   steps 1–4 is the first basin one local solve fell in, and that basin depends on
   rounding: from the same start, perturbed by 1e-12, the (gci, size) front's GCI end
   on the SB60 family moved by 4 %.

**When two designs are the same.** Objective values are compared in units of the
front's extent: the range of each objective over the sweep's reaching designs that no
other reaching design dominates exactly (``front_extent``). A far, dominated design
found late does not widen the unit, so it cannot merge or drop designs of the front. Two
designs whose values differ by at most ``same`` (default 1 %) of that extent in both
objectives are the same design for the front: of such twins, the first found that is
not dominated is kept, the others are marked ``same_as`` it (a twin of a dominated
design is judged on its own, ``classify``). A design is dominated when another is at
least as good in both objectives up to that tolerance and better by more than it in
one (ε-dominance): a design 0.01 % smaller but 30 % worse conditioned does not stand
next to the better one as a trade-off.

**Why the first version returned fewer designs than levels.** Its ε-points collapsed
onto one design: once the continuation met the size term's kink (a length at 0, where
``|d|`` is not differentiable) or a working set of joint limits that it never released,
every later level started from that design and no step was accepted (``improve``
explains both; they are fixed there). And its ``a`` end stopped short of designs the
continuation found, so it was dominated. The front's size then depended on rounding
(a 1e-15 change in the damped least squares moved it from 5 designs to 4).

Every design is checked by forward kinematics (``fk_check``, independent of the
solver's residual) and only designs that reach every pose count. Each design is
measured by the objectives' own values (GCI and KCI as P-II Eq. 38–39 define them, the
clearance as the true smallest term over the task, the others as ``objectives`` does).

**With bodies** (``clearance``, a ``clearance.ClearanceModel``): every improvement keeps
every clearance term at least the model's clearance (``improve``), a design counts as
reaching a pose only when it is that clear there too, and ``clearance`` may be one of
the two objectives (``--pareto clearance,size``). Pure math.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import InputError
from reachwise.kinematics.indices import gci, kci, lci
from reachwise.kinematics.robot import Robot
from reachwise.synthesis.bound_hits import BoundHit, bound_hits
from reachwise.synthesis.clearance import ClearanceModel
from reachwise.synthesis.fk_check import reached_by_fk
from reachwise.synthesis.improve import ImproveOptions, improve
from reachwise.synthesis.objectives import (
    OBJECTIVES,
    Objective,
    Terms,
    check_objective,
    evaluate_terms,
    smallest_designable,
)
from reachwise.synthesis.pareto_settle import Settler
from reachwise.synthesis.problem import SynthesisProblem
from reachwise.synthesis.solvers import Workspace

Array = NDArray[np.float64]
#: How a design of the sweep was found (module docstring, steps 1–5).
Stage = Literal["start", "end", "level", "polish", "gap", "settle"]
#: Two designs within this fraction of the front's extent in both objectives are one.
SAME = 0.01
#: Stiffness of the level penalty (``objectives.Objective.penalty``): a level is held
#: to within ~0.5 % where the front is steep (30 let designs drift 10 % past it).
LEVEL_PENALTY = 1000.0
#: The improvement's stopping tolerance in the sweep (relative decrease over its
#: window): designs are told apart at 1 % of the front's extent, 1e-4 bought nothing.
#: The bodies' barrier acts within 5 mm of the clearance: with the improvement's 5 cm,
#: on the whole tunnel-87 (start solved at 0.05 m, the front keeping 0.025 m) the 27
#: boom–feed terms at 0.05 m put ~7 into the cost against ~1 of the objective, and
#: the sweep spanned 0.15 % in size (4 designs); with 5 mm, 5 designs (clearance
#: 0.030–0.069 m, size 6.418–6.473 m).
#: A solve that ends above its start's cost still returns its own design: the start is
#: a design the sweep has already (or the reach-only start), and a different design
#: is one more candidate for the front (``ImproveOptions.never_worse``; with it, the
#: whole tunnel-87's front had 4 designs instead of 5).
SWEEP_OPTIONS = ImproveOptions(tolerance=1e-3, clearance_band=0.005, never_worse=False)


@dataclass(frozen=True)
class ParetoOptions:
    """Options of the sweep beyond the improvement's: ``improve`` (default
    ``SWEEP_OPTIONS``), ``settle``, the settling passes' budget of improvements
    (module docstring, step 5; default ``2 · points + 4``, 0 turns them off), and
    ``progress``, called after each improvement with a ``ParetoProgress`` (a
    ``KeyboardInterrupt`` it raises propagates: ending the sweep is ``stop``'s)."""

    improve: ImproveOptions | None = None
    settle: int | None = None
    progress: Callable[[ParetoProgress], None] | None = None


@dataclass(frozen=True, eq=False)
class ParetoPoint:
    """One design of the front's sweep: its weights (and the level it held the second
    objective at, for an ε-constraint point), the design and joints, whether every pose
    is reached (forward kinematics, ``fk_check``), the objective values (``values``:
    every objective name) and its LCIs; ``dominated`` when it is not on the front
    (dominated, the same as the earlier design ``same_as``, or not reaching)."""

    index: int
    weights: dict[str, float]
    robot: Robot
    design: Array
    q: Array
    reached: NDArray[np.bool_]
    values: dict[str, float]
    lci: Array
    bound_hits: tuple[BoundHit, ...]
    dominated: bool = False
    level: float | None = None  # the second objective's level (ε-constraint point)
    stage: Stage = "level"
    same_as: int | None = None
    z: Array = field(default_factory=lambda: np.zeros(0))  # the decision vector

    @property
    def all_reached(self) -> bool:
        return bool(self.reached.all())


@dataclass(frozen=True)
class ParetoProgress:
    """One improvement of the sweep done: its ``stage`` (module docstring, steps 1–5),
    the improvements done (``solves``) and the sweep's ``budget`` of them (steps 1–4
    and the settling's; the sweep may end before it), the designs on the front so far
    (``front``) and the last design's values of the two objectives (``values``, in the
    order of the sweep's names)."""

    stage: Stage
    solves: int
    budget: int
    front: int
    values: tuple[float, float]


class _Stopped(Exception):
    """The sweep's ``stop`` callback asked to end it."""


@dataclass(frozen=True, eq=False)
class ParetoResult:
    """The sweep over two objectives ``names`` from the reach-only ``start`` design;
    ``points`` holds every design tried, ``front`` the non-dominated distinct ones;
    ``target`` is the number of front designs asked for, ``same`` the tolerance;
    ``partial`` when the sweep was stopped (``pareto_sweep``'s ``stop``) before its end,
    its front then being that of the designs found until the stop."""

    names: tuple[str, str]
    start: ParetoPoint
    points: tuple[ParetoPoint, ...]
    target: int = 0
    same: float = SAME
    partial: bool = False  # the sweep was stopped: the designs found until then

    @property
    def front(self) -> tuple[ParetoPoint, ...]:
        """The non-dominated designs, ordered by the first objective's value."""
        keep = [p for p in self.points if not p.dominated]
        return tuple(sorted(keep, key=lambda p: p.values[self.names[0]]))


def check_names(names: Sequence[str]) -> tuple[str, str]:
    """Two different objective names."""
    if len(names) != 2 or names[0] == names[1]:
        raise InputError("pareto", "objectives", f"two different objectives, got {list(names)}")
    check_objective(dict.fromkeys(names, 1.0), "pareto")
    return names[0], names[1]


def dominated(
    values: Array,
    senses: Sequence[int],
    tol: float = 1e-9,
    scale: Array | None = None,
    twins: bool = True,
) -> NDArray[np.bool_]:
    """Per row of ``values (m, k)``: is another row at least as good in every column
    (up to ``tol``) and better by more than ``tol`` in one (``senses``: +1 higher is
    better, −1 lower)? With ``twins``, rows within ``tol`` of an earlier row in every
    column count as dominated by it (one design, one point). Differences are measured
    in units of ``scale`` per column (default: the column's largest magnitude)."""
    v = np.asarray(values, dtype=np.float64) * np.asarray(senses, dtype=np.float64)
    if scale is None:
        scale = np.abs(v).max(axis=0) if len(v) else np.ones(v.shape[1])
    scale = np.maximum(np.asarray(scale, dtype=np.float64), 1e-300)
    m = len(v)
    out = np.zeros(m, dtype=np.bool_)
    for i in range(m):
        for j in range(m):
            if i == j:
                continue
            d = (v[j] - v[i]) / scale
            same = bool(np.all(np.abs(d) <= tol))
            if (twins and same and j < i) or (not same and np.all(d >= -tol) and np.any(d > tol)):
                out[i] = True
                break
    return out


def extent(values: Array) -> Array:
    """Per column of ``values (m, k)``: its range, floored (a single design, or an
    objective that does not change, gives a unit of 1e-9 of its magnitude)."""
    v = np.asarray(values, dtype=np.float64).reshape(-1, 2)
    if len(v) == 0:
        return np.ones(2)
    span = v.max(axis=0) - v.min(axis=0)
    return np.asarray(np.maximum(span, np.maximum(1e-9 * np.abs(v).max(axis=0), 1e-300)))


def front_extent(values: Array, senses: Sequence[int]) -> Array:
    """``extent`` of the rows of ``values (m, k)`` that no other row dominates exactly
    (at least as good in every column, better in one; ``senses`` as in ``dominated``):
    the front's own range, whatever dominated designs lie around it."""
    v = np.asarray(values, dtype=np.float64).reshape(-1, 2)
    if len(v) == 0:
        return extent(v)
    return extent(v[~dominated(v, senses, tol=0.0, scale=np.ones(2), twins=False)])


def classify(points: Sequence[ParetoPoint], names: tuple[str, str], same: float = SAME
             ) -> list[ParetoPoint]:  # fmt: skip
    """``points`` with ``dominated`` and ``same_as`` set (module docstring): designs that
    do not reach every pose are off the front; of the others, those ε-dominated, or the
    same as an earlier design that is kept (in the order found).

    A design is dropped as a twin only of a design that stays on the front: were it
    dropped as the twin of an earlier design that is itself dominated, a chain of twins
    and dominance could empty the front (seen on tunnel-87: 18 reaching designs, every
    one marked). The ε-dominance alone never empties it: a design that ε-dominates
    another is better by more than ``same`` in one objective and worse by at most
    ``same`` in the other, so the sum of both (in units of the extent, signed so that
    higher is better) grows strictly along it and the design with the largest sum is
    not dominated; the first such design found is kept."""
    a, b = names
    ok = [p for p in points if p.all_reached]
    vals = np.array([[p.values[a], p.values[b]] for p in ok]).reshape(-1, 2)
    senses = (OBJECTIVES[a], OBJECTIVES[b])
    scale = front_extent(vals, senses)
    beaten = dominated(vals, senses, same, scale, twins=False) if ok else np.zeros(0, bool)
    flags: dict[int, bool] = {}
    twin: dict[int, int | None] = {}
    kept: list[int] = []
    for i, p in enumerate(ok):
        twin[p.index] = next(
            (ok[j].index for j in kept if np.all(np.abs(vals[j] - vals[i]) / scale <= same)),
            None,
        )
        flags[p.index] = bool(beaten[i]) or twin[p.index] is not None
        if not flags[p.index]:
            kept.append(i)
    return [
        replace(p, dominated=flags.get(p.index, True), same_as=twin.get(p.index)) for p in points
    ]


def _on_front(
    p: ParetoPoint, points: Sequence[ParetoPoint], names: tuple[str, str], same: float
) -> bool:
    """Is ``p`` (one of ``points``) a distinct, non-dominated design among them?"""
    mine = [q for q in classify(points, names, same) if q.index == p.index]
    return bool(mine) and not mine[0].dominated


def measure(
    problem: SynthesisProblem,
    z: Array,
    index: int,
    weights: dict[str, float],
    level: float | None = None,
    stage: Stage = "level",
    bodies: ClearanceModel | None = None,
) -> ParetoPoint:
    """A design of the sweep, measured by every objective (GCI/KCI per P-II Eq. 38–39)
    and checked by forward kinematics at every posture (``fk_check``); with ``bodies``
    its clearance too (the smallest term; a pose less clear than the model's clearance
    is not reached)."""
    design, Q = problem.split(z)
    robot = problem.robot_at(design, name=f"{problem.template.name}-pareto-{index}")
    reached = reached_by_fk(robot, Q, problem.task) & problem.within_bounds(z)
    lcis = np.asarray(lci(robot, Q), dtype=np.float64)
    terms = evaluate_terms(
        problem, z, ("size", "limits", "bounds"), margin=problem.template.design.margin
    )
    values = {"gci": gci(lcis), "kci": kci(lcis), **terms.values}
    if bodies is not None:
        d = bodies.terms(problem, z).distance
        smallest = d.min(axis=1) if d.shape[1] else np.full(problem.K, np.inf)
        reached = reached & (smallest >= bodies.clearance)
        values["clearance"] = smallest_designable(bodies, problem, z)
    return ParetoPoint(
        index, weights, robot, design.copy(), Q, reached, values, lcis,
        tuple(bound_hits(problem, design)), level=level, stage=stage, z=z.copy(),
    )  # fmt: skip


@dataclass
class _Sweep:
    """The designs a sweep has found and how it improves one more (module docstring):
    the problem, the two objectives ``a`` and ``b``, the workspace, the improvement's
    options, the bodies' model, the common reference of the objectives' terms and the
    ``stop`` and ``progress`` callbacks (``pareto_sweep``) with the ``budget`` of
    improvements the progress reports and the tolerance ``same`` it counts the front by."""

    problem: SynthesisProblem
    a: str
    b: str
    workspace: Workspace | None
    options: ImproveOptions
    clearance: ClearanceModel | None
    ref: Terms
    stop: Callable[[], None] | None
    progress: Callable[[ParetoProgress], None] | None = None
    budget: int = 0
    same: float = SAME
    found: list[ParetoPoint] = field(default_factory=list)

    @property
    def margin(self) -> float:
        return self.problem.template.design.margin

    def level_of(self, p: ParetoPoint, name: str) -> float:
        """A design's value of ``name`` as a level is held: the optimized term's, which
        for the clearance is the soft minimum (``objectives``), not the true one."""
        if name != "clearance":
            return p.values[name]
        soft = evaluate_terms(self.problem, p.z, (name,), margin=self.margin, bodies=self.clearance)
        return soft.values[name]

    def objective(self, name: str, level: float | None = None) -> Objective:
        """The scalarised objective of one design of the sweep: improve ``name``, the
        other objective held at ``level`` (none: an end), referenced to the start."""
        other = self.b if name == self.a else self.a
        levels = {} if level is None else {other: level}
        return Objective(
            {name: 1.0}, margin=self.margin, levels=levels, penalty=LEVEL_PENALTY,
            bodies=self.clearance,
        ).referenced(self.ref)  # fmt: skip

    def terms(self, p: ParetoPoint) -> Terms:
        """Both objectives' terms of a design (what every scalarised cost reads)."""
        both = Objective({self.a: 1.0, self.b: 1.0}, margin=self.margin, bodies=self.clearance)
        return both.terms(self.problem, p.z)

    def settle(self, budget: int, same: float) -> int:
        """Step 5: the settling passes of ``pareto_settle`` with at most ``budget``
        improvements; returns how many it spent."""
        names = (self.a, self.b)
        settler = Settler(
            self.a, self.b, self.found, self.objective, self.terms,
            lambda z, name, level: self.solve(z, name, level, stage="settle"),
            lambda: [p for p in classify(self.found, names, same) if not p.dominated],
            self.level_of,
        )  # fmt: skip
        return settler.run(budget)

    def solve(self, z: Array, name: str, level: float | None = None, stage: Stage = "level"
              ) -> ParetoPoint:  # fmt: skip
        """Improve ``name`` from ``z`` (holding the other objective at ``level``); report
        it to ``progress``. A ``KeyboardInterrupt`` of ``stop`` ends the sweep."""
        if self.stop is not None:
            try:
                self.stop()
            except KeyboardInterrupt:
                raise _Stopped from None
        other = self.b if name == self.a else self.a
        obj = self.objective(name, level)
        z1 = improve(self.problem, z, obj, self.workspace, self.options, self.clearance).z
        p = measure(
            self.problem, z1, len(self.found), {name: 1.0, other: 0.0}, level, stage,
            self.clearance,
        )  # fmt: skip
        self.found.append(p)
        if self.progress is not None:
            names = (self.a, self.b)
            front = sum(not q.dominated for q in classify(self.found, names, self.same))
            values = (p.values[self.a], p.values[self.b])
            done = len(self.found)  # an end's polish in settling may go one past its budget
            self.progress(ParetoProgress(stage, done, max(self.budget, done), front, values))
        return p

    def best(self, name: str) -> ParetoPoint:
        """The design found best in ``name`` (of those reaching every pose, if any)."""
        ok = [p for p in self.found if p.all_reached] or self.found
        return max(ok, key=lambda p: OBJECTIVES[name] * p.values[name])

    def ends_and_levels(self, z0: Array, points: int) -> None:
        """Steps 1–3: the two ends, the fixed levels of ``b`` continued from each end
        (from the ``b`` end every level is looser than the last, so each ε-problem starts
        from a design that meets its level and the result is at least as good in ``a``;
        from the ``a`` end the level pulls the design across: they follow different
        basins of the improvement, the front keeps the best), and the polished ends."""
        a, b = self.a, self.b
        end_a = self.solve(z0, a, stage="end")
        end_b = self.solve(z0, b, stage="end")
        va, vb = self.level_of(end_a, b), self.level_of(end_b, b)
        for ts, p in (
            (np.linspace(1.0, 0.0, points), end_b),
            (np.linspace(0.0, 1.0, points), end_a),
        ):
            for t in ts[1:-1]:
                p = self.solve(p.z, a, float(va + t * (vb - va)))
        for name, other in ((a, b), (b, a)):
            top = self.solve(self.best(name).z, name, stage="polish")
            self.solve(top.z, other, self.level_of(top, name), stage="polish")

    def fill_gaps(self, points: int, budget: int, same: float) -> None:
        """Step 4: new levels of ``b`` in the largest untried gaps of the front until it
        has ``points`` designs, no gap is wider than two tolerances, or ``budget``
        improvements are spent. Each level is solved first from the neighbour better in
        ``b``, which meets the level (a feasible start: the result is at least as good
        in ``a``), and from the other only if that gave no new front design."""
        a, b = self.a, self.b
        tried: set[tuple[int, int]] = set()
        while len(self.found) < budget:
            marked = classify(self.found, (a, b), same)
            front = sorted((q for q in marked if not q.dominated), key=lambda q: q.values[a])
            if len(front) >= points:
                return
            vals = np.array([[q.values[a], q.values[b]] for q in front]).reshape(-1, 2)
            unit = extent(vals)
            gaps = []
            for (i, left), right in zip(enumerate(front[:-1]), front[1:], strict=True):
                key = (left.index, right.index)
                width = float(np.linalg.norm((vals[i + 1] - vals[i]) / unit))
                if key not in tried and width > 2.0 * same:
                    gaps.append((width, key, left, right))
            if not gaps:
                return
            _, key, left, right = max(gaps, key=lambda g: g[0])
            tried.add(key)
            level = 0.5 * (self.level_of(left, b) + self.level_of(right, b))
            first, second = sorted((left, right), key=lambda q: -OBJECTIVES[b] * q.values[b])
            new = self.solve(first.z, a, level, stage="gap")
            if len(self.found) < budget and not _on_front(new, self.found, (a, b), same):
                self.solve(second.z, a, level, stage="gap")


def pareto_sweep(
    problem: SynthesisProblem,
    z0: Array,
    names: Sequence[str],
    points: int = 8,
    workspace: Workspace | None = None,
    options: ImproveOptions | ParetoOptions | None = None,
    same: float = SAME,
    max_solves: int | None = None,
    stop: Callable[[], None] | None = None,
    clearance: ClearanceModel | None = None,
) -> ParetoResult:
    """The front of the module docstring from the reaching vector ``z0``: aims at
    ``points`` non-dominated designs with at most ``max_solves`` improvements (default
    ``4 · points + 4``) in steps 1–4, then at most the settling budget in step 5.
    ``stop``, if given, is called before each improvement; a ``KeyboardInterrupt`` it
    raises (a command's Ctrl-C) ends the sweep between the compiled solves, and the
    designs found until then are returned as a ``partial`` result.
    ``clearance`` (the bodies' model) keeps every design that clear and measures it.
    ``options``: the improvement's (``ImproveOptions``, settling by default) or a
    ``ParetoOptions`` with the settling passes' budget and the ``progress`` callback too."""
    a, b = check_names(names)
    if clearance is None and "clearance" in (a, b):
        raise InputError(
            "pareto", "objectives", "the clearance objective needs the bodies' clearance model"
        )
    if points < 2:
        raise InputError("pareto", "points", f"at least 2, got {points}")
    if not 0 < same < 0.5:
        raise InputError("pareto", "same", f"must lie in (0, 0.5), got {same}")
    opts = options if isinstance(options, ParetoOptions) else ParetoOptions(options)
    settle = 2 * points + 4 if opts.settle is None else int(opts.settle)
    if settle < 0:
        raise InputError("pareto", "settle", f"at least 0, got {settle}")
    budget = 4 * points + 4 if max_solves is None else int(max_solves)
    z0 = np.asarray(z0, dtype=np.float64)
    start = measure(problem, z0, -1, {}, stage="start", bodies=clearance)
    if not start.all_reached:
        raise InputError("pareto", "start", "the start design does not reach every pose")
    margin = problem.template.design.margin
    ref = Objective({a: 1.0, b: 1.0}, margin=margin, bodies=clearance).terms(problem, z0)
    total = max(budget, 2 * points + 2) + settle  # steps 1-3 take 2 * points + 2
    sweep = _Sweep(
        problem, a, b, workspace, opts.improve or SWEEP_OPTIONS, clearance, ref, stop,
        opts.progress, total, same,
    )  # fmt: skip
    partial = False
    try:
        sweep.ends_and_levels(z0, points)
        sweep.fill_gaps(points, budget, same)
        sweep.settle(settle, same)
    except _Stopped:
        partial = True
    points_found = tuple(classify(sweep.found, (a, b), same))
    return ParetoResult((a, b), start, points_found, points, same, partial)
