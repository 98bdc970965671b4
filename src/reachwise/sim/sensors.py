"""Depth cameras in a simulation: frames rendered at their rate in simulated time and
streamed into the distance scene.

A scenario's ``sensors:`` (:class:`~reachwise.sim.scenarios.SensorSpec`) become
:class:`DepthSensor` objects, each feeding one scene object (the sensor's ``name``): a
cloud in world coordinates that the controllers avoid like any other.

- **Schedule.** Frame ``k`` (``k = 0, 1, …``) is captured at the first tick at or
  after ``k / rate`` and handed to the scene at the first tick at or after its capture
  time plus ``latency``: ``replace_cloud(name, cloud, block=True, stamp=capture time)``
  before that tick's distance query. The controllers use it from then on, its age is
  known from its stamp, and every run of a scenario sees the same frames at the same
  ticks (reproducible). Frame 0 is in the scene when the run starts (the camera was
  running before; taken at t = 0).
- **What it sees** (:class:`Sight`): every object with a surface (``mesh`` or
  ``box``, in the scene or not — ``scene: false``), moving ones at their pose at the
  capture time and with the shape scheduled by then; clouds from files and scans have
  no surface and are not seen. With ``self_filter`` the robots' links (their collision
  meshes at the joint state of the capture tick) are rendered too and the pixels that
  see them first return nothing — the robot-body filter of real pipelines: a robot
  neither avoids itself nor sees through itself. Every robot of the scenario is
  filtered (their poses are known from their joints; robot–robot pairs are watched on
  their own link clouds).
- **Randomness.** Frame ``k``'s noise and dropout come from
  ``numpy.random.default_rng([seed, k])``, so any frame can be rendered again from the
  state at its capture (:meth:`DepthSensor.render`; the viewer does, in playback).
- A frame without any return hands over a single point at the far limit on the
  optical axis (a cloud has at least one point; it says "nothing nearer").

The controllers' margins must cover what the camera adds to the obstacle's travel and
to the distance's uncertainty: a frame is up to ``1/rate + latency`` old when it is
replaced (:meth:`DepthSensor.max_age`), a surface facing the camera at depth ``z`` is
sampled every :meth:`~reachwise.geometry.depth_camera.DepthCamera.pixel_spacing` and
its depth noise is ``noise · z²`` (see
:func:`reachwise.control.safety.protective_separation`).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from reachwise.geometry.cloud import PointCloud, voxel_downsample
from reachwise.geometry.depth_camera import DepthCamera, DepthFrame, Intrinsics

if TYPE_CHECKING:
    from reachwise.distance.scene import SceneLike
    from reachwise.kinematics.robot import Robot
    from reachwise.sim.contact import Solid
    from reachwise.sim.memory_feed import MemoryFeed
    from reachwise.sim.motion import Trajectory
    from reachwise.sim.scenarios import SensorSpec

__all__ = ["BodySurface", "DepthSensor", "ObjectSurface", "Sight"]

F64 = NDArray[np.float64]
Mesh = tuple[F64, NDArray[np.int64]]


def _placed(mesh: Mesh, T: F64) -> Mesh:
    v, f = mesh
    return np.ascontiguousarray(v @ T[:3, :3].T + T[:3, 3]), f


@dataclass(frozen=True, eq=False)
class ObjectSurface:
    """The surface of an object: its ``shapes`` ``(t_from, (vertices, faces))`` in the
    object frame (the last one whose ``t_from`` has come is in use), at ``pose`` or
    moving along ``trajectory``; ``solid`` for the containment test."""

    name: str
    shapes: tuple[tuple[float, Mesh, Solid], ...]
    pose: F64 = field(default_factory=lambda: np.eye(4))
    trajectory: Trajectory | None = None

    def pose_at(self, t: float) -> F64:
        """The object's world pose at ``t`` (s)."""
        return self.pose if self.trajectory is None else self.trajectory.pose(t)

    def shape_at(self, t: float) -> tuple[Mesh, Solid]:
        """The mesh (object frame) and solid in use at ``t`` (s)."""
        mesh, solid = self.shapes[0][1], self.shapes[0][2]
        for t_from, m, s in self.shapes[1:]:
            if t_from <= t + 1e-9:
                mesh, solid = m, s
        return mesh, solid

    def mesh_at(self, t: float) -> Mesh:
        """The world mesh at ``t`` (s)."""
        return _placed(self.shape_at(t)[0], self.pose_at(t))


@dataclass(frozen=True, eq=False)
class BodySurface:
    """A robot link's collision surface: ``mesh`` in the frame of ``link`` (frame index
    ``index`` of ``robot.link_names``) of scenario robot ``robot``, and its solid."""

    name: str
    robot: str
    link: str
    index: int
    mesh: Mesh
    solid: Solid


@dataclass(frozen=True, eq=False)
class Sight:
    """Everything a camera can see: the objects' surfaces and the robots' links."""

    robots: dict[str, Robot]
    objects: dict[str, ObjectSurface]
    bodies: dict[str, BodySurface]

    def frames(self, qs: dict[str, F64]) -> dict[str, F64]:
        """Every robot's frame poses (``fk_all``) at joint states ``qs``."""
        return {r: np.asarray(self.robots[r].fk_all(q)) for r, q in qs.items()}

    def meshes(self, t: float, fk: dict[str, F64]) -> tuple[list[Mesh], list[Mesh]]:
        """World meshes at ``t``: the objects', and the robots' links (``fk``: each
        robot's frame poses)."""
        objs = [s.mesh_at(t) for s in self.objects.values()]
        body = [_placed(b.mesh, fk[b.robot][b.index]) for b in self.bodies.values()]
        return objs, body


class DepthSensor:
    """One depth camera of a run (see the module docstring): its model, mount,
    schedule and the frames on their way to the scene."""

    def __init__(self, spec: SensorSpec, dt: float, robots: dict[str, Robot]) -> None:
        self.spec = spec
        self.name = spec.name
        self.dt = dt
        intr = Intrinsics.from_fov(spec.width, spec.height, spec.fov_rad)
        self.camera = DepthCamera(intr, spec.near, spec.far, spec.noise, spec.dropout)
        self.mount: tuple[str, int] | None = None
        if spec.link is not None:
            robot = robots[spec.link.robot]
            self.mount = (spec.link.robot, robot.link_index(spec.link.link))
        self.offset = spec.matrix()  # world pose, or the pose in the mount's link frame
        #: The scene memory this camera feeds (None: its own object in the scene).
        self.feed: MemoryFeed | None = None
        self._pending: deque[tuple[int, int, float, DepthFrame]] = deque()
        self._next = 1  # the next frame to capture (frame 0 starts the run)
        self.in_use = 0  # the frame in the scene now

    # ------------------------------------------------------------------ schedule
    @property
    def period(self) -> float:
        return 1.0 / self.spec.rate

    def capture_tick(self, k: int) -> int:
        """The tick at which frame ``k`` is captured: the first at or after ``k/rate``."""
        return math.ceil(k * self.period / self.dt - 1e-9)

    def delivery_tick(self, k: int) -> int:
        """The tick at which frame ``k`` reaches the scene: the first at or after its
        capture plus the latency (frame 0: at once)."""
        if k == 0:
            return 0
        return math.ceil((self.capture_tick(k) * self.dt + self.spec.latency) / self.dt - 1e-9)

    def max_age(self) -> float:
        """The oldest a frame is (s) at the tick the next one replaces it: its capture
        to the next frame's delivery, about ``1/rate + latency`` rounded up to ticks
        (the largest over the first 1000 frames of the schedule)."""
        gaps = [self.delivery_tick(k + 1) - self.capture_tick(k) for k in range(1, 1000)]
        return max(gaps) * self.dt

    # ------------------------------------------------------------------ frames
    def pose(self, fk: dict[str, F64]) -> F64:
        """The camera's world pose (on its link: from the robots' frame poses ``fk``)."""
        if self.mount is None:
            return self.offset
        robot, index = self.mount
        return np.asarray(fk[robot][index] @ self.offset)

    def render(self, k: int, sight: Sight, qs: dict[str, F64]) -> DepthFrame:
        """Frame ``k`` of the world at its capture time, the robots at joint states
        ``qs`` (theirs at that tick): the same frame every time it is asked for."""
        t = self.capture_tick(k) * self.dt
        fk = sight.frames(qs)
        objs, body = sight.meshes(t, fk)
        rng = np.random.default_rng([self.spec.seed, k])
        pose = self.pose(fk)
        if not self.spec.self_filter:
            objs, body = objs + body, []
        if not objs and not body:
            z = self.camera.measure(np.full(self.camera.shape, np.nan), rng)
            return DepthFrame(z, np.zeros((0, 3)), pose, np.zeros(self.camera.shape, bool))
        return self.camera.frame(objs, pose, rng, body=body)

    def cloud(self, frame: DepthFrame) -> PointCloud:
        """The cloud handed to the scene: the frame's points (``voxel``-downsampled), or
        one point at the far limit on the optical axis when it returned none."""
        pts = frame.points
        if len(pts) == 0:
            far = frame.pose[:3, 3] + self.spec.far * frame.pose[:3, 2]
            pts = far[None]
        cloud = PointCloud(np.array(pts, dtype=np.float64), name=self.name)
        if self.spec.voxel is not None and len(pts) > 1:
            cloud = voxel_downsample(cloud, self.spec.voxel)
        return cloud

    def start(self, scene: SceneLike, sight: Sight, qs: dict[str, F64]) -> None:
        """Add the sensor's object to ``scene`` with frame 0 (the robots at ``qs``),
        stamped t = 0; a camera that feeds a memory fuses frame 0 into it instead."""
        frame = self.render(0, sight, qs)
        if self.feed is not None:
            self.feed.fuse(self.camera, frame, 0.0)
            return
        cloud = self.cloud(frame)
        scene.add_object(self.name, cloud)
        scene.replace_cloud(self.name, cloud, block=True, stamp=0.0)

    def _deliver(self, scene: SceneLike, frame: DepthFrame, stamp: float) -> None:
        if self.feed is not None:
            self.feed.fuse(self.camera, frame, stamp)
        else:
            scene.replace_cloud(self.name, self.cloud(frame), block=True, stamp=stamp)

    def step(self, scene: SceneLike, tick: int, sight: Sight, qs: dict[str, F64]) -> None:
        """Per tick, before the distance query: capture the frame due at ``tick`` (the
        robots at ``qs``) and hand over the frames whose latency has passed."""
        while self.capture_tick(self._next) <= tick:
            k = self._next
            self._next += 1
            frame = self.render(k, sight, qs)
            self._pending.append((self.delivery_tick(k), k, self.capture_tick(k) * self.dt, frame))
        while self._pending and self._pending[0][0] <= tick:
            _, k, stamp, frame = self._pending.popleft()
            self._deliver(scene, frame, stamp)
            self.in_use = k

    def frame_in_use(self, tick: int) -> int:
        """The frame in the scene at ``tick`` by the schedule (what :meth:`step` does):
        the last one delivered by then."""
        guess = max(0, math.floor((tick * self.dt - self.spec.latency) * self.spec.rate) + 2)
        while guess > 0 and self.delivery_tick(guess) > tick:
            guess -= 1
        return guess
