"""The collision server's scene and the records it keeps beside it.

:class:`ServiceCore` holds the distance scene (:class:`reachwise.distance.Scene`), the
robots and their YAML models, the latest joint states and run-time poses with their
time stamps, what the server keeps beside each object (:class:`ObjectMeta`), the
handed-over clouds not saved yet (:class:`CloudWait`) and the layout of the answers.
It looks robots and objects up (an unknown one is told as the scene tells it, with
the closest name) and applies checked inputs. The request handlers of
:class:`reachwise.server.service.SceneService` are built on it: the answers
(:mod:`reachwise.server.answering`), streamed clouds (:mod:`reachwise.server.handover`)
and the state directory (:mod:`reachwise.server.persistence`).
"""

from __future__ import annotations

import logging
import math
import secrets
import threading
import time
import uuid
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

import reachwise.server.protocol as P
from reachwise.distance._common import check_pose
from reachwise.distance.engine import STRATEGIES, StrategyName
from reachwise.distance.index import cloud_index
from reachwise.distance.ingest import CloudIngest
from reachwise.distance.scene import OnLink, PoseSource, Runtime, Scene
from reachwise.errors import InputError, NameTaken, UnknownName, check_choice
from reachwise.geometry.cloud import PointCloud
from reachwise.io.robot_file import robot_to_dict
from reachwise.kinematics.robot import Robot
from reachwise.server.counters import Metrics, SequenceCounter
from reachwise.server.state import (
    StateStore,
)

log = logging.getLogger("reachwise.server")


#: Where an object's pose comes from: kind, pose, robot and link.
ObjectSource = tuple[
    Literal["fixed", "link", "runtime"], NDArray[np.float64], str | None, str | None
]


def wire_error(code: P.ErrorCode, field: str, message: str) -> P.ProtocolError:
    return P.ProtocolError(code, field, message)


def protocol_error_of(exc: Exception, op: str) -> P.ProtocolError:
    """What a request's failure is on the wire: a :class:`ProtocolError` as it is,
    a scene input error ``invalid``, anything unexpected ``internal`` (logged)."""
    if isinstance(exc, P.ProtocolError):
        return exc
    if isinstance(exc, UnknownName):
        return wire_error(P.ErrorCode.UNKNOWN_ID, exc.field or exc.source, str(exc))
    if isinstance(exc, NameTaken):
        return wire_error(P.ErrorCode.EXISTS, exc.field or exc.source, exc.reason)
    if isinstance(exc, InputError):
        return wire_error(P.ErrorCode.INVALID, exc.field or exc.source, str(exc))
    log.error("request %s failed: %s", op, P.failure_text(exc), exc_info=exc)
    return wire_error(P.ErrorCode.INTERNAL, "", P.failure_text(exc))


def unknown_error(kind: str, name: str, valid: Iterable[str], where: str) -> P.ProtocolError:
    """An unknown robot or object, told as the scene tells it (with the closest name)."""
    return wire_error(
        P.ErrorCode.UNKNOWN_ID, where, UnknownName("server", kind, name, valid).reason
    )


@dataclass(frozen=True)
class ObjectMeta:
    """What the server keeps beside the scene's object: its saved cloud (file, point
    count, version and stamp; None: does not age, NaN: unknown) and whose time stamp
    its pose carries (``("robot", name)``, ``("object", name)`` or None)."""

    cloud_file: str | None
    stamp_of: tuple[str, str] | None
    points: int = 0
    version: int = 0
    stamp: float | None = None


@dataclass(frozen=True, eq=False)
class CloudWait:
    """A handed-over cloud: object ``name``, its ``version`` on the wire and in the
    scene, the scene's ``ingest`` worker that indexes it and the scene's
    ``generation`` then (a ``clear`` makes a new one), its ``points`` and ``stamp``;
    ``deadline`` (monotonic s) for a ``block`` reply."""

    name: str
    version: int
    scene_version: int
    ingest: CloudIngest
    generation: int
    points: NDArray[Any]
    stamp: float
    deadline: float = math.inf


class ServiceCore:
    """The scene behind the wire and the server's records beside it (see the module
    docstring): ``store`` (optional) is the state directory, which
    :meth:`~reachwise.server.persistence.ScenePersistence.load` restores (the server is
    not ready before); ``clock`` stamps inputs that carry no time stamp."""

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
        self._meta: dict[str, ObjectMeta] = {}
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

    @property
    def ready(self) -> bool:
        return self.state == "ready"

    # ------------------------------------------------------------------ lookups
    def _robot(self, name: str, where: str) -> Robot:
        r = self._robots.get(name)
        if r is None:
            raise unknown_error("robot", name, self._robots, where)
        return r

    def _object(self, name: str, where: str) -> None:
        if name not in self._meta:
            raise unknown_error("object", name, self._meta, where)

    def _adopt(self, saved: dict[str, str | None] | None = None) -> list[str]:
        """Take over what a change did to the scene (call under the lock): its robots
        (and their YAML models), its objects — the saved cloud file of each new one
        from ``saved`` (an object without one, such as a scene memory's, is left out of
        the state directory), whose time stamp its pose carries from its pose source —
        and a new layout. What the scene no longer holds is forgotten; the saved cloud
        files of its objects are returned, to be deleted once the new manifest is
        saved."""
        robots = self.scene.robots
        self._robots = {k: r for k, r in robots.items() if isinstance(r, Robot)}
        self._models = {k: self._models.get(k) or robot_to_dict(r) for k, r in self._robots.items()}
        for name in self._robots.keys() - self._joints.keys():  # added with its joints
            q = self.scene.joint_state(name)
            if q is not None:
                stamp = self.scene.joint_stamp(name)
                self._joints[name] = (q, self.clock() if math.isnan(stamp) else stamp)
                self._live_dirty = True
        objects = self.scene.objects
        meta = {}
        for name, obj in objects.items():
            old = self._meta.get(name)
            if old is None:
                points = len(obj.cloud)
                cloud_file = (saved or {}).get(name)
                old = ObjectMeta(cloud_file, stamp_source(name, obj.source), points)
            meta[name] = old
        dropped = [m.cloud_file for k, m in self._meta.items() if k not in meta and m.cloud_file]
        self._meta = meta
        for kept in (self._joints, self._runtime, self._unsaved, self._version_base):
            for name in [k for k in kept if k not in robots and k not in objects]:
                del kept[name]
                self._live_dirty |= kept is self._joints or kept is self._runtime
        self._pairs_changed()
        return dropped

    def _check_q(self, robot: Robot, q: NDArray[np.float64], where: str) -> None:
        if q.shape != (robot.n,):
            raise wire_error(
                P.ErrorCode.WRONG_SHAPE,
                where,
                f"robot {robot.name!r} has {robot.n} joint variables; got shape {q.shape}",
            )

    def _check_runtime(self, name: str, where: str) -> None:
        self._object(name, where)
        meta = self._meta[name]
        if meta.stamp_of != ("object", name):
            raise wire_error(
                P.ErrorCode.INVALID, where, f"object {name!r}: its pose is not set at run time"
            )

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
            raise wire_error(P.ErrorCode.INVALID, pose_at, exc.reason) from None

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

    def _pairs_changed(self) -> None:
        """A pair, margin, the order, an object or a robot changed: the next reply sends
        a new layout."""
        self._layout_count += 1
        self._layout = None
        self._clouds = None


def stamp_source(name: str, source: PoseSource) -> tuple[str, str] | None:
    """Whose time stamp the pose of object ``name`` carries: its robot's joint state
    (on a link), its own (set at run time) or none (fixed)."""
    if isinstance(source, OnLink):
        return ("robot", source.robot)
    if isinstance(source, Runtime):
        return ("object", name)
    return None


def indexed_cloud(points: NDArray[np.float64], name: str, frame: str) -> PointCloud:
    """A validated cloud with its k-d tree built (P-V Table 1 initialization)."""
    cloud = PointCloud(points, frame=frame, name=name)
    cloud_index(cloud)
    return cloud
