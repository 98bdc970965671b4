"""Settling a Pareto sweep on a problem whose answer is known by brute force.

Two variables ``z = (x, y)`` in the unit square: ``size = x + 0.1`` (to minimize) and
``gci = (0.2 + x) (1 + h(y))`` (to maximize) with two basins in ``y``: a low hump at
``y = 0.2`` and a high one at ``y = 0.8``. A local hill climb on a grid stays in the
basin it starts in. A sweep continued from the low basin holds low designs at every
level; one design found in the high basin must, by settling, carry every level and the
``gci`` end into it — the best each level offers, checked against a brute-force search
over the grid — and which design is the best at a level must not depend on the order
the designs were found.
"""

from __future__ import annotations

from typing import cast

import numpy as np
import pytest

from reachwise.errors import InputError
from reachwise.kinematics.robot import Robot
from reachwise.synthesis.objectives import Objective, Terms
from reachwise.synthesis.pareto import (
    LEVEL_PENALTY,
    ParetoOptions,
    ParetoPoint,
    classify,
    pareto_sweep,
)
from reachwise.synthesis.pareto_settle import Level, Settler
from reachwise.synthesis.problem import SynthesisProblem

STEP = 0.01
GRID = np.round(np.arange(0.0, 1.0 + STEP / 2, STEP), 10)


def values(z: np.ndarray) -> dict[str, float]:
    x, y = float(z[0]), float(z[1])
    h = 0.5 * np.exp(-(((y - 0.2) / 0.1) ** 2)) + np.exp(-(((y - 0.8) / 0.1) ** 2))
    return {"gci": (0.2 + x) * (1.0 + h), "size": x + 0.1}


REF = Terms(values=values(np.array([0.5, 0.2])), gradients={})


def objective(name: str, level: float | None) -> Objective:
    other = "size" if name == "gci" else "gci"
    levels = {} if level is None else {other: level}
    return Objective({name: 1.0}, levels=levels, penalty=LEVEL_PENALTY).referenced(REF)


def cost(z: np.ndarray, name: str, level: float | None) -> float:
    return objective(name, level).cost(Terms(values=values(z), gradients={}))


def climb(z: np.ndarray, name: str, level: float | None) -> np.ndarray:
    """A local method: grid steps to the best neighbour until none is better."""
    z = np.round(np.asarray(z, dtype=float) / STEP) * STEP
    while True:
        moves = [z + STEP * np.array(d) for d in ((1, 0), (-1, 0), (0, 1), (0, -1))]
        moves = [m for m in moves if np.all((m >= -1e-12) & (m <= 1 + 1e-12))]
        best = min(moves, key=lambda m: cost(m, name, level))
        if cost(best, name, level) >= cost(z, name, level):
            return z
        z = best


def point(index: int, z: np.ndarray, name: str, level: float | None, stage: str) -> ParetoPoint:
    other = "size" if name == "gci" else "gci"
    return ParetoPoint(
        index, {name: 1.0, other: 0.0}, cast(Robot, None), z.copy(), np.zeros((1, 1)),
        np.ones(1, dtype=bool), values(z), np.zeros(1), (), level=level,
        stage=stage,  # type: ignore[arg-type]
        z=z.copy(),
    )  # fmt: skip


def sweep_in_the_low_basin() -> list[ParetoPoint]:
    """Ends, levels continued from the ``size`` end (all in the low basin) and one
    design of the high basin at the middle level."""
    found: list[ParetoPoint] = []

    def solve(z: np.ndarray, name: str, level: float | None, stage: str = "level") -> ParetoPoint:
        found.append(point(len(found), climb(z, name, level), name, level, stage))
        return found[-1]

    z0 = np.array([0.5, 0.2])
    solve(z0, "gci", None, "end")
    p = solve(z0, "size", None, "end")
    for level in (0.3, 0.5, 0.7, 0.9):
        p = solve(p.z, "gci", level)
    solve(np.array([0.4, 0.7]), "gci", 0.5, "gap")
    return found


def settler(found: list[ParetoPoint]) -> Settler[ParetoPoint]:
    def solve(z: np.ndarray, name: str, level: float | None) -> ParetoPoint:
        found.append(point(len(found), climb(z, name, level), name, level, "settle"))
        return found[-1]

    return Settler(
        "gci", "size", found, objective,
        lambda p: Terms(values=dict(p.values), gradients={}), solve,
        lambda: [p for p in classify(found, ("gci", "size")) if not p.dominated],
        lambda p, name: p.values[name],
    )  # fmt: skip


def brute_force(name: str, level: float | None) -> float:
    return min(cost(np.array([x, y]), name, level) for x in GRID for y in GRID)


def test_settling_carries_every_level_to_its_best_design() -> None:
    found = sweep_in_the_low_basin()
    s = settler(found)
    levels = [t for t in s.tasks() if t.level is not None]
    assert [t.level for t in levels] == [0.3, 0.5, 0.7, 0.9]
    # before: the low basin holds the levels the continuation solved (not the best)
    assert any(s.score(s.best(t), t)[0] > brute_force(t.name, t.level) + 1e-3 for t in levels)  # type: ignore[arg-type]
    spent = s.run(budget=60)
    assert 0 < spent < 60  # a fixed point within the budget
    for t in [Level("gci", None), *levels]:
        best = s.best(t)
        assert best is not None
        assert abs(best.z[1] - 0.8) <= STEP + 1e-12  # the high basin
        assert s.score(best, t)[0] == pytest.approx(brute_force(t.name, t.level), abs=1e-9)
    # the front gained the high basin's designs: ordered by size, GCI rises with it
    front = sorted(s.front(), key=lambda p: p.values["size"])
    assert len(front) >= 4
    assert all(abs(p.z[1] - 0.8) <= STEP + 1e-12 for p in front if p.values["size"] > 0.15)


def test_the_best_design_at_a_level_does_not_depend_on_the_order_found() -> None:
    found = sweep_in_the_low_basin()
    settler(found).run(budget=60)
    rng = np.random.default_rng(0)
    tasks = settler(list(found)).tasks()
    want = {t.key: settler(list(found)).best(t) for t in tasks}
    for _ in range(5):
        shuffled = [found[i] for i in rng.permutation(len(found))]
        # twins: the same design found twice must still give one answer
        shuffled.append(point(len(found), shuffled[0].z, "gci", 0.5, "settle"))
        s = settler(shuffled)
        for t in tasks:
            got, ref = s.best(t), want[t.key]
            assert got is not None and ref is not None
            assert np.array_equal(got.z, ref.z)


def test_a_negative_settling_budget_is_refused() -> None:
    with pytest.raises(InputError, match="settle"):
        pareto_sweep(
            cast(SynthesisProblem, None), np.zeros(1), ("gci", "size"),
            options=ParetoOptions(settle=-1),
        )  # fmt: skip
