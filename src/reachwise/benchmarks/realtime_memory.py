"""``reachwise bench realtime-memory``: the 1 kHz loop of ``bench realtime`` with the
scene memory on.

The loop, the arm, the room and the camera are those of
:mod:`reachwise.benchmarks.realtime` (its section 2), but the camera thread no longer
hands over each frame's 307 200 points: it fuses the 640 × 480 depth image into a
:class:`~reachwise.distance.scene_memory.SceneMemory` of the 4 × 4 × 2.7 m cell around
the arm (3 cm voxels, the defaults: shadow 0.5 m, memory 3 s; the floor cropped, as a
cell's ground plane is) and hands over the occupied and shadow voxels' centres with
``Scene.replace_cloud``, 30 times a second, as a scenario's memory does. The arm is
not drawn in the bench's frames, so there is no self-filter; the body's voxels are
left out of the hand-over at the arm's joint state of that moment.

Measured besides the loop's figures: ``memory.fuse`` (one frame integrated),
``memory.frame_to_map`` (a frame's arrival to its obstacles handed to the scene: fuse,
collect, hand over; the issue's bound is 33 ms), ``memory.obstacles`` (voxels handed
over). The loop's ``handoff`` is the same span as ``memory.frame_to_map`` here. Then the
machine's own stalls (section 3) over as long. Targets: the loop's (tick median ≤
300 µs, p99.9 ≤ 1 ms, max ≤ 3 ms, 0 ticks waited for a build, ≥ 29 swaps/s) and frame
to map p99 ≤ 33 ms.
"""

from __future__ import annotations

import time

import numpy as np

import reachwise.benchmarks.realtime as realtime
from reachwise.benchmarks._harness import BenchReport, Target
from reachwise.distance.scene import Scene
from reachwise.distance.scene_memory import MemoryConfig, SceneMemory, ViewIntrinsics
from reachwise.runtime.realtime import keep_freed_memory

#: The memory's cell (m, world): 4 × 4 m around the arm, from 5 cm above the floor.
CELL = (np.array([-1.5, -2.0, 0.05]), np.array([2.5, 2.0, 2.75]))


def run(quick: bool = False) -> BenchReport:
    """The loop with the memory on, and the machine's stalls (module docstring)."""
    rep = BenchReport("realtime-memory")
    rep.notes.append(f"freed memory kept for reuse (glibc mallopt): {keep_freed_memory()}")
    pose, f = realtime.camera_pose()
    w, h = realtime.CAMERA_SIZE
    view = ViewIntrinsics(f, f, 0.5 * w - 0.5, 0.5 * h - 0.5, 0.2, 10.0)
    depths = [realtime.camera_depth(k) for k in range(realtime.FRAMES)]
    memory = SceneMemory(*CELL, MemoryConfig(voxel=0.03))
    memory.integrate(depths[0], pose, view, 0.0)
    fuse_us: list[float] = []
    map_us: list[float] = []
    sizes: list[int] = []

    def feed(scene: Scene, k: int, stamp: float) -> None:
        t0 = time.perf_counter()
        memory.integrate(depths[k % len(depths)], pose, view, stamp)
        t1 = time.perf_counter()
        pts = memory.obstacles(stamp)
        scene.replace_cloud("camera", pts, stamp=stamp)
        fuse_us.append((t1 - t0) * 1e6)
        map_us.append((time.perf_counter() - t0) * 1e6)
        sizes.append(len(pts))

    realtime._loop(rep, quick, feed, memory.obstacles())
    rep.add_samples("memory.fuse", np.array(fuse_us))
    rep.add_samples("memory.frame_to_map", np.array(map_us))
    rep.metrics["memory.obstacles.median"] = float(np.median(sizes))
    rep.metrics["memory.voxels"] = float(np.prod(memory.shape))
    rep.targets["frame_to_map_p99"] = Target(rep.metrics["memory.frame_to_map.p99"], 33_000.0)
    rep.notes.append(
        f"memory: {memory.shape[0]}x{memory.shape[1]}x{memory.shape[2]} voxels of 3 cm, "
        "fused from the camera thread (its kernels release the GIL); the loop's "
        "'handoff' is the frame's whole way into the map and the scene"
    )
    realtime._machine(rep, quick)
    return rep
