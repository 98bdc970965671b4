"""The distance scene's types: where an object's pose comes from, a named cloud, one
answer of every watched pair, and the scene interface a controller and a simulation use.

:class:`~reachwise.distance.scene.Scene` (in process) and
``reachwise.server.client.SceneClient`` (over the network) both hold
:class:`SceneObject` objects and answer with a :class:`SceneResult`; code written against
:class:`SceneLike` never knows which of the two it talks to. Every name here is also
importable from :mod:`reachwise.distance.scene`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.distance.answers import PairAnswers, rows_of
from reachwise.distance.engine import StrategyName
from reachwise.distance.pairs import PairKind, PairResult, WatchedPair
from reachwise.errors import UnknownName
from reachwise.geometry.cloud import PointCloud

__all__ = [
    "Fixed",
    "OnLink",
    "PoseSource",
    "RobotLike",
    "Runtime",
    "SceneLike",
    "SceneObject",
    "SceneResult",
]


@runtime_checkable
class RobotLike(Protocol):
    """What the scene needs of a robot (``reachwise.kinematics.robot.Robot`` has it).

    ``link_names``: ``"link_0"`` (the base link), ``"link_1"`` … ``"link_n"`` (the link
    moved by joint i), then ``"tool"``. ``fk_all(q)`` returns the world poses of those
    frames, shape ``(len(link_names), 4, 4)``, in that order.
    """

    @property
    def name(self) -> str: ...

    @property
    def link_names(self) -> tuple[str, ...]: ...

    def fk_all(self, q: ArrayLike) -> NDArray[np.float64]: ...


@dataclass(frozen=True, eq=False)
class Fixed:
    """A pose fixed in world (4x4)."""

    pose: NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class OnLink:
    """Attached to ``link`` of ``robot``: world pose = link pose @ ``offset``."""

    robot: str
    link: str
    offset: NDArray[np.float64]

    @cached_property
    def identity(self) -> bool:
        """The offset is the identity (the per-tick pose needs no extra product)."""
        return bool(np.array_equal(self.offset, np.eye(4)))


@dataclass(frozen=True)
class Runtime:
    """Set at run time with :meth:`Scene.set_pose` (identity until then)."""


PoseSource = Fixed | OnLink | Runtime


@dataclass(frozen=True, eq=False)
class SceneObject:
    """A named cloud and where its pose comes from."""

    name: str
    cloud: PointCloud
    source: PoseSource


@dataclass(frozen=True)
class SceneResult:
    """Every watched pair's answer from one :meth:`Scene.query_all` call.

    ``sequence`` numbers the answers (1, 2, …; it only grows); ``measured_at`` (s) is
    the time stamp of the oldest input the answer depends on (joint states and run-time
    poses of the answered pairs' objects, and the query itself when the scene has a
    clock), NaN when one of them is unknown; ``computed_at`` (s) when the answer was
    ready (NaN without a clock). ``valid`` False with a ``reason`` marks missing data
    (a remote scene whose server did not answer: every distance is then NaN); the
    controller makes a protective stop on it.

    ``versions`` maps each object to the version of its cloud the answer used, and
    ``cloud_stamps`` to the time stamp (s) of that cloud's measurement: ``+inf`` for a
    cloud that does not age (a CAD part, a map: added without a stamp), NaN when it is
    unknown. A controller bounds the age of the clouds it relies on with them, as it
    bounds the age of the joint states with ``measured_at``.

    The in-process scene's ``pairs`` is a
    ``reachwise.distance.answers.PairAnswers``: the numbers of every pair in one
    array (:attr:`rows`), each :class:`PairResult` made when it is first read.
    """

    sequence: int
    pairs: Sequence[PairResult]
    measured_at: float = math.nan
    computed_at: float = math.nan
    valid: bool = True
    reason: str = ""
    versions: Mapping[str, int] = field(default_factory=dict)
    cloud_stamps: Mapping[str, float] = field(default_factory=dict)

    @property
    def rows(self) -> NDArray[np.float64]:
        """Every pair's numbers as a read-only (P, 13) array, in the order of ``pairs``
        (layout: ``reachwise.distance.answers``)."""
        pairs = self.pairs
        if isinstance(pairs, PairAnswers):
            return pairs.rows
        return rows_of(pairs)

    def at_risk(self) -> tuple[PairResult, ...]:
        """Pairs within their margin, nearest first."""
        return tuple(
            sorted((p for p in self.pairs if not p.result.no_risk), key=lambda p: p.result.distance)
        )

    def get(self, a: str, b: str) -> PairResult:
        """The answer of pair (a, b) (or (b, a), seen from a)."""
        for p in self.pairs:
            if (p.a, p.b) == (a, b):
                return p
            if (p.a, p.b) == (b, a):
                va, vb = p.versions
                return PairResult(a, b, p.margin, p.kind, p.result.swapped(), (vb, va))
        raise UnknownName(
            "scene", "watched pair", f"({a}, {b})", (f"({p.a}, {p.b})" for p in self.pairs)
        )


@runtime_checkable
class SceneLike(Protocol):
    """The scene interface a controller and a simulation use: :class:`Scene` in
    process, :class:`reachwise.server.client.SceneClient` over the network. Code
    written against it never knows which of the two it talks to."""

    @property
    def strategy(self) -> StrategyName: ...

    @property
    def robots(self) -> Mapping[str, RobotLike]: ...

    @property
    def objects(self) -> dict[str, SceneObject]: ...

    @property
    def pairs(self) -> tuple[WatchedPair, ...]: ...

    def add_robot(
        self, robot: RobotLike, q: ArrayLike | None = None, *, stamp: float | None = None
    ) -> None: ...

    def set_joints(self, robot: str, q: ArrayLike, *, stamp: float | None = None) -> None: ...

    def add_object(
        self,
        name: str,
        cloud: PointCloud | ArrayLike,
        pose: ArrayLike | None = None,
        *,
        robot: str | None = None,
        link: str | None = None,
        dynamic: bool = False,
        stamp: float = math.inf,
    ) -> SceneObject: ...

    def set_pose(self, name: str, pose: ArrayLike, *, stamp: float | None = None) -> None: ...

    def replace_cloud(
        self,
        name: str,
        cloud: PointCloud | ArrayLike,
        *,
        block: bool = False,
        stamp: float | None = None,
    ) -> int: ...

    def watch(self, a: str, b: str, margin: float, *, kind: PairKind = "custom") -> WatchedPair: ...

    def unwatch(self, a: str, b: str) -> None: ...

    def watch_self(
        self, robot: str, margin: float, exclude: Iterable[tuple[str, str]] = ()
    ) -> tuple[WatchedPair, ...]: ...

    def watch_environment(
        self, robot: str, margin: float, objects: Iterable[str] | None = None
    ) -> tuple[WatchedPair, ...]: ...

    def watch_robots(
        self, robot_a: str, robot_b: str, margin: float
    ) -> tuple[WatchedPair, ...]: ...

    def robot_objects(self, robot: str) -> tuple[SceneObject, ...]: ...

    def poses(self) -> dict[str, NDArray[np.float64]]: ...

    def query_all(self) -> SceneResult: ...

    def close(self) -> None: ...
