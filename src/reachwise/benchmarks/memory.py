"""``reachwise bench memory``: fusing one 640 × 480 depth frame into the scene memory of
a 4 × 4 × 3 m cell, at 3 cm and 5 cm voxels, against the straightforward per-ray update
(OctoMap's method: every pixel's ray walked voxel by voxel from the camera to its point,
the voxels passed marked free, the end voxel occupied; Amanatides & Woo's traversal,
compiled with numba like ours, with the same self-filter and no shadow).

The frame is a rendered cell: floor, two walls, a table and a person-sized box, seen by
a camera in a corner 2 m up (:class:`~reachwise.geometry.depth_camera.DepthCamera`,
60° field of view), with 4 % of the pixels marked as the robot's (self-filter), fed as
a depth camera gives it: float32 metres, NaN without a return (``32FC1``), which the
memory reads without a float64 copy.
Besides wall time, the thread's CPU time of each pass of the update (``cpu_3cm.project``
…) and of the hand-over. Targets: ≤ 5 ms median, ≤ 15 ms p99 at 3 cm; ≤ 2 ms median at
5 cm (one core), on the wall-time figures.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator

import numpy as np
import trimesh
from numba import njit

from reachwise.benchmarks._harness import BenchReport, Target, time_calls
from reachwise.distance.scene_memory import MemoryConfig, SceneMemory, ViewIntrinsics
from reachwise.geometry.depth_camera import DepthCamera, Intrinsics

LOWER = np.array([-2.0, -2.0, 0.0])
UPPER = np.array([2.0, 2.0, 3.0])


def cell_frame() -> tuple[np.ndarray, np.ndarray, np.ndarray, ViewIntrinsics]:
    """The benchmark's depth image (float32 m, NaN: no return, as a ``32FC1`` camera
    gives it), robot mask, camera pose and intrinsics."""
    boxes = [  # (size, centre), m
        ([4.0, 4.0, 0.02], [0.0, 0.0, -0.01]),  # floor
        ([0.02, 4.0, 3.0], [2.0, 0.0, 1.5]),  # walls
        ([4.0, 0.02, 3.0], [0.0, 2.0, 1.5]),
        ([1.2, 0.8, 0.75], [0.5, 0.6, 0.375]),  # a table
        ([0.35, 0.25, 1.7], [-0.6, 0.9, 0.85]),  # a person
    ]
    parts = [
        trimesh.creation.box(size, trimesh.transformations.translation_matrix(centre))
        for size, centre in boxes
    ]
    intr = Intrinsics.from_fov(640, 480, math.radians(60.0))
    cam = DepthCamera(intr, near=0.2, far=6.0)
    eye = np.array([-1.8, -1.8, 2.0])
    look = np.array([0.3, 0.5, 0.6])
    z = (look - eye) / np.linalg.norm(look - eye)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, y, z])
    T[:3, 3] = eye
    depth = cam.depth(parts, T).astype(np.float32)
    body = np.zeros(depth.shape, dtype=bool)
    body[380:480, 280:400] = True  # the robot's pixels: 4 % of the image
    K = ViewIntrinsics(intr.fx, intr.fy, intr.cx, intr.cy, cam.near, cam.far)
    return depth, body, T, K


@njit(cache=True, nogil=True)
def _per_ray(state, depth, body, camera, pose_wc, grid):  # type: ignore[no-untyped-def]
    """OctoMap's update: each returned pixel's ray traversed voxel by voxel."""
    fx, fy, cx, cy = camera[0], camera[1], camera[2], camera[3]
    vox = grid[3]
    nx, ny, nz = state.shape
    H, W = depth.shape
    R = pose_wc[:3, :3]
    o = pose_wc[:3, 3]
    start = np.empty(3)
    g = np.empty(3)
    for a in range(3):
        start[a] = (o[a] - grid[a]) / vox
    for r in range(H):
        for c in range(W):
            d = depth[r, c]
            if d != d or body[r, c]:
                continue
            xc = (c - cx) / fx * d
            yc = (r - cy) / fy * d
            for a in range(3):
                g[a] = (R[a, 0] * xc + R[a, 1] * yc + R[a, 2] * d + o[a] - grid[a]) / vox
            dirx, diry, dirz = g[0] - start[0], g[1] - start[1], g[2] - start[2]
            i, j, k = (
                math.floor(start[0]),
                math.floor(start[1]),
                math.floor(start[2]),
            )
            ei, ej, ek = math.floor(g[0]), math.floor(g[1]), math.floor(g[2])
            si = 1 if dirx > 0 else -1
            sj = 1 if diry > 0 else -1
            sk = 1 if dirz > 0 else -1
            tdx = abs(1.0 / dirx) if dirx != 0 else 1e30
            tdy = abs(1.0 / diry) if diry != 0 else 1e30
            tdz = abs(1.0 / dirz) if dirz != 0 else 1e30
            tx = ((i + (si > 0)) - start[0]) / dirx if dirx != 0 else 1e30
            ty = ((j + (sj > 0)) - start[1]) / diry if diry != 0 else 1e30
            tz = ((k + (sk > 0)) - start[2]) / dirz if dirz != 0 else 1e30
            steps = abs(ei - i) + abs(ej - j) + abs(ek - k)
            for _ in range(steps):
                if 0 <= i < nx and 0 <= j < ny and 0 <= k < nz and state[i, j, k] != 2:
                    state[i, j, k] = 1
                if tx < ty and tx < tz:
                    i += si
                    tx += tdx
                elif ty < tz:
                    j += sj
                    ty += tdy
                else:
                    k += sk
                    tz += tdz
            if 0 <= ei < nx and 0 <= ej < ny and 0 <= ek < nz:
                state[ei, ej, ek] = 2
    return 0


def _stage_cpu(
    mem: SceneMemory,
    depth: np.ndarray,
    body: np.ndarray,
    T: np.ndarray,
    K: ViewIntrinsics,
    reps: int,
) -> dict[str, np.ndarray]:
    """The thread's CPU time (µs) of each pass of a frame's update (``prepare``,
    ``project``, ``mark``; ``fuse`` their sum) and of the hand-over's collection with
    its index (``handover``: :meth:`SceneMemory.obstacle_cloud`), frame by frame: what
    the update costs one core whatever else the machine runs."""
    out: dict[str, list[float]] = {k: [] for k in ("prepare", "project", "mark", "handover")}
    clock = time.thread_time_ns
    t = mem.stamp
    for _ in range(reps):
        t += 0.033
        c0 = clock()
        frame = mem.prepare(depth, T, K, t, body)
        c1 = clock()
        mem.project(frame)
        c2 = clock()
        mem.mark(frame)
        c3 = clock()
        mem.obstacle_cloud()
        c4 = clock()
        for key, a, b in (("prepare", c0, c1), ("project", c1, c2), ("mark", c2, c3)):
            out[key].append((b - a) * 1e-3)
        out["handover"].append((c4 - c3) * 1e-3)
    cpu = {k: np.array(v) for k, v in out.items()}
    cpu["fuse"] = cpu["prepare"] + cpu["project"] + cpu["mark"]
    return cpu


def run(quick: bool = False) -> BenchReport:
    rep = BenchReport("memory")
    depth, body, T, K = cell_frame()
    reps = 15 if quick else 100
    camera = np.array([K.fx, K.fy, K.cx, K.cy, K.near, K.far])
    for voxel, tag in ((0.03, "3cm"), (0.05, "5cm")):
        mem = SceneMemory(LOWER, UPPER, MemoryConfig(voxel=voxel))
        state = np.zeros(mem.shape, dtype=np.uint8)
        grid = np.array([*LOWER, voxel])
        frames = iter(range(10**9))

        def fuse(m: SceneMemory = mem, n: Iterator[int] = frames) -> None:
            m.integrate(depth, T, K, 0.033 * next(n), body)

        def per_ray(s: np.ndarray = state, g: np.ndarray = grid) -> None:
            _per_ray(s, depth, body, camera, T, g)

        rep.add_samples(f"reachwise.fuse_{tag}", time_calls(fuse, reps))
        rep.add_samples(f"reachwise.collect_{tag}", time_calls(mem.obstacles, max(5, reps // 5)))
        rep.add_samples(
            f"reachwise.handover_{tag}", time_calls(mem.obstacle_cloud, max(5, reps // 5))
        )
        for stage, cpu in _stage_cpu(mem, depth, body, T, K, reps).items():
            rep.metrics[f"reachwise.cpu_{tag}.{stage}.median"] = float(np.median(cpu))
            rep.metrics[f"reachwise.cpu_{tag}.{stage}.p99"] = float(np.percentile(cpu, 99))
        rep.add_samples(f"per_ray.fuse_{tag}", time_calls(per_ray, max(5, reps // 5)))
        rep.ratio(f"reachwise.fuse_{tag}", f"per_ray.fuse_{tag}")
        counts = mem.counts()
        rep.metrics[f"voxels_{tag}.occupied"] = float(counts.occupied)
        rep.metrics[f"voxels_{tag}.shadow"] = float(counts.shadow)
        rep.metrics[f"voxels_{tag}.free"] = float(counts.free)
    m = rep.metrics
    rep.targets["fuse_3cm_median_us"] = Target(m["reachwise.fuse_3cm.median"], 5000)
    rep.targets["fuse_3cm_p99_us"] = Target(m["reachwise.fuse_3cm.p99"], 15000)
    rep.targets["fuse_5cm_median_us"] = Target(m["reachwise.fuse_5cm.median"], 2000)
    rep.notes.append(
        "fuse = projective free/shadow update + occupied marks of one 640 x 480 frame; "
        "collect = decay + the centres handed to the distance scene (once per hand-over); "
        "handover = collect + the centres' index (SceneMemory.obstacle_cloud); "
        "cpu_<voxel>.<pass> = the thread's CPU time per pass (prepare, project, mark, "
        "their sum fuse, handover), frame by frame: the cost on one core under any load"
    )
    return rep
