"""The collision server: a ZeroMQ service around the distance scene (P-IV/P-V architecture).

In the thesis's collision avoidance architecture (P-III §4.1 Fig. 2, P-IV, P-V §I–II) a
*collision server* holds every point cloud, keeps their poses current from the joint
sensors and the laser scanner, and sends the control system the shortest distances of all
watched pairs every control cycle (10 ms in P-V). This module is that server's
scene side; :mod:`reachwise.server.transport` puts it on the wire.

:class:`SceneService` — the scene behind the wire (:class:`reachwise.distance.Scene`):
validated requests in (:mod:`reachwise.server.protocol`), replies or typed errors out.
The *initialization phase* of P-V Table 1 (robots, clouds and their spatial indices,
pair rules) happens in ``add_object`` and the scene operations that change the scene
(``add_robot``, ``watch*``, :mod:`reachwise.distance.scene_ops`); the *calculation
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

:class:`SceneService` is built from one module per concept: the scene and the records
kept beside it (:mod:`reachwise.server.service_core`), the answers to queries and
binary ticks (:mod:`reachwise.server.answering`), streamed clouds
(:mod:`reachwise.server.handover`) and the state directory
(:mod:`reachwise.server.persistence`); this module adds the setup requests and the
dispatch.

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

import logging
import math
import time
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import reachwise.server.protocol as P
from reachwise._version import __version__
from reachwise.distance._common import check_pose
from reachwise.distance.engine import StrategyName
from reachwise.errors import InputError
from reachwise.server.answering import SceneAnswering
from reachwise.server.handover import BLOCK_LIMIT, CLOUD_INTERVAL, CloudHandover
from reachwise.server.persistence import LIVE_INTERVAL
from reachwise.server.service_core import (
    CloudWait,
    indexed_cloud,
    protocol_error_of,
    wire_error,
)
from reachwise.server.state import (
    StateStore,
)

log = logging.getLogger("reachwise.server")

__all__ = [
    "BLOCK_LIMIT",
    "CLOUD_INTERVAL",
    "LIVE_INTERVAL",
    "CloudWait",
    "SceneService",
    "answer",
]

ALWAYS_ALLOWED = frozenset({"hello", "health", "metrics"})


class SceneService(SceneAnswering, CloudHandover):
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
        super().__init__(strategy, store, clock)
        self._handlers: dict[type[P.Request], Callable[[Any], P.Reply]] = {
            P.Hello: self._hello,
            P.Health: self._health,
            P.Metrics: self._metrics,
            P.AddObject: self._add_object,
            P.ReplaceCloud: self._replace_cloud,
            P.SetJoints: self._set_joints,
            P.SetPose: self._set_pose,
            P.Query: self._query,
            P.OperationCall: self._operation,
        }

    # ------------------------------------------------------------------ entry
    def handle(self, request: P.Request) -> P.Reply:
        """Answer one request or raise :class:`~reachwise.server.protocol.ProtocolError`.

        Scene input errors become ``invalid``; anything unexpected ``internal`` (logged),
        so the caller can always send a typed reply.
        """
        if request.OP not in ALWAYS_ALLOWED and not self.ready:
            why = f": {self.reason}" if self.reason else ""
            raise wire_error(P.ErrorCode.NOT_READY, "op", f"the server is {self.state}{why}")
        try:
            return self._handlers[type(request)](request)
        except Exception as exc:
            raise protocol_error_of(exc, request.OP) from None

    # ------------------------------------------------------------------ always allowed
    def _hello(self, req: P.Hello) -> P.Reply:
        if P.PROTOCOL_VERSION not in req.versions:
            raise wire_error(
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

    def _operation(self, req: P.OperationCall) -> P.Reply:
        """A registered scene operation (:mod:`reachwise.distance.scene_ops`) run on
        this server's scene, its result in the wire form its result type gives. One
        that changes the scene (the transport runs it on the writer thread) makes a
        new layout and is persisted before the reply. A staged one
        (:func:`~reachwise.distance.scene_ops.staged_operation`) runs its first stage
        without the scene lock and only its hand-over under it."""
        op = P.operation(req.operation, "body.operation")
        if op.hand_over is not None:
            prepared = op.function(self.scene, **req.arguments)
            with self.lock:
                result = op.hand_over(self.scene, prepared)
                return P.OperationResult(P.encode_value(result, op.result))
        dropped: list[str] = []
        with self.lock:
            try:
                result = op.function(self.scene, **req.arguments)
            finally:
                if op.mutates:  # a failed call may have changed part of the scene
                    dropped = self._adopt()
                    manifest = self._manifest()
            reply = P.OperationResult(P.encode_value(result, op.result))
        if op.mutates:
            self._persist(manifest)
        for cloud_file in dropped:  # of objects the change removed, once unlisted
            self._drop_file(cloud_file)
        return reply

    # ------------------------------------------------------------------ initialization phase
    def _add_object(self, req: P.AddObject) -> P.Reply:
        with self.lock:
            if req.name in self._meta:
                raise wire_error(
                    P.ErrorCode.EXISTS, "body.name", f"object {req.name!r} already exists"
                )
            if (req.robot is None) != (req.link is None):
                raise wire_error(
                    P.ErrorCode.INVALID,
                    "body.link" if req.link is None else "body.robot",
                    "give both robot and link",
                )
            if req.robot is not None and req.link is not None:
                r = self._robot(req.robot, "body.robot")
                if req.link not in r.link_names:
                    raise wire_error(
                        P.ErrorCode.UNKNOWN_ID,
                        "body.link",
                        f"robot {req.robot!r} has no link {req.link!r}; "
                        f"links: {list(r.link_names)}",
                    )
                if req.dynamic:
                    raise wire_error(
                        P.ErrorCode.INVALID, "body.dynamic", "an object on a link cannot be dynamic"
                    )
        # the index is built outside the lock (P-V Table 1 steps 1-3)
        cloud = indexed_cloud(req.cloud, req.name, req.link or "world")
        cloud_file = self.store.write_cloud(cloud.points) if self.store is not None else None
        try:
            with self.lock:
                if req.name in self._meta:
                    raise wire_error(
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
                        stamp=req.cloud_stamp,
                    )
                except InputError as exc:
                    raise wire_error(P.ErrorCode.INVALID, "body.pose", exc.reason) from None
                if req.dynamic:
                    self._runtime[req.name] = (check_pose(req.pose, "body.pose"), self.clock())
                self._adopt({req.name: cloud_file})
                if req.stamp != math.inf:  # the saved cloud ages from its stamp (None: unknown)
                    self._meta[req.name] = replace(self._meta[req.name], stamp=req.cloud_stamp)
                manifest = self._manifest()
        except BaseException:
            self._drop_file(cloud_file)
            raise
        self._persist(manifest)
        return P.ObjectReply(req.name, len(cloud))

    def close(self) -> None:
        """Stop the scene's cloud-indexing worker."""
        self.scene.close()


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
