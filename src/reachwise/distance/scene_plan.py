"""What a scene query needs, made once per change of the scene's contents.

:func:`make_plan` turns the watched pairs, the objects and the robots of a
:class:`~reachwise.distance.scene.Scene` into a :class:`QueryPlan`: the pair table the
compiled query reads (``reachwise.distance.scene_arrays.SceneArrays``; warm starts
kept for the pairs unchanged since the last plan), the robots whose forward kinematics
place a watched object, and the inputs whose time stamps the answer depends on.
:meth:`Scene.query_all <reachwise.distance.scene.Scene.query_all>` reuses the plan
until a robot, an object, a pair or a cloud changes.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from reachwise.distance.engine import StrategyName
from reachwise.distance.pairs import WatchedPair
from reachwise.distance.scene_arrays import SceneArrays
from reachwise.distance.scene_types import OnLink, RobotLike, Runtime, SceneObject
from reachwise.kinematics.robot import Robot

__all__ = ["QueryPlan", "make_plan"]


@dataclass(frozen=True, eq=False)
class QueryPlan:
    """What :meth:`Scene.query_all <reachwise.distance.scene.Scene.query_all>` needs:
    ``layout`` the watched pairs in order, ``objects`` their names, ``kinematics``
    (robot name, robot, its frame rows or None for a robot that is not a
    :class:`~reachwise.kinematics.robot.Robot`) for the robots placing a watched object,
    ``robots`` and ``runtime`` whose stamps the answer depends on, ``arguments`` of the
    compiled query after the rows (None: pair by pair)."""

    layout: tuple[WatchedPair, ...]
    objects: frozenset[str]
    kinematics: tuple[tuple[str, RobotLike, NDArray[np.float64] | None], ...]
    robots: tuple[str, ...]
    runtime: tuple[str, ...]
    arguments: tuple[object, ...] | None

    def with_arguments(self, arguments: tuple[object, ...]) -> QueryPlan:
        """The same plan over the compiled query's new ``arguments`` (a cloud swapped in)."""
        return QueryPlan(
            self.layout, self.objects, self.kinematics, self.robots, self.runtime, arguments
        )


@dataclass(frozen=True, eq=False)
class SceneContents:
    """What a plan is made from: the scene's watched ``pairs`` (in order), ``objects``
    and ``robots`` by name, each object's ``slot`` and each robot's first ``frame_row``
    in ``arrays``, the pairs whose warm start is dropped (``fresh``) and the
    ``strategy`` (the default one answers in one compiled call)."""

    arrays: SceneArrays
    pairs: Mapping[tuple[str, str], WatchedPair]
    objects: Mapping[str, SceneObject]
    robots: Mapping[str, RobotLike]
    slot: Mapping[str, int]
    frame_row: Mapping[str, int]
    fresh: set[tuple[str, str]]
    strategy: StrategyName


def make_plan(contents: SceneContents) -> QueryPlan:
    """What a query needs, from the current contents: the pair table (warm starts
    kept for pairs unchanged since the last plan; ``contents.fresh`` is emptied), the
    robots whose kinematics place a watched object, the stamps to check."""
    arrays = contents.arrays
    old = _plan_warm(arrays, contents.slot)
    layout = tuple(contents.pairs.values())
    slot = contents.slot
    warm = np.full((len(layout), 2), -1, np.int64)
    for k, p in enumerate(layout):
        key = (p.a, p.b)
        if key in old and key not in contents.fresh:
            warm[k] = old[key]
    contents.fresh.clear()
    arrays.set_pairs(
        np.array([slot[p.a] for p in layout], np.int64),
        np.array([slot[p.b] for p in layout], np.int64),
        np.array([p.margin for p in layout], np.float64),
        warm,
    )
    used = {n for p in layout for n in (p.a, p.b)}
    robots: list[str] = []
    runtime = []
    for n in sorted(used, key=slot.__getitem__):
        src = contents.objects[n].source
        if isinstance(src, OnLink) and src.robot not in robots:
            robots.append(src.robot)
        elif isinstance(src, Runtime):
            runtime.append(n)
    kinematics = []
    for r in robots:
        robot = contents.robots[r]
        row = contents.frame_row[r]
        native = isinstance(robot, Robot)
        frames = arrays.frames[row : row + len(robot.link_names)] if native else None
        kinematics.append((r, robot, frames))
    args = arrays.arguments() if contents.strategy == "default" else None
    return QueryPlan(
        layout, frozenset(used), tuple(kinematics), tuple(robots), tuple(runtime), args
    )


def _plan_warm(
    arrays: SceneArrays, slot: Mapping[str, int]
) -> dict[tuple[str, str], NDArray[np.int64]]:
    """The warm starts of the pairs in the last plan's table, by pair."""
    if arrays.warm.shape[0] == 0:
        return {}
    names = {s: n for n, s in slot.items()}
    return {
        (names[a], names[b]): arrays.warm[k].copy()
        for k, (a, b) in enumerate(zip(arrays.pair_a.tolist(), arrays.pair_b.tolist(), strict=True))
    }
