"""A simulation run written as a recording (ROS 2, or ROS 1 for a ``.bag`` path), to
replay and share like a real cell.

:class:`BagRecorder` is handed to :func:`reachwise.sim.simulate.simulate`
(``recorder=``); the run calls :meth:`BagRecorder.start` with the built world,
:meth:`BagRecorder.tick` once per tick after the distance query, and
:meth:`BagRecorder.close` at the end. It writes, with receive times in simulated time:

- every tick, each robot's ``sensor_msgs/JointState`` on ``/joint_states`` (one robot)
  or ``/<robot>/joint_states``, its joints named as
  :func:`~reachwise.io.ros.joint_state.robot_joint_names` names them;
- each depth camera frame when it reaches the scene (its capture plus the latency; the
  header stamp is the capture time), in the camera's optical frame ``<camera>_optical``:
  the depth image (``/<camera>/depth/image_rect_raw``, ``32FC1``, NaN where no return)
  with its ``/<camera>/depth/camera_info``, and the cloud the scene was handed
  (``/<camera>/points``: world frame, float64, after the sensor's voxel filter — the
  scene's input exactly);
- ``/tf_static`` ``world`` → ``<camera>_optical`` for a fixed camera, ``/tf`` at each
  capture for one on a robot link.

:func:`scenario_robot` gives a replay the scenario's robot and the clouds its links
carry, so that ``reachwise replay --scenario`` answers as the run did.

The frames are rendered again from the state at their capture (a sensor renders the
same frame every time it is asked: :meth:`~reachwise.sim.sensors.DepthSensor.render`),
so the recorder changes nothing in the run.
"""

from __future__ import annotations

from collections import deque
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from reachwise.errors import UnknownName
from reachwise.io.ros.bag_writer import BagWriter
from reachwise.io.ros.joint_state import robot_joint_names

if TYPE_CHECKING:
    from reachwise.geometry.cloud import PointCloud
    from reachwise.geometry.depth_camera import DepthFrame
    from reachwise.kinematics.robot import Robot
    from reachwise.sim.sensors import DepthSensor
    from reachwise.sim.world import World

__all__ = ["BagRecorder", "scenario_robot"]

#: The fixed frame of a recorded run.
WORLD = "world"


class BagRecorder:
    """Writes a run to the bag ``path`` (``.bag``: ROS 1, ``.mcap``: MCAP, else ROS 2
    sqlite3); see the module docstring."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._writer: BagWriter | None = None
        self._names: dict[str, tuple[str, ...]] = {}
        self._topics: dict[str, str] = {}
        self._next: dict[str, int] = {}
        self._pending: dict[str, deque[tuple[int, int, DepthFrame]]] = {}

    def start(self, world: World) -> None:
        """Open the bag for a run of ``world``."""
        self._writer = BagWriter(self.path)
        one = len(world.agents) == 1
        for a in world.agents:
            self._names[a.name] = robot_joint_names(a.robot)
            self._topics[a.name] = "/joint_states" if one else f"/{a.name}/joint_states"
        f = self._writer.factory
        for s in world.sensors:
            self._next[s.name] = 0
            self._pending[s.name] = deque()
            if s.mount is None:
                tf = f.tf([f.transform(0.0, WORLD, _optical(s), s.offset)])
                self._writer.write("/tf_static", "tf2_msgs/msg/TFMessage", tf, 0.0)

    def tick(self, k: int, t: float, world: World) -> None:
        """Tick ``k`` (time ``t``), after its distance query: the frames captured and
        delivered by now, then the joint states."""
        w = self._writer
        if w is None:
            raise RuntimeError("BagRecorder.tick before start")
        qs = {a.name: a.plant.q for a in world.agents}
        for s in world.sensors:
            self._capture(s, k, world, qs)
            pending = self._pending[s.name]
            while pending and pending[0][0] <= k:
                _, frame_k, frame = pending.popleft()
                self._deliver(s, frame_k, frame, t)
        f = w.factory
        for a in world.agents:
            msg = f.joint_state(t, self._names[a.name], a.plant.q)
            w.write(self._topics[a.name], "sensor_msgs/msg/JointState", msg, t)

    def _capture(self, s: DepthSensor, k: int, world: World, qs: dict[str, np.ndarray]) -> None:
        """Render the frames of ``s`` captured by tick ``k`` (the robots at ``qs``)."""
        if world.sight is None:
            return
        while s.capture_tick(self._next[s.name]) <= k:
            n = self._next[s.name]
            self._next[s.name] += 1
            frame = s.render(n, world.sight, qs)
            self._pending[s.name].append((s.delivery_tick(n), n, frame))
            if s.mount is not None and self._writer is not None:
                f = self._writer.factory
                tc = s.capture_tick(n) * s.dt
                tf = f.tf([f.transform(tc, WORLD, _optical(s), frame.pose)])
                self._writer.write("/tf", "tf2_msgs/msg/TFMessage", tf, tc)

    def _deliver(self, s: DepthSensor, n: int, frame: DepthFrame, t: float) -> None:
        """Frame ``n`` of ``s`` reaches the scene at ``t``: image, CameraInfo, cloud."""
        w = self._writer
        assert w is not None
        f = w.factory
        tc = s.capture_tick(n) * s.dt
        optical = _optical(s)
        base = f"/{s.name}"
        w.write(
            f"{base}/depth/camera_info",
            "sensor_msgs/msg/CameraInfo",
            f.camera_info(tc, optical, s.camera.intrinsics),
            t,
        )
        w.write(
            f"{base}/depth/image_rect_raw",
            "sensor_msgs/msg/Image",
            f.depth_image(tc, optical, frame.depth),
            t,
        )
        cloud = s.cloud(frame)
        w.write(
            f"{base}/points",
            "sensor_msgs/msg/PointCloud2",
            f.point_cloud(tc, WORLD, cloud.points),
            t,
        )

    def close(self) -> None:
        """Finish the bag."""
        if self._writer is not None:
            self._writer.close()
            self._writer = None


def _optical(s: DepthSensor) -> str:
    return f"{s.name}_optical"


def scenario_robot(
    scenario: str | Path, robot: str | None = None
) -> tuple[Robot, dict[str, PointCloud]]:
    """A scenario's robot (``robot``: its name in the scenario; default the first) as
    its runs record it, and the clouds its links carry in the run (link → cloud in the
    link frame): what a replay of a recorded run needs to answer as the run did."""
    from reachwise.distance.scene import OnLink
    from reachwise.sim.world import build_world, close_scene

    world = build_world(scenario)
    try:
        names = [a.name for a in world.agents]
        name = names[0] if robot is None else robot
        if name not in names:
            raise UnknownName(str(scenario), "robot", name, names)
        model = next(a.robot for a in world.agents if a.name == name)
        clouds = {
            o.source.link: o.cloud
            for o in world.scene.objects.values()
            if isinstance(o.source, OnLink) and o.source.robot == name
        }
    finally:
        close_scene(world.scene)
    return model, clouds
