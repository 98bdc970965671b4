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
import numbers
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from types import MappingProxyType
from typing import Literal, Protocol, get_args, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.distance._common import (
    DistanceResult,
    as_cloud,
    check_margin,
    check_pose,
)
from reachwise.distance.engine import STRATEGIES, PairQuery, StrategyName
from reachwise.distance.index import INDICES, cloud_index
from reachwise.distance.ingest import CloudIngest, Ready, ready_cloud
from reachwise.errors import InputError, UnknownName, check_choice
from reachwise.geometry.cloud import PointCloud


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


#: Why a pair is watched: links of one robot (``self``), a robot and its environment,
#: two robots, or a rule given by hand (``custom``).
PairKind = Literal["self", "robot-environment", "robot-robot", "custom"]
PAIR_KINDS: tuple[PairKind, ...] = get_args(PairKind)


@dataclass(frozen=True)
class WatchedPair:
    """A pair of objects to watch: ``kind`` (:data:`PairKind`), ``margin`` in metres."""

    a: str
    b: str
    margin: float
    kind: PairKind


@dataclass(frozen=True)
class PairResult:
    """One watched pair's answer: object names, margin, kind and the distance result
    (``point_a`` on ``a``; ``direction`` from ``b`` to ``a``), and ``versions``, the
    versions of the two objects' clouds it was computed on (0: the cloud the object was
    added with; see :meth:`Scene.replace_cloud`)."""

    a: str
    b: str
    margin: float
    kind: PairKind
    result: DistanceResult
    versions: tuple[int, int] = (0, 0)


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
    """

    sequence: int
    pairs: tuple[PairResult, ...]
    measured_at: float = math.nan
    computed_at: float = math.nan
    valid: bool = True
    reason: str = ""
    versions: Mapping[str, int] = field(default_factory=dict)
    cloud_stamps: Mapping[str, float] = field(default_factory=dict)

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


class Scene:
    """Objects, robots and watched pairs; :meth:`query_all` answers every pair.

    ``clock`` (optional, s): stamps inputs given without ``stamp=``, the query and its
    end (:attr:`SceneResult.measured_at`, :attr:`SceneResult.computed_at`); a
    simulation passes its simulated time.
    """

    def __init__(
        self, *, strategy: StrategyName = "default", clock: Callable[[], float] | None = None
    ) -> None:
        self.strategy = check_choice(strategy, STRATEGIES, source="scene", kind="strategy")
        self.clock = clock
        self._objects: dict[str, SceneObject] = {}
        self._robots: dict[str, RobotLike] = {}
        self._q: dict[str, NDArray[np.float64] | None] = {}
        self._runtime: dict[str, NDArray[np.float64]] = {}
        # time stamps (s) of the joint states and run-time poses; NaN = unknown
        self._q_stamp: dict[str, float] = {}
        self._pose_stamp: dict[str, float] = {}
        self._pairs: dict[tuple[str, str], WatchedPair] = {}
        self._queries: dict[tuple[str, str], PairQuery] = {}
        self._sequence = 0
        # cloud versions: the one in use per object, the last one handed over, and the
        # time stamp of the one in use (+inf: does not age); the read-only snapshots
        # the answers carry are replaced, never changed, when a cloud is swapped in
        self._versions: Mapping[str, int] = MappingProxyType({})
        self._cloud_stamps: Mapping[str, float] = MappingProxyType({})
        self._issued: dict[str, int] = {}
        self._ingest = CloudIngest()

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

    def add_robot(
        self, robot: RobotLike, q: ArrayLike | None = None, *, stamp: float | None = None
    ) -> None:
        """Register ``robot`` under ``robot.name``, optionally with its joint state
        measured at ``stamp``."""
        if not isinstance(robot, RobotLike):
            raise InputError("robot", "", "needs name, link_names and fk_all(q)")
        if robot.name in self._robots:
            raise InputError("scene", f"robot {robot.name!r}", "already registered")
        self._robots[robot.name] = robot
        self._q[robot.name] = None
        if q is not None:
            self.set_joints(robot.name, q, stamp=stamp)

    def set_joints(self, robot: str, q: ArrayLike, *, stamp: float | None = None) -> None:
        """The joint state of ``robot`` (one value per non-fixed joint), measured at
        ``stamp`` (s; default: the scene's clock, or unknown)."""
        self._robot(robot)
        arr = np.array(q, dtype=np.float64, copy=True).reshape(-1)
        if not np.isfinite(arr).all():
            raise InputError(f"robot {robot!r}", "q", "contains NaN or inf")
        t = self._stamp(stamp, f"robot {robot!r}")
        self._q[robot] = arr
        self._q_stamp[robot] = t

    def add_object(
        self,
        name: str,
        cloud: PointCloud | ArrayLike,
        pose: ArrayLike | None = None,
        *,
        robot: str | None = None,
        link: str | None = None,
        dynamic: bool = False,
    ) -> SceneObject:
        """Add a cloud. With ``robot`` and ``link`` it is attached to that link and
        ``pose`` is its fixed offset from the link frame; with ``dynamic=True`` its
        world pose is set at run time (``pose`` is the initial one); else ``pose`` is a
        fixed world pose. ``None`` means identity. The cloud's index is built now."""
        if not isinstance(name, str) or not name:
            raise InputError("scene", "object name", "must be a non-empty string")
        if name in self._objects:
            raise InputError("scene", f"object {name!r}", "already exists")
        c = as_cloud(cloud, name)
        P = check_pose(pose, f"pose of {name!r}").copy()
        source: PoseSource
        if robot is not None or link is not None:
            if robot is None or link is None:
                raise InputError("scene", f"object {name!r}", "give both robot and link")
            r = self._robot(robot)
            if link not in r.link_names:
                raise UnknownName(f"robot {robot!r}", "link", link, r.link_names)
            if dynamic:
                raise InputError("scene", f"object {name!r}", "a link object cannot be dynamic")
            source = OnLink(robot, link, P)
        elif dynamic:
            source = Runtime()
            self._runtime[name] = P
            self._pose_stamp[name] = self._stamp(None, f"object {name!r}")
        else:
            source = Fixed(P)
        cloud_index(c)
        obj = SceneObject(name, c, source)
        self._objects[name] = obj
        self._issued[name] = 0
        self._set_version(name, 0, math.inf)
        return obj

    def set_pose(self, name: str, pose: ArrayLike, *, stamp: float | None = None) -> None:
        """The world pose of a run-time (``dynamic``) object, measured at ``stamp``
        (s; default: the scene's clock, or unknown)."""
        obj = self._object(name)
        if not isinstance(obj.source, Runtime):
            raise InputError("scene", f"object {name!r}", "its pose is not set at run time")
        P = check_pose(pose, f"pose of {name!r}").copy()
        t = self._stamp(stamp, f"object {name!r}")
        self._runtime[name] = P
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
        on the scene's worker thread (:class:`~reachwise.distance.ingest.CloudIngest`)
        and swapped in at the start of the first :meth:`query_all` after it is ready, so
        a query never waits for a build. Until then the answers use the previous
        cloud, and say so (:attr:`SceneResult.versions`). A newer hand-over for the
        same object supersedes one still waiting; a cloud with bad points is never
        swapped in (its error is in :meth:`CloudIngest.errors`). An array is read on
        the worker thread: do not write into it afterwards.

        ``block=True`` checks and indexes the cloud now, in the caller, and swaps it in
        before returning (bad points raise :class:`~reachwise.errors.CloudError`).
        Either way the warm starts of the object's pairs are dropped at the swap."""
        self._object(name)
        t = self._stamp(stamp, f"object {name!r}")
        version = self._issued[name] + 1
        # no dtype here: a float32 frame is converted on the worker, not on this thread
        points = cloud if isinstance(cloud, PointCloud) else np.asarray(cloud)
        if block:
            self._install(ready_cloud(name, version, points, t))
            self._issued[name] = version
            return version
        self._issued[name] = version
        self._ingest.submit(name, version, points, t)
        return version

    # ------------------------------------------------------------------ rules
    def watch(self, a: str, b: str, margin: float, *, kind: PairKind = "custom") -> WatchedPair:
        """Watch objects ``a`` and ``b`` with ``margin`` metres (replaces an earlier rule
        for the same pair); ``kind`` (:data:`PairKind`) says why."""
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
        self._queries[key] = self._make_query(pair)
        return pair

    def unwatch(self, a: str, b: str) -> None:
        for key in ((a, b), (b, a)):
            self._pairs.pop(key, None)
            self._queries.pop(key, None)

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

    def watch_self(
        self,
        robot: str,
        margin: float,
        exclude: Iterable[tuple[str, str]] = (),
    ) -> tuple[WatchedPair, ...]:
        """Self-collision pairs of ``robot``: every two of its objects except those on
        the same link, on adjacent links (neighbours in ``link_names``: joint i joins
        link_{i-1} and link_i; the tool is adjacent to the last link) and the pairs in
        ``exclude`` (each a pair of link names or object names, either order)."""
        r = self._robot(robot)
        index = {n: i for i, n in enumerate(r.link_names)}
        excl = {frozenset(e) for e in exclude}
        objs = self.robot_objects(robot)
        out = []
        for i, oa in enumerate(objs):
            for ob in objs[i + 1 :]:
                la = oa.source.link  # type: ignore[union-attr]
                lb = ob.source.link  # type: ignore[union-attr]
                if abs(index[la] - index[lb]) <= 1:
                    continue
                if frozenset((la, lb)) in excl or frozenset((oa.name, ob.name)) in excl:
                    continue
                out.append(self.watch(oa.name, ob.name, margin, kind="self"))
        return tuple(out)

    def watch_environment(
        self, robot: str, margin: float, objects: Iterable[str] | None = None
    ) -> tuple[WatchedPair, ...]:
        """Pairs of every object of ``robot`` with every object not on a robot (or with
        the named ``objects``)."""
        mine = self.robot_objects(robot)
        if objects is None:
            others = [o.name for o in self._objects.values() if not isinstance(o.source, OnLink)]
        else:
            others = [self._object(n).name for n in objects]
        return tuple(
            self.watch(o.name, e, margin, kind="robot-environment") for o in mine for e in others
        )

    def watch_robots(self, robot_a: str, robot_b: str, margin: float) -> tuple[WatchedPair, ...]:
        """Pairs of every object of ``robot_a`` with every object of ``robot_b``."""
        if robot_a == robot_b:
            raise InputError("scene", "watch_robots", "use watch_self for one robot")
        oa = self.robot_objects(robot_a)
        ob = self.robot_objects(robot_b)
        return tuple(self.watch(x.name, y.name, margin, kind="robot-robot") for x in oa for y in ob)

    # ------------------------------------------------------------------ queries
    def poses(self) -> dict[str, NDArray[np.float64]]:
        """Current world pose of every object (forward kinematics of each robot once)."""
        fk: dict[str, NDArray[np.float64]] = {}
        return {name: self._pose(obj, fk) for name, obj in self._objects.items()}

    def query_all(self) -> SceneResult:
        """Answer every watched pair at the current joint states and poses; the result
        carries its sequence number, time stamps and cloud versions (see
        :class:`SceneResult`). Clouds indexed since the last call are swapped in first."""
        for ready in self._ingest.take_ready():
            self._install(ready)
        clock = self.clock
        measured = clock() if clock is not None else math.inf
        fk: dict[str, NDArray[np.float64]] = {}
        cache: dict[str, NDArray[np.float64]] = {}
        out = []
        versions = self._versions
        for key, pair in self._pairs.items():
            for n in key:
                if n not in cache:
                    obj = self._objects[n]
                    cache[n] = self._pose(obj, fk)
                    t = self._input_stamp(obj)
                    if t != t or t < measured:  # unknown (NaN, then kept) or older
                        measured = t
            res = self._queries[key](cache[pair.a], cache[pair.b])
            out.append(
                PairResult(
                    pair.a,
                    pair.b,
                    pair.margin,
                    pair.kind,
                    res,
                    (versions[pair.a], versions[pair.b]),
                )
            )
        self._sequence += 1
        computed = clock() if clock is not None else math.nan
        return SceneResult(
            self._sequence,
            tuple(out),
            measured_at=measured if measured != math.inf else math.nan,
            computed_at=computed,
            versions=versions,
            cloud_stamps=self._cloud_stamps,
        )

    def close(self) -> None:
        """Stop the cloud-ingestion worker (a remote scene disconnects here)."""
        self._ingest.close()

    def _install(self, ready: Ready) -> None:
        """Swap in a built cloud (unless a newer version is in use already): the object
        takes the cloud, the index registry its index, its pairs fresh warm starts."""
        if ready.version <= self._versions.get(ready.name, -1):
            return
        obj = self._objects[ready.name]
        INDICES.put(ready.cloud, ready.index)
        self._objects[ready.name] = SceneObject(ready.name, ready.cloud, obj.source)
        self._set_version(ready.name, ready.version, ready.stamp)
        for key in list(self._queries):
            if ready.name in key:
                self._queries[key] = self._make_query(self._pairs[key])

    def _set_version(self, name: str, version: int, stamp: float) -> None:
        """New read-only snapshots of the versions and cloud stamps (answers already
        given keep theirs)."""
        self._versions = MappingProxyType({**self._versions, name: version})
        self._cloud_stamps = MappingProxyType({**self._cloud_stamps, name: stamp})

    # ------------------------------------------------------------------ helpers
    def _stamp(self, stamp: float | None, source: str) -> float:
        """A checked measurement time stamp (s), the clock's reading, or NaN."""
        if stamp is None:
            return self.clock() if self.clock is not None else math.nan
        if (
            isinstance(stamp, bool)
            or not isinstance(stamp, numbers.Real)
            or not math.isfinite(stamp)
        ):
            raise InputError(source, "stamp", f"must be a finite time in s, got {stamp!r}")
        return float(stamp)

    def _input_stamp(self, obj: SceneObject) -> float:
        """Time stamp of the input ``obj``'s pose comes from (+inf for a fixed one)."""
        src = obj.source
        if isinstance(src, OnLink):
            return self._q_stamp.get(src.robot, math.nan)
        if isinstance(src, Runtime):
            return self._pose_stamp.get(obj.name, math.nan)
        return math.inf

    def _make_query(self, pair: WatchedPair) -> PairQuery:
        return PairQuery(
            self._objects[pair.a].cloud,
            self._objects[pair.b].cloud,
            margin=pair.margin,
            strategy=self.strategy,
        )

    def _robot(self, name: str) -> RobotLike:
        r = self._robots.get(name)
        if r is None:
            raise UnknownName("scene", "robot", name, self._robots)
        return r

    def _object(self, name: str) -> SceneObject:
        o = self._objects.get(name)
        if o is None:
            raise UnknownName("scene", "object", name, self._objects)
        return o

    def _pose(self, obj: SceneObject, fk: dict[str, NDArray[np.float64]]) -> NDArray[np.float64]:
        src = obj.source
        if isinstance(src, Fixed):
            return src.pose
        if isinstance(src, Runtime):
            return self._runtime[obj.name]
        frames = fk.get(src.robot)
        if frames is None:
            robot = self._robots[src.robot]
            q = self._q[src.robot]
            if q is None:
                raise InputError(
                    "scene", f"robot {src.robot!r}", "has no joint state; call set_joints first"
                )
            frames = np.asarray(robot.fk_all(q), dtype=np.float64)
            n = len(robot.link_names)
            if frames.shape != (n, 4, 4):
                raise InputError(
                    f"robot {src.robot!r}",
                    "fk_all",
                    f"expected shape ({n}, 4, 4), got {frames.shape}",
                )
            fk[src.robot] = frames
        link_pose = frames[self._robots[src.robot].link_names.index(src.link)]
        if src.identity:
            return np.ascontiguousarray(link_pose)
        return np.ascontiguousarray(link_pose @ src.offset)


__all__ = [
    "Fixed",
    "OnLink",
    "PairResult",
    "RobotLike",
    "Runtime",
    "Scene",
    "SceneLike",
    "SceneObject",
    "SceneResult",
    "WatchedPair",
]
