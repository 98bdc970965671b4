"""``reachwise bench replay``: a recorded cell replayed through the distance scene.

A recording made here (MCAP, in a temporary folder; not timed): 3 s (``--quick``: 1 s)
of a Panda's joint states at 1 kHz and a depth camera at 30 frames/s, 640 × 480
``16UC1`` images (307 200 points each, every pixel valid: a tilted wall 1.2–1.6 m
away) with their CameraInfo, and a static TF from the camera to the world. Three
links carry 1000-point clouds. Then, on one core (the process is pinned to one CPU):

- ``replay.frame``: :func:`~reachwise.io.ros.replay.replay_recording` end to end,
  blocking hand-overs, a frame (query) per joint state; the time per camera frame
  (wall time / camera frames) over 3 replays (``--quick``: 1); and
  ``replay.frames_per_s``, camera frames replayed per second with their 1 kHz joint
  stream — target ≥ 30 (the camera's own rate: a replay keeps up with the recording);
- ``decode.ours`` vs ``decode.loop``: one 307 200-pixel depth image to points in the
  optical frame, with :func:`~reachwise.io.ros.depth_image.depth_points` and with a
  plain per-pixel loop (``struct.unpack_from`` and the pinhole formula, pixel by
  pixel), interleaved; ``loop_over_ours``.
"""

from __future__ import annotations

import os
import struct
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from reachwise.benchmarks._harness import BenchReport, Target, time_interleaved

W, H, FPS, JOINT_HZ = 640, 480, 30, 1000


def _depth_mm() -> np.ndarray:
    v = np.arange(H, dtype=np.float64)[:, None]
    u = np.arange(W, dtype=np.float64)[None, :]
    return np.asarray(1200.0 + 400.0 * v / H + 50.0 * u / W, dtype=np.uint16)


def _record(path: Path, seconds: float) -> None:
    from reachwise.geometry.depth_camera import Intrinsics
    from reachwise.io.ros.bag_writer import BagWriter

    intr = Intrinsics.from_fov(W, H)
    depth = _depth_mm()
    names = [f"panda_joint{k}" for k in range(1, 8)]
    q0 = np.array([0.0, -0.4, 0.0, -2.0, 0.0, 1.6, 0.8])
    cam = np.eye(4)
    cam[:3, 3] = [1.6, 0.0, 0.6]
    cam[:3, :3] = [[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]  # z toward the robot
    with BagWriter(path) as w:
        f = w.factory
        w.write(
            "/tf_static",
            "tf2_msgs/msg/TFMessage",
            f.tf([f.transform(0.0, "world", "cam", cam)]),
            0.0,
        )
        n = round(seconds * JOINT_HZ)
        per_frame = JOINT_HZ // FPS
        for i in range(n):
            t = i / JOINT_HZ
            if i % per_frame == 0:
                img = f.depth_image(t, "cam", depth.astype(np.float32))
                img.encoding, img.step = "16UC1", 2 * W
                img.data = depth.view(np.uint8).reshape(-1).copy()
                w.write(
                    "/depth/camera_info",
                    "sensor_msgs/msg/CameraInfo",
                    f.camera_info(t, "cam", intr),
                    t,
                )
                w.write("/depth/image", "sensor_msgs/msg/Image", img, t)
            q = q0 + 0.2 * np.sin(t + np.arange(7))
            w.write("/joint_states", "sensor_msgs/msg/JointState", f.joint_state(t, names, q), t)


def _loop_decode(
    msg: Any, fx: float, fy: float, cx: float, cy: float
) -> list[tuple[float, float, float]]:
    """The baseline: pixel by pixel with struct and the pinhole formula."""
    raw = bytes(msg.data)
    fmt = ">H" if msg.is_bigendian else "<H"
    out = []
    for v in range(msg.height):
        row = v * msg.step
        for u in range(msg.width):
            d = struct.unpack_from(fmt, raw, row + 2 * u)[0]
            if d == 0:
                continue
            z = d * 1e-3
            out.append(((u - cx) * z / fx, (v - cy) * z / fy, z))
    return out


def _pin_one_core() -> str:
    try:
        cpu = min(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {cpu})
        return f"pinned to CPU {cpu}"
    except (AttributeError, OSError):
        return "not pinned (sched_setaffinity unavailable)"


def run(quick: bool = False) -> BenchReport:
    """Replay a recorded cell and decode its depth images (see the module docstring)."""
    from reachwise.geometry.cloud import PointCloud
    from reachwise.io.robot_file import load_robot
    from reachwise.io.ros.bag import Recording
    from reachwise.io.ros.depth_image import camera_from_info, depth_points
    from reachwise.io.ros.replay import ReplaySpec, replay_recording

    rep = BenchReport("replay")
    affinity = os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else None
    rep.notes.append(_pin_one_core())
    seconds = 1.0 if quick else 3.0
    try:
        with tempfile.TemporaryDirectory() as tmp:
            bag = Path(tmp) / "cell.mcap"
            _record(bag, seconds)
            robot = load_robot("panda")
            rng = np.random.default_rng(0)
            clouds = {
                link: PointCloud(rng.normal(scale=0.06, size=(1000, 3)))
                for link in ("link_3", "link_5", "link_7")
            }
            spec = ReplaySpec(joints="/joint_states", clouds=("/depth/image",))
            replay_recording(bag, robot, spec, link_clouds=clouds)  # compile, warm caches
            per_frame = []
            frames = 0
            for _ in range(1 if quick else 3):
                t0 = time.perf_counter()
                res = replay_recording(bag, robot, spec, link_clouds=clouds)
                wall = time.perf_counter() - t0
                frames = res.clouds["/depth/image"]
                per_frame.append(wall / frames * 1e6)
            rep.add_samples("replay.frame", np.array(per_frame))
            fps = 1e6 / float(np.median(per_frame))
            rep.metrics["replay.frames_per_s"] = fps
            rep.metrics["replay.camera_frames"] = float(frames)
            rep.metrics["replay.joint_states"] = float(res.t.size)
            rep.metrics["replay.points_per_frame"] = float(W * H)
            rep.targets["replay.frames_per_s"] = Target(fps, float(FPS), higher_is_better=True)
            with Recording(bag) as rec:
                it = rec.messages(["/depth/image", "/depth/camera_info"])
                info = next(m.msg for m in it if m.topic == "/depth/camera_info")
                image = next(m.msg for m in rec.messages(["/depth/image"]))
            cam = camera_from_info(info)
            i = cam.intrinsics
            samples = time_interleaved(
                {
                    "decode.ours": lambda _: depth_points(image, cam),
                    "decode.loop": lambda _: _loop_decode(image, i.fx, i.fy, i.cx, i.cy),
                },
                repeat=1 if quick else 3,
                warmup=1,
            )
            for name, s in samples.items():
                rep.add_samples(name, s)
            rep.ratio("decode.loop", "decode.ours")
    finally:
        if affinity is not None:
            os.sched_setaffinity(0, affinity)
    return rep
