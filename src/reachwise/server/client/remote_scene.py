"""The remote scene: :class:`SceneClient`, a scene on a collision server with the
in-process scene's interface.

The control system of the thesis asks the collision server for the shortest distances
every control cycle (P-III §4.1 Fig. 2, P-IV, P-V §II). :class:`SceneClient` has the
methods and result types of :class:`reachwise.distance.Scene` — ``add_robot``,
``set_joints``, ``add_object``, ``set_pose``, ``replace_cloud``, ``watch*``,
``unwatch``, ``robot_objects``, ``poses``, ``query_all`` — and satisfies
:class:`~reachwise.distance.scene.SceneLike`, so a controller written against it runs
unchanged against either.

What the network adds, and how the client reports it:

- **Deadlines.** Every call has one (``deadline`` for the per-tick calls
  ``set_joints``, ``set_pose``, ``query_all``; ``setup_deadline`` for the rest; or
  ``deadline=`` on the call). A missed deadline drops the socket
  (:class:`~reachwise.server.client.channel.Channel`, the *Lazy Pirate*).
- **Missing data is a result, not an exception.** When ``query_all`` gets no answer in
  time (or the server is still restoring its state), it returns a
  :class:`~reachwise.server.client.results.ServerSceneResult` with ``valid=False``, the
  ``reason``, the last sequence number, and every pair's distance NaN — missing data,
  on which the controller's safety layer makes a protective stop (thesis §3.3;
  controller issue). A joint state or pose that could not be delivered makes the next
  result invalid too, since the server answered with older inputs. Setup calls
  (registering robots and clouds, pair rules) raise :class:`ServerUnavailable`
  instead: nothing sensible follows them.
- **Time stamps** (seconds, this client's ``clock``, :func:`time.monotonic` by
  default): ``set_joints``/``set_pose``/``replace_cloud`` stamp their measurement
  (``stamp=``, default now); a result carries ``measured_at`` (the oldest input it
  depends on), ``computed_at`` (when its reply arrived, an upper bound of the end of
  the computation), ``compute_time`` (the server's computation, s) and, per object,
  the ``versions`` of the clouds it used and their ``cloud_stamps``. The server passes
  every stamp back as the sending client gave it, so clients whose stamps meet in one
  answer (a camera process and a control process) share one clock: the default
  :func:`time.monotonic` does on one host (see :mod:`reachwise.server.protocol`).
- **Streamed clouds.** :meth:`SceneClient.replace_cloud` sends the points as a raw
  frame straight from the caller's contiguous float32 or float64 array (no copy) and
  returns the version the server gave the cloud; the server indexes it off its request
  thread. ``block=True`` returns once that version is indexed (every later answer uses
  it).
- **The per-tick query** goes out as one binary frame once the client holds the
  scene's layout (from its first full reply), and its answer is one float64 array
  whose :class:`~reachwise.server.client.results.ServerSceneResult` builds its pair
  results the first time they are read.
- **Errors** the server reports for bad input raise :class:`ServerInputError`, an
  :class:`~reachwise.errors.InputError` (as the in-process scene raises), carrying the
  typed ``code`` and the ``field``.

``batch_inputs=True`` holds joint states and poses until the next ``query_all`` and
sends them with it, atomically: one round trip per control tick.

``mirror=True`` is for a client that *owns* the server's scene, as a simulator does
(:func:`~reachwise.server.client.owned.owned_scene`): it keeps a local copy of
everything it registers and sends, so ``objects``, ``robots``, ``pairs``,
``robot_objects`` and ``poses()`` are answered without a round trip (and without
waiting on a server that may be gone); the distance queries still go to the server,
and a reply whose pair list differs from the local copy is reported as invalid. The
registered scene operations that change the scene, and the staged ones that hand a
result over into it (a depth frame fused into a scene memory), run on the local copy
too, after the server's reply: they are deterministic, so the copy's clouds are the
server's (a mirroring client pays for fusing each frame locally as well).

A client belongs to one thread (one REQ socket); give each thread its own.
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

import reachwise.server.protocol as P
from reachwise.distance._common import as_cloud, check_added_stamp, check_pose
from reachwise.distance.engine import STRATEGIES, StrategyName
from reachwise.distance.scene import (
    Fixed,
    OnLink,
    Runtime,
    Scene,
    SceneLike,
    SceneObject,
    WatchedPair,
)
from reachwise.distance.scene_queries import describe, object_poses
from reachwise.errors import CloudError, InputError, check_choice
from reachwise.geometry.cloud import PointCloud
from reachwise.kinematics.robot import Robot
from reachwise.server.client.client_base import SETUP_DEADLINE, TICK_DEADLINE
from reachwise.server.client.errors import ServerError, ServerUnavailable
from reachwise.server.client.remote_query import RemoteQueries
from reachwise.server.client.results import scene_object

__all__ = ["SETUP_DEADLINE", "TICK_DEADLINE", "SceneClient"]


def _vector(q: ArrayLike, robot: str) -> NDArray[np.float64]:
    try:
        arr = np.array(q, dtype=np.float64, copy=True).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise InputError(f"robot {robot!r}", "q", f"not numeric: {exc}") from None
    if not np.isfinite(arr).all():
        raise InputError(f"robot {robot!r}", "q", "contains NaN or inf")
    return arr


def _cloud_array(cloud: ArrayLike, name: str) -> NDArray[np.floating[Any]]:
    """``cloud`` as an (N, 3) array to send: the caller's own array when it is a
    C-contiguous float32/float64 one (no copy), else a float64 copy."""
    arr = cloud if isinstance(cloud, np.ndarray) else np.asarray(cloud)
    if arr.dtype not in (np.float32, np.float64) or not arr.flags.c_contiguous:
        try:
            arr = np.ascontiguousarray(arr, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise CloudError(f"cloud {name!r}", "points", f"not numeric: {exc}") from None
    if arr.ndim != 2 or arr.shape[1] != 3 or arr.shape[0] == 0:
        raise CloudError(f"cloud {name!r}", "points", f"expected shape (N, 3), got {arr.shape}")
    return arr


class SceneClient(RemoteQueries):
    """A scene on a collision server at ``address`` (see the module docstring).

    ``keys``: a ``reachwise serve keygen`` folder (or :class:`ClientKeys`) for a CURVE
    server. ``clock`` stamps measurements and results (s). ``name`` is sent in hello.
    ``batch_inputs`` and ``mirror``: see the module docstring.
    """

    def run_operation(
        self, name: str, arguments: dict[str, Any], deadline: float | None = None
    ) -> Any:
        """Run the registered scene operation ``name``
        (:func:`reachwise.distance.scene_ops.scene_operation`) with ``arguments`` (by
        name) on the server's scene and return its result, checked against the
        operation's result type. Joint states and poses not sent yet go first. Raises
        as :meth:`call`; calling the operation with this client does this."""
        op = P.operation(name, "operation")
        if self._pending_joints or self._pending_poses:
            self.flush(deadline)
        rep = self._setup(P.OperationCall(name, arguments), P.OperationResult, deadline)
        try:
            result = P.decode_value(rep.result, op.result, "body.result")
        except P.ProtocolError as exc:
            raise ServerError(f"invalid reply to {name}: {exc}", exc.code, exc.field) from None
        if self._mirror is not None and (op.mutates or op.hand_over is not None):
            # the same change on the local copy; a staged operation hands its result
            # over into the scene (a fused frame's cloud), so it is applied too
            prepared = op.function(self._mirror, **arguments)
            if op.hand_over is not None:
                op.hand_over(self._mirror, prepared)
        return result

    # ------------------------------------------------------------------ service calls
    def hello(self, deadline: float | None = None) -> P.HelloReply:
        """Server name, version, protocol and instance (raises if versions differ)."""
        return self._setup(P.Hello(self.name), P.HelloReply, deadline)

    def health(self, deadline: float | None = None) -> P.HealthReply:
        """Readiness, state and a sequence number that only grows."""
        return self._setup(P.Health(), P.HealthReply, deadline)

    def metrics(self, deadline: float | None = None) -> P.MetricsReply:
        """Request and error counts and the query latency histograms."""
        return self._setup(P.Metrics(), P.MetricsReply, deadline)

    def wait_ready(self, timeout: float = 30.0, poll: float = 0.5) -> P.HealthReply:
        """Ask for health until the server is ready (retrying on a fresh socket after
        each lost reply); raises :class:`ServerUnavailable` after ``timeout`` s, or
        :class:`ServerError` if the server failed to restore its state."""
        end = time.monotonic() + timeout
        last = "no reply"
        while True:
            left = end - time.monotonic()
            if left <= 0:
                raise ServerUnavailable(f"{self.address} not ready within {timeout:g} s ({last})")
            try:
                h = self.health(deadline=min(poll, left))
            except ServerUnavailable as exc:
                last = str(exc)
                continue
            if h.ready:
                return h
            if h.state == "failed":
                raise ServerError(f"{self.address} failed: {h.reason}", P.ErrorCode.NOT_READY)
            last = f"state {h.state}"
            time.sleep(min(0.05, max(0.0, end - time.monotonic())))

    # ------------------------------------------------------------------ scene interface
    @property
    def strategy(self) -> StrategyName:
        """The server scene's distance strategy."""
        return check_choice(
            describe(self).strategy, STRATEGIES, source=self.address, kind="strategy"
        )

    @property
    def sequence(self) -> int:
        """The server's last sequence number."""
        return self.metrics().sequence

    @property
    def robots(self) -> dict[str, Robot]:
        """Registered robots, rebuilt from the YAML mappings the server sends (with
        ``mirror``: the local copy's)."""
        if self._mirror is not None:
            return {k: r for k, r in self._mirror.robots.items() if isinstance(r, Robot)}
        return describe(self).robots

    @property
    def objects(self) -> dict[str, SceneObject]:
        """Every object with its cloud and pose source (downloads the clouds; with
        ``mirror``: the local copy)."""
        if self._mirror is not None:
            self._mirror.swap_in()
            return self._mirror.objects
        return {o.name: scene_object(o) for o in describe(self, clouds=True).objects}

    @property
    def pairs(self) -> tuple[WatchedPair, ...]:
        """Watched pairs in query order (with ``mirror``: the local copy)."""
        if self._mirror is not None:
            return self._mirror.pairs
        return describe(self).pairs

    def set_joints(
        self,
        robot: str,
        q: ArrayLike,
        *,
        stamp: float | None = None,
        deadline: float | None = None,
    ) -> None:
        """The joint state of ``robot`` measured at ``stamp`` (default now). A missed
        deadline does not raise: the next :meth:`query_all` result is invalid."""
        arr = _vector(q, robot)
        t = self.clock() if stamp is None else float(stamp)
        if self._mirror is not None:
            self._mirror.set_joints(robot, arr, stamp=t)
        if self.batch_inputs:
            self._pending_joints[robot] = (arr, t)
            return
        self._tick_call(P.SetJoints(robot, arr, t), f"joint state of {robot!r}", deadline)

    def set_pose(
        self,
        name: str,
        pose: ArrayLike,
        *,
        stamp: float | None = None,
        deadline: float | None = None,
    ) -> None:
        """The world pose of run-time object ``name`` measured at ``stamp``."""
        P_ = check_pose(pose, f"pose of {name!r}")
        t = self.clock() if stamp is None else float(stamp)
        if self._mirror is not None:
            self._mirror.set_pose(name, P_, stamp=t)
        if self.batch_inputs:
            self._pending_poses[name] = (P_, t)
            return
        self._tick_call(P.SetPose(name, P_, t), f"pose of {name!r}", deadline)

    def _tick_call(self, request: P.Request, what: str, deadline: float | None) -> None:
        try:
            self.call(request, self.deadline if deadline is None else deadline)
        except ServerUnavailable as exc:
            self._lost = f"{what} not delivered: {exc}"
        except ServerError as exc:
            if exc.code != P.ErrorCode.NOT_READY:
                raise
            self._lost = f"{what} not delivered: {exc}"

    def flush(self, deadline: float | None = None) -> None:
        """Send the joint states and poses held back by ``batch_inputs`` now."""
        joints, poses = self._pending_joints, self._pending_poses
        self._pending_joints, self._pending_poses = {}, {}
        for robot, (q, t) in joints.items():
            self._tick_call(P.SetJoints(robot, q, t), f"joint state of {robot!r}", deadline)
        for name, (pose, t) in poses.items():
            self._tick_call(P.SetPose(name, pose, t), f"pose of {name!r}", deadline)

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
        deadline: float | None = None,
    ) -> SceneObject:
        """Add a cloud (see :meth:`reachwise.distance.Scene.add_object`) measured at
        ``stamp`` (s, this client's clock, as :meth:`replace_cloud`'s; +inf, the
        default: it does not age; NaN: unknown, stale under ``max_cloud_age``); the
        server builds its index before it replies."""
        if not isinstance(name, str) or not name:
            raise InputError("scene", "object name", "must be a non-empty string")
        added = check_added_stamp(stamp, name)
        c = as_cloud(cloud, name)
        pose_arr = check_pose(pose, f"pose of {name!r}").copy()
        request = P.AddObject(name, c.points, pose_arr, robot, link, dynamic, added)
        self._setup(request, P.ObjectReply, deadline)
        if self._mirror is not None:
            return self._mirror.add_object(
                name, c, pose_arr, robot=robot, link=link, dynamic=dynamic, stamp=added
            )
        source: Fixed | OnLink | Runtime
        if robot is not None and link is not None:
            source = OnLink(robot, link, pose_arr)
        elif dynamic:
            source = Runtime()
        else:
            source = Fixed(pose_arr)
        return SceneObject(name, c, source)

    def replace_cloud(
        self,
        name: str,
        cloud: PointCloud | ArrayLike,
        *,
        block: bool = False,
        stamp: float | None = None,
        deadline: float | None = None,
    ) -> int:
        """Hand over a new cloud for object ``name`` (a new scan, a camera frame)
        measured at ``stamp`` (s, this client's clock; default now); returns the version
        the server gave it (1, 2, … per object; the cloud it was added with is 0).

        The points travel as a raw frame: a C-contiguous float32 or float64 (N, 3)
        array (or a :class:`PointCloud`) is sent from its own memory, without a copy
        (do not write into it until the call returns); anything else is converted to
        float64 first. The server replies at once and indexes the cloud off its request
        thread; until it is swapped in, answers use the previous cloud and say so
        (:attr:`SceneResult.versions`). ``block=True`` returns once this version (or a
        newer one) is indexed, so that every later answer uses it; bad points then
        raise :class:`ServerInputError` (without ``block`` such a cloud is never swapped
        in, as in process)."""
        if not isinstance(name, str) or not name:
            raise InputError("scene", "object name", "must be a non-empty string")
        points = cloud.points if isinstance(cloud, PointCloud) else _cloud_array(cloud, name)
        t = self.clock() if stamp is None else float(stamp)
        rep = self._setup(P.ReplaceCloud(name, points, t, block), P.ObjectReply, deadline)
        if self._mirror is not None:  # a copy (the caller may reuse its array), indexed
            # on the mirror's worker, not here: the local copy only serves ``objects``
            copy = np.array(points, dtype=np.float64)
            self._mirror.replace_cloud(name, copy, block=False, stamp=t)
        return rep.version

    # describe, clear and the pair rules are the scene's own operations, carried over
    # the wire
    describe = describe
    clear = Scene.clear
    add_robot = Scene.add_robot
    watch = Scene.watch
    unwatch = Scene.unwatch
    watch_self = Scene.watch_self
    watch_environment = Scene.watch_environment
    watch_robots = Scene.watch_robots

    def robot_objects(self, robot: str) -> tuple[SceneObject, ...]:
        """Objects attached to ``robot``'s links, base to tool."""
        if self._mirror is not None:
            self._mirror.swap_in()
            return self._mirror.robot_objects(robot)
        d = describe(self, clouds=True)
        model = d.robots.get(robot)
        if model is None:
            raise InputError(
                "scene", f"robot {robot!r}", f"not registered; robots: {list(d.robots)}"
            )
        order = {n: i for i, n in enumerate(model.link_names)}
        mine = [o for o in d.objects if o.source == "link" and o.robot == robot]
        return tuple(scene_object(o) for o in sorted(mine, key=lambda o: order[str(o.link)]))

    def poses(self) -> dict[str, NDArray[np.float64]]:
        """Current world pose of every object (with ``mirror``: computed locally from
        what this client sent)."""
        if self._mirror is not None:
            return self._mirror.poses()
        return object_poses(self)


if TYPE_CHECKING:

    def _conforms(a: Scene, b: SceneClient) -> tuple[SceneLike, SceneLike]:
        return a, b  # mypy checks that both satisfy SceneLike
