"""The scene memory's block stamps against the plain per-voxel rules: a frame that frees
a whole brick or half-brick of voxels stamps its blocks, not its voxels, and skips
writing their states when a brick is known to be all free; the map must not tell the
difference.
Smooth frames (a plane behind the cell, a person-sized patch in front, a hole without
returns, the robot's pixels) from cameras around the cell, fused close together in
time, so that whole bricks are freed, stay free, and are seen from behind a surface by
another camera within the free hold."""

from __future__ import annotations

import numpy as np
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from reachwise.distance._memory_kernel import BLOCK, from_blocks, to_blocks
from reachwise.distance.scene_memory import MemoryConfig, SceneMemory, ViewIntrinsics
from tests.distance.test_scene_memory import camera_pose, reference_update

LOWER, UPPER = np.array([-0.6, -0.6, 0.0]), np.array([0.6, 0.6, 0.9])


def smooth_frame(rng: np.random.Generator, h: int = 36, w: int = 48):
    """A plane 0.8–2.5 m beyond the cell's centre, tilted at random; a rectangle of
    pixels sees a surface 0.3–0.6 m in front of the cell's centre (a person); another
    one sees nothing; another one is the robot, 0.5 m from the camera."""
    K = ViewIntrinsics(fx=w * 0.6, fy=w * 0.6, cx=(w - 1) / 2, cy=(h - 1) / 2, near=0.2, far=6.0)
    T = camera_pose(rng)
    centre = 0.5 * (LOWER + UPPER)
    reach = float(np.linalg.norm(centre - T[:3, 3]))
    normal = np.array([*rng.normal(scale=0.3, size=2), 1.0])
    normal /= np.linalg.norm(normal)
    offset = reach + rng.uniform(0.8, 2.5)
    v, u = np.mgrid[0:h, 0:w]
    rays = np.stack([(u - K.cx) / K.fx, (v - K.cy) / K.fy, np.ones((h, w))], axis=-1)
    depth = offset / (rays @ normal)
    depth[(depth <= 0) | (depth > K.far)] = np.nan  # a sensor gives no return there

    def patch() -> tuple[slice, slice]:
        r0, c0 = rng.integers(0, h - 6), rng.integers(0, w - 6)
        return slice(r0, r0 + rng.integers(3, 14)), slice(c0, c0 + rng.integers(3, 14))

    depth[patch()] = reach - rng.uniform(0.3, 0.6)
    depth[patch()] = np.nan
    body = np.zeros((h, w), dtype=bool)
    robot = patch()
    body[robot] = True
    depth[robot] = 0.5
    return depth, body, K, T


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), frames=st.integers(2, 6))
def test_block_stamps_keep_the_per_voxel_rules(seed: int, frames: int) -> None:
    """After every frame the state and the time each voxel was last seen free equal
    the plain per-voxel update's (the rules written once in numpy), while whole bricks
    and half-bricks are freed by block stamps. Frames 20 ms apart, the free hold 50 ms:
    a voxel a block stamp freed must not be shadowed by the next camera's view from behind."""
    rng = np.random.default_rng(seed)
    cfg = MemoryConfig(voxel=0.05, shadow_depth=0.4, memory_s=1.0, free_hold_s=0.05)
    fast, slow = SceneMemory(LOWER, UPPER, cfg), SceneMemory(LOWER, UPPER, cfg)
    freed = np.full(slow.state.size, -np.inf)
    stamped = 0
    for f in range(frames):
        depth, body, K, T = smooth_frame(rng)
        fast.integrate(depth, T, K, t=0.02 * f, body=body)
        reference_update(slow, freed, depth, body, K, T, 0.02 * f)
        assert np.array_equal(fast.state, slow.state)
        assert np.array_equal(fast.freed_at.reshape(-1), freed)
        stamped += int(np.count_nonzero(fast._freed_block == 0.02 * f))
    # only runs where whole blocks were freed by their stamp count (hypothesis fails
    # the test when too few do)
    assume(stamped > 0)


def test_a_brick_freed_whole_then_marked_is_written_again_when_freed_whole() -> None:
    """A brick freed whole (its voxels free, the brick known all free), then a point
    marked in it, then freed whole again: the point's voxel is free again; then a
    shadow cast into it from in front, then freed whole again: free again; and a
    snapshot restored keeps when the voxels were seen free."""
    K = ViewIntrinsics(fx=40.0, fy=40.0, cx=23.5, cy=17.5, near=0.2, far=6.0)
    T = np.eye(4)  # along world +z from the origin
    mem = SceneMemory([-0.2, -0.2, 1.0], [0.2, 0.2, 1.4], MemoryConfig(voxel=0.05))
    wall = np.full((36, 48), 3.0)
    mem.integrate(wall, T, K, t=0.0)
    assert np.all(mem.state == 1) and np.all(mem.freed_at == 0.0)
    person = wall.copy()
    person[17:19, 23:25] = 1.22
    mem.integrate(person, T, K, t=1.0)
    hit = mem.voxel_of([0.01525, 0.01525, 1.22])  # pixel (18, 24)'s point
    assert mem.state[hit] == 2
    mem.integrate(wall, T, K, t=2.0)
    assert np.all(mem.state == 1) and np.all(mem.freed_at == 2.0)
    # a person in front of the cell: no point in it, a shadow behind them, then gone
    mem.integrate(np.where(person == 1.22, 0.9, wall), T, K, t=3.0)
    assert mem.state[mem.voxel_of([0.01525, 0.01525, 1.2])] == 3
    assert np.count_nonzero(mem.state == 3) < mem.state.size
    mem.integrate(wall, T, K, t=4.0)
    assert np.all(mem.state == 1) and np.all(mem.freed_at == 4.0)
    snap = mem.snapshot()
    mem.clear()
    assert np.all(mem.freed_at == -np.inf)
    mem.restore(snap)
    assert np.all(mem.state == 1) and np.all(mem.freed_at == 4.0)


def test_robot_pixels_free_whole_bricks_in_front_of_the_robot_and_shadow_none() -> None:
    """A brick the robot's pixels alone cover is freed whole in front of the robot's
    depth (its block stamped, as in front of a scene surface), and nothing at or behind
    the robot's depth is shadowed; one pixel without a return under it, and the same
    frame decides the blocks over it voxel by voxel (not stamped), with the same map.
    After every frame the map equals the plain per-voxel update's."""
    K = ViewIntrinsics(fx=40.0, fy=40.0, cx=23.5, cy=17.5, near=0.2, far=6.0)
    T = np.eye(4)  # along world +z from the origin
    lower, upper = [-0.2, -0.2, 1.0], [0.2, 0.2, 1.4]
    cfg = MemoryConfig(voxel=0.05)
    mem = SceneMemory(lower, upper, cfg)
    slow = SceneMemory(lower, upper, cfg)
    freed = np.full(slow.state.size, -np.inf)
    robot = np.ones((36, 48), dtype=bool)

    def fuse(depth: np.ndarray, t: float) -> None:
        mem.integrate(depth, T, K, t=t, body=robot)
        reference_update(slow, freed, depth, robot, K, T, t)
        assert np.array_equal(mem.state, slow.state)
        assert np.array_equal(mem.seen_at, slow.seen_at)
        assert np.array_equal(mem.freed_at.reshape(-1), freed)

    fuse(np.full((36, 48), 3.0), 0.0)  # the robot 3 m away fills the view
    assert np.all(mem.state == 1) and np.all(mem._freed_block == 0.0)
    near_robot = np.full((36, 48), 1.2)
    fuse(near_robot, 1.0)  # the robot inside the cell: free before it, the rest kept
    z = mem.origin[2] + (np.arange(mem.shape[2]) + 0.5) * cfg.voxel
    in_front = z < 1.2 - cfg.surface_band - 0.02  # off-axis centres lie a little deeper
    assert np.all(mem.freed_at[:, :, in_front] == 1.0)
    assert np.all(mem.state == 1)  # behind the robot: free since 0.0, never shadowed
    assert np.all(mem.freed_at[:, :, z > 1.2 + 0.02] == 0.0)
    hole = np.full((36, 48), 3.0)
    hole[17, 23] = np.nan
    fuse(hole, 2.0)  # a pixel without a return: voxel by voxel, the same map
    assert np.all(mem.state == 1) and 0 < np.count_nonzero(mem.freed_at < 2.0) < 16
    assert not np.all(mem._freed_block == 2.0)  # the half-bricks over the hole


@settings(max_examples=20, deadline=None)
@given(shape=st.tuples(st.integers(1, 13), st.integers(1, 13), st.integers(1, 13)))
def test_the_voxels_own_free_stamps_are_kept_block_by_block(shape: tuple[int, int, int]) -> None:
    """The per-voxel stamps' block layout: voxel (i, j, k)'s stamp at its block
    (i, j, k) // BLOCK and place ((i mod BLOCK)·BLOCK + j mod BLOCK)·BLOCK + k mod BLOCK,
    the places past the grid's end never seen free (-inf), and back to the grid
    unchanged."""
    stamps = np.arange(float(np.prod(shape))).reshape(shape)  # every stamp distinct
    blocks = to_blocks(stamps)
    i, j, k = np.indices(shape)
    place = ((i % BLOCK) * BLOCK + j % BLOCK) * BLOCK + k % BLOCK
    assert blocks.shape == (*(-(-n // BLOCK) for n in shape), BLOCK**3)
    assert np.array_equal(blocks[i // BLOCK, j // BLOCK, k // BLOCK, place], stamps)
    assert np.count_nonzero(blocks == -np.inf) == blocks.size - stamps.size
    assert np.array_equal(from_blocks(blocks, shape), stamps)


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), before=st.integers(1, 4), after=st.integers(1, 4))
def test_a_restored_memory_decides_as_the_one_it_was_taken_from(
    seed: int, before: int, after: int
) -> None:
    """A snapshot restored into a fresh memory (the voxels' free stamps put back in
    their block layout) and then fed the same frames as the memory it was taken from,
    20 ms apart within the 50 ms free hold: after every frame both hold the same
    states, the same times seen occupied and the same times seen free."""
    rng = np.random.default_rng(seed)
    cfg = MemoryConfig(voxel=0.05, shadow_depth=0.4, memory_s=1.0, free_hold_s=0.05)
    kept, restored = SceneMemory(LOWER, UPPER, cfg), SceneMemory(LOWER, UPPER, cfg)
    for f in range(before):
        depth, body, K, T = smooth_frame(rng)
        kept.integrate(depth, T, K, t=0.02 * f, body=body)
    restored.restore(kept.snapshot())
    assert np.array_equal(restored.freed_at, kept.freed_at)
    for f in range(before, before + after):
        depth, body, K, T = smooth_frame(rng)
        for mem in (kept, restored):
            mem.integrate(depth, T, K, t=0.02 * f, body=body)
        assert np.array_equal(restored.state, kept.state)
        assert np.array_equal(restored.seen_at, kept.seen_at)
        assert np.array_equal(restored.freed_at, kept.freed_at)
