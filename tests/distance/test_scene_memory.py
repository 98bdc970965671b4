"""The scene memory against a brute-force reference and its stated properties: a voxel
holding an observed point is occupied; a voxel in front of an observed surface is free;
a shadow voxel is never freed until some camera sees it free; the robot's pixels change
nothing; the distance answer is never larger than the distance to the observed points."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from reachwise.distance.scene_memory import (
    STATES,
    MemoryConfig,
    SceneMemory,
    ViewIntrinsics,
)
from reachwise.errors import InputError

FREE, OCC, SHADOW, UNKNOWN = STATES["free"], STATES["occupied"], STATES["shadow"], STATES["unknown"]
LOWER, UPPER = np.array([-0.6, -0.6, 0.0]), np.array([0.6, 0.6, 0.9])


def camera_pose(rng: np.random.Generator) -> np.ndarray:
    """A camera about 1.5 m from the box's centre, its optical axis towards it."""
    centre = 0.5 * (LOWER + UPPER)
    eye = centre + rng.normal(size=3) * [1.0, 1.0, 0.5]
    eye = centre + (eye - centre) / np.linalg.norm(eye - centre) * rng.uniform(1.0, 1.8)
    z = centre + rng.normal(scale=0.1, size=3) - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, rng.normal(size=3))
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, y, z])
    T[:3, 3] = eye
    return T


def random_frame(rng: np.random.Generator, h: int = 18, w: int = 24):
    """A depth image with random surfaces (NaN holes) and a random robot mask."""
    K = ViewIntrinsics(fx=w * 0.9, fy=w * 0.9, cx=(w - 1) / 2, cy=(h - 1) / 2, near=0.2, far=4.0)
    depth = rng.uniform(0.8, 2.6, size=(h, w))
    depth[rng.random((h, w)) < 0.1] = np.nan
    body = rng.random((h, w)) < 0.1
    return depth, body, K, camera_pose(rng)


def reference_update(mem: SceneMemory, freed: np.ndarray, depth, body, K, T, t) -> None:
    """The update written the plainest way: every voxel centre projected, one at a time
    in numpy, then every pixel's point marked; ``freed`` (one per voxel, flat) is when
    each voxel was last seen free, written here. Each return is read as a float32, as
    the memory keeps it (:func:`~reachwise.distance._memory_kernel.prepare_frame`'s
    ``code``; about 0.1 µm at 2 m): a float64 or millimetre point within that of a voxel's
    face lands in the same voxel here as there; the farthest reach is the float64
    return's, as there."""
    cfg = mem.config
    farthest = np.nanmax(np.asarray(depth, dtype=np.float64))
    depth = np.asarray(depth, dtype=np.float64).astype(np.float32).astype(np.float64)
    idx = np.indices(mem.shape).reshape(3, -1).T
    centres = mem.origin + (idx + 0.5) * cfg.voxel
    cw = np.linalg.inv(T)
    pc = centres @ cw[:3, :3].T + cw[:3, 3]
    z = pc[:, 2]
    h, w = depth.shape
    reach = farthest + cfg.shadow_depth
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.floor(K.fx * pc[:, 0] / z + K.cx + 0.5)
        v = np.floor(K.fy * pc[:, 1] / z + K.cy + 0.5)
    ok = (z > K.near) & (z <= reach) & (u >= 0) & (u < w) & (v >= 0) & (v < h)
    state = mem.state.reshape(-1)
    for n in np.flatnonzero(ok):
        r, c = int(v[n]), int(u[n])
        d = depth[r, c]
        if not np.isfinite(d):
            continue
        if z[n] < d - cfg.surface_band:
            state[n], freed[n] = FREE, t
        elif (
            z[n] <= d + cfg.shadow_depth
            and not body[r, c]
            and state[n] != OCC
            and t - freed[n] > cfg.free_hold_s
        ):
            state[n] = SHADOW
    for r, c in zip(*np.nonzero(np.isfinite(depth) & ~body), strict=True):
        p = T[:3, :3] @ (np.array([(c - K.cx) / K.fx, (r - K.cy) / K.fy, 1.0]) * depth[r, c])
        key = mem.voxel_of(p + T[:3, 3])
        if key is not None:
            mem.state[key] = OCC
            mem.seen_at[key] = t


def observed_points(depth, body, K, T) -> np.ndarray:
    r, c = np.nonzero(np.isfinite(depth) & ~body)
    d = depth[r, c]
    pc = np.column_stack([(c - K.cx) / K.fx * d, (r - K.cy) / K.fy * d, d])
    return pc @ T[:3, :3].T + T[:3, 3]


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), frames=st.integers(1, 4))
def test_the_kernel_equals_the_plain_reference(seed: int, frames: int) -> None:
    rng = np.random.default_rng(seed)
    cfg = MemoryConfig(voxel=0.1, shadow_depth=0.3, memory_s=1.0, free_hold_s=0.05)
    fast, slow = SceneMemory(LOWER, UPPER, cfg), SceneMemory(LOWER, UPPER, cfg)
    freed = np.full(slow.state.size, -np.inf)
    for f in range(frames):
        depth, body, K, T = random_frame(rng)
        fast.integrate(depth, T, K, t=0.04 * f, body=body)
        reference_update(slow, freed, depth, body, K, T, 0.04 * f)
        assert np.array_equal(fast.state, slow.state)
        assert np.array_equal(fast.freed_at.reshape(-1), freed)


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), frames=st.integers(1, 3))
def test_float32_metres_and_uint16_millimetres_fuse_as_their_values(seed: int, frames: int) -> None:
    """A camera's own pixel types, read without a float64 copy: a float32 image (NaN: no
    return) and a uint16 image in millimetres (``depth_scale=0.001``, 0: no return) fuse
    as the plain reference fuses their values in metres."""
    rng = np.random.default_rng(seed)
    cfg = MemoryConfig(voxel=0.1, shadow_depth=0.3, memory_s=1.0, free_hold_s=0.05)
    f4, u2, slow = (SceneMemory(LOWER, UPPER, cfg) for _ in range(3))
    slow_u2 = SceneMemory(LOWER, UPPER, cfg)
    freed, freed_u2 = np.full(slow.state.size, -np.inf), np.full(slow.state.size, -np.inf)
    for f in range(frames):
        depth, body, K, T = random_frame(rng)
        d32 = depth.astype(np.float32)
        mm = np.nan_to_num(np.round(depth * 1000.0), nan=0.0).astype(np.uint16)
        metres = np.where(mm > 0, mm * 0.001, np.nan)
        f4.integrate(d32, T, K, t=0.04 * f, body=body)
        u2.integrate(mm, T, K, t=0.04 * f, body=body, depth_scale=0.001)
        reference_update(slow, freed, d32.astype(np.float64), body, K, T, 0.04 * f)
        reference_update(slow_u2, freed_u2, metres, body, K, T, 0.04 * f)
        assert np.array_equal(f4.state, slow.state)
        assert np.array_equal(f4.freed_at.reshape(-1), freed)
        assert np.array_equal(u2.state, slow_u2.state)
        assert np.array_equal(u2.freed_at.reshape(-1), freed_u2)
    assert np.count_nonzero(u2.state == OCC) > 0


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_observed_points_are_occupied_and_space_before_them_free(seed: int) -> None:
    rng = np.random.default_rng(seed)
    mem = SceneMemory(LOWER, UPPER, MemoryConfig(voxel=0.08, shadow_depth=0.3))
    depth, body, K, T = random_frame(rng)
    mem.integrate(depth, T, K, t=0.0, body=body)
    pts = observed_points(depth, body, K, T)
    occupied = set()
    for p in pts:
        key = mem.voxel_of(p)
        if key is not None:
            assert mem.state[key] == OCC
            occupied.add(key)
    # a voxel whose centre lies strictly in front of the surface seen through its pixel
    # (and that holds no observed point) is free
    cw = np.linalg.inv(T)
    for key in zip(*np.nonzero(mem.state != FREE), strict=True):
        if key in occupied:
            continue
        pc = cw[:3, :3] @ mem.centre(key) + cw[:3, 3]
        if pc[2] <= K.near:
            continue
        u = math.floor(K.fx * pc[0] / pc[2] + K.cx + 0.5)
        v = math.floor(K.fy * pc[1] / pc[2] + K.cy + 0.5)
        if 0 <= u < depth.shape[1] and 0 <= v < depth.shape[0] and not body[v, u]:
            d = depth[v, u]
            assert not (np.isfinite(d) and pc[2] < d - mem.config.surface_band), key


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_a_shadow_is_freed_only_by_a_camera_that_sees_it_free(seed: int) -> None:
    """Frames from two cameras; after each frame every voxel that was shadow before is
    free only if that frame's reference update marked it seen free."""
    rng = np.random.default_rng(seed)
    cfg = MemoryConfig(voxel=0.1, shadow_depth=0.4, memory_s=0.05, free_hold_s=0.0)
    mem = SceneMemory(LOWER, UPPER, cfg)
    for f in range(6):
        depth, body, K, T = random_frame(rng)
        before = mem.state.copy()
        freed_before = mem.freed_at.copy()
        mem.integrate(depth, T, K, t=0.1 * f, body=body)
        mem.obstacles()  # decay: occupied voxels older than memory_s become shadow
        was_shadow = before == SHADOW
        seen_free_now = mem.freed_at > freed_before
        assert not np.any(was_shadow & (mem.state == FREE) & ~seen_free_now)
        assert not np.any((before != FREE) & (mem.state == FREE) & ~seen_free_now)
        assert not np.any((before != UNKNOWN) & (mem.state == UNKNOWN))


def test_occupied_fades_to_shadow_never_to_free_and_a_person_who_leaves_is_forgotten() -> None:
    K = ViewIntrinsics(fx=60.0, fy=60.0, cx=39.5, cy=29.5, near=0.2, far=4.0)
    T = np.eye(4)  # looking along world +z from the origin
    mem = SceneMemory([-1.0, -1.0, 0.5], [1.0, 1.0, 3.5], MemoryConfig(voxel=0.05, memory_s=1.0))
    wall = np.full((60, 80), 3.0)
    person = wall.copy()
    person[20:40, 30:50] = 1.5
    mem.integrate(person, T, K, t=0.0)
    front = mem.voxel_of([0.0, 0.0, 1.5])
    behind = mem.voxel_of([0.0, 0.0, 1.8])  # within shadow_depth behind the person
    assert mem.state[front] == OCC and mem.state[behind] == SHADOW
    # the camera is blinded (no returns): nothing is freed, the person fades to shadow
    mem.integrate(np.full((60, 80), np.nan), T, K, t=2.0)
    mem.obstacles()
    assert mem.state[front] == SHADOW and mem.state[behind] == SHADOW
    # the robot (1 m from the camera) hides the person: its pixels free only the space
    # in front of it and never enter the map
    body = np.zeros((60, 80), dtype=bool)
    body[15:45, 25:55] = True
    hidden = wall.copy()
    hidden[body] = 1.0
    mem.integrate(hidden, T, K, t=2.1, body=body)
    assert mem.state[front] == SHADOW and mem.state[behind] == SHADOW
    assert mem.state[mem.voxel_of([0.0, 0.0, 0.7])] == FREE
    assert mem.state[mem.voxel_of([0.0, 0.0, 1.0])] != OCC
    # the person is seen gone: one frame forgets them
    mem.integrate(wall, T, K, t=2.2)
    assert mem.state[front] == FREE and mem.state[behind] == FREE
    assert not any(np.linalg.norm(mem.obstacles() - [0, 0, 1.5], axis=1) < 0.5)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_the_distance_answer_is_never_larger_than_the_distance_to_what_was_seen(seed: int) -> None:
    rng = np.random.default_rng(seed)
    mem = SceneMemory(LOWER - 1.5, UPPER + 1.5, MemoryConfig(voxel=0.07))
    depth, body, K, T = random_frame(rng)
    mem.integrate(depth, T, K, t=0.0, body=body)
    pts = observed_points(depth, body, K, T)
    inside = np.all((pts >= mem.origin) & (pts < mem.origin + np.array(mem.shape) * 0.07), axis=1)
    pts = pts[inside]
    if len(pts) == 0:
        return
    centres = mem.obstacles()
    queries = rng.uniform(LOWER - 1.0, UPPER + 1.0, size=(50, 3))
    d_map = cKDTree(centres).query(queries)[0] - mem.inflation
    d_true = cKDTree(pts).query(queries)[0]
    assert np.all(d_map <= d_true + 1e-12)


def box_halfspaces(R: np.ndarray, c: np.ndarray, half: np.ndarray) -> np.ndarray:
    """The six world half-spaces ``n · x ≤ d`` of a box (rotation ``R``, centre ``c``)."""
    n = np.concatenate([R.T, -R.T])
    return np.column_stack([n, np.concatenate([half, half]) + n @ c])


def box_distance(x: np.ndarray, R: np.ndarray, c: np.ndarray, half: np.ndarray) -> np.ndarray:
    """The exact distance of points ``x`` to a solid box (0 inside)."""
    local = (x - c) @ R
    return np.linalg.norm(np.maximum(np.abs(local) - half, 0.0), axis=1)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_the_robots_body_is_no_obstacle_and_stays_not_free(seed: int) -> None:
    """A random box-shaped robot part in a random map: no voxel within the inflation
    of the part is returned (exact box distance), every other obstacle voxel farther
    than sqrt(3) times it is (the planes' bound at a corner), the two answers differ by
    the left-out voxels only, and no state changes."""
    rng = np.random.default_rng(seed)
    mem = SceneMemory(LOWER, UPPER, MemoryConfig(voxel=0.05, shadow_depth=0.4))
    for f in range(2):
        depth, body, K, T = random_frame(rng)
        mem.integrate(depth, T, K, t=0.04 * f, body=body)
    everything = mem.obstacles()
    state = mem.state.copy()
    R = Rotation.random(random_state=int(rng.integers(2**31))).as_matrix()
    c = everything[rng.integers(len(everything))] if len(everything) else np.zeros(3)
    c = c + rng.normal(scale=0.05, size=3)
    half = rng.uniform(0.02, 0.25, size=3)
    left = mem.obstacles(body=[box_halfspaces(R, c, half)])
    assert np.array_equal(mem.state, state)  # not freed, not changed
    d_left = box_distance(left, R, c, half)
    assert np.all(d_left > mem.inflation - 1e-12)
    d_all = box_distance(everything, R, c, half)
    far = everything[d_all > math.sqrt(3.0) * mem.inflation + 1e-12]
    kept = {tuple(p) for p in np.round(left, 9)}
    assert {tuple(p) for p in np.round(far, 9)} <= kept
    assert kept <= {tuple(p) for p in np.round(everything, 9)}
    # a voxel the box holds at its centre is in the map but not an obstacle
    inside = everything[d_all == 0.0]
    assert not kept & {tuple(p) for p in np.round(inside, 9)}
    if len(inside):
        assert all(mem.state[mem.voxel_of(p)] in (OCC, SHADOW) for p in inside)


def test_a_body_piece_that_is_not_half_spaces_is_a_typed_error() -> None:
    mem = SceneMemory([0, 0, 0], [1, 1, 1], MemoryConfig(voxel=0.1))
    with pytest.raises(InputError, match=r"body\[0\]"):
        mem.obstacles(body=[np.ones((6, 3))])
    with pytest.raises(InputError, match="unit"):
        mem.obstacles(body=[np.ones((6, 4))])


def test_bad_inputs_are_typed_errors() -> None:
    with pytest.raises(InputError, match="voxel"):
        MemoryConfig(voxel=0.0)
    with pytest.raises(InputError, match="voxel"):
        MemoryConfig(voxel=True)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="upper"):
        SceneMemory([0, 0, 0], [1, -1, 1])
    with pytest.raises(InputError, match="exceed"):
        SceneMemory([0, 0, 0], [100, 100, 100], MemoryConfig(voxel=0.01))
    mem = SceneMemory([0, 0, 0], [1, 1, 1], MemoryConfig(voxel=0.1))
    K = ViewIntrinsics(10.0, 10.0, 4.5, 4.5, 0.1, 3.0)
    with pytest.raises(InputError, match="pose"):
        mem.integrate(np.ones((10, 10)), np.eye(4) * 2, K, t=0.0)
    with pytest.raises(InputError, match="body"):
        mem.integrate(np.ones((10, 10)), np.eye(4), K, t=0.0, body=np.zeros((3, 3), bool))
    for scale in (0.0, -0.001, math.nan):
        with pytest.raises(InputError, match="depth_scale"):
            mem.integrate(np.ones((10, 10), np.uint16), np.eye(4), K, t=0.0, depth_scale=scale)
    rot = np.eye(4)
    rot[:3, :3] = Rotation.from_rotvec([0.1, 0.2, 0.3]).as_matrix()
    mem.integrate(np.ones((10, 10)), rot, K, t=0.0)  # a valid call


def test_the_benchmarks_per_ray_baseline_marks_what_the_memory_marks() -> None:
    """The baseline of ``bench memory`` (a ray walked voxel by voxel) ends each ray in
    the voxel the memory marks occupied, and frees only voxels the ray passes."""
    from reachwise.benchmarks.memory import _per_ray

    rng = np.random.default_rng(3)
    cfg = MemoryConfig(voxel=0.05, shadow_depth=0.0, free_hold_s=0.0)
    mem = SceneMemory(LOWER, UPPER, cfg)
    depth, body, K, T = random_frame(rng, 30, 40)
    mem.integrate(depth, T, K, t=0.0, body=body)
    state = np.zeros(mem.shape, dtype=np.uint8)
    camera = np.array([K.fx, K.fy, K.cx, K.cy, K.near, K.far])
    _per_ray(state, depth, body, camera, T, np.array([*LOWER, cfg.voxel]))
    assert np.array_equal(state == 2, mem.state == OCC)
    assert (state == 1).sum() > 0


def test_what_the_robot_hides_keeps_its_state_and_the_robot_casts_no_shadow() -> None:
    """A camera on the z axis; the robot 1 m away covers the image's centre. Space it
    hides keeps what was seen there before: free stays free, shadow stays shadow,
    never-seen stays unknown; and nothing behind the robot's pixels becomes occupied or
    shadow, even without a scene surface behind it."""
    K = ViewIntrinsics(fx=60.0, fy=60.0, cx=39.5, cy=29.5, near=0.2, far=4.0)
    T = np.eye(4)
    cfg = MemoryConfig(voxel=0.05, shadow_depth=0.5, free_hold_s=0.0)
    body = np.zeros((60, 80), dtype=bool)
    body[15:45, 25:55] = True
    robot = np.full((60, 80), np.nan)
    robot[body] = 1.0
    ahead, behind = [0.0, 0.0, 0.7], [0.0, 0.0, 1.8]  # in front of / behind the robot
    # (hidden: the voxels between the robot and 2.9 m whose centre's pixel sees it)
    # never seen: the robot alone (no scene surface anywhere) frees what lies in front
    # of it and leaves everything behind it unknown
    mem = SceneMemory([-1.0, -1.0, 0.5], [1.0, 1.0, 3.5], cfg)
    mem.integrate(robot, T, K, t=0.0, body=body)
    assert mem.state[mem.voxel_of(ahead)] == FREE
    hidden = np.zeros(mem.shape, dtype=bool)
    for key in zip(*np.indices(mem.shape).reshape(3, -1), strict=True):
        c = mem.centre(key)
        u = math.floor(K.fx * c[0] / c[2] + K.cx + 0.5)
        v = math.floor(K.fy * c[1] / c[2] + K.cy + 0.5)
        if 1.0 < c[2] < 2.9 and 0 <= u < 80 and 0 <= v < 60 and body[v, u]:
            hidden[key] = True
    assert hidden.any() and np.all(mem.state[hidden] == UNKNOWN)
    # seen free (a wall at 3 m), then hidden by the robot: stays free
    mem.integrate(np.full((60, 80), 3.0), T, K, t=0.1)
    assert np.all(mem.state[hidden] == FREE)
    mem.integrate(np.where(body, 1.0, 3.0), T, K, t=0.2, body=body)
    assert np.all(mem.state[hidden] == FREE)
    # a person at 1.5 m shadows what lies behind them; the robot then hides it: kept
    person = np.full((60, 80), 3.0)
    person[20:40, 30:50] = 1.5
    mem.integrate(person, T, K, t=0.3)
    assert mem.state[mem.voxel_of(behind)] == SHADOW
    mem.integrate(np.where(body, 1.0, 3.0), T, K, t=0.4, body=body)
    assert mem.state[mem.voxel_of(behind)] == SHADOW
