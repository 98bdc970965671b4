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
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.control.tick.types import AvoidanceRows
from reachwise.distance.scene import OnLink, SceneLike, SceneResult
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
    when that object moves (zeros: static, the default).
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
    """Turns a :class:`SceneResult` into :class:`AvoidancePoints` for one robot.

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
        a_link: list[int] = []
        a_pt: list[NDArray[np.float64]] = []
        b_link: list[int] = []
        b_pt: list[NDArray[np.float64]] = []
        normal: list[NDArray[np.float64]] = []
        dist: list[float] = []
        margin: list[float] = []
        task: list[bool] = []
        names: list[str] = []
        vel: list[NDArray[np.float64]] = []
        nan3 = np.full(3, np.nan)
        zero3 = np.zeros(3)
        tw = twists or {}
        for p in result.pairs:
            r = p.result
            if r.no_risk:
                continue
            la = self._link.get(p.a)
            lb = self._link.get(p.b)
            if la is None and lb is None:
                continue
            rho0 = self._margins.get((p.a, p.b), p.margin)
            # a moving object's pair counts out to the scene's margin: the controller
            # brings it in by the obstacle's travel during its reaction time
            other_moves = (la is not None and p.b in tw) or (lb is not None and p.a in tw)
            if r.distance > rho0 and not (other_moves and r.distance <= p.margin):
                continue
            if la is not None and lb is not None:
                a_link.append(la)
                a_pt.append(r.point_a)
                b_link.append(lb)
                b_pt.append(r.point_b)
                normal.append(r.direction)
                task.append(False)
                vel.append(zero3)
            elif la is not None:
                a_link.append(la)
                a_pt.append(r.point_a)
                b_link.append(-1)
                b_pt.append(nan3)
                normal.append(r.direction)
                task.append(la in self.tool_links)
                vel.append(_point_velocity(tw.get(p.b), r.point_b, zero3))
            else:
                lbi = -1 if lb is None else lb
                a_link.append(lbi)
                a_pt.append(r.point_b)
                b_link.append(-1)
                b_pt.append(nan3)
                normal.append(-np.asarray(r.direction))
                task.append(lbi in self.tool_links)
                vel.append(_point_velocity(tw.get(p.a), r.point_a, zero3))
            dist.append(r.distance)
            margin.append(rho0)
            names.append(f"{p.a}|{p.b}")
        if not dist:
            return AvoidancePoints.empty(result.sequence, stamp, computed)
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
        )


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
