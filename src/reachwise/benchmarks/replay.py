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
  ``replay.cpu_frame`` and ``replay.frames_per_cpu_s`` the same in the process's CPU
  time (all its threads, on the one CPU it is pinned to): on a machine shared with
  other work the wall clock also counts the time the CPU ran someone else, the CPU
  time only what the replay cost — the wall-clock figure is the one that says the
  replay kept up on this machine, the CPU one what it would do with the core to itself;
- ``decode.ours`` vs ``decode.loop``: one 307 200-pixel depth image to points in the
  optical frame, with :func:`~reachwise.io.ros.depth_image.depth_points` and with a
  plain per-pixel loop (``struct.unpack_from`` and the pinhole formula, pixel by
  pixel), interleaved; ``loop_over_ours``;
- ``index.ordered`` vs ``index.sorted``: one depth image to an indexed cloud, projected
  in pixel Z-order and indexed over that order
  (:func:`~reachwise.distance.index.index_of_ordered`, what the replay does) and
  projected row by row and indexed by the general build that sorts the points
  (:func:`~reachwise.distance.index.build_index`), interleaved; ``sorted_over_ordered``;
- ``cloud.ours`` vs ``cloud.loop``: the same 307 200 points as a driver's PointCloud2
  (float32 x, y, z, rgb; 16 bytes a point) to an ``(N, 3)`` float32 array with
  :func:`~reachwise.io.ros.pointcloud2.pointcloud2_points` and point by point with
  ``struct`` as the ROS reference ``read_points`` does.
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


def _cloud_message(points: np.ndarray) -> Any:
    """A PointCloud2 of ``points`` as a depth camera driver sends it: float32 x, y, z
    and a float32 rgb, 16 bytes a point, one row."""
    from types import SimpleNamespace as Msg

    n = len(points)
    rec = np.zeros(n, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("rgb", "<f4")])
    for j, c in enumerate("xyz"):
        rec[c] = points[:, j]
    fields = [Msg(name=c, offset=4 * j, datatype=7, count=1) for j, c in enumerate("xyz")]
    fields.append(Msg(name="rgb", offset=12, datatype=7, count=1))
    return Msg(
        header=Msg(stamp=Msg(sec=0, nanosec=0), frame_id="cam"),
        height=1,
        width=n,
        fields=fields,
        is_bigendian=False,
        point_step=16,
        row_step=16 * n,
        data=rec.view(np.uint8),
        is_dense=True,
    )


def _loop_cloud(msg: Any) -> list[tuple[float, float, float]]:
    """The baseline: point by point with struct, as ``read_points`` does."""
    raw = bytes(msg.data)
    offsets = {f.name: f.offset for f in msg.fields}
    fmt = ("<" if not msg.is_bigendian else ">") + "f"
    out = []
    for v in range(msg.height):
        for u in range(msg.width):
            base = v * msg.row_step + u * msg.point_step
            out.append(
                (
                    struct.unpack_from(fmt, raw, base + offsets["x"])[0],
                    struct.unpack_from(fmt, raw, base + offsets["y"])[0],
                    struct.unpack_from(fmt, raw, base + offsets["z"])[0],
                )
            )
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
    rep = BenchReport("replay")
    affinity = os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else None
    rep.notes.append(_pin_one_core())
    seconds = 1.0 if quick else 3.0
    try:
        with tempfile.TemporaryDirectory() as tmp:
            bag = Path(tmp) / "cell.mcap"
            _record(bag, seconds)
            _replay_rate(rep, bag, quick)
            _decode_costs(rep, bag, quick)
    finally:
        if affinity is not None:
            os.sched_setaffinity(0, affinity)
    return rep


def _replay_rate(rep: BenchReport, bag: Path, quick: bool) -> None:
    """Frames replayed per second (wall and CPU) of the recorded cell ``bag``."""
    from reachwise.geometry.cloud import PointCloud
    from reachwise.io.robot_file import load_robot
    from reachwise.io.ros.replay import ReplaySpec, replay_recording

    robot = load_robot("panda")
    rng = np.random.default_rng(0)
    clouds = {
        link: PointCloud(rng.normal(scale=0.06, size=(1000, 3)))
        for link in ("link_3", "link_5", "link_7")
    }
    spec = ReplaySpec(joints="/joint_states", clouds=("/depth/image",))
    replay_recording(bag, robot, spec, link_clouds=clouds)  # compile, warm caches
    per_frame = []
    cpu_per_frame = []
    frames = 0
    for _ in range(1 if quick else 3):
        t0, c0 = time.perf_counter(), time.process_time()
        res = replay_recording(bag, robot, spec, link_clouds=clouds)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        frames = res.clouds["/depth/image"]
        per_frame.append(wall / frames * 1e6)
        cpu_per_frame.append(cpu / frames * 1e6)
    rep.add_samples("replay.frame", np.array(per_frame))
    rep.add_samples("replay.cpu_frame", np.array(cpu_per_frame))
    fps = 1e6 / float(np.median(per_frame))
    cpu_fps = 1e6 / float(np.median(cpu_per_frame))
    rep.metrics["replay.frames_per_s"] = fps
    rep.metrics["replay.frames_per_cpu_s"] = cpu_fps
    rep.metrics["replay.camera_frames"] = float(frames)
    rep.metrics["replay.joint_states"] = float(res.t.size)
    rep.metrics["replay.points_per_frame"] = float(W * H)
    rep.targets["replay.frames_per_s"] = Target(fps, float(FPS), higher_is_better=True)
    rep.targets["replay.frames_per_cpu_s"] = Target(cpu_fps, float(FPS), higher_is_better=True)


def _decode_costs(rep: BenchReport, bag: Path, quick: bool) -> None:
    """Decoding the first depth image of ``bag`` into points, its ordered index and a
    PointCloud2's points, each against its plain-loop or sorted baseline."""
    from reachwise.distance.index import build_index, index_of_ordered
    from reachwise.io.ros.bag import Recording
    from reachwise.io.ros.depth_image import DepthProjector, camera_from_info, depth_points
    from reachwise.io.ros.pointcloud2 import pointcloud2_points

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
    proj = DepthProjector(cam)
    pose = np.eye(4)

    def ordered(_: int) -> object:
        pts, codes, centroid = proj.ordered_points(image, pose)
        return index_of_ordered(pts, codes, centroid)

    samples |= time_interleaved(
        {
            "index.ordered": ordered,
            "index.sorted": lambda _: build_index(proj.points(image, pose)),
        },
        repeat=3 if quick else 10,
        warmup=1,
    )
    cloud = _cloud_message(depth_points(image, cam))
    samples |= time_interleaved(
        {
            "cloud.ours": lambda _: pointcloud2_points(cloud, dtype=np.float32),
            "cloud.loop": lambda _: _loop_cloud(cloud),
        },
        repeat=1 if quick else 3,
        warmup=1,
    )
    for name, s in samples.items():
        rep.add_samples(name, s)
    rep.ratio("decode.loop", "decode.ours")
    rep.ratio("cloud.loop", "cloud.ours")
    rep.ratio("index.sorted", "index.ordered")
