"""The controller's avoidance inputs, and the converter from a distance scene's answer.

A :class:`~reachwise.distance.scene.SceneResult` speaks of named objects; the
controller of one robot needs, for every watched pair closer than its margin, the
robot part's closest point (its *obstacle avoidance point*, thesis §3.3), the link it
is fixed to, the collision-line direction pointing away from the other object, the
distance and the margin ``ρ_O``:

- robot part ``a`` vs. an object that is not on this robot (environment, scan, another
  robot): one point on ``a``; the direction is the query's ``direction`` (b → a), or
  its opposite when the robot part is the pair's ``b``;
- a self-collision pair (both objects on this robot's links): a point on each link;
  the controller uses the relative Jacobian ``J_a(p_a) − J_b(p_b)`` of the two points,
  so both parts may move to open the gap;
- parts rigidly carried with the tool — by default every link after the last actuated
  joint (a hanging grabber, a drill feed) and the tool frame — are *tool parts*: their
  repulsion is added to the task velocity (P-V Eq. 6) unless the other object is on
  the same robot.

A moving object (its twist given per call) also gives each point the velocity of the
object's closest point, for the controller's velocity-aware repulsion and guard.

The points also carry the measurement time of the oldest cloud the robot's pairs were
answered on (``cloud_stamp``, from the answer's ``cloud_stamps``; +inf when none ages)
and its name: the controller bounds the age of the clouds with it
(``SafetyConfig.max_cloud_age``), as it bounds the age of the joint states.

An in-process scene's answer holds every pair's numbers in one array
(:attr:`~reachwise.distance.scene.SceneResult.rows`); without twists the converter
reads them there in one compiled call (``reachwise.control._rows``) instead of
looping over :class:`~reachwise.distance.scene.PairResult` objects — same rules, same
points.

Pairs answered "no risk" (beyond the margin) give no point. A pair whose answer holds
NaN or infinite numbers while claiming to be within the margin is kept, so the
controller's safety check sees it and stops. An answer marked invalid (missing data:
a collision server that did not answer in time) gives points marked invalid with its
reason, on which the controller stops too.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from typing import Any, NamedTuple, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.control._rows import select_rows
from reachwise.control.tick.types import AvoidanceRows
from reachwise.distance.answers import PairAnswers
from reachwise.distance.scene import OnLink, SceneLike, SceneResult, WatchedPair
from reachwise.errors import InputError
from reachwise.kinematics.robot import Robot

__all__ = ["AvoidancePoints", "SceneConverter", "default_tool_links"]


@dataclass(frozen=True, eq=False)
class AvoidancePoints:
    """Avoidance inputs of one robot for one control tick (``m`` points).

    ``sequence`` is the distance query's number, ``stamp`` the time (s) of the joint
    state and scan it describes, ``computed`` when the answer was ready. Per point:
    ``a_link`` frame index (``robot.link_names``) and ``a_point`` (world) of the robot
    part; ``b_link``/``b_point`` the other part on the same robot (self-collision) or
    ``-1``/NaN; ``normal`` the unit collision-line vector pointing away from the
    other object; ``distance`` and ``margin`` (m); ``task_space`` True for a tool part
    handled in task space (P-V Eq. 6); ``pairs`` the object names ``"a|b"``.
    ``valid`` False (with a ``reason``) stands for missing distance data.
    ``obstacle_velocity`` (m, 3): world velocity of the other object's closest point
    when that object moves (zeros: static, the default). ``cloud_stamp`` (s): when the
    oldest cloud the points were computed on was measured (+inf: none of them ages,
    NaN: unknown), ``cloud`` its object's name.
    """

    sequence: int
    stamp: float
    computed: float
    a_link: NDArray[np.int64]
    a_point: NDArray[np.float64]
    b_link: NDArray[np.int64]
    b_point: NDArray[np.float64]
    normal: NDArray[np.float64]
    distance: NDArray[np.float64]
    margin: NDArray[np.float64]
    task_space: NDArray[np.bool_]
    pairs: tuple[str, ...] = field(default=())
    valid: bool = True
    reason: str = ""
    obstacle_velocity: NDArray[np.float64] | None = None
    cloud_stamp: float = math.inf
    cloud: str = ""
    #: The compiled tick's input group, as ``tuple(AvoidanceRows(...))`` (built here).
    kernel_rows: tuple[NDArray[Any], ...] = field(init=False, repr=False, compare=False)

    @classmethod
    def empty(cls, sequence: int, stamp: float, computed: float | None = None) -> AvoidancePoints:
        """No pair within its margin."""
        z3 = np.zeros((0, 3))
        return cls(
            sequence, stamp, stamp if computed is None else computed,
            np.zeros(0, np.int64), z3, np.zeros(0, np.int64), z3, z3,
            np.zeros(0), np.zeros(0), np.zeros(0, np.bool_),
        )  # fmt: skip

    @classmethod
    def of_checked(
        cls,
        sequence: int,
        stamp: float,
        computed: float,
        rows: AvoidanceRows,
        pairs: tuple[str, ...],
        cloud_stamp: float,
        cloud: str,
    ) -> AvoidancePoints:
        """Valid points from arrays that are already what the constructor makes of its
        inputs — C-ordered int64, float64 and bool arrays of shapes (m,) and (m, 3), as
        ``reachwise.control._rows`` returns them — without a second look (the
        converter's per-tick path)."""
        self = object.__new__(cls)
        put = object.__setattr__
        put(self, "sequence", sequence)
        put(self, "stamp", stamp)
        put(self, "computed", computed)
        for name, value in zip(AvoidanceRows._fields, rows, strict=True):
            put(self, name, value)
        put(self, "pairs", pairs)
        put(self, "valid", True)
        put(self, "reason", "")
        put(self, "cloud_stamp", cloud_stamp)
        put(self, "cloud", cloud)
        put(self, "kernel_rows", tuple(rows))
        return self

    def __post_init__(self) -> None:
        m = int(np.asarray(self.distance).shape[0])
        if self.obstacle_velocity is None:
            object.__setattr__(self, "obstacle_velocity", np.zeros((m, 3)))
        shapes = {
            "distance": (m,),
            "a_link": (m,),
            "a_point": (m, 3),
            "b_link": (m,),
            "b_point": (m, 3),
            "normal": (m, 3),
            "obstacle_velocity": (m, 3),
            "margin": (m,),
            "task_space": (m,),
        }
        for name, shape in shapes.items():
            if np.shape(getattr(self, name)) != shape:
                raise InputError(
                    "avoidance points",
                    name,
                    f"expected {shape}, got {np.shape(getattr(self, name))}",
                )
        # plain C-contiguous arrays: the compiled controller takes them as they are
        for name in ("a_link", "b_link"):
            object.__setattr__(self, name, np.ascontiguousarray(getattr(self, name), np.int64))
        object.__setattr__(self, "task_space", np.ascontiguousarray(self.task_space, np.bool_))
        for name in ("a_point", "b_point", "normal", "distance", "margin", "obstacle_velocity"):
            v = np.ascontiguousarray(getattr(self, name), np.float64)
            object.__setattr__(self, name, v)
        velocity: NDArray[np.float64] = self.obstacle_velocity  # type: ignore[assignment]
        rows = AvoidanceRows(
            a_link=self.a_link,
            a_point=self.a_point,
            b_link=self.b_link,
            b_point=self.b_point,
            normal=self.normal,
            obstacle_velocity=velocity,
            distance=self.distance,
            margin=self.margin,
            task_space=self.task_space,
        )
        object.__setattr__(self, "kernel_rows", tuple(rows))

    def __len__(self) -> int:
        return int(self.distance.shape[0])


def default_tool_links(robot: Robot) -> tuple[int, ...]:
    """Frame indices of the parts carried with the tool: every link after the last
    actuated joint (passive ones included) and the tool frame."""
    last = -1
    for k, i in enumerate(robot.movable_joints):
        if robot.actuated[k]:
            last = i
    start = last + 1  # link_{i+1} is moved by joint i (0-based)
    return tuple(range(start, len(robot.link_names)))


class SceneConverter:
    """Turns a :class:`~reachwise.distance.SceneResult` into :class:`AvoidancePoints` for one robot.

    Built once per robot from the scene's objects (which cloud is fixed to which link),
    then called every tick. ``tool_links`` (frame indices or link names) override
    :func:`default_tool_links`; ``margins`` override the pair margins ``ρ_O`` by
    ``(a, b)`` object names (the scene may watch pairs farther out, for logging).
    """

    def __init__(
        self,
        scene: SceneLike,
        robot: Robot,
        tool_links: Iterable[int | str] | None = None,
        margins: Mapping[tuple[str, str], float] | None = None,
    ) -> None:
        self.robot = robot
        self._link: dict[str, int] = {}
        for name, obj in scene.objects.items():
            src = obj.source
            if isinstance(src, OnLink) and src.robot == robot.name:
                self._link[name] = robot.link_index(src.link)
        tl = default_tool_links(robot) if tool_links is None else tool_links
        self.tool_links = frozenset(robot.link_index(t) for t in tl)
        self._margins: dict[tuple[str, str], float] = {}
        for (a, b), v in (margins or {}).items():
            self._margins[(a, b)] = float(v)
            self._margins[(b, a)] = float(v)
        self._table: _RowTable | None = None

    def __call__(
        self,
        result: SceneResult,
        stamp: float | None = None,
        computed: float | None = None,
        *,
        twists: Mapping[str, tuple[ArrayLike, ArrayLike, ArrayLike]] | None = None,
    ) -> AvoidancePoints:
        """The avoidance points of ``result``. ``stamp`` (s): the time of the inputs it
        describes, by default the result's ``measured_at`` (an older ``measured_at``
        wins over a given ``stamp``: data is never made younger than it is);
        ``computed``: by default the result's ``computed_at``, else ``stamp``. An
        invalid result gives empty points marked invalid, with its reason.
        ``twists`` ``{object: (v, ω, origin)}`` (world, m/s, rad/s, m) give the motion
        of moving objects: their closest points' velocities ``v + ω × (p − origin)``
        become the points' ``obstacle_velocity``."""
        measured = result.measured_at
        if stamp is None or measured < stamp:
            stamp = measured
        if computed is None:
            computed = result.computed_at if math.isfinite(result.computed_at) else stamp
        if not result.valid:
            empty = AvoidancePoints.empty(result.sequence, stamp, computed)
            return replace(empty, valid=False, reason=result.reason or "missing distance data")
        if not twists and isinstance(result.pairs, PairAnswers):
            return self._from_rows(result, result.pairs, stamp, computed)
        tw = twists or {}
        rows = [row for p in result.pairs if (row := self._row(p, tw)) is not None]
        cloud_stamp, cloud = self._oldest_cloud(result, _watched(result.pairs, self._link))
        if not rows:
            empty = AvoidancePoints.empty(result.sequence, stamp, computed)
            return replace(empty, cloud_stamp=cloud_stamp, cloud=cloud)
        a_link, a_pt, b_link, b_pt, normal, dist, margin, task, names, vel = zip(*rows, strict=True)
        return AvoidancePoints(
            result.sequence,
            stamp,
            stamp if computed is None else computed,
            np.array(a_link, np.int64),
            np.array(a_pt, float).reshape(-1, 3),
            np.array(b_link, np.int64),
            np.array(b_pt, float).reshape(-1, 3),
            np.array(normal, float).reshape(-1, 3),
            np.array(dist, float),
            np.array(margin, float),
            np.array(task, np.bool_),
            tuple(names),
            obstacle_velocity=np.array(vel, float).reshape(-1, 3),
            cloud_stamp=cloud_stamp,
            cloud=cloud,
        )

    def _row(self, p: Any, tw: Mapping[str, tuple[ArrayLike, ArrayLike, ArrayLike]]) -> _Row | None:
        """The avoidance row of one answered pair ``p``, or ``None`` when it does not
        act (no risk, no robot link in it, or beyond its margin). A robot part against
        a robot part is a self-collision row; a part against an object keeps the part
        as point a (the direction turned if the part is the pair's ``b``), with the
        object's point velocity from its twist in ``tw``."""
        r = p.result
        if r.no_risk:
            return None
        la = self._link.get(p.a)
        lb = self._link.get(p.b)
        if la is None and lb is None:
            return None
        rho0 = self._margins.get((p.a, p.b), p.margin)
        # a moving object's pair counts out to the scene's margin: the controller
        # brings it in by the obstacle's travel during its reaction time
        other_moves = (la is not None and p.b in tw) or (lb is not None and p.a in tw)
        if r.distance > rho0 and not (other_moves and r.distance <= p.margin):
            return None
        name = f"{p.a}|{p.b}"
        if la is not None and lb is not None:
            return _Row(
                la, r.point_a, lb, r.point_b, r.direction, r.distance, rho0, False, name, _ZERO3
            )
        if la is not None:
            vel = _point_velocity(tw.get(p.b), r.point_b, _ZERO3)
            return _Row(
                la, r.point_a, -1, _NAN3, r.direction, r.distance, rho0,
                la in self.tool_links, name, vel,
            )  # fmt: skip
        lbi = -1 if lb is None else lb
        vel = _point_velocity(tw.get(p.a), r.point_a, _ZERO3)
        return _Row(
            lbi, r.point_b, -1, _NAN3, -np.asarray(r.direction), r.distance, rho0,
            lbi in self.tool_links, name, vel,
        )  # fmt: skip

    def _from_rows(
        self, result: SceneResult, answers: PairAnswers, stamp: float, computed: float
    ) -> AvoidancePoints:
        """The points of an answer held as rows (no twists): one compiled call."""
        table = self._table
        if table is None or table.layout is not answers.layout:
            table = self._table = self._row_table(answers.layout)
        cloud_stamp, cloud = self._oldest_cloud(result, table.watched)
        a_link, a_pt, b_link, b_pt, normal, velocity, dist, margin, task, keep = select_rows(
            answers.rows, table.link_a, table.link_b, table.rho0, table.tool_a, table.tool_b
        )
        rows = AvoidanceRows(
            a_link=a_link,
            a_point=a_pt,
            b_link=b_link,
            b_point=b_pt,
            normal=normal,
            obstacle_velocity=velocity,
            distance=dist,
            margin=margin,
            task_space=task,
        )
        names = table.names
        pairs = tuple(names[k] for k in keep.tolist())
        return AvoidancePoints.of_checked(
            result.sequence, stamp, computed, rows, pairs, cloud_stamp, cloud
        )

    def _row_table(self, layout: tuple[WatchedPair, ...]) -> _RowTable:
        """Per pair of ``layout``: this robot's frame of each object, ``ρ_O``, tool flags."""
        la = np.array([self._link.get(p.a, -1) for p in layout], np.int64)
        lb = np.array([self._link.get(p.b, -1) for p in layout], np.int64)
        rho0 = np.array([self._margins.get((p.a, p.b), p.margin) for p in layout], np.float64)
        tools = self.tool_links
        return _RowTable(
            layout,
            la,
            lb,
            rho0,
            np.array([k in tools for k in la.tolist()], np.bool_),
            np.array([k in tools for k in lb.tolist()], np.bool_),
            tuple(f"{p.a}|{p.b}" for p in layout),
            _watched(layout, self._link),
        )

    @staticmethod
    def _oldest_cloud(result: SceneResult, watched: tuple[str, ...]) -> tuple[float, str]:
        """Stamp and name of the oldest cloud among ``watched`` (NaN wins: unknown)."""
        stamps = result.cloud_stamps
        oldest = math.inf
        name = ""
        for o in watched:
            t = stamps.get(o, math.inf)
            if t != t:
                return t, o
            if t < oldest:
                oldest = t
                name = o
        return oldest, name


_NAN3 = np.full(3, np.nan)
_NAN3.setflags(write=False)
_ZERO3 = np.zeros(3)
_ZERO3.setflags(write=False)


class _Row(NamedTuple):
    """One avoidance point being collected (the fields of :class:`AvoidancePoints`)."""

    a_link: int
    a_point: Any
    b_link: int
    b_point: Any
    normal: Any
    distance: float
    margin: float
    task_space: bool
    name: str
    obstacle_velocity: Any


@dataclass(frozen=True, eq=False)
class _RowTable:
    """What :meth:`SceneConverter._from_rows` needs per pair of one answer layout."""

    layout: tuple[WatchedPair, ...]
    link_a: NDArray[np.int64]
    link_b: NDArray[np.int64]
    rho0: NDArray[np.float64]
    tool_a: NDArray[np.bool_]
    tool_b: NDArray[np.bool_]
    names: tuple[str, ...]
    watched: tuple[str, ...]


class _Pair(Protocol):
    @property
    def a(self) -> str: ...

    @property
    def b(self) -> str: ...


def _watched(pairs: Iterable[_Pair], links: Mapping[str, int]) -> tuple[str, ...]:
    """The objects of the pairs that involve the robot (an object on one of its links)."""
    out: dict[str, None] = {}
    for p in pairs:
        a, b = p.a, p.b
        if a in links or b in links:
            out[a] = None
            out[b] = None
    return tuple(out)


def _point_velocity(
    twist: tuple[ArrayLike, ArrayLike, ArrayLike] | None,
    point: NDArray[np.float64],
    zero: NDArray[np.float64],
) -> NDArray[np.float64]:
    """``v + ω × (p − origin)`` of a moving object's point (``zero`` if it is static)."""
    if twist is None:
        return zero
    v, w, origin = (np.asarray(x, dtype=float) for x in twist)
    return np.asarray(v + np.cross(w, np.asarray(point, dtype=float) - origin), dtype=float)
