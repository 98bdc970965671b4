"""A small recorded cell for the replay tests: the built-in Panda (joint states at
100 Hz, its joints named, in a shuffled order with a finger joint), a point-cloud
camera and a depth camera (10 Hz), TF; written with our BagWriter."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

import reachwise
from reachwise.geometry.cloud import PointCloud
from reachwise.geometry.depth_camera import DepthCamera, Intrinsics
from reachwise.io.ros.bag_writer import BagWriter
from reachwise.kinematics.robot import Robot

JOINTS = [f"panda_joint{k}" for k in range(1, 8)]
INTR = Intrinsics(16, 12, 14.0, 14.0, 7.5, 5.5)
T_WORLD_CAM = np.eye(4)
T_WORLD_CAM[:3, 3] = [0.9, 0.1, 0.5]


def panda() -> Robot:
    return reachwise.load_robot("panda")


def link_clouds(robot: Robot) -> dict[str, PointCloud]:
    rng = np.random.default_rng(5)
    return {
        link: PointCloud(rng.normal(scale=0.05, size=(60, 3)))
        for link in ("link_3", "link_5", "link_7")
    }


def joint_path(t: float, n: int = 7) -> np.ndarray:
    q0 = np.array([-0.74, 0.1, 0.08, -2.03, -0.01, 2.13, -0.65])[:n]
    return q0 + 0.3 * np.sin(2.0 * t + np.arange(n))


def obstacle(k: int) -> np.ndarray:
    """Frame k's obstacle points in the camera frame ("cam"): a patch moving closer."""
    rng = np.random.default_rng(100 + k)
    pts = rng.uniform(-0.1, 0.1, (80, 3))
    pts[:, 0] -= 0.3 + 0.02 * k
    return pts


def cam_optical_pose(t: float) -> np.ndarray:
    """world -> cam_optical, moving in time (a dynamic TF edge cam -> cam_optical)."""
    T = np.eye(4)
    T[:3, :3] = (
        Rotation.from_rotvec([0.0, 0.0, 0.1 * t]).as_matrix()
        @ Rotation.from_euler("zyx", [0, np.pi / 2, -np.pi / 2]).as_matrix()
    )
    T[:3, 3] = [0.0, 0.05 * t, 0.0]
    return T


def depth_image(k: int) -> np.ndarray:
    z = np.full((INTR.height, INTR.width), 0.7 + 0.01 * k, np.float32)
    z[:2, :3] = np.nan
    return z


Hook = Callable[[str, Any, float], Any]


def write_cell(
    path: Path, hook: Hook | None = None, *, seconds: float = 1.0, joints: list[str] = JOINTS
) -> Path:
    """The recording; ``hook(topic, msg, t)`` may change (or replace) each message;
    ``joints``: the robot's joint names."""
    rng = np.random.default_rng(1)
    with BagWriter(path) as w:
        f = w.factory

        def put(topic: str, typ: str, msg: Any, t: float) -> None:
            if hook is not None:
                msg = hook(topic, msg, t)
            w.write(topic, typ, msg, t)

        put(
            "/tf_static",
            "tf2_msgs/msg/TFMessage",
            f.tf([f.transform(0.0, "world", "cam", T_WORLD_CAM)]),
            0.0,
        )
        for k in range(int(seconds * 10) + 2):  # the dynamic edge, covering the run
            t = 0.1 * k
            put(
                "/tf",
                "tf2_msgs/msg/TFMessage",
                f.tf([f.transform(t, "cam", "cam_optical", cam_optical_pose(t))]),
                t,
            )
        for i in range(int(seconds * 100) + 1):
            t = 0.01 * i
            if i % 10 == 5:
                k = i // 10
                put(
                    "/points",
                    "sensor_msgs/msg/PointCloud2",
                    f.point_cloud(t - 0.005, "cam", obstacle(k)),
                    t,
                )
                put(
                    "/depth/camera_info",
                    "sensor_msgs/msg/CameraInfo",
                    f.camera_info(t, "cam_optical", INTR),
                    t,
                )
                put(
                    "/depth/image",
                    "sensor_msgs/msg/Image",
                    f.depth_image(t, "cam_optical", depth_image(k)),
                    t,
                )
            order = rng.permutation(len(joints) + 1)
            names = np.array([*joints, "panda_finger_joint1"])[order]
            pos = np.array([*joint_path(t, len(joints)), 0.04])[order]
            put(
                "/joint_states", "sensor_msgs/msg/JointState", f.joint_state(t, list(names), pos), t
            )
    return path


def depth_world_points(k: int, t: float) -> np.ndarray:
    cam = DepthCamera(INTR, near=0.0, far=100.0)
    pts = cam.points(depth_image(k).astype(np.float64))
    T = T_WORLD_CAM @ cam_optical_pose(t)
    return pts @ T[:3, :3].T + T[:3, 3]
