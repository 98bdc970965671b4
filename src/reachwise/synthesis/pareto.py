"""Pareto fronts of two design objectives (beyond the thesis).

Real design trades reach margin, conditioning, size and joint travel; one weighted sum
gives one design. The front here is built from one design that reaches every pose (the
reach-only best run), every design of it improved in the null space of the task
(``improve``), so every design reaches every pose:

1. the two ends: the design improved for objective ``a`` alone and for ``b`` alone;
2. between them, ``points − 2`` designs that improve ``a`` while ``b`` is held at evenly
   spaced levels between its values at the two ends (the ε-constraint method, the level
   enforced by a penalty, ``objectives.Objective.levels``), each starting from the
   previous one (a continuation from the ``a`` end). A sweep of the weights alone would
   reach only the convex hull of the front — on the SB60 family it jumps from one end
   to the other — while the levels spread the designs along it;
3. each end once more, from the best design for its objective that the sweep found (a
   local method's first end can land short of what the continuation reached).

Each design is measured by the objectives' own values (GCI and KCI as P-II Eq. 38–39
define them, the others as ``objectives`` does), and the designs no other design beats in
both (the non-dominated ones) form the front. Pure math.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import InputError
from reachwise.kinematics.indices import gci, kci, lci
from reachwise.kinematics.robot import Robot
from reachwise.synthesis.bound_hits import BoundHit, bound_hits
from reachwise.synthesis.improve import ImproveOptions, improve
from reachwise.synthesis.objectives import OBJECTIVES, Objective, check_objective, evaluate_terms
from reachwise.synthesis.problem import SynthesisProblem
from reachwise.synthesis.solvers import Workspace

Array = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class ParetoPoint:
    """One design of the front's sweep: its weights (and the level it held the second
    objective at, for an ε-constraint point), the design and joints, whether every pose
    is reached, the objective values (``values``: every objective name) and its LCIs."""

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

    @property
    def all_reached(self) -> bool:
        return bool(self.reached.all())


@dataclass(frozen=True, eq=False)
class ParetoResult:
    """The sweep over two objectives ``names`` from the reach-only ``start`` design."""

    names: tuple[str, str]
    start: ParetoPoint
    points: tuple[ParetoPoint, ...]

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


def dominated(values: Array, senses: Sequence[int], tol: float = 1e-9) -> NDArray[np.bool_]:
    """Per row of ``values (m, k)``: is another row at least as good in every column and
    better in one (``senses``: +1 higher is better, −1 lower)? Rows equal within ``tol``
    (relative) to an earlier row count as dominated by it (one design, one point)."""
    v = np.asarray(values, dtype=np.float64) * np.asarray(senses, dtype=np.float64)
    scale = np.maximum(np.abs(v).max(axis=0), 1e-300)
    m = len(v)
    out = np.zeros(m, dtype=np.bool_)
    for i in range(m):
        for j in range(m):
            if i == j:
                continue
            d = (v[j] - v[i]) / scale
            same = bool(np.all(np.abs(d) <= tol))
            if (same and j < i) or (not same and np.all(d >= -tol) and np.any(d > tol)):
                out[i] = True
                break
    return out


def measure(
    problem: SynthesisProblem,
    z: Array,
    index: int,
    weights: dict[str, float],
    level: float | None = None,
) -> ParetoPoint:
    """A design of the sweep, measured by every objective (GCI/KCI per P-II Eq. 38–39)."""
    design, Q = problem.split(z)
    robot = problem.robot_at(design, name=f"{problem.template.name}-pareto-{index}")
    ev = problem.evaluate(z)
    pos_ok, ori_ok, _ = problem.point_status(ev)
    lcis = np.asarray(lci(robot, Q), dtype=np.float64)
    terms = evaluate_terms(
        problem, z, ("size", "limits", "bounds"), margin=problem.template.design.margin
    )
    values = {"gci": gci(lcis), "kci": kci(lcis), **terms.values}
    return ParetoPoint(
        index, weights, robot, design.copy(), Q, pos_ok & ori_ok, values, lcis,
        tuple(bound_hits(problem, design)), level=level,
    )  # fmt: skip


def pareto_sweep(
    problem: SynthesisProblem,
    z0: Array,
    names: Sequence[str],
    points: int = 8,
    workspace: Workspace | None = None,
    options: ImproveOptions | None = None,
) -> ParetoResult:
    """The front of the module docstring from the reaching vector ``z0``."""
    a, b = check_names(names)
    if points < 2:
        raise InputError("pareto", "points", f"at least 2, got {points}")
    z0 = np.asarray(z0, dtype=np.float64)
    start = measure(problem, z0, -1, {})
    if not start.all_reached:
        raise InputError("pareto", "start", "the start design does not reach every pose")
    margin = problem.template.design.margin
    ref = Objective({a: 1.0, b: 1.0}, margin=margin).terms(problem, z0)

    def solve(z: Array, weights: dict[str, float], levels: dict[str, float]) -> Array:
        obj = Objective(weights, margin=margin, levels=levels).referenced(ref)
        return improve(problem, z, obj, workspace, options).z

    def value(z: Array, name: str) -> float:
        return Objective({name: 1.0}, margin=margin).terms(problem, z).values[name]

    end_a = solve(z0, {a: 1.0}, {})
    end_b = solve(z0, {b: 1.0}, {})
    va, vb = value(end_a, b), value(end_b, b)
    found: list[tuple[Array, dict[str, float], float | None]] = [(end_a, {a: 1.0, b: 0.0}, None)]
    z = end_a
    for t in np.linspace(0.0, 1.0, points)[1:-1]:
        level = float(va + t * (vb - va))
        z = solve(z, {a: 1.0}, {b: level})
        found.append((z, {a: 1.0, b: 0.0}, level))
    found.append((end_b, {a: 0.0, b: 1.0}, None))
    # polish the ends from the best design the sweep found for each objective: a local
    # method's end can land short of what the continuation reached
    for name, w in ((a, {a: 1.0, b: 0.0}), (b, {a: 0.0, b: 1.0})):
        sense = OBJECTIVES[name]
        best = max((f[0] for f in found), key=lambda x: sense * value(x, name))
        found.append((solve(best, {name: 1.0}, {}), w, None))
    out = [measure(problem, x, i, w, lv) for i, (x, w, lv) in enumerate(found)]
    senses = (OBJECTIVES[a], OBJECTIVES[b])
    ok = [p for p in out if p.all_reached]
    vals = np.array([[p.values[a], p.values[b]] for p in ok]).reshape(-1, 2)
    dom = dominated(vals, senses) if ok else np.zeros(0, dtype=np.bool_)
    flags = {p.index: bool(d) for p, d in zip(ok, dom, strict=True)}
    marked = tuple(replace(p, dominated=flags.get(p.index, True)) for p in out)
    return ParetoResult((a, b), start, marked)
