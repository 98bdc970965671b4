"""The distance scene: named clouds, where their poses come from, and the pairs to watch.

This is the collision server's state of P-IV/P-V (thesis §3.1, P-V §II): point clouds
of robot parts, other robots, obstacles and the scanned environment; part poses kept
up to date from joint states through forward kinematics; rules saying which pairs to
watch with which margin (self-collision pairs of a robot's links except adjacent ones
and listed exclusions, robot–environment, robot–robot); and one call,
:meth:`Scene.query_all`, answering every watched pair with the exact distance
(:mod:`reachwise.distance.engine`). Each pair keeps a warm-started
:class:`~reachwise.distance.engine.PairQuery`, so at 100 Hz successive answers start
from the previous closest pair.

Pose sources of an object: fixed in world, attached to a robot link (the link's world
pose from ``robot.fk_all(q)`` times a fixed offset), or set at run time
(:meth:`Scene.set_pose`). The environment cloud can be replaced at run time
(:meth:`Scene.replace_cloud`, e.g. after a new scan); its index is rebuilt at once.

Every answer carries what a safety layer needs to trust it (controller issue; the
collision server's results carry the same): ``sequence`` (1, 2, … per answer),
``measured_at`` — the time stamp of the oldest input it depends on (joint states and
run-time poses take an optional ``stamp=``, the time they were measured, s) —,
``computed_at`` (s, when the answer was ready) and ``valid``/``reason`` (an in-process
answer is always valid; a remote one may stand for missing data). The scene reads no
clock of its own: give it one (``Scene(clock=...)``) to stamp unstamped inputs and the
computation; without one those times are NaN ("unknown").
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Annotated

import numpy as np
from numpy.typing import ArrayLike, NDArray

import reachwise.distance._batch as B
import reachwise.distance.scene_rules as scene_rules
from reachwise.distance._common import (
    as_cloud,
    check_added_stamp,
    check_margin,
    check_pose,
)
from reachwise.distance.answers import ROW_COLUMNS, PairAnswers
from reachwise.distance.engine import STRATEGIES, StrategyName
from reachwise.distance.index import cloud_index
from reachwise.distance.ingest import CloudIngest, ready_cloud
from reachwise.distance.pairs import PAIR_KINDS, PairKind, PairResult, WatchedPair
from reachwise.distance.scene_ops import ArrayShape, scene_change
from reachwise.distance.scene_plan import SceneContents, make_plan
from reachwise.distance.scene_state import SceneState, positive_length
from reachwise.distance.scene_types import (
    Fixed,
    OnLink,
    PoseSource,
    RobotLike,
    Runtime,
    SceneLike,
    SceneObject,
    SceneResult,
)
from reachwise.errors import InputError, NameTaken, UnknownName, check_choice
from reachwise.geometry.cloud import PointCloud
from reachwise.kinematics.fk import fk_all_into


class Scene(SceneState):
    """Objects, robots and watched pairs; :meth:`query_all` answers every pair.

    ``clock`` (optional, s): stamps inputs given without ``stamp=``, the query and its
    end (``SceneResult.measured_at``, ``SceneResult.computed_at``); a
    simulation passes its simulated time. ``voxel`` (m, optional): thin every cloud
    handed over with :meth:`replace_cloud` to one point per voxel of that edge before
    it is indexed (``reachwise.distance.voxel.voxel_thin``); the thinned cloud is
    the one swapped in, and the answers are exact on it.

    With the default strategy the scene keeps its state as arrays
    (``reachwise.distance.scene_arrays.SceneArrays``) and answers every pair in
    one compiled call, forward kinematics once per robot before it; the answer's
    pairs are made on demand from one array of numbers
    (``reachwise.distance.answers.PairAnswers``). The other strategies answer
    pair by pair with :class:`~reachwise.distance.engine.PairQuery`.
    """

    def __init__(
        self,
        *,
        strategy: StrategyName = "default",
        clock: Callable[[], float] | None = None,
        voxel: float | None = None,
    ) -> None:
        self.strategy = check_choice(strategy, STRATEGIES, source="scene", kind="strategy")
        self.clock = clock
        self._voxel = None if voxel is None else positive_length(voxel, "voxel")
        self._generation = 0
        self._empty()

    # ------------------------------------------------------------------ contents
    @property
    def objects(self) -> dict[str, SceneObject]:
        return dict(self._objects)

    @property
    def robots(self) -> dict[str, RobotLike]:
        return dict(self._robots)

    @property
    def pairs(self) -> tuple[WatchedPair, ...]:
        return tuple(self._pairs.values())

    @property
    def sequence(self) -> int:
        """How many times :meth:`query_all` has answered."""
        return self._sequence

    @property
    def generation(self) -> int:
        """How many times :meth:`clear` has emptied the scene: what was handed over
        before a clear belongs to an older generation."""
        return self._generation

    @property
    def versions(self) -> Mapping[str, int]:
        """The version of each object's cloud in use now (see :meth:`replace_cloud`)."""
        return self._versions

    @property
    def ingest(self) -> CloudIngest:
        """The worker that indexes handed-over clouds (its counters, errors, ``wait``)."""
        return self._ingest

    def swap_in(self) -> None:
        """Swap in the clouds indexed since the last swap now (:meth:`query_all` does
        this first); e.g. a server that waited for a cloud puts it in use at once."""
        for ready in self._ingest.take_ready():
            self._install(ready)

    @property
    def swaps(self) -> int:
        """Clouds swapped in by :meth:`query_all` (built on the worker)."""
        return self._swaps

    @property
    def swaps_deferred(self) -> int:
        """Queries that found a built cloud but the worker holding the hand-over lock
        at that instant: they went on with the cloud in use instead of waiting (the
        next query swaps it in)."""
        return self._deferred

    @property
    def queries_during_build(self) -> int:
        """Queries answered while the worker was building a newer cloud for one of
        their pairs' objects: each answered on the cloud in use, without waiting."""
        return self._during_build

    @scene_change
    def add_robot(
        self,
        robot: RobotLike,
        q: Annotated[ArrayLike, ArrayShape((None,))] | None = None,
        *,
        stamp: float | None = None,
    ) -> None:
        """Register ``robot`` under ``robot.name``, optionally with its joint state
        ``q`` (any array-like of floats) measured at ``stamp``. Through the collision
        server a robot travels as a :class:`~reachwise.kinematics.robot.Robot`'s YAML
        mapping."""
        if not isinstance(robot, RobotLike):
            raise InputError("robot", "", "needs name, link_names and fk_all(q)")
        if robot.name in self._robots:
            raise NameTaken("scene", "robot", f"robot {robot.name!r} is already registered")
        arr = None if q is None else _joint_values(robot, q)  # checked before any change
        if arr is not None:
            self._q_stamp[robot.name] = self._stamp(stamp, f"robot {robot.name!r}")
        self._robots[robot.name] = robot
        self._q[robot.name] = arr
        self._frame_row[robot.name] = self._arrays.add_frames(len(robot.link_names))
        self._plan = None

    def set_joints(self, robot: str, q: ArrayLike, *, stamp: float | None = None) -> None:
        """The joint state of ``robot`` (one value per non-fixed joint), measured at
        ``stamp`` (s; default: the scene's clock, or unknown)."""
        arr = _joint_values(self._robot(robot), q)
        t = self._stamp(stamp, f"robot {robot!r}")
        self._q[robot] = arr
        self._q_stamp[robot] = t

    def joint_state(self, robot: str) -> NDArray[np.float64] | None:
        """The latest joint state of ``robot`` (:meth:`set_joints`; a read-only array,
        replaced, never changed, by the next one), or None before the first."""
        self._robot(robot)
        return self._q[robot]

    def joint_stamp(self, robot: str) -> float:
        """When the latest joint state of ``robot`` was measured (s; NaN: unknown or
        none yet)."""
        self._robot(robot)
        return self._q_stamp.get(robot, math.nan)

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
    ) -> SceneObject:
        """Add a cloud. With ``robot`` and ``link`` it is attached to that link and
        ``pose`` is its fixed offset from the link frame; with ``dynamic=True`` its
        world pose is set at run time (``pose`` is the initial one); else ``pose`` is a
        fixed world pose. ``None`` means identity. The cloud's index is built now.

        ``stamp`` (s) is when the cloud was measured: +inf (the default) for a cloud
        that does not age (a CAD part, a map), NaN for one whose time is unknown — its
        age counts as unknown, so a controller with ``SafetyConfig.max_cloud_age``
        treats it as stale until :meth:`replace_cloud` hands over a stamped one. A name
        in use raises :class:`~reachwise.errors.NameTaken` (an ``InputError``)."""
        if not isinstance(name, str) or not name:
            raise InputError("scene", "object name", "must be a non-empty string")
        if name in self._objects:
            raise NameTaken("scene", "name", f"object {name!r} already exists")
        added = check_added_stamp(stamp, name)
        c = as_cloud(cloud, name)
        P = check_pose(pose, f"pose of {name!r}").copy()
        source: PoseSource
        row = -1
        if robot is not None or link is not None:
            if robot is None or link is None:
                raise InputError("scene", f"object {name!r}", "give both robot and link")
            r = self._robot(robot)
            if link not in r.link_names:
                raise UnknownName(f"robot {robot!r}", "link", link, r.link_names)
            if dynamic:
                raise InputError("scene", f"object {name!r}", "a link object cannot be dynamic")
            source = OnLink(robot, link, P)
            row = self._frame_row[robot] + r.link_names.index(link)
        elif dynamic:
            source = Runtime()
            self._pose_stamp[name] = self._stamp(None, f"object {name!r}")
        else:
            source = Fixed(P)
        index = cloud_index(c)
        obj = SceneObject(name, c, source)
        self._objects[name] = obj
        self._slot[name] = self._arrays.add_object(index, P, row)
        self._plan = None
        self._issued[name] = 0
        self._set_version(name, 0, added)
        return obj

    def set_pose(self, name: str, pose: ArrayLike, *, stamp: float | None = None) -> None:
        """The world pose of a run-time (``dynamic``) object, measured at ``stamp``
        (s; default: the scene's clock, or unknown)."""
        obj = self._object(name)
        if not isinstance(obj.source, Runtime):
            raise InputError("scene", f"object {name!r}", "its pose is not set at run time")
        P = check_pose(pose, f"pose of {name!r}")
        t = self._stamp(stamp, f"object {name!r}")
        self._arrays.set_pose(self._slot[name], P)
        self._pose_stamp[name] = t

    def replace_cloud(
        self,
        name: str,
        cloud: PointCloud | ArrayLike,
        *,
        block: bool = False,
        stamp: float | None = None,
    ) -> int:
        """Hand over a new cloud for object ``name`` (a new scan or camera frame),
        measured at ``stamp`` (s; default: the scene's clock, or unknown); returns its
        version (1, 2, … per object; the cloud it was added with is version 0).

        ``block=False`` (the default) returns at once: the cloud is checked and indexed
        on the scene's worker thread (``reachwise.distance.ingest.CloudIngest``)
        and swapped in at the start of the first :meth:`query_all` after it is ready, so
        a query never waits for a build. Until then the answers use the previous
        cloud, and say so (``SceneResult.versions``). A newer hand-over for the
        same object supersedes one still waiting; a cloud with bad points is never
        swapped in (its error is in ``CloudIngest.errors``). An array (float64 or
        float32, any strides) is read on the worker thread: do not write into it
        afterwards.

        ``block=True`` checks and indexes the cloud now, in the caller, and swaps it in
        before returning (bad points raise :class:`~reachwise.errors.CloudError`).
        Either way the warm starts of the object's pairs are dropped at the swap, and
        a scene made with ``voxel`` thins the cloud first."""
        self._object(name)
        t = self._stamp(stamp, f"object {name!r}")
        version = self._issued[name] + 1
        # no dtype here: a float32 frame is converted on the worker, not on this thread
        points = cloud if isinstance(cloud, PointCloud) else np.asarray(cloud)
        if block:
            self._install(ready_cloud(name, version, points, t, self._ingest.voxel))
            self._issued[name] = version
            return version
        self._issued[name] = version
        self._ingest.submit(name, version, points, t)
        return version

    # ------------------------------------------------------------------ rules
    @scene_change
    def watch(self, a: str, b: str, margin: float, *, kind: PairKind = "custom") -> WatchedPair:
        """Watch objects ``a`` and ``b`` with ``margin`` metres (replaces an earlier rule
        for the same pair); ``kind`` (``PairKind``) says why."""
        kind = check_choice(kind, PAIR_KINDS, source=f"pair ({a!r}, {b!r})", kind="pair kind")
        self._object(a)
        self._object(b)
        if a == b:
            raise InputError(
                "scene", f"pair ({a!r}, {b!r})", "an object cannot be paired with itself"
            )
        m = check_margin(margin)
        key = (a, b) if (b, a) not in self._pairs else (b, a)
        pair = WatchedPair(key[0], key[1], m, kind)
        self._pairs[key] = pair
        self._fresh.add(key)
        if self.strategy != "default":
            self._queries[key] = self._make_query(pair)
        self._plan = None
        return pair

    @scene_change
    def unwatch(self, a: str, b: str) -> None:
        """Stop watching the pair ``a``, ``b`` (either order; nothing if it was not)."""
        for key in ((a, b), (b, a)):
            self._pairs.pop(key, None)
            self._queries.pop(key, None)
        self._plan = None

    def robot_objects(self, robot: str) -> tuple[SceneObject, ...]:
        """Objects attached to ``robot``'s links, base to tool."""
        r = self._robot(robot)
        order = {n: i for i, n in enumerate(r.link_names)}
        objs = [
            o
            for o in self._objects.values()
            if isinstance(o.source, OnLink) and o.source.robot == robot
        ]
        return tuple(sorted(objs, key=lambda o: order[o.source.link]))  # type: ignore[union-attr]

    # the pair rules over a robot's objects, written once for any SceneLike
    watch_self = scene_rules.watch_self
    watch_environment = scene_rules.watch_environment
    watch_robots = scene_rules.watch_robots

    # ------------------------------------------------------------------ queries
    def poses(self) -> dict[str, NDArray[np.float64]]:
        """Current world pose of every object (forward kinematics of each robot once;
        the same numbers :meth:`query_all` places the objects with)."""
        arrays = self._arrays
        for robot in {
            o.source.robot for o in self._objects.values() if isinstance(o.source, OnLink)
        }:
            self._forward_kinematics(robot)
        out = np.empty_like(arrays.poses)
        everything = np.ones(arrays.src.shape[0], np.bool_)
        B.place_objects(arrays.frames, arrays.fixed, arrays.src, arrays.identity, everything, out)
        return {name: out[self._slot[name]].copy() for name in self._objects}

    def query_all(self) -> SceneResult:
        """Answer every watched pair at the current joint states and poses; the result
        carries its sequence number, time stamps and cloud versions (see
        :class:`SceneResult`). Clouds indexed since the last call are swapped in first
        (never waiting for the worker: see :attr:`swaps_deferred`)."""
        ingest = self._ingest
        if ingest.has_ready:
            taken = ingest.try_take_ready()
            if taken is None:
                self._deferred += 1
            else:
                for ready in taken:
                    self._install(ready)
        plan = self._plan
        if plan is None:
            plan = self._plan = make_plan(
                SceneContents(
                    self._arrays,
                    self._pairs,
                    self._objects,
                    self._robots,
                    self._slot,
                    self._frame_row,
                    self._fresh,
                    self.strategy,
                )
            )
        building = ingest.building
        if building is not None and building in plan.objects:
            self._during_build += 1
        clock = self.clock
        measured = clock() if clock is not None else math.inf
        for name, robot, frames in plan.kinematics:
            q = self._q[name]
            if q is None:
                raise InputError(
                    "scene", f"robot {name!r}", "has no joint state; call set_joints first"
                )
            if frames is not None:
                fk_all_into(robot, q, frames)  # type: ignore[arg-type]
            else:
                self._forward_kinematics(name)
        stamps = self._q_stamp
        for name in plan.robots:
            t = stamps.get(name, math.nan)
            if t != t or t < measured:  # unknown (NaN, then kept) or older
                measured = t
        stamps = self._pose_stamp
        for name in plan.runtime:
            t = stamps.get(name, math.nan)
            if t != t or t < measured:
                measured = t
        rows = np.empty((len(plan.layout), ROW_COLUMNS))
        if plan.arguments is not None:
            B.query_pairs(rows, *plan.arguments)
        else:
            self._query_pairwise(plan, rows)
        rows.setflags(write=False)
        self._sequence += 1
        computed = clock() if clock is not None else math.nan
        versions = self._versions
        return SceneResult(
            self._sequence,
            PairAnswers(plan.layout, rows, versions),
            measured_at=measured if measured != math.inf else math.nan,
            computed_at=computed,
            versions=versions,
            cloud_stamps=self._cloud_stamps,
        )

    @scene_change
    def clear(self) -> None:
        """Remove every robot, object and pair, as a new scene of the same strategy,
        clock and voxel has none, and count one more :attr:`generation`. Clouds handed
        over and not swapped in yet are dropped: the worker that indexed them is told
        to stop (its build in progress ends on it, then its thread exits), and a new
        one indexes the clouds handed over from now on."""
        self._ingest.stop()
        self._stop_ingest.detach()
        self._empty()
        self._generation += 1

    def close(self) -> None:
        """Stop the cloud-ingestion worker (a remote scene disconnects here); a scene
        that is garbage-collected stops it too."""
        self._stop_ingest()


def _joint_values(robot: RobotLike, q: ArrayLike) -> NDArray[np.float64]:
    """``q`` as a fresh, read-only vector of finite joint values, one per joint variable
    of ``robot`` when it says how many (``n``)."""
    n = getattr(robot, "n", None)  # a RobotLike need not say
    arr = np.array(q, dtype=np.float64, copy=True).reshape(-1)
    if n is not None and arr.shape != (n,):
        raise InputError(
            f"robot {robot.name!r}", "q", f"has {n} joint variables; got {arr.size} values"
        )
    if not np.isfinite(arr).all():
        raise InputError(f"robot {robot.name!r}", "q", "contains NaN or inf")
    arr.setflags(write=False)
    return arr


__all__ = [
    "Fixed",
    "OnLink",
    "PairResult",
    "PoseSource",
    "RobotLike",
    "Runtime",
    "Scene",
    "SceneLike",
    "SceneObject",
    "SceneResult",
    "WatchedPair",
]
