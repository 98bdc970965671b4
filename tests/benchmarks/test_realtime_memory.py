"""``bench realtime-memory`` fuses the same frames ``bench realtime`` hands over as
points: its depth images, back-projected through the camera's pose and pinhole model,
are those points; fused, they mark the voxels of those points occupied."""

from __future__ import annotations

import numpy as np

from reachwise.benchmarks import realtime
from reachwise.benchmarks.realtime_memory import CELL
from reachwise.distance.scene_memory import STATES, MemoryConfig, SceneMemory, ViewIntrinsics


def test_the_depth_image_is_the_frames_points() -> None:
    T, f = realtime.camera_pose()
    assert np.allclose(T[:3, :3].T @ T[:3, :3], np.eye(3)) and np.linalg.det(T[:3, :3]) > 0
    depth = realtime.camera_depth(3)
    h, w = depth.shape
    assert (w, h) == realtime.CAMERA_SIZE
    v, u = np.indices(depth.shape)
    pc = np.stack([(u - (0.5 * w - 0.5)) / f * depth, (v - (0.5 * h - 0.5)) / f * depth, depth])
    world = pc.reshape(3, -1).T @ T[:3, :3].T + T[:3, 3]
    pts = realtime.camera_frame(3).astype(np.float64)
    assert np.allclose(world, pts, atol=1e-4)  # float32 points


def test_a_fused_frame_marks_its_points_voxels_occupied() -> None:
    T, f = realtime.camera_pose()
    w, h = realtime.CAMERA_SIZE
    memory = SceneMemory(*CELL, MemoryConfig(voxel=0.05))
    memory.integrate(
        realtime.camera_depth(0),
        T,
        ViewIntrinsics(f, f, 0.5 * w - 0.5, 0.5 * h - 0.5, 0.2, 10.0),
        0.0,
    )
    pts = realtime.camera_frame(0).astype(np.float64)[::97]
    idx = [memory.voxel_of(p) for p in pts]
    inside = [i for i in idx if i is not None]
    assert len(inside) > 100
    assert all(memory.state[i] == STATES["occupied"] for i in inside)
