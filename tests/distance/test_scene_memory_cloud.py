"""The scene memory's hand-over cloud: its points are the occupied and shadow voxels'
centres (after the fading) in the Morton order of their voxels, its index is built
over that order and answers distances exactly, and a scene takes it without a build."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.distance import cdist

from reachwise.distance import closest_points
from reachwise.distance.index import INDICES, LEAF_SIZE
from reachwise.distance.ingest import ready_cloud
from reachwise.distance.scene_memory import STATES, MemoryConfig, SceneMemory
from reachwise.geometry.cloud import PointCloud
from tests.distance.test_build import check_tree
from tests.distance.test_scene_memory import LOWER, UPPER, box_halfspaces, random_frame

OCC, SHADOW = STATES["occupied"], STATES["shadow"]


def interleaved(i: int, j: int, k: int) -> int:
    """The Morton code of voxel (i, j, k), bit by bit: i's bit b at 3b + 2, j's at
    3b + 1, k's at 3b."""
    code = 0
    for b in range(20):
        code |= (
            ((i >> b) & 1) << (3 * b + 2)
            | ((j >> b) & 1) << (3 * b + 1)
            | ((k >> b) & 1) << (3 * b)
        )
    return code


@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    frames=st.integers(1, 5),
    voxel=st.sampled_from([0.04, 0.05, 0.07]),
)
def test_the_cloud_is_the_obstacle_voxels_in_morton_order_and_exact(
    seed: int, frames: int, voxel: float
) -> None:
    """Frames fused at random times (some voxels fade, some are freed again, bricks
    empty and fill): the cloud holds exactly the centres of the voxels that are
    occupied or shadow after the fading (written out with numpy), in increasing Morton
    code; its index has the tree layout, and distances on it equal brute force."""
    rng = np.random.default_rng(seed)
    mem = SceneMemory(LOWER - 0.3, UPPER + 0.2, MemoryConfig(voxel=voxel, memory_s=0.1))
    t = 0.0
    for _ in range(frames):
        t += rng.uniform(0.0, 0.2)
        depth, body, K, T = random_frame(rng)
        mem.integrate(depth, T, K, t=t, body=body)
    t_query = t + rng.uniform(0.0, 0.2)
    faded = (mem.state == OCC) & (t_query - mem.seen_at > mem.config.memory_s)
    expected_state = np.where(faded, SHADOW, mem.state)
    cloud = mem.obstacle_cloud(t_query, name="memory")
    assert np.array_equal(mem.state, expected_state)
    idx = np.argwhere((expected_state == OCC) | (expected_state == SHADOW))
    if len(idx) == 0:
        assert cloud is None
        return
    assert cloud is not None and cloud.name == "memory"
    pts = cloud.points
    codes = [interleaved(*v) for v in idx]
    order = np.argsort(codes)
    centres = mem.origin + (idx[order] + 0.5) * voxel
    np.testing.assert_allclose(pts, centres, rtol=0, atol=1e-12)
    assert all(a < b for a, b in zip(np.sort(codes)[:-1], np.sort(codes)[1:], strict=True))
    np.testing.assert_array_equal(pts, mem.obstacles(t_query))
    index = INDICES.peek(cloud)
    assert index is not None
    check_tree(pts, (index.points, index.perm, index.boxes, index.info), LEAF_SIZE)
    np.testing.assert_allclose(index.centroid, pts.mean(axis=0), rtol=0, atol=1e-12)
    other = rng.uniform(LOWER - 0.5, UPPER + 0.5, size=(30, 3))
    res = closest_points(PointCloud(other), cloud)
    assert abs(res.distance - cdist(other, pts).min()) <= 1e-12


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_the_cloud_without_the_body_keeps_the_order(seed: int) -> None:
    """Leaving out a body piece keeps the other centres, in the same order, and the
    index over them exact."""
    rng = np.random.default_rng(seed)
    mem = SceneMemory(LOWER, UPPER, MemoryConfig(voxel=0.05))
    depth, body, K, T = random_frame(rng)
    mem.integrate(depth, T, K, t=0.0, body=body)
    everything = mem.obstacles()
    if len(everything) < 2:
        return
    c = everything[rng.integers(len(everything))]
    piece = box_halfspaces(np.eye(3), c, np.full(3, 0.1))
    cloud = mem.obstacle_cloud(body=[piece])
    kept = mem.obstacles(body=[piece])
    if len(kept) == 0:
        assert cloud is None
        return
    assert cloud is not None
    np.testing.assert_array_equal(cloud.points, kept)
    rows = [np.flatnonzero((everything == p).all(axis=1))[0] for p in kept]
    assert rows == sorted(rows)  # a subsequence of the whole, in its order
    index = INDICES.peek(cloud)
    assert index is not None
    check_tree(kept, (index.points, index.perm, index.boxes, index.info), LEAF_SIZE)


def test_a_scene_takes_the_cloud_without_building_its_index() -> None:
    rng = np.random.default_rng(4)
    mem = SceneMemory(LOWER, UPPER, MemoryConfig(voxel=0.05))
    depth, body, K, T = random_frame(rng)
    mem.integrate(depth, T, K, t=0.0, body=body)
    cloud = mem.obstacle_cloud()
    assert cloud is not None
    ready = ready_cloud("memory", 3, cloud, 0.0)
    built = INDICES.peek(cloud)
    assert built is not None and ready.cloud is cloud and ready.index.version == 3
    assert ready.index.points is built.points and ready.index.boxes is built.boxes


def test_an_empty_memory_has_no_cloud() -> None:
    mem = SceneMemory(LOWER, UPPER, MemoryConfig(voxel=0.05))
    assert mem.obstacle_cloud() is None
    assert mem.obstacles().shape == (0, 3)


def brute_obstacles(mem: SceneMemory) -> np.ndarray:
    """The occupied and shadow voxels' centres, in the order of their Morton codes."""
    idx = np.argwhere((mem.state == OCC) | (mem.state == SHADOW))
    order = np.argsort([interleaved(*v) for v in idx])
    return mem.origin + (idx[order].reshape(-1, 3) + 0.5) * mem.config.voxel


def test_after_restore_and_clear_the_obstacles_are_the_maps() -> None:
    """A snapshot restored after frames that freed and filled other bricks, and after
    a clear: the obstacles are those of the restored map; after clear, none."""
    rng = np.random.default_rng(11)
    mem = SceneMemory(LOWER, UPPER, MemoryConfig(voxel=0.05))
    depth, body, K, T = random_frame(rng)
    mem.integrate(depth, T, K, t=0.0, body=body)
    snap = mem.snapshot()
    before = mem.obstacles(0.0).copy()
    assert len(before)
    for f in range(1, 4):
        depth, body, K, T = random_frame(rng)
        mem.integrate(depth, T, K, t=0.04 * f, body=body)
        mem.obstacles()
    mem.restore(snap)
    np.testing.assert_array_equal(mem.obstacles(0.0), before)
    mem.clear()
    assert mem.obstacle_cloud() is None
    mem.restore(snap)
    after = mem.obstacles(0.0)
    np.testing.assert_array_equal(after, before)
    np.testing.assert_allclose(after, brute_obstacles(mem), rtol=0, atol=1e-12)
