"""Test messages built byte by byte with :mod:`struct`, independent of the decoders."""

from __future__ import annotations

import struct
from types import SimpleNamespace
from typing import Any

import numpy as np

#: PointField datatype -> struct format character.
STRUCT = {1: "b", 2: "B", 3: "h", 4: "H", 5: "i", 6: "I", 7: "f", 8: "d"}
SIZE = {k: struct.calcsize(v) for k, v in STRUCT.items()}


def stamp(t: float) -> SimpleNamespace:
    sec = int(np.floor(t))
    return SimpleNamespace(sec=sec, nanosec=round((t - sec) * 1e9))


def header(t: float, frame: str = "cam") -> SimpleNamespace:
    return SimpleNamespace(stamp=stamp(t), frame_id=frame)


def field(name: str, offset: int, datatype: int, count: int = 1) -> SimpleNamespace:
    return SimpleNamespace(name=name, offset=offset, datatype=datatype, count=count)


def cloud_message(
    values: dict[str, np.ndarray],
    fields: list[SimpleNamespace],
    *,
    height: int,
    width: int,
    point_step: int,
    row_step: int,
    big: bool,
    dense: bool,
    t: float = 1.5,
) -> SimpleNamespace:
    """A PointCloud2 whose points (values[name] of shape (height, width)) are packed one
    value at a time with struct; padding bytes are 0xAB."""
    order = ">" if big else "<"
    data = bytearray(b"\xab" * (row_step * height))
    for v in range(height):
        for u in range(width):
            base = v * row_step + u * point_step
            for f in fields:
                struct.pack_into(
                    order + STRUCT[f.datatype], data, base + f.offset, values[f.name][v, u]
                )
    return SimpleNamespace(
        header=header(t),
        height=height,
        width=width,
        fields=fields,
        is_bigendian=big,
        point_step=point_step,
        row_step=row_step,
        data=np.frombuffer(bytes(data), np.uint8),
        is_dense=dense,
    )


def brute_points(msg: Any) -> list[tuple[float, float, float]]:
    """Every point's x, y, z read one value at a time with struct (row by row)."""
    order = ">" if msg.is_bigendian else "<"
    by_name = {f.name: f for f in msg.fields}
    raw = bytes(msg.data)
    out = []
    for v in range(msg.height):
        for u in range(msg.width):
            base = v * msg.row_step + u * msg.point_step
            out.append(
                tuple(
                    float(
                        struct.unpack_from(
                            order + STRUCT[by_name[c].datatype], raw, base + by_name[c].offset
                        )[0]
                    )
                    for c in "xyz"
                )
            )
    return out


def depth_message(
    raw: np.ndarray, encoding: str, *, step: int, big: bool, t: float = 2.0
) -> SimpleNamespace:
    """A depth Image of ``raw`` (uint16 or float32 pixel values) packed with struct."""
    fmt = (">" if big else "<") + ("H" if encoding in ("16UC1", "mono16") else "f")
    h, w = raw.shape
    data = bytearray(b"\xcd" * (step * h))
    for v in range(h):
        for u in range(w):
            struct.pack_into(fmt, data, v * step + u * struct.calcsize(fmt), raw[v, u])
    return SimpleNamespace(
        header=header(t),
        height=h,
        width=w,
        encoding=encoding,
        is_bigendian=int(big),
        step=step,
        data=np.frombuffer(bytes(data), np.uint8),
    )


def camera_info(w: int, h: int, fx: float, fy: float, cx: float, cy: float) -> SimpleNamespace:
    return SimpleNamespace(
        header=header(2.0), width=w, height=h, k=[fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0]
    )
