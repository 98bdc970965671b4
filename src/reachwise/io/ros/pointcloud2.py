"""``sensor_msgs/PointCloud2`` to arrays.

A PointCloud2 is ``height`` rows of ``width`` points; each point is ``point_step``
bytes holding the ``fields`` (name, byte ``offset``, ``datatype`` 1–8 = int8, uint8,
int16, uint16, int32, uint32, float32, float64, and ``count`` elements), in big-endian
byte order when ``is_bigendian``; each row is ``row_step`` bytes, of which the first
``width · point_step`` hold points and the rest is padding. ``height == 1`` is an
unorganized cloud; ``height > 1`` an organized one (an image of points, row ``v``,
column ``u``). ``is_dense`` false says some points may be invalid (NaN or inf).

The decoding here follows that definition exactly: one numpy structured dtype from the
fields with ``itemsize = point_step``, rows read ``row_step`` apart so that padding is
skipped (the ROS reference ``read_points`` ignores it), organized clouds kept as
``(height, width)`` where asked, and non-finite points dropped from unorganized output
when ``is_dense`` is false. A message that contradicts itself (fields beyond
``point_step``, rows shorter than their points, too few bytes, non-finite points in a
cloud marked dense) raises :class:`~reachwise.io.ros.recording_error.RecordingError`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from reachwise.io.ros.recording_error import RecordingError
from reachwise.io.ros.stamps import header_stamp

__all__ = ["DATATYPES", "pointcloud2_array", "pointcloud2_dtype", "pointcloud2_points"]

#: ``sensor_msgs/PointField`` datatype codes and their numpy types.
DATATYPES: dict[int, str] = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}


def _stamp(msg: Any) -> float | None:
    try:
        return header_stamp(msg)
    except AttributeError:
        return None


def pointcloud2_dtype(
    fields: Any,
    point_step: int,
    is_bigendian: bool,
    *,
    topic: str = "PointCloud2",
    t: float | None = None,
) -> np.dtype[np.void]:
    """The structured dtype of one point: every field of ``fields`` (objects with
    ``name``, ``offset``, ``datatype``, ``count``) at its offset, ``itemsize =
    point_step``, in the message's byte order; a field of ``count > 1`` is a
    sub-array. ``topic`` and ``t`` (s) go into the errors."""
    step = int(point_step)
    if step <= 0:
        raise RecordingError(topic, t, "point_step", f"must be positive, got {step}")
    order = ">" if is_bigendian else "<"
    names: list[str] = []
    formats: list[Any] = []
    offsets: list[int] = []
    for f in fields:
        name = str(f.name)
        code = DATATYPES.get(int(f.datatype))
        if code is None:
            raise RecordingError(
                topic, t, f"fields.{name}.datatype", f"must be 1..8, got {int(f.datatype)}"
            )
        count = int(f.count)
        if count < 1:
            raise RecordingError(topic, t, f"fields.{name}.count", f"must be >= 1, got {count}")
        if name in names:
            raise RecordingError(topic, t, f"fields.{name}", "appears twice")
        offset = int(f.offset)
        end = offset + np.dtype(code).itemsize * count
        if offset < 0 or end > step:
            raise RecordingError(
                topic,
                t,
                "point_step",
                f"field {name!r} spans bytes {offset}..{end} of a {step}-byte point",
            )
        names.append(name)
        formats.append(order + code if count == 1 else (order + code, (count,)))
        offsets.append(offset)
    return np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": step})


def pointcloud2_array(msg: Any, *, topic: str = "PointCloud2") -> NDArray[np.void]:
    """Every point of ``msg`` with all its fields: a structured array of shape
    ``(height, width)`` (a view of the message's bytes; row padding skipped)."""
    t = _stamp(msg)
    dtype = pointcloud2_dtype(msg.fields, msg.point_step, msg.is_bigendian, topic=topic, t=t)
    h, w = int(msg.height), int(msg.width)
    step, row = dtype.itemsize, int(msg.row_step)
    if h < 0 or w < 0:
        raise RecordingError(topic, t, "width", f"height {h} and width {w} must be >= 0")
    if h > 1 and row < w * step:
        raise RecordingError(
            topic, t, "row_step", f"{row} bytes hold fewer than width·point_step = {w * step}"
        )
    data = np.frombuffer(memoryview(msg.data).cast("B"), dtype=np.uint8)
    need = 0 if h * w == 0 else (h - 1) * row + w * step
    if data.size < need:
        raise RecordingError(topic, t, "data", f"has {data.size} bytes, {h}×{w} points need {need}")
    if h * w == 0:
        return np.zeros((h, w), dtype)
    return np.ndarray(
        (h, w), dtype=dtype, buffer=data, offset=0, strides=(row if h > 1 else w * step, step)
    )


def pointcloud2_points(
    msg: Any,
    *,
    organized: bool = False,
    topic: str = "PointCloud2",
    dtype: type[np.floating[Any]] = np.float64,
) -> NDArray[np.floating[Any]]:
    """The ``x``, ``y``, ``z`` of every point of ``msg`` in its ``header.frame_id``.

    ``organized=False``: ``(N, 3)``, row by row, without the non-finite points when
    ``is_dense`` is false. ``organized=True``: ``(height, width, 3)``, invalid points
    kept as they are (NaN), so pixel ``(v, u)`` stays at ``[v, u]``. ``dtype`` of the
    output (float64, or float32 to halve the memory)."""
    t = _stamp(msg)
    names = {str(f.name): f for f in msg.fields}
    missing = [c for c in "xyz" if c not in names]
    if missing:
        raise RecordingError(
            topic, t, "fields", f"no {', '.join(missing)} field (has {sorted(names)})"
        )
    for c in "xyz":
        if int(names[c].count) != 1:
            raise RecordingError(topic, t, f"fields.{c}.count", "must be 1")
    arr = pointcloud2_array(msg, topic=topic)
    out = np.empty((*arr.shape, 3), dtype)
    for j, c in enumerate("xyz"):
        out[..., j] = arr[c]
    if organized:
        return out
    flat = out.reshape(-1, 3)
    finite = np.isfinite(flat).all(axis=1)
    if finite.all():
        return flat
    if bool(msg.is_dense):
        bad = int(np.flatnonzero(~finite)[0])
        raise RecordingError(
            topic, t, "is_dense", f"is true but point {bad} is not finite ({flat[bad].tolist()})"
        )
    return flat[finite]
