"""The collision server: a ZeroMQ service around the distance scene (P-IV/P-V architecture).

In the thesis's collision avoidance architecture (P-III §4.1 Fig. 2, P-IV, P-V §I–II) a
*collision server* holds every point cloud, keeps their poses current from the joint
sensors and the laser scanner, and sends the control system the shortest distances of all
watched pairs every control cycle (10 ms in P-V). This module is that server's
scene side; :mod:`reachwise.server.transport` puts it on the wire.

:class:`SceneService` — the scene behind the wire (:class:`reachwise.distance.Scene`):
validated requests in (:mod:`reachwise.server.protocol`), replies or typed errors out.
The *initialization phase* of P-V Table 1 (robots, clouds and their spatial indices,
pair rules) happens in ``add_robot``, ``add_object`` and the scene operations that
change the scene (``watch*``, :mod:`reachwise.distance.scene_ops`); the *calculation
phase* in ``set_joints`` (link poses by forward kinematics on the server), ``set_pose``
and ``query``; ``clear`` empties the scene (a simulator that owns it starts each run
from an empty one). With a state directory every change of the initialization phase is
persisted before it is acknowledged, and restored at start
(:mod:`reachwise.server.state`).

New clouds (``replace_cloud``: a scan, a depth camera's frames at 30 Hz) are handed to
the scene as the in-process scene takes them (:meth:`reachwise.distance.Scene.
replace_cloud` with ``block=False``): the reply, with the cloud's version, goes out at
once; the scene's worker thread indexes the cloud, and the first query after that
swaps it in, so a query never waits for a build. With ``block`` the reply waits until
that version is indexed (:class:`CloudWait`; the transport parks it without holding
up anything else). Every query reply carries the version and the stamp of each cloud
it used. With a state directory the newest cloud of each object is saved lazily, at
most every :data:`CLOUD_INTERVAL` seconds and once it has been indexed, with its
version and stamp; a restart resumes from it (versions handed out after the last save
before a crash may be handed out again; the stamps tell the clouds apart).

Until the state directory has been restored the server answers ``health`` with
``ready: false`` and refuses scene requests with ``not_ready``. A bad request of any kind
gets a typed error reply; the server never stops serving because of one.

Sequence numbers: every query and health reply draws the next number of one counter.
With a state directory the counter never goes back, also across crashes: the server
reserves numbers in blocks (:data:`reachwise.server.counters.SEQUENCE_BLOCK`) in
``sequence.json`` and starts after the reserved block when it restarts (numbers may
skip, never repeat).
"""

from __future__ import annotations

import functools
import logging
import math
import secrets
import threading
import time
import uuid
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

import reachwise.server.protocol as P
from reachwise._version import __version__
from reachwise.distance._common import NO_RISK, check_pose
from reachwise.distance.engine import STRATEGIES, StrategyName
from reachwise.distance.index import cloud_index
from reachwise.distance.scene import Fixed, OnLink, Scene, SceneObject, SceneResult
from reachwise.errors import InputError, UnknownName, check_choice
from reachwise.geometry.cloud import PointCloud
from reachwise.io.robot_file import robot_from_dict
from reachwise.kinematics.robot import Robot
from reachwise.server.counters import Metrics, SequenceCounter
from reachwise.server.state import (
    JointState,
    LiveState,
    Manifest,
    ObjectState,
    PairState,
    PoseState,
    RobotState,
    StateStore,
    matrix4,
)

log = logging.getLogger("reachwise.server")

#: How often the writer thread saves the latest joint states and poses (s).
LIVE_INTERVAL = 0.2
#: How often the writer thread saves the newest streamed cloud of each object (s).
CLOUD_INTERVAL = 1.0
#: Longest a ``block`` hand-over waits for its cloud to be indexed (s).
BLOCK_LIMIT = 120.0

ALWAYS_ALLOWED = frozenset({"hello", "health", "metrics"})

#: Where an object's pose comes from: kind, pose, robot and link.
_Source = tuple[Literal["fixed", "link", "runtime"], NDArray[np.float64], str | None, str | None]


def _err(code: P.ErrorCode, field: str, message: str) -> P.ProtocolError:
    return P.ProtocolError(code, field, message)


def _protocol_error(exc: Exception, op: str) -> P.ProtocolError:
    """What a request's failure is on the wire: a :class:`ProtocolError` as it is,
    a scene input error ``invalid``, anything unexpected ``internal`` (logged)."""
    if isinstance(exc, P.ProtocolError):
        return exc
    if isinstance(exc, UnknownName):
        return _err(P.ErrorCode.UNKNOWN_ID, exc.field or exc.source, str(exc))
    if isinstance(exc, InputError):
        return _err(P.ErrorCode.INVALID, exc.field or exc.source, str(exc))
    log.error("request %s failed: %s", op, P.failure_text(exc), exc_info=exc)
    return _err(P.ErrorCode.INTERNAL, "", P.failure_text(exc))


def _unknown(kind: str, name: str, valid: Iterable[str], where: str) -> P.ProtocolError:
    """An unknown robot or object, told as the scene tells it (with the closest name)."""
    return _err(P.ErrorCode.UNKNOWN_ID, where, UnknownName("server", kind, name, valid).reason)


@dataclass(frozen=True)
class _ObjectMeta:
    """What the server keeps beside the scene's object: its saved cloud (file, point
    count, version and stamp; None: does not age) and whose time stamp its pose carries
    (``("robot", name)``, ``("object", name)`` or None)."""

    cloud_file: str | None
    stamp_of: tuple[str, str] | None
    points: int = 0
    version: int = 0
    stamp: float | None = None


@dataclass(frozen=True, eq=False)
class CloudWait:
    """A handed-over cloud: object ``name``, its ``version`` on the wire and in the
    ``scene`` (the scene it was handed to: a ``clear`` replaces it), its ``points``
    and ``stamp``; ``deadline`` (monotonic s) for a ``block`` reply."""

    name: str
    version: int
    scene_version: int
    scene: Scene
    points: NDArray[Any]
    stamp: float
    deadline: float = math.inf


class SceneService:
    """The scene behind the wire (thread-safe): :meth:`handle` one request.

    ``store`` (optional) is the state directory; :meth:`load` restores it (the server
    is not ready before). ``clock`` stamps inputs that carry no time stamp.
    """

    def __init__(
        self,
        strategy: StrategyName = "default",
        store: StateStore | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.strategy = check_choice(strategy, STRATEGIES, source="server", kind="strategy")
        self.scene = Scene(strategy=self.strategy)
        self.store = store
        self.clock = clock
        self.lock = threading.RLock()
        self.metrics = Metrics()
        self.sequence = SequenceCounter(store)
        self.instance = uuid.uuid4().hex
        self.started = time.monotonic()
        self.state = "loading" if store is not None else "ready"
        self.reason = ""
        self._models: dict[str, dict[str, Any]] = {}
        self._robots: dict[str, Robot] = {}
        self._joints: dict[str, tuple[NDArray[np.float64], float]] = {}
        self._runtime: dict[str, tuple[NDArray[np.float64], float]] = {}
        self._meta: dict[str, _ObjectMeta] = {}
        self._live_dirty = False
        # layout keys: a random tag of this start in the high half, a counter below
        self._layout_tag = secrets.randbelow(2**31 - 1) + 1
        self._layout_count = 0
        self._layout: P.Layout | None = None
        self._all_sources: tuple[tuple[str, str], ...] = ()  # of the layout's pairs
        # the cloud table of the answers, kept while neither the versions nor the
        # layout change (one per swap, not one per query)
        self._clouds: tuple[object, int, NDArray[np.float64], bytes] | None = None
        # wire version = scene version + base (non-zero after a restore)
        self._version_base: dict[str, int] = {}
        # per object the newest handed-over cloud not saved yet
        self._unsaved: dict[str, CloudWait] = {}
        self._clouds_saved_at = time.monotonic()
        self._handlers: dict[type[P.Request], Callable[[Any], P.Reply]] = {
            P.Hello: self._hello,
            P.Health: self._health,
            P.Metrics: self._metrics,
            P.AddRobot: self._add_robot,
            P.AddObject: self._add_object,
            P.ReplaceCloud: self._replace_cloud,
            P.SetJoints: self._set_joints,
            P.SetPose: self._set_pose,
            P.Clear: self._clear,
            P.Query: self._query,
            P.Describe: self._describe,
            P.OperationCall: self._operation,
        }

    @property
    def ready(self) -> bool:
        return self.state == "ready"

    # ------------------------------------------------------------------ entry
    def handle(self, request: P.Request) -> P.Reply:
        """Answer one request or raise :class:`~reachwise.server.protocol.ProtocolError`.

        Scene input errors become ``invalid``; anything unexpected ``internal`` (logged),
        so the caller can always send a typed reply.
        """
        if request.OP not in ALWAYS_ALLOWED and not self.ready:
            why = f": {self.reason}" if self.reason else ""
            raise _err(P.ErrorCode.NOT_READY, "op", f"the server is {self.state}{why}")
        try:
            return self._handlers[type(request)](request)
        except Exception as exc:
            raise _protocol_error(exc, request.OP) from None

    # ------------------------------------------------------------------ lookups
    def _robot(self, name: str, where: str) -> Robot:
        r = self._robots.get(name)
        if r is None:
            raise _unknown("robot", name, self._robots, where)
        return r

    def _object(self, name: str, where: str) -> None:
        if name not in self._meta:
            raise _unknown("object", name, self._meta, where)

    def _check_q(self, robot: Robot, q: NDArray[np.float64], where: str) -> None:
        if q.shape != (robot.n,):
            raise _err(
                P.ErrorCode.WRONG_SHAPE,
                where,
                f"robot {robot.name!r} has {robot.n} joint variables; got shape {q.shape}",
            )

    def _check_runtime(self, name: str, where: str) -> None:
        self._object(name, where)
        meta = self._meta[name]
        if meta.stamp_of != ("object", name):
            raise _err(
                P.ErrorCode.INVALID, where, f"object {name!r}: its pose is not set at run time"
            )

    # ------------------------------------------------------------------ always allowed
    def _hello(self, req: P.Hello) -> P.Reply:
        if P.PROTOCOL_VERSION not in req.versions:
            raise _err(
                P.ErrorCode.UNSUPPORTED_VERSION,
                "body.versions",
                f"the client speaks {list(req.versions)}; "
                f"this server speaks {list(P.SUPPORTED_VERSIONS)}",
            )
        return P.HelloReply("reachwise", __version__, P.PROTOCOL_VERSION, self.instance, self.ready)

    def _health(self, req: P.Health) -> P.Reply:
        with self.lock:
            counts = (
                (len(self._robots), len(self._meta), len(self.scene.pairs))
                if self.ready
                else (0, 0, 0)
            )
        return P.HealthReply(
            self.ready,
            self.state,
            self.reason,
            self.sequence.take(),
            self.instance,
            time.monotonic() - self.started,
            *counts,
        )

    def _metrics(self, req: P.Metrics) -> P.Reply:
        return self.metrics.snapshot(time.monotonic() - self.started, self.sequence.last)

    # ------------------------------------------------------------------ calculation phase
    def _checked_pose(
        self, name: str, pose: NDArray[np.float64], name_at: str, pose_at: str
    ) -> NDArray[np.float64]:
        """The pose of run-time object ``name`` checked as the scene checks it; errors
        name ``name_at`` (unknown or not a run-time object) or ``pose_at``."""
        self._check_runtime(name, name_at)
        try:
            return check_pose(pose, pose_at)
        except InputError as exc:
            raise _err(P.ErrorCode.INVALID, pose_at, exc.reason) from None

    def _store_joints(self, robot: str, q: NDArray[np.float64], stamp: float) -> None:
        """Apply checked joint values (call under the lock)."""
        self.scene.set_joints(robot, q)
        # a decoded array is a read-only view of its message: kept as it is
        kept = q if not q.flags.writeable and q.dtype == np.float64 else q.copy()
        self._joints[robot] = (kept, stamp)
        self._live_dirty = True

    def _store_pose(self, name: str, pose: NDArray[np.float64], stamp: float) -> None:
        """Apply a checked run-time pose (call under the lock)."""
        self.scene.set_pose(name, pose)
        self._runtime[name] = (pose.copy(), stamp)
        self._live_dirty = True

    def _set_joints(self, req: P.SetJoints) -> P.Reply:
        stamp = self.clock() if req.stamp is None else req.stamp
        with self.lock:
            self._check_q(self._robot(req.robot, "body.robot"), req.q, "body.q")
            self._store_joints(req.robot, req.q, stamp)
        return P.Ack()

    def _set_pose(self, req: P.SetPose) -> P.Reply:
        stamp = self.clock() if req.stamp is None else req.stamp
        with self.lock:
            pose = self._checked_pose(req.name, req.pose, "body.name", "body.pose")
            self._store_pose(req.name, pose, stamp)
        return P.Ack()

    def _query(self, req: P.Query) -> P.Reply:
        stamp = self.clock() if req.stamp is None else req.stamp
        with self.lock:
            if req.pairs is not None:
                return self._query_pairs(req, stamp)
            layout = self._layout or self._current_layout()
            seq, measured, compute, rows, clouds, _ = self._answer_every(
                stamp, req.joints, req.poses, layout
            )
            if req.layout == layout.name:  # the per-tick answer: every field made here
                return P.tick_query_reply(layout, seq, measured, compute, rows, clouds)
            return P.QueryReply(
                seq,
                measured,
                compute,
                layout.name,
                layout.pairs,
                rows,
                layout.objects,
                layout.robots,
                clouds,
            )

    def _checked_inputs(
        self,
        joints: Mapping[str, NDArray[np.float64]] | None,
        poses: Mapping[str, NDArray[np.float64]] | None,
    ) -> dict[str, NDArray[np.float64]]:
        """Check a query's joint states and poses (call under the lock); the checked
        poses. Every input is checked before any is applied: a query's inputs are
        atomic."""
        if joints:
            robots = self._robots
            for name, q in joints.items():
                robot = robots.get(name)
                if robot is None or q.shape != (robot.n,):  # the error, named
                    where = f"body.joints.{name}"
                    self._check_q(self._robot(name, where), q, where)
        if not poses:
            return {}
        return {
            name: self._checked_pose(name, pose, f"body.poses.{name}", f"body.poses.{name}")
            for name, pose in poses.items()
        }

    def _apply_inputs(
        self,
        joints: Mapping[str, NDArray[np.float64]] | None,
        poses: Mapping[str, NDArray[np.float64]],
        stamp: float,
    ) -> None:
        """Apply checked joint states and poses (call under the lock)."""
        for name, q in (joints or {}).items():
            self._store_joints(name, q, stamp)
        for name, pose in poses.items():
            self._store_pose(name, pose, stamp)

    def _answer_every(
        self,
        stamp: float,
        joints: Mapping[str, NDArray[np.float64]] | None,
        poses: Mapping[str, NDArray[np.float64]] | None,
        layout: P.Layout,
    ) -> tuple[int, float, float, NDArray[np.float64], NDArray[np.float64], bytes]:
        """Apply a query's inputs and answer every watched pair (call under the lock,
        ``layout`` the current one): sequence, measured_at, compute time, the rows (in
        the layout's pair order), the cloud table and its bytes."""
        if joints or poses:
            self._apply_inputs(joints, self._checked_inputs(joints, poses), stamp)
        res, compute = self._query_all()
        measured = self._measured_at(None, stamp, self._all_sources)
        clouds, cloud_bytes = self._cloud_table(res.versions, res.cloud_stamps, layout)
        return self.sequence.take(), measured, compute, res.rows, clouds, cloud_bytes

    def _query_all(self) -> tuple[SceneResult, float]:
        """Every watched pair's answer and its computation time (s)."""
        t0 = time.perf_counter()
        res = self.scene.query_all()
        return res, time.perf_counter() - t0

    def _query_pairs(self, req: P.Query, stamp: float) -> P.Reply:
        """A query of chosen watched pairs (call under the lock): their rows alone,
        with their own list (no layout a tick can refer to)."""
        poses = self._checked_inputs(req.joints, req.poses)
        watched = {frozenset((p.a, p.b)) for p in self.scene.pairs}
        for i, (a, b) in enumerate(req.pairs or ()):
            if frozenset((a, b)) not in watched:
                raise _err(
                    P.ErrorCode.UNKNOWN_PAIR,
                    f"body.pairs[{i}]",
                    f"pair ({a!r}, {b!r}) is not watched",
                )
        wanted = {frozenset(p) for p in req.pairs or ()}
        self._apply_inputs(req.joints, poses, stamp)
        res, compute = self._query_all()
        layout = self._current_layout()
        pairs = tuple(p for p in res.pairs if frozenset((p.a, p.b)) in wanted)
        measured = self._measured_at(pairs, stamp)
        seq = self.sequence.take()
        clouds, _ = self._cloud_table(res.versions, res.cloud_stamps, layout)
        return P.QueryReply(
            seq,
            measured,
            compute,
            "",
            tuple(P.PairInfo(p.a, p.b, p.margin, p.kind) for p in pairs),
            _rows(pairs),
            layout.objects,
            layout.robots,
            clouds,
        )

    def tick(self, raw: P.Buffer, limits: P.Limits) -> tuple[bytes, float | None]:
        """Answer one binary tick (:mod:`reachwise.server.protocol.tick`): the reply
        frame (a tick, or a typed error frame) and the answer's computation time (s;
        None for an error). The layout is held (the lock) from decoding to answering,
        so the indices mean what the client meant.

        The per-tick path: the frame is read straight into the inputs and the reply
        written from the answer's parts (no :class:`~reachwise.server.protocol.Query`
        or :class:`~reachwise.server.protocol.QueryReply` is made); the answer, the
        checks and the typed errors are :meth:`handle`'s for that query."""
        rid = None
        try:
            with self.lock:
                if self.state != "ready":
                    why = f": {self.reason}" if self.reason else ""
                    raise _err(P.ErrorCode.NOT_READY, "op", f"the server is {self.state}{why}")
                layout = self._layout or self._current_layout()
                rid, stamp, joints, poses = P.read_tick(raw, layout, limits)
                self.metrics.tick()
                seq, measured, compute, rows, clouds, cloud_bytes = self._answer_every(
                    self.clock() if stamp is None else stamp, joints, poses, layout
                )
        except Exception as exc:
            err = _protocol_error(exc, "query")
            if err.request_id is None:
                err.request_id = rid
            self.metrics.error(err.code)
            return P.encode_error(err.request_id, P.ErrorReply.of(err)), None
        frame = P.tick_reply_frame(
            rid, seq, layout.key, measured, compute, rows, clouds.shape[0], cloud_bytes
        )
        return frame, compute

    def _current_layout(self) -> P.Layout:
        """The layout of the answers: watched pairs, objects, robots (call under the lock)."""
        if self._layout is None:
            infos = tuple(P.PairInfo(p.a, p.b, p.margin, p.kind) for p in self.scene.pairs)
            key = (self._layout_tag << 32) | (self._layout_count & 0xFFFFFFFF)
            self._layout = P.Layout(key, infos, tuple(self._meta), tuple(self._robots))
            self._all_sources = self._sources(infos)
        return self._layout

    def _pairs_changed(self) -> None:
        """A pair, margin, the order, an object or a robot changed: the next reply sends
        a new layout."""
        self._layout_count += 1
        self._layout = None
        self._clouds = None

    def _cloud_table(
        self, versions: Mapping[str, int], stamps: Mapping[str, float], layout: P.Layout
    ) -> tuple[NDArray[np.float64], bytes]:
        """Version and stamp of each object's cloud in layout order, and the table's
        bytes in a tick reply (call under the lock); the scene replaces its version map
        at every swap, so one table serves every answer until the next swap or layout
        change."""
        cached = self._clouds
        if cached is not None and cached[0] is versions and cached[1] == layout.key:
            return cached[2], cached[3]
        base = self._version_base
        table = np.array(
            [
                (versions.get(n, 0) + base.get(n, 0), stamps.get(n, math.nan))
                for n in layout.objects
            ],
            dtype=np.float64,
        ).reshape(len(layout.objects), P.CLOUD_COLUMNS)
        table.setflags(write=False)
        self._clouds = (versions, layout.key, table, table.tobytes())
        return table, self._clouds[3]

    def _measured_at(
        self,
        pairs: tuple[Any, ...] | None,
        stamp: float,
        every: tuple[tuple[str, str], ...] = (),
    ) -> float:
        """The oldest of ``stamp`` and the stamps of the inputs the poses of ``pairs``'
        objects come from (``pairs`` None: those of every watched pair, ``every``)."""
        sources = every if pairs is None else self._sources(pairs)
        oldest = stamp
        for kind, key in sources:
            entry = self._joints.get(key) if kind == "robot" else self._runtime.get(key)
            if entry is not None and entry[1] < oldest:
                oldest = entry[1]
        return oldest

    def _sources(self, pairs: Iterable[Any]) -> tuple[tuple[str, str], ...]:
        """The inputs (``("robot", name)`` or ``("object", name)``) the poses of the
        pairs' objects come from, each once."""
        out: dict[tuple[str, str], None] = {}
        for p in pairs:
            for name in (p.a, p.b):
                src = self._meta[name].stamp_of
                if src is not None:
                    out[src] = None
        return tuple(out)

    def _describe(self, req: P.Describe) -> P.Reply:
        with self.lock:
            self.scene.swap_in()  # the clouds in use: those indexed so far
            objects = tuple(
                P.ObjectInfo(
                    name,
                    len(obj.cloud),
                    *self._source(name, obj),
                    cloud=obj.cloud.points if req.clouds else None,
                )
                for name, obj in self.scene.objects.items()
            )
            return P.DescribeReply(
                self.strategy,
                dict(self._models),
                {k: v[0] for k, v in self._joints.items()},
                objects,
                tuple(P.PairInfo(p.a, p.b, p.margin, p.kind) for p in self.scene.pairs),
                self.sequence.last,
            )

    def _operation(self, req: P.OperationCall) -> P.Reply:
        """A registered scene operation (:mod:`reachwise.distance.scene_ops`) run on
        this server's scene, its result in the wire form its result type gives. One
        that changes the scene (the transport runs it on the writer thread) makes a
        new layout and is persisted before the reply."""
        op = P.operation(req.operation, "body.operation")
        with self.lock:
            try:
                result = op.function(self.scene, **req.arguments)
            finally:
                if op.mutates:  # a failed call may have changed part of the scene
                    self._pairs_changed()
                    manifest = self._manifest()
            reply = P.OperationResult(P.encode_value(result, op.result))
        if op.mutates:
            self._persist(manifest)
        return reply

    # ------------------------------------------------------------------ initialization phase
    def _add_robot(self, req: P.AddRobot) -> P.Reply:
        try:
            robot = robot_from_dict(req.robot, "robot")
        except InputError as exc:
            field = f"body.robot.{exc.field}" if exc.field else "body.robot"
            raise _err(P.ErrorCode.INVALID, field, exc.reason) from None
        P.check_name(robot.name, "body.robot.name")  # addressable by every later request
        with self.lock:
            if robot.name in self._robots:
                raise _err(
                    P.ErrorCode.EXISTS,
                    "body.robot.name",
                    f"robot {robot.name!r} is already registered",
                )
            if req.q is not None:
                self._check_q(robot, req.q, "body.q")
            self.scene.add_robot(robot)
            self._robots[robot.name] = robot
            self._models[robot.name] = req.robot
            self._pairs_changed()  # the robots of the layout
            if req.q is not None:
                self._store_joints(
                    robot.name, req.q, self.clock() if req.stamp is None else req.stamp
                )
            manifest = self._manifest()
        self._persist(manifest)
        return P.RobotReply(robot.name, robot.link_names, robot.n)

    def _add_object(self, req: P.AddObject) -> P.Reply:
        with self.lock:
            if req.name in self._meta:
                raise _err(P.ErrorCode.EXISTS, "body.name", f"object {req.name!r} already exists")
            if (req.robot is None) != (req.link is None):
                raise _err(
                    P.ErrorCode.INVALID,
                    "body.link" if req.link is None else "body.robot",
                    "give both robot and link",
                )
            if req.robot is not None and req.link is not None:
                r = self._robot(req.robot, "body.robot")
                if req.link not in r.link_names:
                    raise _err(
                        P.ErrorCode.UNKNOWN_ID,
                        "body.link",
                        f"robot {req.robot!r} has no link {req.link!r}; "
                        f"links: {list(r.link_names)}",
                    )
                if req.dynamic:
                    raise _err(
                        P.ErrorCode.INVALID, "body.dynamic", "an object on a link cannot be dynamic"
                    )
        # the index is built outside the lock (P-V Table 1 steps 1-3)
        cloud = _cloud(req.cloud, req.name, req.link or "world")
        cloud_file = self.store.write_cloud(cloud.points) if self.store is not None else None
        try:
            with self.lock:
                if req.name in self._meta:
                    raise _err(
                        P.ErrorCode.EXISTS, "body.name", f"object {req.name!r} already exists"
                    )
                try:
                    self.scene.add_object(
                        req.name,
                        cloud,
                        req.pose,
                        robot=req.robot,
                        link=req.link,
                        dynamic=req.dynamic,
                    )
                except InputError as exc:
                    raise _err(P.ErrorCode.INVALID, "body.pose", exc.reason) from None
                stamp_of = None
                if req.robot is not None:
                    stamp_of = ("robot", req.robot)
                elif req.dynamic:
                    stamp_of = ("object", req.name)
                    self._runtime[req.name] = (check_pose(req.pose, "body.pose"), self.clock())
                self._meta[req.name] = _ObjectMeta(cloud_file, stamp_of, len(cloud))
                self._pairs_changed()  # the objects of the layout
                manifest = self._manifest()
        except BaseException:
            self._drop_file(cloud_file)
            raise
        self._persist(manifest)
        return P.ObjectReply(req.name, len(cloud))

    def _replace_cloud(self, req: P.ReplaceCloud) -> P.Reply:
        """Hand the cloud over and reply with its version; with ``block`` wait here (up
        to :data:`BLOCK_LIMIT`) until it is indexed. The transport does not call this
        for ``block``: it parks the :class:`CloudWait` instead (:meth:`settle`)."""
        wait = self.hand_over(req)
        if not req.block:
            return P.ObjectReply(wait.name, len(wait.points), wait.version)
        wait.scene.ingest.wait(wait.name, wait.scene_version, BLOCK_LIMIT)
        reply = self.settle(wait)
        if reply is None:
            raise _err(
                P.ErrorCode.INTERNAL,
                "cloud",
                f"version {wait.version} of {wait.name!r} was not indexed in {BLOCK_LIMIT:g} s",
            )
        return reply

    def hand_over(self, req: P.ReplaceCloud) -> CloudWait:
        """Give the scene the new cloud (no copy, no build here: its worker indexes it)
        and remember it for the state directory; raises for an unknown object."""
        if not self.ready:
            raise _err(P.ErrorCode.NOT_READY, "op", f"the server is {self.state}")
        stamp = self.clock() if req.stamp is None else req.stamp
        with self.lock:
            self._object(req.name, "body.name")
            scene = self.scene
            v = scene.replace_cloud(req.name, req.cloud, block=False, stamp=stamp)
            wait = CloudWait(
                req.name,
                v + self._version_base.get(req.name, 0),
                v,
                scene,
                req.cloud,
                stamp,
                time.monotonic() + BLOCK_LIMIT if req.block else math.inf,
            )
            if self.store is not None:
                self._unsaved[req.name] = wait
        return wait

    def settle(self, wait: CloudWait) -> P.ObjectReply | None:
        """The reply to a ``block`` hand-over once its version (or a newer one) is
        indexed, None while it is not; raises ``invalid`` for a cloud whose points were
        refused, ``unknown_id`` when the scene was cleared meanwhile."""
        if not wait.scene.ingest.wait(wait.name, wait.scene_version, 0.0):
            return None
        with self.lock:
            if wait.scene is not self.scene:
                raise _err(P.ErrorCode.UNKNOWN_ID, "body.name", "the scene was cleared meanwhile")
            failed = wait.scene.ingest.errors().get(wait.name)
            if failed is not None and failed[0] == wait.scene_version:
                raise _err(P.ErrorCode.INVALID, "cloud", str(failed[1]))
            self.scene.swap_in()  # in use from now on, not only from the next query
        return P.ObjectReply(wait.name, len(wait.points), wait.version)

    def flush_clouds(self, force: bool = False, timeout: float = 0.0) -> None:
        """Save the newest handed-over cloud of each object (writer thread), at most
        every :data:`CLOUD_INTERVAL` s unless ``force``; only indexed clouds are saved
        (``timeout`` s to wait for builds in progress), never refused ones."""
        if self.store is None or not self._unsaved or not self.ready:
            return
        now = time.monotonic()
        if not force and now - self._clouds_saved_at < CLOUD_INTERVAL:
            return
        self._clouds_saved_at = now
        with self.lock:
            pending = list(self._unsaved.values())
        for w in pending:
            if not w.scene.ingest.wait(w.name, w.scene_version, timeout):
                continue  # still being indexed: the next round
            failed = w.scene.ingest.errors().get(w.name)
            refused = failed is not None and failed[0] == w.scene_version
            cloud_file = None if refused else self.store.write_cloud(w.points)
            with self.lock:
                current = self._unsaved.get(w.name) is w
                if current:
                    del self._unsaved[w.name]
                old = self._meta.get(w.name)
                if cloud_file is None or w.scene is not self.scene or old is None:
                    manifest = None
                else:
                    self._meta[w.name] = _ObjectMeta(
                        cloud_file, old.stamp_of, len(w.points), w.version, w.stamp
                    )
                    manifest = self._manifest()
            if manifest is None:
                self._drop_file(cloud_file)
                continue
            try:
                self._persist(manifest)
            except P.ProtocolError:
                continue  # reported in health; the next change retries
            if old is not None:
                self._drop_file(old.cloud_file)

    def _clear(self, req: P.Clear) -> P.Reply:
        with self.lock:
            dropped = [m.cloud_file for m in self._meta.values()]
            old_scene = self.scene
            self.scene = Scene(strategy=self.strategy)
            self._models, self._robots, self._meta = {}, {}, {}
            self._joints, self._runtime = {}, {}
            self._unsaved, self._version_base = {}, {}
            self._pairs_changed()
            self._live_dirty = True
            manifest = self._manifest()
        old_scene.close()  # its indexing worker
        self._persist(manifest)
        for f in dropped:
            self._drop_file(f)
        return P.Ack()

    # ------------------------------------------------------------------ persistence
    def _manifest(self) -> Manifest | None:
        """The initialization-phase state to persist (call under the lock); None
        without a state directory."""
        if self.store is None:
            return None
        objects = []
        for name, obj in self.scene.objects.items():
            meta = self._meta[name]
            source, pose, robot, link = self._source(name, obj)
            objects.append(
                ObjectState(
                    name=name,
                    cloud=str(meta.cloud_file),
                    points=meta.points,
                    source=source,
                    pose=matrix4(pose),
                    robot=robot,
                    link=link,
                    version=meta.version,
                    stamp=meta.stamp,
                )
            )
        return Manifest(
            strategy=self.strategy,
            robots=tuple(RobotState(name=k, model=v) for k, v in self._models.items()),
            objects=tuple(objects),
            pairs=tuple(
                PairState(a=p.a, b=p.b, margin=p.margin, kind=p.kind) for p in self.scene.pairs
            ),
        )

    def _source(self, name: str, obj: SceneObject) -> _Source:
        """Where object ``name``'s pose comes from: ``fixed`` (its world pose), ``link``
        (its offset, robot and link) or ``runtime`` (its current pose)."""
        src = obj.source
        if isinstance(src, Fixed):
            return "fixed", src.pose, None, None
        if isinstance(src, OnLink):
            return "link", src.offset, src.robot, src.link
        return "runtime", self._runtime[name][0], None, None

    def _persist(self, manifest: Manifest | None) -> None:
        """Write the manifest; the change is applied already, so a failure is reported
        as such (and in health) rather than as if nothing had happened."""
        if self.store is None or manifest is None:
            return
        try:
            self.store.write_manifest(manifest)
        except OSError as exc:
            self.reason = f"state directory not writable: {exc}"
            log.error("%s", self.reason)
            raise _err(
                P.ErrorCode.INTERNAL,
                "state",
                f"applied, but the state directory could not be written: {exc}",
            ) from None
        self.reason = ""

    def _drop_file(self, cloud_file: str | None) -> None:
        if self.store is not None and cloud_file is not None:
            (self.store.root / "clouds" / cloud_file).unlink(missing_ok=True)

    def flush_live(self, force: bool = False) -> None:
        """Save the latest joint states and run-time poses if they changed."""
        if self.store is None or not self.ready or not (self._live_dirty or force):
            return
        with self.lock:
            live = LiveState(
                joints={
                    k: JointState(q=tuple(float(v) for v in q), stamp=t)
                    for k, (q, t) in self._joints.items()
                },
                poses={
                    k: PoseState(pose=matrix4(p), stamp=t) for k, (p, t) in self._runtime.items()
                },
            )
            self._live_dirty = False
        self.store.write_live(live)

    def close(self) -> None:
        """Stop the scene's cloud-indexing worker."""
        self.scene.close()

    def load(self) -> None:
        """Restore the state directory into a fresh scene, then become ready. A bad
        state leaves the server ``failed`` (not ready) with the reason."""
        if self.store is None:
            self.state = "ready"
            return
        try:
            self._restore(self.store)
        except Exception as exc:
            log.exception("restoring %s failed", self.store.root)
            self.reason = f"restoring {self.store.root} failed: {exc}"
            self.state = "failed"
            return
        self.state = "ready"
        log.info("state restored from %s", self.store.root)

    def _restore(self, store: StateStore) -> None:
        snap = store.read()
        if snap is None:
            return
        m, live = snap.manifest, snap.live
        where = str(store.root / "scene.json")
        scene = Scene(strategy=m.strategy)
        robots: dict[str, Robot] = {}
        joints: dict[str, tuple[NDArray[np.float64], float]] = {}
        runtime: dict[str, tuple[NDArray[np.float64], float]] = {}
        meta: dict[str, _ObjectMeta] = {}
        base: dict[str, int] = {}
        for rs in m.robots:
            robot = robot_from_dict(rs.model, f"{where}: robot {rs.name!r}")
            scene.add_robot(robot)
            robots[robot.name] = robot
            js = live.joints.get(robot.name)
            if js is not None:
                q = np.array(js.q, dtype=np.float64)
                scene.set_joints(robot.name, q)
                joints[robot.name] = (q, js.stamp)
        for o in m.objects:
            cloud = _cloud(snap.clouds[o.name], o.name, o.link or "world")
            pose = np.array(o.pose, dtype=np.float64)
            saved = (o.cloud, o.points, o.version, o.stamp)
            if o.source == "runtime":
                ps = live.poses.get(o.name)
                stamp = self.clock()
                if ps is not None:
                    pose, stamp = np.array(ps.pose, dtype=np.float64), ps.stamp
                scene.add_object(o.name, cloud, pose, dynamic=True)
                runtime[o.name] = (check_pose(pose, o.name), stamp)
                meta[o.name] = _ObjectMeta(saved[0], ("object", o.name), *saved[1:])
            elif o.source == "link":
                scene.add_object(o.name, cloud, pose, robot=o.robot, link=o.link)
                meta[o.name] = _ObjectMeta(saved[0], ("robot", str(o.robot)), *saved[1:])
            else:
                scene.add_object(o.name, cloud, pose)
                meta[o.name] = _ObjectMeta(saved[0], None, *saved[1:])
            if o.version > 0:  # a handed-over cloud: its version and stamp go on
                cloud_stamp = math.inf if o.stamp is None else o.stamp
                base[o.name] = o.version - scene.replace_cloud(
                    o.name, cloud, block=True, stamp=cloud_stamp
                )
        for p in m.pairs:
            scene.watch(p.a, p.b, p.margin, kind=p.kind)
        removed = store.remove_unreferenced(m)
        if removed:
            log.info("removed %d unreferenced state files", len(removed))
        with self.lock:
            old_scene, self.scene = self.scene, scene
            self.strategy = m.strategy
            self._robots = robots
            self._models = {rs.name: rs.model for rs in m.robots}
            self._joints = joints
            self._runtime = runtime
            self._meta = meta
            self._version_base = base
            self._unsaved = {}
            self._pairs_changed()
        old_scene.close()


def _cloud(points: NDArray[np.float64], name: str, frame: str) -> PointCloud:
    """A validated cloud with its k-d tree built (P-V Table 1 initialization)."""
    cloud = PointCloud(points, frame=frame, name=name)
    cloud_index(cloud)
    return cloud


def _rows(pairs: tuple[Any, ...]) -> NDArray[np.float64]:
    """The pairs' answers as the rows of :class:`~reachwise.server.protocol.QueryReply`:
    every row starts as the no-risk row (one copy), the pairs within their margins are
    written over it."""
    out = _no_risk_rows(len(pairs)).copy()
    for k, p in enumerate(pairs):
        r = p.result
        if not r.no_risk:
            row = out[k]
            row[0] = r.distance
            row[1:4] = r.point_a
            row[4:7] = r.point_b
            row[7:10] = r.direction
            row[10] = r.index_a
            row[11] = r.index_b
            row[12] = 0.0
    return out


#: The row of a pair beyond its margin (as the in-process ``NO_RISK`` result).
_NO_RISK_ROW = np.array(
    [
        NO_RISK.distance,
        *NO_RISK.point_a.tolist(),
        *NO_RISK.point_b.tolist(),
        *NO_RISK.direction.tolist(),
        float(NO_RISK.index_a),
        float(NO_RISK.index_b),
        1.0,
    ]
)


@functools.lru_cache(maxsize=64)
def _no_risk_rows(n: int) -> NDArray[np.float64]:
    """``n`` no-risk rows (read-only; an answer copies them)."""
    rows = np.tile(_NO_RISK_ROW, (n, 1))
    rows.setflags(write=False)
    return rows


def answer(service: SceneService, rid: int, req: P.Request) -> tuple[bytes, P.Reply | None]:
    """The reply frame of one request (a typed error frame on failure) and the reply."""
    try:
        reply = service.handle(req)
        return P.encode_reply(rid, reply), reply
    except P.ProtocolError as exc:
        service.metrics.error(exc.code)
        return P.encode_error(rid, P.ErrorReply.of(exc)), None
    except Exception as exc:  # an unencodable reply would be our bug: still answer
        log.error("encoding the reply to %s failed: %s", req.OP, P.failure_text(exc), exc_info=exc)
        service.metrics.error(P.ErrorCode.INTERNAL)
        err = P.ErrorReply(P.ErrorCode.INTERNAL, "", P.failure_text(exc))
        return P.encode_error(rid, err), None
