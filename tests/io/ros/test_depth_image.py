"""Depth images (16UC1 millimetres, 32FC1 metres) with CameraInfo to points, against a
brute-force per-pixel back-projection; padded rows, both byte orders, invalid pixels."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from reachwise.io.ros.depth_image import camera_from_info, depth_image_metres, depth_points
from reachwise.io.ros.recording_error import RecordingError
from tests.io.ros._messages import camera_info, depth_message


def brute_points(msg: object, fx: float, fy: float, cx: float, cy: float) -> np.ndarray:
    """Pixel by pixel with struct: the point z·((u−cx)/fx, (v−cy)/fy, 1) of each valid one."""
    m = msg
    mm = m.encoding in ("16UC1", "mono16")  # type: ignore[attr-defined]
    fmt = (">" if m.is_bigendian else "<") + ("H" if mm else "f")  # type: ignore[attr-defined]
    raw = bytes(m.data)  # type: ignore[attr-defined]
    out = []
    for v in range(m.height):  # type: ignore[attr-defined]
        for u in range(m.width):  # type: ignore[attr-defined]
            d = struct.unpack_from(fmt, raw, v * m.step + u * struct.calcsize(fmt))[0]  # type: ignore[attr-defined]
            z = d / 1000.0 if mm else float(d)
            if (mm and d == 0) or not (np.isfinite(z) and z > 0):
                continue
            out.append(((u - cx) / fx * z, (v - cy) / fy * z, z))
    return np.array(out, dtype=np.float64).reshape(-1, 3)


@settings(max_examples=100, deadline=None)
@given(
    encoding=st.sampled_from(["16UC1", "32FC1", "mono16"]),
    h=st.integers(1, 7),
    w=st.integers(1, 9),
    pad=st.integers(0, 6),
    big=st.booleans(),
    fx=st.floats(50.0, 900.0),
    fy=st.floats(50.0, 900.0),
    cx=st.floats(-5.0, 10.0),
    cy=st.floats(-5.0, 10.0),
    seed=st.integers(0, 2**32 - 1),
)
def test_points_equal_the_brute_force_back_projection(
    encoding: str,
    h: int,
    w: int,
    pad: int,
    big: bool,
    fx: float,
    fy: float,
    cx: float,
    cy: float,
    seed: int,
) -> None:
    rng = np.random.default_rng(seed)
    invalid = rng.random((h, w)) < 0.25
    if encoding == "32FC1":
        raw = rng.uniform(0.2, 8.0, (h, w)).astype(np.float32)
        raw[invalid] = np.nan
        step = 4 * w + 4 * pad
    else:
        raw = rng.integers(1, 65535, (h, w)).astype(np.uint16)
        raw[invalid] = 0
        step = 2 * w + 2 * pad
    msg = depth_message(raw, encoding, step=step, big=big)
    cam = camera_from_info(camera_info(w, h, fx, fy, cx, cy))
    got = depth_points(msg, cam)
    expected = brute_points(msg, fx, fy, cx, cy)
    assert got.shape == expected.shape
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)


def test_millimetres_and_zero_invalid() -> None:
    raw = np.array([[0, 1000], [2500, 65535]], dtype=np.uint16)
    z = depth_image_metres(depth_message(raw, "16UC1", step=4, big=False))
    assert np.isnan(z[0, 0])
    np.testing.assert_allclose(z[[0, 1, 1], [1, 0, 1]], [1.0, 2.5, 65.535], rtol=0, atol=1e-12)


def test_metres_nan_and_nonpositive_invalid() -> None:
    raw = np.array([[np.nan, 1.25, 0.0, -1.0, np.inf]], dtype=np.float32)
    z = depth_image_metres(depth_message(raw, "32FC1", step=20, big=True))
    assert np.isnan(z[0, [0, 2, 3, 4]]).all()
    assert z[0, 1] == 1.25


def test_unknown_encoding_is_an_error_naming_topic_and_time() -> None:
    msg = depth_message(np.zeros((2, 2), np.uint16), "16UC1", step=4, big=False)
    msg.encoding = "rgb8"
    with pytest.raises(RecordingError, match=r"/depth.*encoding.*rgb8.*t = 2\.0"):
        depth_image_metres(msg, topic="/depth")


def test_image_size_must_match_camera_info() -> None:
    msg = depth_message(np.ones((2, 3), np.uint16), "16UC1", step=6, big=False)
    cam = camera_from_info(camera_info(4, 2, 100, 100, 1, 1))
    with pytest.raises(RecordingError, match="3×2 pixels"):
        depth_points(msg, cam, topic="/depth")


def test_skewed_camera_matrix_is_an_error() -> None:
    info = camera_info(4, 2, 100, 100, 1, 1)
    info.k[1] = 0.5
    with pytest.raises(RecordingError, match="k"):
        camera_from_info(info)


def test_short_step_is_an_error() -> None:
    msg = depth_message(np.ones((2, 3), np.uint16), "16UC1", step=6, big=False)
    msg.step = 4
    with pytest.raises(RecordingError, match="step"):
        depth_image_metres(msg)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_projector_equals_points_moved_by_the_pose(seed: int) -> None:
    from scipy.spatial.transform import Rotation

    from reachwise.io.ros.depth_image import DepthProjector

    rng = np.random.default_rng(seed)
    raw = rng.uniform(0.3, 5.0, (6, 8)).astype(np.float32)
    raw[rng.random((6, 8)) < 0.3] = np.nan
    msg = depth_message(raw, "32FC1", step=32, big=False)
    cam = camera_from_info(camera_info(8, 6, 9.0, 11.0, 3.5, 2.5))
    proj = DepthProjector(cam)
    for _ in range(2):  # a second pose: the rotated rays follow it
        T = np.eye(4)
        T[:3, :3] = Rotation.random(random_state=rng).as_matrix()
        T[:3, 3] = rng.uniform(-2, 2, 3)
        expected = depth_points(msg, cam) @ T[:3, :3].T + T[:3, 3]
        np.testing.assert_allclose(proj.points(msg, T), expected, rtol=0, atol=1e-12)


def test_pixel_z_order_against_bit_by_bit_interleaving() -> None:
    from reachwise.io.ros.depth_image import pixel_z_order

    def code(u: int, v: int) -> int:
        return sum(((u >> b) & 1) << (2 * b) | ((v >> b) & 1) << (2 * b + 1) for b in range(12))

    for h, w in ((1, 1), (3, 5), (7, 4), (12, 16)):
        order, codes = pixel_z_order(h, w)
        expected = sorted((code(i % w, i // w), i) for i in range(h * w))
        assert order.tolist() == [i for _, i in expected]
        assert codes.tolist() == [c for c, _ in expected]


@settings(max_examples=40, deadline=None)
@given(
    encoding=st.sampled_from(["16UC1", "32FC1"]),
    big=st.booleans(),
    seed=st.integers(0, 2**32 - 1),
)
def test_ordered_points_are_the_projected_points_in_pixel_z_order(
    encoding: str, big: bool, seed: int
) -> None:
    """The same points as the row-major projection (bit for bit), each tagged with its
    pixel's Z-order code, codes increasing; the mean point is theirs."""
    from scipy.spatial.transform import Rotation

    from reachwise.io.ros.depth_image import DepthProjector, pixel_z_order

    rng = np.random.default_rng(seed)
    h, w = int(rng.integers(1, 9)), int(rng.integers(1, 11))
    if encoding == "16UC1":
        raw = rng.integers(0, 5000, (h, w)).astype(np.uint16)
        raw[rng.random((h, w)) < 0.3] = 0
    else:
        raw = rng.uniform(0.3, 5.0, (h, w)).astype(np.float32)
        raw[rng.random((h, w)) < 0.2] = np.nan
        raw[rng.random((h, w)) < 0.1] = -1.0
        raw[rng.random((h, w)) < 0.1] = np.inf
    msg = depth_message(raw, encoding, step=w * raw.itemsize + 3, big=big)
    cam = camera_from_info(camera_info(w, h, 9.0, 11.0, 3.5, 2.5))
    proj = DepthProjector(cam)
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    T[:3, 3] = rng.uniform(-2, 2, 3)
    pts, codes, centroid = proj.ordered_points(msg, T)
    row_major = proj.points(msg, T)
    order, all_codes = pixel_z_order(h, w)
    valid = np.isfinite(depth_image_metres(msg)).reshape(-1)
    in_z_order = valid[order]
    np.testing.assert_array_equal(codes, all_codes[in_z_order])
    # the k-th valid pixel in Z-order is row rank[k] of the row-major points
    rank = np.cumsum(valid) - 1
    np.testing.assert_array_equal(pts, row_major[rank[order[in_z_order]]])
    assert (np.diff(codes) > 0).all()
    if len(pts):
        np.testing.assert_allclose(centroid, row_major.mean(axis=0), rtol=0, atol=1e-12)
