"""The per-tick query as one binary frame each way: the fast path of a control loop.

A controller asks the collision server for every watched pair once per tick, at up to
1 kHz, carrying its joint states (P-V Table 1's calculation phase). Through the full
protocol that costs a msgpack map of names and arrays each way and a field-by-field
check of both. Once a client holds the scene's :class:`~reachwise.server.protocol.
layout.Layout` (from one full query reply) the tick needs no names at all:

request (little-endian, 8-byte aligned throughout)::

    header  40 bytes  magic b"RWq\\x01", flags u32 (0), request id u64, layout key u64,
                      stamp f64 (NaN: none), joint entries u32 J, pose entries u32 K
    entries 8 bytes × (J + K): int32 index, int32 value count — J robot entries (index
                      into the layout's robots, count = joint values), then K pose
                      entries (index into its objects, count 16: a 4 x 4 pose)
    values  8 bytes × (sum of the counts): float64, in entry order

reply::

    header  56 bytes  magic b"RWr\\x01", flags u32 (0), request id u64, sequence u64,
                      layout key u64, measured_at f64, compute_time f64, pairs u32 P,
                      objects u32 M
    rows    P x 13 float64: the rows of :class:`~reachwise.server.protocol.replies.
                      QueryReply` in the layout's pair order
    clouds  M x 2 float64: version and stamp of each object's cloud, layout order

Both frames are told from a msgpack message by their first byte (``R``: a msgpack
integer, never a request or reply map). A tick decodes into exactly the
:class:`~reachwise.server.protocol.requests.Query` the full protocol would carry (names
looked up in the layout), so the server answers both through one handler; an error is
an ordinary typed error frame. What a cached layout makes redundant is not checked per
tick: names (indices are range-checked), map keys, the pair list. The values are
checked for finiteness as in the full protocol. Of a reply the client checks the
structure (magic, request id, layout key, counts, length); the numbers are the
server's, read as they are when the result is built.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from reachwise.server.protocol.fields import (
    FLOAT,
    Buffer,
    ErrorCode,
    Limits,
    ProtocolError,
    unchecked,
)
from reachwise.server.protocol.layout import Layout
from reachwise.server.protocol.replies import CLOUD_COLUMNS, ROW_COLUMNS, QueryReply
from reachwise.server.protocol.requests import Query

__all__ = [
    "TICK_MAGIC",
    "TICK_REPLY_MAGIC",
    "decode_tick",
    "decode_tick_reply",
    "encode_tick",
    "encode_tick_inputs",
    "encode_tick_reply",
    "is_tick",
    "is_tick_reply",
    "read_tick",
    "read_tick_reply",
    "tick_reply_frame",
]

TICK_MAGIC = b"RWq\x01"
TICK_REPLY_MAGIC = b"RWr\x01"
_REQUEST = struct.Struct("<4sIQQdII")
_REPLY = struct.Struct("<4sIQQQddII")
_F8 = np.dtype(FLOAT)
#: Values of one pose entry (a 4 x 4 matrix, row-major).
POSE_VALUES = 16


def is_tick(raw: Buffer) -> bool:
    """Whether ``raw`` is (meant to be) a binary tick request."""
    return raw[:4] == TICK_MAGIC


def is_tick_reply(raw: Buffer) -> bool:
    """Whether ``raw`` is (meant to be) a binary tick reply."""
    return raw[:4] == TICK_REPLY_MAGIC


# --------------------------------------------------------------------------- request


def encode_tick(request_id: int, query: Query, layout: Layout) -> bytes | None:
    """``query`` as one tick frame under ``layout``; None when a tick cannot carry it
    (chosen pairs, another layout, a name the layout does not hold, a wrong shape):
    the full protocol then does."""
    if query.pairs is not None or query.layout != layout.name:
        return None
    return encode_tick_inputs(request_id, layout, query.stamp, query.joints, query.poses)


def encode_tick_inputs(
    request_id: int,
    layout: Layout,
    stamp: float | None,
    joints: Mapping[str, NDArray[np.float64]] | None = None,
    poses: Mapping[str, NDArray[np.float64]] | None = None,
) -> bytes | None:
    """The tick frame of a query of every pair under ``layout`` carrying ``joints``
    and ``poses`` (:func:`encode_tick` without making the :class:`Query`: a client's
    per-tick path); None when a tick cannot carry them."""
    if not layout.key:
        return None
    if not joints and not poses:  # the usual tick: the header alone
        return _REQUEST.pack(
            TICK_MAGIC, 0, request_id, layout.key, math.nan if stamp is None else stamp, 0, 0
        )
    entries: list[int] = []
    values: list[bytes] = []
    nj = 0
    if joints:
        index = layout.robot_index
        for name, q in joints.items():
            i = index.get(name)
            if i is None or q.ndim != 1:
                return None
            entries += (i, q.shape[0])
            values.append(q.astype(_F8, copy=False).tobytes())
        nj = len(joints)
    npose = 0
    if poses:
        index = layout.object_index
        for name, pose in poses.items():
            i = index.get(name)
            if i is None or pose.shape != (4, 4):
                return None
            entries += (i, POSE_VALUES)
            values.append(np.ascontiguousarray(pose, dtype=_F8).tobytes())
        npose = len(poses)
    stamp = math.nan if stamp is None else stamp
    head = _REQUEST.pack(TICK_MAGIC, 0, request_id, layout.key, stamp, nj, npose)
    return b"".join((head, _entry_struct(nj + npose).pack(*entries), *values))


def _error(code: ErrorCode, field: str, message: str, rid: int | None) -> ProtocolError:
    return ProtocolError(code, field, message, rid)


def decode_tick(raw: Buffer, layout: Layout, limits: Limits) -> tuple[int, Query]:
    """Check one tick frame against the server's current ``layout`` and give the
    request id and the :class:`Query` it stands for; raises :class:`ProtocolError`."""
    rid, stamp, joints, poses = read_tick(raw, layout, limits)
    query: Query = unchecked(
        Query, stamp=stamp, joints=joints, poses=poses, pairs=None, layout=layout.name
    )
    return rid, query


def read_tick(
    raw: Buffer, layout: Layout, limits: Limits
) -> tuple[
    int, float | None, dict[str, NDArray[np.float64]] | None, dict[str, NDArray[np.float64]] | None
]:
    """:func:`decode_tick` without making the :class:`Query`: the request id, the
    stamp (None: none), the joint states and the poses (None: no entries of that kind),
    every one checked as :func:`decode_tick` checks it (the server's per-tick path)."""
    n = len(raw)
    if n > limits.max_message_bytes:
        raise _error(
            ErrorCode.TOO_LARGE,
            "message",
            f"{n} bytes exceed the cap of {limits.max_message_bytes}",
            None,
        )
    if n < _REQUEST.size:
        raise _error(
            ErrorCode.BAD_MESSAGE, "message", f"a tick has at least {_REQUEST.size} bytes", None
        )
    magic, flags, rid, key, stamp, nj, npose = _REQUEST.unpack_from(raw)
    if magic != TICK_MAGIC:
        raise _error(ErrorCode.BAD_MESSAGE, "message", "not a tick frame", None)
    if rid >= 2**63:
        raise _error(ErrorCode.BAD_MESSAGE, "id", "not an integer in [0, 2**63)", None)
    if flags:
        raise _error(ErrorCode.BAD_MESSAGE, "flags", "reserved flags must be 0", rid)
    if key != layout.key or not key:
        raise _error(
            ErrorCode.STALE_LAYOUT,
            "layout",
            f"layout {key} is not the current one; send the query in full",
            rid,
        )
    if stamp != stamp:  # NaN: no stamp
        stamp = None
    elif math.isinf(stamp):
        raise _error(ErrorCode.NON_FINITE, "body.stamp", f"must be finite, got {stamp!r}", rid)
    if nj or npose:
        joints, poses = _entries(raw, n, rid, nj, npose, layout)
        return rid, stamp, joints, poses
    if n != _REQUEST.size:
        raise _error(ErrorCode.WRONG_SHAPE, "values", "a tick without entries has no values", rid)
    return rid, stamp, None, None


#: ``struct`` formats of the entries of a tick, by entry count.
_ENTRY_STRUCTS: dict[int, struct.Struct] = {}


def _entry_struct(entries: int) -> struct.Struct:
    """The format of ``entries`` entries (int32 index, int32 count each)."""
    fmt = _ENTRY_STRUCTS.get(entries)
    if fmt is None:
        fmt = _ENTRY_STRUCTS[entries] = struct.Struct(f"<{2 * entries}i")
    return fmt


#: Up to this many values are checked for finiteness in Python (numpy below its
#: per-call cost for small arrays).
_SMALL = 64


def _entries(
    raw: Buffer, n: int, rid: int, nj: int, npose: int, layout: Layout
) -> tuple[dict[str, NDArray[np.float64]] | None, dict[str, NDArray[np.float64]] | None]:
    """The joint states and poses of a tick's entries (see :func:`decode_tick`)."""
    if nj > len(layout.robots) or npose > len(layout.objects):
        raise _error(
            ErrorCode.WRONG_SHAPE,
            "entries",
            f"{nj} joint and {npose} pose entries for {len(layout.robots)} robots "
            f"and {len(layout.objects)} objects",
            rid,
        )
    ne = nj + npose
    start = _REQUEST.size + 8 * ne
    if n < start:
        raise _error(ErrorCode.WRONG_SHAPE, "entries", f"{ne} entries need {start} bytes", rid)
    ent = _entry_struct(ne).unpack_from(raw, _REQUEST.size)
    counts = ent[1::2]
    total = sum(counts)
    if min(counts) < 0 or n != start + 8 * total:
        raise _error(
            ErrorCode.WRONG_SHAPE,
            "values",
            f"the frame holds {n - start} value bytes; the entries need {8 * total}",
            rid,
        )
    values = np.frombuffer(raw, dtype=_F8, offset=start)
    finite = (
        all(map(math.isfinite, values.tolist()))
        if total <= _SMALL
        else bool(np.isfinite(values).all())
    )
    if ne == 1 and finite:  # the usual tick: one robot's joint state (or one pose)
        i = ent[0]
        names = layout.objects if npose else layout.robots
        if 0 <= i < len(names):
            if not npose:
                return {names[i]: values}, None
            if total == POSE_VALUES:
                return None, {names[i]: values.reshape(4, 4)}
    return _each_entry(ent, values, finite, nj, rid, layout)


def _each_entry(
    ent: tuple[int, ...],
    values: NDArray[np.float64],
    finite: bool,
    nj: int,
    rid: int,
    layout: Layout,
) -> tuple[dict[str, NDArray[np.float64]] | None, dict[str, NDArray[np.float64]] | None]:
    """Several entries, or an error to name: the joint states and poses entry by entry
    (``ent`` the (index, count) pairs, the first ``nj`` of them joint states; ``finite``
    whether every value is)."""
    ne = len(ent) // 2
    joints: dict[str, NDArray[np.float64]] | None = None
    poses: dict[str, NDArray[np.float64]] | None = None
    off = 0
    for k in range(ne):
        i, c = ent[2 * k], ent[2 * k + 1]
        pose = k >= nj
        names = layout.objects if pose else layout.robots
        if not 0 <= i < len(names):
            raise _error(
                ErrorCode.WRONG_SHAPE,
                f"entries[{k}]",
                f"index {i} outside the layout's {len(names)} {'objects' if pose else 'robots'}",
                rid,
            )
        name = names[i]
        v = values[off : off + c]
        off += c
        if not finite:
            bad = c - int(np.count_nonzero(np.isfinite(v)))
            if bad:
                where = f"body.{'poses' if pose else 'joints'}.{name}"
                raise _error(
                    ErrorCode.NON_FINITE,
                    where,
                    f"{bad} of {c} values are not finite (NaN or inf)",
                    rid,
                )
        if pose:
            if c != POSE_VALUES:
                raise _error(
                    ErrorCode.WRONG_SHAPE,
                    f"body.poses.{name}",
                    f"expected shape (4, 4), got {c} values",
                    rid,
                )
            if poses is None:
                poses = {}
            target = poses
            v = v.reshape(4, 4)
        else:
            if joints is None:
                joints = {}
            target = joints
        if name in target:
            raise _error(ErrorCode.BAD_MESSAGE, f"entries[{k}]", f"{name!r} given twice", rid)
        target[name] = v
    return joints, poses


# --------------------------------------------------------------------------- reply


def encode_tick_reply(request_id: int, reply: QueryReply, layout: Layout) -> bytes:
    """The tick frame of ``reply`` (an answer to every pair of ``layout``)."""
    clouds = reply.clouds
    if clouds is None:
        clouds = np.empty((0, CLOUD_COLUMNS))
    return tick_reply_frame(
        request_id,
        reply.sequence,
        layout.key,
        reply.measured_at,
        reply.compute_time,
        reply.rows,
        clouds.shape[0],
        clouds.astype(_F8, copy=False).tobytes(),
    )


def tick_reply_frame(
    request_id: int,
    sequence: int,
    key: int,
    measured_at: float,
    compute_time: float,
    rows: NDArray[np.float64],
    objects: int,
    clouds: bytes,
) -> bytes:
    """:func:`encode_tick_reply` from the parts of the reply (the server's per-tick
    path: no :class:`QueryReply` made): the (P, 13) ``rows`` and the cloud table of
    ``objects`` rows as its float64 bytes (kept by the server while it holds)."""
    head = _REPLY.pack(
        TICK_REPLY_MAGIC,
        0,
        request_id,
        sequence,
        key,
        measured_at,
        compute_time,
        rows.shape[0],
        objects,
    )
    return b"".join((head, rows.astype(_F8, copy=False).tobytes(), clouds))


def decode_tick_reply(raw: Buffer, layout: Layout) -> tuple[int, QueryReply]:
    """The request id and the :class:`QueryReply` of one tick reply frame, checked
    against the ``layout`` the request was sent under; raises :class:`ProtocolError`."""
    rid, seq, measured, compute, rows, clouds = read_tick_reply(raw, layout)
    return rid, tick_query_reply(layout, seq, measured, compute, rows, clouds)


def tick_query_reply(
    layout: Layout,
    sequence: int,
    measured_at: float,
    compute_time: float,
    rows: NDArray[np.float64],
    clouds: NDArray[np.float64] | None,
) -> QueryReply:
    """The per-tick :class:`QueryReply` under ``layout``: the answer rows and the cloud
    table, no pairs, objects or robots (made without checks: every field is ours)."""
    reply: QueryReply = unchecked(
        QueryReply,
        sequence=sequence,
        measured_at=measured_at,
        compute_time=compute_time,
        layout=layout.name,
        pairs=None,
        rows=rows,
        objects=None,
        robots=None,
        clouds=clouds,
    )
    return reply


def read_tick_reply(
    raw: Buffer, layout: Layout
) -> tuple[int, int, float, float, NDArray[np.float64], NDArray[np.float64]]:
    """:func:`decode_tick_reply` without making the :class:`QueryReply` (a client's
    per-tick path): request id, sequence, measured_at, compute_time, the rows and the
    cloud table (read-only views of ``raw``), checked as :func:`decode_tick_reply`
    checks them."""
    n = len(raw)
    if n < _REPLY.size:
        raise _error(ErrorCode.BAD_MESSAGE, "message", "too short for a tick reply", None)
    magic, flags, rid, seq, key, measured, compute, npairs, nobj = _REPLY.unpack_from(raw)
    if magic != TICK_REPLY_MAGIC or flags:
        raise _error(ErrorCode.BAD_MESSAGE, "message", "not a tick reply frame", None)
    if key != layout.key:
        raise _error(ErrorCode.BAD_MESSAGE, "layout", f"reply under layout {key}", rid)
    if npairs != len(layout.pairs) or nobj != len(layout.objects):
        raise _error(
            ErrorCode.WRONG_SHAPE,
            "message",
            f"{npairs} rows and {nobj} clouds for a layout of {len(layout.pairs)} pairs "
            f"and {len(layout.objects)} objects",
            rid,
        )
    n_rows = ROW_COLUMNS * npairs
    if n != _REPLY.size + 8 * (n_rows + CLOUD_COLUMNS * nobj):
        raise _error(ErrorCode.WRONG_SHAPE, "message", f"{n} bytes do not match the counts", rid)
    if not math.isfinite(measured) or not (math.isfinite(compute) and compute >= 0.0):
        raise _error(ErrorCode.WRONG_TYPE, "message", "bad measured_at or compute_time", rid)
    # read-only views of the frame, each made in one call
    rows = np.ndarray((npairs, ROW_COLUMNS), _F8, raw, _REPLY.size)
    clouds = np.ndarray((nobj, CLOUD_COLUMNS), _F8, raw, _REPLY.size + 8 * n_rows)
    return rid, seq, measured, compute, rows, clouds
