"""The replay benchmark's baseline decodes what ours decodes (a wrong baseline would
make its ratio meaningless)."""

from __future__ import annotations

import numpy as np

from reachwise.benchmarks.replay import _cloud_message, _loop_cloud, _loop_decode
from reachwise.io.ros.depth_image import camera_from_info, depth_points
from reachwise.io.ros.pointcloud2 import pointcloud2_points
from tests.io.ros._messages import camera_info, depth_message


def test_the_per_pixel_loop_equals_depth_points() -> None:
    rng = np.random.default_rng(2)
    raw = rng.integers(0, 4000, (7, 9)).astype(np.uint16)
    raw[0, 0] = 0
    for big in (False, True):
        msg = depth_message(raw, "16UC1", step=20, big=big)
        cam = camera_from_info(camera_info(9, 7, 30.0, 40.0, 4.0, 3.0))
        loop = np.array(_loop_decode(msg, 30.0, 40.0, 4.0, 3.0))
        np.testing.assert_allclose(loop, depth_points(msg, cam), rtol=1e-12, atol=1e-15)


def test_the_point_loop_equals_pointcloud2_points() -> None:
    pts = np.random.default_rng(3).normal(size=(40, 3)).astype(np.float32).astype(np.float64)
    msg = _cloud_message(pts)
    np.testing.assert_array_equal(np.array(_loop_cloud(msg)), pts)
    np.testing.assert_array_equal(pointcloud2_points(msg), pts)


def test_both_index_builds_index_the_same_points() -> None:
    """bench replay's index.ordered and index.sorted build trees over the same points
    (a ratio between different work would mean nothing)."""
    from reachwise.distance.index import build_index, index_of_ordered
    from reachwise.io.ros.depth_image import DepthProjector

    rng = np.random.default_rng(4)
    raw = rng.integers(0, 4000, (12, 16)).astype(np.uint16)
    raw[rng.random((12, 16)) < 0.2] = 0
    msg = depth_message(raw, "16UC1", step=32, big=False)
    proj = DepthProjector(camera_from_info(camera_info(16, 12, 30.0, 40.0, 8.0, 6.0)))
    pose = np.eye(4)
    ordered = index_of_ordered(*proj.ordered_points(msg, pose))
    built = build_index(proj.points(msg, pose))
    assert len(ordered) == len(built) == int((raw > 0).sum())
    key = np.lexsort(ordered.points.T)
    np.testing.assert_array_equal(ordered.points[key], built.points[np.lexsort(built.points.T)])
