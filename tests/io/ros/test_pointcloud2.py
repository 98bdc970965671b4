"""PointCloud2 decoding against a brute-force per-point decoder (struct, one value at a
time): any field layout, padded points and rows, both byte orders, organized and
non-dense clouds; and the messages that contradict themselves."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from reachwise.io.ros.pointcloud2 import pointcloud2_array, pointcloud2_dtype, pointcloud2_points
from reachwise.io.ros.recording_error import RecordingError
from tests.io.ros._messages import SIZE, brute_points, cloud_message, field

_RANGES = {
    1: (-128, 127),
    2: (0, 255),
    3: (-3000, 3000),
    4: (0, 6000),
    5: (-9000, 9000),
    6: (0, 9000),
}


@st.composite
def clouds(draw: st.DrawFn) -> object:
    types = {c: draw(st.sampled_from([1, 2, 3, 4, 5, 6, 7, 8])) for c in "xyz"}
    extra = draw(st.booleans())
    names = ["x", "y", "z", *(["intensity"] if extra else [])]
    if extra:
        types["intensity"] = draw(st.sampled_from([2, 7]))
    order = draw(st.permutations(names))
    offset, fields = 0, []
    for name in order:
        offset += draw(st.integers(0, 3))  # gaps between fields
        fields.append(field(name, offset, types[name]))
        offset += SIZE[types[name]]
    point_step = offset + draw(st.integers(0, 5))
    height = draw(st.integers(1, 4))
    width = draw(st.integers(0, 6))
    row_step = width * point_step + draw(st.integers(0, 9)) * (height > 1)
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    values = {}
    for name in names:
        dt = types[name]
        if dt in _RANGES:
            lo, hi = _RANGES[dt]
            values[name] = rng.integers(lo, hi + 1, (height, width))
        else:
            v = rng.uniform(-5, 5, (height, width))
            values[name] = v.astype(np.float32).astype(np.float64) if dt == 7 else v
    dense = draw(st.booleans())
    if not dense and types["x"] in (7, 8) and width > 0:
        holes = rng.random((height, width)) < 0.3
        values["x"][holes] = np.nan
    msg = cloud_message(
        values,
        fields,
        height=height,
        width=width,
        point_step=point_step,
        row_step=row_step,
        big=draw(st.booleans()),
        dense=dense,
    )
    return msg


@settings(max_examples=150, deadline=None)
@given(clouds())
def test_points_equal_the_brute_force_decoder(msg: object) -> None:
    expected = np.array(brute_points(msg), dtype=np.float64).reshape(-1, 3)
    got = pointcloud2_points(msg)
    finite = np.isfinite(expected).all(axis=1)
    np.testing.assert_array_equal(got, expected[finite])
    organized = pointcloud2_points(msg, organized=True)
    assert organized.shape == (msg.height, msg.width, 3)  # type: ignore[attr-defined]
    np.testing.assert_array_equal(organized.reshape(-1, 3), expected)


def test_organized_cloud_keeps_pixel_positions() -> None:
    h, w = 3, 4
    v, u = np.mgrid[0:h, 0:w]
    values = {"x": u.astype(float), "y": v.astype(float), "z": (10 * v + u).astype(float)}
    fields = [field("x", 0, 8), field("y", 8, 8), field("z", 16, 8)]
    msg = cloud_message(
        values,
        fields,
        height=h,
        width=w,
        point_step=24,
        row_step=24 * w + 16,
        big=False,
        dense=True,
    )
    pts = pointcloud2_points(msg, organized=True)
    # pixel (v, u) at [v, u], not transposed (the mistake of reshaping (width, height))
    assert pts[2, 1].tolist() == [1.0, 2.0, 21.0]
    assert pts[0, 3].tolist() == [3.0, 0.0, 3.0]


def test_padded_rows_are_skipped() -> None:
    """Row padding is not read as points: 2 rows of 2 points, 8 bytes of padding each."""
    values = {c: np.array([[1.0, 2.0], [3.0, 4.0]]) * (j + 1) for j, c in enumerate("xyz")}
    fields = [field("x", 0, 7), field("y", 4, 7), field("z", 8, 7)]
    msg = cloud_message(
        values, fields, height=2, width=2, point_step=12, row_step=32, big=False, dense=True
    )
    np.testing.assert_array_equal(
        pointcloud2_points(msg), [[1, 2, 3], [2, 4, 6], [3, 6, 9], [4, 8, 12]]
    )


def test_all_fields_as_a_structured_array() -> None:
    fields = [field("x", 0, 7), field("y", 4, 7), field("z", 8, 7), field("intensity", 12, 2)]
    values = {
        "x": np.ones((1, 2)),
        "y": np.zeros((1, 2)),
        "z": np.ones((1, 2)),
        "intensity": np.array([[7, 9]]),
    }
    msg = cloud_message(
        values, fields, height=1, width=2, point_step=16, row_step=32, big=True, dense=True
    )
    arr = pointcloud2_array(msg)
    assert arr.shape == (1, 2)
    assert arr["intensity"].tolist() == [[7, 9]]


def test_count_gives_a_sub_array() -> None:
    dt = pointcloud2_dtype([field("x", 0, 7), field("n", 4, 7, count=3)], 16, False)
    assert dt.itemsize == 16
    assert dt["n"].shape == (3,)


def _msg(**over: object) -> object:
    values = {c: np.zeros((1, 2)) for c in "xyz"}
    fields = [field("x", 0, 7), field("y", 4, 7), field("z", 8, 7)]
    msg = cloud_message(
        values, fields, height=1, width=2, point_step=12, row_step=24, big=False, dense=True
    )
    for k, v in over.items():
        setattr(msg, k, v)
    return msg


def test_field_beyond_point_step_is_an_error_naming_topic_and_time() -> None:
    with pytest.raises(RecordingError, match=r"/cam/points.*point_step.*t = 1\.5"):
        pointcloud2_points(_msg(point_step=8), topic="/cam/points")


def test_fields_without_xyz_are_an_error() -> None:
    msg = _msg(fields=[field("x", 0, 7), field("y", 4, 7), field("rgb", 8, 7)])
    with pytest.raises(RecordingError, match=r"fields.*no z"):
        pointcloud2_points(msg, topic="/c")


def test_too_few_bytes_is_an_error() -> None:
    with pytest.raises(RecordingError, match="data"):
        pointcloud2_points(_msg(width=3))


def test_unknown_datatype_is_an_error() -> None:
    with pytest.raises(RecordingError, match="datatype"):
        pointcloud2_points(_msg(fields=[field("x", 0, 9), field("y", 4, 7), field("z", 8, 7)]))


def test_short_rows_are_an_error() -> None:
    values = {c: np.zeros((2, 2)) for c in "xyz"}
    fields = [field("x", 0, 7), field("y", 4, 7), field("z", 8, 7)]
    msg = cloud_message(
        values, fields, height=2, width=2, point_step=12, row_step=24, big=False, dense=True
    )
    msg.row_step = 20  # type: ignore[attr-defined]
    with pytest.raises(RecordingError, match="row_step"):
        pointcloud2_points(msg)


def test_dense_cloud_with_nan_is_an_error_not_silent() -> None:
    values = {c: np.zeros((1, 2)) for c in "xyz"}
    values["y"][0, 1] = math.nan
    fields = [field("x", 0, 8), field("y", 8, 8), field("z", 16, 8)]
    msg = cloud_message(
        values, fields, height=1, width=2, point_step=24, row_step=48, big=False, dense=True
    )
    with pytest.raises(RecordingError, match="is_dense"):
        pointcloud2_points(msg)
    msg.is_dense = False  # type: ignore[attr-defined]
    assert pointcloud2_points(msg).tolist() == [[0.0, 0.0, 0.0]]
