"""A replay's cloud topic: an organized PointCloud2 comes as a cloud indexed over its
pixels' Z-order — the same points as the row-major decode moved into the fixed frame,
a valid tree, distances equal to brute force — and an unorganized one, or a dense one
with a NaN, takes the row-major path as before."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.distance import cdist
from scipy.spatial.transform import Rotation

from reachwise.distance import closest_points
from reachwise.distance.index import INDICES
from reachwise.geometry.cloud import PointCloud
from reachwise.io.ros.cloud_topic import POINTCLOUD2, CloudTopic
from reachwise.io.ros.pointcloud2 import pointcloud2_points
from reachwise.io.ros.recording_error import RecordingError
from reachwise.io.ros.transform_tree import TransformTree
from tests.distance.test_build import check_tree
from tests.io.ros._messages import cloud_message, field

FIELDS = [field("x", 0, 7), field("y", 4, 7), field("z", 8, 7), field("i", 12, 7)]


def _message(rng: np.random.Generator, h: int, w: int, dense: bool, nan: float):
    vals = {c: rng.uniform(-1.0, 1.0, (h, w)).astype(np.float32) for c in "xyzi"}
    vals["z"] += 2.0
    if nan:
        vals["y"][rng.random((h, w)) < nan] = np.nan
    return cloud_message(
        vals, FIELDS, height=h, width=w, point_step=16, row_step=16 * w + 4, big=False,
        dense=dense,
    )  # fmt: skip


def _tree(T: np.ndarray) -> TransformTree:
    tree = TransformTree()
    quat = Rotation.from_matrix(T[:3, :3]).as_quat()
    tree.add("world", "cam", 0.0, T[:3, 3], quat, static=True)
    return tree


@settings(max_examples=30, deadline=None)
@given(h=st.integers(2, 9), w=st.integers(1, 11), seed=st.integers(0, 2**32 - 1))
def test_an_organized_cloud_is_indexed_over_its_pixel_order(h: int, w: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    msg = _message(rng, h, w, dense=False, nan=0.3)
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    T[:3, 3] = rng.uniform(-1, 1, 3)
    row_major = pointcloud2_points(msg) @ T[:3, :3].T + T[:3, 3]
    got, stamp = CloudTopic("/pc", POINTCLOUD2, None).points(msg, 0.0, _tree(T), "world")
    assert stamp == 1.5
    if len(row_major) == 0:  # no finite point: the far placeholder
        assert not isinstance(got, PointCloud) and np.all(got == 1.0e6)
        return
    assert isinstance(got, PointCloud)
    index = INDICES.peek(got)
    assert index is not None
    check_tree(got.points, (index.points, index.perm, index.boxes, index.info), 8)
    # the same points (each within rounding of the row-major decode), one for one
    assert len(got) == len(row_major)
    assert cdist(got.points, row_major).min(axis=1).max() < 1e-12
    assert cdist(row_major, got.points).min(axis=1).max() < 1e-12
    link = PointCloud(rng.normal(scale=0.3, size=(25, 3)))
    res = closest_points(link, got)
    assert res.distance == pytest.approx(cdist(link.points, row_major).min(), abs=1e-9)


def test_unorganized_and_bad_dense_clouds_take_the_row_major_path() -> None:
    rng = np.random.default_rng(3)
    topic = CloudTopic("/pc", POINTCLOUD2, None)
    flat = _message(rng, 1, 40, dense=True, nan=0.0)
    got, _ = topic.points(flat, 0.0, _tree(np.eye(4)), "cam")
    assert not isinstance(got, PointCloud)
    np.testing.assert_array_equal(got, pointcloud2_points(flat))
    dense_with_nan = _message(rng, 4, 5, dense=True, nan=0.5)
    with pytest.raises(RecordingError, match="is_dense"):  # as the row-major decode says
        topic.points(dense_with_nan, 0.0, _tree(np.eye(4)), "cam")


def _depth_frames(encoding: str, k: int) -> list[np.ndarray]:
    """``k`` raw 48 × 64 depth images of a wall with a box in front of it, moving, with
    no-return pixels: 0 for 16UC1 millimetres; NaN, 0, a negative and inf for 32FC1."""
    rng = np.random.default_rng(7)
    frames = []
    for i in range(k):
        z = np.full((48, 64), 2.2 - 0.1 * i)
        z[10 + 2 * i : 30 + 2 * i, 20:40] = 1.1 + 0.05 * i
        z += rng.uniform(-0.01, 0.01, z.shape)
        holes = rng.random(z.shape) < 0.1
        if encoding == "16UC1":
            raw = np.round(z * 1000.0).astype(np.uint16)
            raw[holes] = 0
        else:
            raw = z.astype(np.float32)
            raw[holes] = rng.choice(np.array([np.nan, 0.0, -1.0, np.inf], np.float32), holes.sum())
        frames.append(raw)
    return frames


@pytest.mark.parametrize("encoding", ["16UC1", "32FC1"])
@pytest.mark.parametrize("big", [False, True])
def test_a_depth_frame_is_fused_in_its_own_pixel_type_as_in_float64_metres(
    encoding: str, big: bool
) -> None:
    """A 16UC1 and a 32FC1 depth image are fused from their own pixels (with the
    depth_scale of their unit), and the memory after each frame is the one the float64
    metres of the same image give (``depth_image_metres``, what the replay fused before):
    same states, same times, same obstacles."""
    from reachwise.distance.scene_memory import MemoryConfig, SceneMemory, ViewIntrinsics
    from reachwise.io.ros.cloud_topic import IMAGE
    from reachwise.io.ros.depth_image import depth_image_metres, depth_image_pixels
    from tests.io.ros._messages import camera_info, depth_message

    size = 2 if encoding == "16UC1" else 4
    topic = CloudTopic("/depth", IMAGE, "/info")
    topic.set_info(camera_info(64, 48, 50.0, 50.0, 32.0, 24.0))
    lower, upper, config = (-1.5, -1.2, 0.0), (1.5, 1.2, 2.6), MemoryConfig(voxel=0.05)
    fused, reference = SceneMemory(lower, upper, config), SceneMemory(lower, upper, config)
    view = ViewIntrinsics(50.0, 50.0, 32.0, 24.0, 0.0, 1.0e3)
    for i, raw in enumerate(_depth_frames(encoding, 4)):
        t = 2.0 + 0.5 * i
        msg = depth_message(raw, encoding, step=64 * size + 6, big=big, t=t)
        pixels, scale = depth_image_pixels(msg)
        assert pixels.dtype == raw.dtype and scale == (1e-3 if encoding == "16UC1" else 1.0)
        obstacles, stamp = topic.fuse(fused, msg, t, TransformTree(), "cam")
        assert stamp == pytest.approx(t)
        reference.integrate(depth_image_metres(msg), np.eye(4), view, stamp)
        np.testing.assert_array_equal(fused.state, reference.state)
        np.testing.assert_array_equal(fused.seen_at, reference.seen_at)
        np.testing.assert_array_equal(fused.freed_at, reference.freed_at)
        expected = reference.obstacle_cloud(stamp, name="/depth")
        assert expected is not None and isinstance(obstacles, PointCloud)
        np.testing.assert_array_equal(obstacles.points, expected.points)
    assert (fused.state != 0).sum() > 1000  # the frames saw something
