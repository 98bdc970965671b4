"""Queries answered while depth frames are fused into a scene memory on the collision
server: does a 30 Hz, 640 × 480 depth stream hold up the control loop's queries?

A server process holds the crane of the server benchmarks (its parts watched against a
scene memory of a 4 × 4 × 3 m box in front of it, 3 cm voxels) and moves it as the
control loop sends its joint states. One client process stands for the depth camera:
``stream_hz`` times a second (absolute schedule; it falls behind when a frame takes
longer) it sends a 640 × 480 depth frame (:func:`depth_frame`: a wall, the floor and a
person walking across) with :func:`~reachwise.distance.scene_memories.fuse_depth`; the
server fuses it without its scene lock, leaving the crane out at its latest joint
state, and swaps the memory's obstacles in. This process is the controller: it sends
its joint state with the query of every pair, ``query_hz`` times a second (the loop of
:mod:`reachwise.benchmarks.server_stream`), first with the camera idle, then while it
streams.

Figures (µs unless the key says otherwise): ``idle_query`` and ``fuse_query``, the
query call's percentiles without and with the stream; ``fuse_call``, the camera's
``fuse_depth`` round trip (sending the frame, fusing, the swap); the frames fused per
second; ``fuse_cloud_age``, the age of the memory each answer used (reply arrival −
the capture stamp of its newest frame: the frame's way to the map the controller
queries, plus up to one frame period).
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from reachwise.benchmarks._harness import BenchReport, Target
from reachwise.benchmarks.distance import part_points
from reachwise.benchmarks.server_setup import (
    LINKS,
    MARGIN,
    ROBOT,
    ServerProcess,
    bench_priority,
    crane_q,
)
from reachwise.benchmarks.server_stream import CAMERA, control_loop, with_camera
from reachwise.distance.scene_memories import add_memory, watch_memory
from reachwise.distance.scene_memory import MemoryConfig
from reachwise.io.robot_file import load_robot
from reachwise.kinematics.robot import Robot
from reachwise.server.client import SceneClient

__all__ = ["INTRINSICS", "LOWER", "POSE", "UPPER", "depth_frame", "run"]

#: The memory's box (m, world): 4 × 4 × 3 m in front of the crane.
LOWER, UPPER = np.array([0.5, -2.0, 0.0]), np.array([4.5, 2.0, 3.0])
WIDTH, HEIGHT = 640, 480
#: The camera's pinhole model (fx, fy, cx, cy, near, far): 60° horizontal field of view.
INTRINSICS = (554.3, 554.3, 319.5, 239.5, 0.2, 8.0)
#: The camera 1.5 m up at the crane's base, looking along world +x (optical z), image
#: x to world −y, image y down.
POSE = np.array(
    [[0.0, 0.0, 1.0, 0.0], [-1.0, 0.0, 0.0, 0.0], [0.0, -1.0, 0.0, 1.5], [0.0, 0.0, 0.0, 1.0]]
)
#: The query percentile target (µs) while the camera streams.
QUERY_P99_LIMIT_US = 2000.0


def depth_frame(k: int) -> NDArray[np.float64]:
    """Frame ``k`` of the camera (m along the optical axis): a wall 4.2 m ahead, the
    floor below the horizon, and a person-sized block 2.5 m ahead walking across the
    view (0.5 m wide, 1.7 m tall, 4 cm to the side per frame); NaN (no return) in the
    top rows."""
    fx, fy, cx, cy = INTRINSICS[:4]
    v, u = np.mgrid[0:HEIGHT, 0:WIDTH].astype(np.float64)
    depth = np.full((HEIGHT, WIDTH), 4.2)
    down = (v - cy) / fy  # the ray's drop per metre of depth
    with np.errstate(divide="ignore"):
        floor = np.where(down > 0, 1.5 / down, np.inf)
    depth = np.minimum(depth, floor)
    side = (u - cx) / fx * 2.5  # lateral position at the person's depth (image x)
    height = 1.5 - down * 2.5  # height at the person's depth
    centre = -1.2 + 0.04 * (k % 60)
    person = (np.abs(side - centre) < 0.25) & (height > 0.0) & (height < 1.7)
    depth[person] = 2.5
    depth[:8] = np.nan
    return depth


#: The camera process: fuses frames at its rate until told to stop; writes what it saw
#: as JSON. Arguments: endpoint, workdir, rate (Hz), frames to cycle.
_CAMERA = """
import json, sys, time
from pathlib import Path
from reachwise.benchmarks.server_memory import INTRINSICS, POSE, depth_frame
from reachwise.benchmarks.server_stream import CAMERA, paced_calls
from reachwise.distance.scene_memories import fuse_depth
from reachwise.io.atomic import atomic_write
from reachwise.server.client import SceneClient
ep, work, rate, count = sys.argv[1], Path(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4])
frames = [depth_frame(k) for k in range(count)]
with SceneClient(ep, setup_deadline=30.0) as c:
    fuse_depth(c, CAMERA, frames[0], POSE, INTRINSICS, time.monotonic())
    atomic_write(work / "camera-ready", b"1")
    report = paced_calls(work, rate, lambda k: fuse_depth(
        c, CAMERA, frames[k % count], POSE, INTRINSICS, time.monotonic()))
del report["results"]
atomic_write(work / "camera.json", json.dumps(report))
"""


def run(quick: bool = False) -> BenchReport:
    rep = BenchReport("server-memory")
    robot = load_robot(ROBOT)
    seconds = 3.0 if quick else 10.0
    stream_hz, query_hz = 30.0, 1000.0
    priority = bench_priority()
    rep.notes.append(
        f"server: separate process on tcp://127.0.0.1; load average at start "
        f"{os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs; server and querying loop "
        + (f"under SCHED_FIFO {priority}" if priority is not None else "at normal priority")
    )
    with tempfile.TemporaryDirectory(prefix="reachwise-bench-memory-") as tmp:
        work = Path(tmp)
        with ServerProcess(work, seconds * 2 + 900.0, priority=priority) as server:
            with SceneClient(server.endpoint, setup_deadline=60.0) as c:
                c.wait_ready(60.0)
                c.add_robot(robot, crane_q(robot, 0))
                for link in LINKS:
                    c.add_object(link, part_points(1000, seed=1), robot=robot.name, link=link)
                add_memory(c, CAMERA, LOWER, UPPER, MemoryConfig(voxel=0.03))
                for link in LINKS:
                    watch_memory(c, link, CAMERA, MARGIN)
            _stream(rep, server, robot, stream_hz, query_hz, seconds, priority)
    return rep


def _stream(
    rep: BenchReport,
    server: ServerProcess,
    robot: Robot,
    stream_hz: float,
    query_hz: float,
    seconds: float,
    priority: int | None,
) -> None:
    """The control loop idle, then while the camera process fuses; the figures into
    ``rep``."""
    work = server.workdir
    idle = control_loop(server.endpoint, robot, query_hz, seconds, priority)
    times, lost, reasons, seen, ages, regressions = with_camera(
        server, robot, _CAMERA, [str(stream_hz), "6"], query_hz, seconds, wait_s=120.0
    )
    report = json.loads((work / "camera.json").read_text())
    calls = np.asarray(report["calls_us"], dtype=np.float64)
    rep.add_samples("idle_query", idle[0])
    rep.metrics["idle.lost_replies"] = float(idle[1])
    rep.add_samples("fuse_query", times)
    rep.metrics["fuse_query.max"] = float(times.max())
    rep.metrics["fuse.lost_replies"] = float(lost)
    if calls.size:
        rep.add_samples("fuse_call", calls)
    rep.metrics["fuse.frames_per_s"] = len(calls) / float(report["span_s"])
    rep.metrics["fuse.failures"] = float(len(report["failures"]))
    rep.metrics["fuse.swaps_seen_per_s"] = (len(seen) - 1) / seconds if seen else 0.0
    rep.metrics["fuse.version_regressions"] = float(regressions)
    if np.isfinite(ages).any():
        rep.add_samples("fuse_cloud_age", ages[np.isfinite(ages)])
    rep.ratio("fuse_query", "idle_query")
    p99 = rep.metrics["fuse_query.p99"] / rep.metrics["idle_query.p99"]
    rep.ratios["fuse_query_p99_over_idle_query_p99"] = p99
    rep.targets["fuse_query_p99_us"] = Target(rep.metrics["fuse_query.p99"], QUERY_P99_LIMIT_US)
    rep.targets["fuse_lost_replies"] = Target(float(lost), 0.0)
    rep.notes.append(
        f"a camera process fuses {WIDTH}x{HEIGHT} depth frames at {stream_hz:g} Hz "
        f"(fuse_depth, float64 over the wire) into a 3 cm memory of a 4x4x3 m box while "
        f"this process sends its joint state and queries every pair at {query_hz:g} Hz for "
        f"{seconds:g} s (idle_query: the same loop just before, camera idle); the crane's "
        f"{len(LINKS)} parts are watched against the memory and left out of it"
    )
    if reasons:
        rep.notes.append(f"lost replies, first reasons: {reasons}")
    if report["failures"]:
        rep.notes.append(f"failed frames, first: {report['failures'][:3]}")
