"""Frames on the wire: the size-checked msgpack envelope, encoding and decoding of
requests (with their raw data frames) and replies, and the hand-checked fast path of
the per-tick msgpack messages (the binary ticks are :mod:`~reachwise.server.protocol.tick`)."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import msgpack
import numpy as np
from numpy.typing import NDArray

from reachwise.server.protocol.fields import (
    DEFAULT_LIMITS,
    FLOAT,
    MAX_LIST,
    MAX_NAME_LENGTH,
    PROTOCOL_VERSION,
    SUPPORTED_VERSIONS,
    Buffer,
    ErrorCode,
    Limits,
    ProtocolError,
    Reader,
    check_depth,
    check_text,
    safe_repr,
)
from reachwise.server.protocol.replies import (
    CLOUD_COLUMNS,
    ROW_COLUMNS,
    ErrorReply,
    QueryReply,
    Reply,
)
from reachwise.server.protocol.requests import (
    REQUESTS,
    Query,
    Request,
    SetJoints,
)

# --------------------------------------------------------------------------- envelopes


def _unpack(raw: bytes | memoryview, limits: Limits) -> object:
    """msgpack-decode ``raw`` after checking its size; every decoder failure is a
    :class:`ProtocolError` (``bad_message`` / ``too_large``)."""
    n = len(raw)
    if n > limits.max_message_bytes:
        raise ProtocolError(
            ErrorCode.TOO_LARGE,
            "message",
            f"{n} bytes exceed the cap of {limits.max_message_bytes}",
        )
    if n == 0:
        raise ProtocolError(ErrorCode.BAD_MESSAGE, "message", "empty frame")
    try:
        obj = msgpack.unpackb(
            raw,
            raw=False,
            use_list=True,
            strict_map_key=True,
            max_str_len=limits.max_message_bytes,
            max_bin_len=limits.max_message_bytes,
            max_array_len=MAX_LIST,
            max_map_len=MAX_LIST,
            max_ext_len=0,
        )
    except Exception as exc:  # msgpack raises ValueError, TypeError, OverflowError …
        raise ProtocolError(
            ErrorCode.BAD_MESSAGE, "message", f"not a valid msgpack message: {type(exc).__name__}"
        ) from None
    check_depth(obj)
    return obj


def _envelope(obj: object, keys: frozenset[str]) -> tuple[dict[str, Any], int | None]:
    if not isinstance(obj, dict):
        raise ProtocolError(ErrorCode.BAD_MESSAGE, "message", "expected a map {v, id, op, body}")
    rid = obj.get("id")
    rid_ok = rid if type(rid) is int and 0 <= rid < 2**63 else None
    v = obj.get("v")
    if type(v) is not int:
        raise ProtocolError(ErrorCode.BAD_MESSAGE, "v", "missing or not an integer", rid_ok)
    if v not in SUPPORTED_VERSIONS:
        raise ProtocolError(
            ErrorCode.UNSUPPORTED_VERSION,
            "v",
            f"version {v} not spoken; this side speaks {list(SUPPORTED_VERSIONS)}",
            rid_ok,
        )
    if obj.keys() <= keys:
        return obj, rid_ok
    extra = sorted(str(k) for k in obj if k not in keys)
    if extra:
        raise ProtocolError(
            ErrorCode.UNKNOWN_FIELD,
            extra[0],
            f"unknown envelope field; known: {sorted(keys)}",
            rid_ok,
        )
    return obj, rid_ok


_REQUEST_KEYS = frozenset({"v", "id", "op", "body"})
_REPLY_KEYS = frozenset({"v", "id", "ok", "body", "error"})


def encode_request(request_id: int, request: Request) -> bytes:
    """The envelope frame of a request (the whole request unless it has data frames:
    :func:`encode_frames`)."""
    return msgpack.packb(
        {"v": PROTOCOL_VERSION, "id": request_id, "op": request.OP, "body": request.body()},
        use_bin_type=True,
    )


def encode_frames(request_id: int, request: Request) -> list[Buffer]:
    """Every frame of a request: the envelope, then its data frames (views of the
    request's arrays, not copies: send them with ``copy=False``)."""
    return [encode_request(request_id, request), *request.data()]


# --------------------------------------------------------------------------- hot path
#
# The per-tick messages (a query with the joint states it carries, its reply, a joint
# state) are checked by hand here, without the field-by-field machinery above: the
# fast checks accept only the common, plainly valid shape and build exactly the object
# the full parser would; anything else (an error, an optional field, a rare form)
# returns None and goes through the full parser, which gives the typed error.

_F8 = np.dtype(FLOAT)
_QUERY_FAST_KEYS = frozenset({"stamp", "joints", "layout"})
_SET_JOINTS_FAST_KEYS = frozenset({"robot", "q", "stamp"})
_QUERY_REPLY_FAST_KEYS = frozenset({"sequence", "measured_at", "compute_time", "layout", "rows"})
_QUERY_REPLY_CLOUD_KEYS = _QUERY_REPLY_FAST_KEYS | {"clouds"}


def _fast_name(v: object) -> bool:
    return type(v) is str and 0 < len(v) <= MAX_NAME_LENGTH and v.isprintable()


def _fast_stamp(v: object) -> bool:
    return v is None or (type(v) is float and math.isfinite(v)) or type(v) is int


def _fast_vector(v: object) -> NDArray[np.float64] | None:
    """A finite float64 vector ``[dtype, [n], bytes]``, or None (let the full check decide)."""
    if type(v) is not list or len(v) != 3:
        return None
    dt, shp, data = v
    if dt != FLOAT or type(shp) is not list or len(shp) != 1 or type(data) is not bytes:
        return None
    n = shp[0]
    if type(n) is not int or n < 0 or len(data) != 8 * n:
        return None
    arr = np.frombuffer(data, dtype=_F8)
    if not all(map(math.isfinite, arr.tolist())):
        return None
    return arr


def _fast_query(body: object) -> Query | None:
    if type(body) is not dict or not body.keys() <= _QUERY_FAST_KEYS:
        return None
    stamp = body.get("stamp")
    layout = body.get("layout")
    joints = body.get("joints")
    if not _fast_stamp(stamp) or not (layout is None or type(layout) is str):
        return None
    if layout is not None and len(layout) > MAX_NAME_LENGTH:
        return None
    arrays = None
    if joints is not None:
        if type(joints) is not dict or len(joints) > MAX_LIST:
            return None
        arrays = {}
        for name, item in joints.items():
            q = _fast_vector(item)
            if q is None or not _fast_name(name):
                return None
            arrays[name] = q
    return Query(None if stamp is None else float(stamp), arrays, None, None, layout)


def _fast_set_joints(body: object) -> SetJoints | None:
    if type(body) is not dict or not body.keys() <= _SET_JOINTS_FAST_KEYS:
        return None
    robot = body.get("robot")
    stamp = body.get("stamp")
    q = _fast_vector(body.get("q"))
    if q is None or not _fast_name(robot) or not _fast_stamp(stamp):
        return None
    return SetJoints(robot, q, None if stamp is None else float(stamp))  # type: ignore[arg-type]


_FAST_REQUESTS: dict[str, Callable[[object], Request | None]] = {
    "query": _fast_query,
    "set_joints": _fast_set_joints,
}


def _fast_clouds(v: object) -> NDArray[np.float64] | None:
    """A cloud table ``[dtype, [m, 2], bytes]`` with whole versions >= 0, or None."""
    if type(v) is not list or len(v) != 3:
        return None
    dt, shp, data = v
    if dt != FLOAT or type(shp) is not list or len(shp) != 2 or type(data) is not bytes:
        return None
    m, c = shp
    if type(m) is not int or m < 0 or c != CLOUD_COLUMNS or len(data) != 8 * CLOUD_COLUMNS * m:
        return None
    arr = np.frombuffer(data, dtype=_F8).reshape(m, CLOUD_COLUMNS)
    ver = arr[:, 0]
    if not bool(np.all((ver >= 0.0) & (ver == np.floor(ver)) & (ver < 2.0**53))):
        return None
    return arr


def _fast_query_reply(body: object) -> QueryReply | None:
    if type(body) is not dict:
        return None
    keys = body.keys()
    if keys == _QUERY_REPLY_CLOUD_KEYS:
        clouds = _fast_clouds(body["clouds"])
        if clouds is None:
            return None
    elif keys == _QUERY_REPLY_FAST_KEYS:
        clouds = None
    else:
        return None
    seq, measured, compute, layout, rows = (
        body["sequence"],
        body["measured_at"],
        body["compute_time"],
        body["layout"],
        body["rows"],
    )
    if type(seq) is not int or seq < 0 or type(measured) is not float or type(compute) is not float:
        return None
    if not (math.isfinite(measured) and math.isfinite(compute) and compute >= 0.0):
        return None
    if type(layout) is not str or len(layout) > MAX_NAME_LENGTH:
        return None
    if type(rows) is not list or len(rows) != 3:
        return None
    dt, shp, data = rows
    if dt != FLOAT or type(shp) is not list or len(shp) != 2 or type(data) is not bytes:
        return None
    n, m = shp
    if type(n) is not int or n < 0 or m != ROW_COLUMNS or len(data) != 8 * ROW_COLUMNS * n:
        return None
    arr = np.frombuffer(data, dtype=_F8).reshape(n, ROW_COLUMNS)
    for ia, ib, flag in arr[:, 10:13].tolist():
        if not (ia.is_integer() and ib.is_integer() and ia >= -1.0 and ib >= -1.0):
            return None
        if flag != 0.0 and flag != 1.0:
            return None
    return QueryReply(seq, measured, compute, layout, None, arr, clouds=clouds)


def decode_request(raw: bytes | memoryview, limits: Limits = DEFAULT_LIMITS) -> tuple[int, Request]:
    """Check and decode a request of one frame; raises :class:`ProtocolError` (with the
    request id when it could be read)."""
    return decode_frames([raw], limits)


def decode_frames(frames: Sequence[Buffer], limits: Limits = DEFAULT_LIMITS) -> tuple[int, Request]:
    """Check and decode the body frames of one request: the msgpack envelope and as
    many data frames as its op takes (:attr:`Request.DATA_FRAMES`); raises
    :class:`ProtocolError` (with the request id when it could be read)."""
    if not frames:
        raise ProtocolError(ErrorCode.BAD_MESSAGE, "frames", "no body frame")
    raw, data = frames[0], frames[1:]
    total = sum(len(f) if isinstance(f, bytes) else f.nbytes for f in frames)
    if total > limits.max_message_bytes:
        raise ProtocolError(
            ErrorCode.TOO_LARGE,
            "message",
            f"{total} bytes exceed the cap of {limits.max_message_bytes}",
        )
    obj, rid = _envelope(_unpack(raw, limits), _REQUEST_KEYS)
    if rid is None:
        raise ProtocolError(ErrorCode.BAD_MESSAGE, "id", "missing or not an integer in [0, 2**63)")
    op = obj.get("op")
    fast = _FAST_REQUESTS.get(op) if type(op) is str and not data else None
    if fast is not None:
        req_fast = fast(obj.get("body"))
        if req_fast is not None:
            return rid, req_fast
    cls = REQUESTS.get(op) if isinstance(op, str) else None
    if cls is None:
        raise ProtocolError(
            ErrorCode.UNKNOWN_OP,
            "op",
            f"unknown op {safe_repr(op)}; known: {sorted(REQUESTS)}",
            rid,
        )
    if len(data) != cls.DATA_FRAMES:
        raise ProtocolError(
            ErrorCode.BAD_MESSAGE,
            "frames",
            f"{op} takes {cls.DATA_FRAMES} data frame(s) after its header, got {len(data)}",
            rid,
        )
    if "body" not in obj:
        raise ProtocolError(ErrorCode.MISSING_FIELD, "body", "required field is missing", rid)
    try:
        r = Reader(obj["body"])
        req = cls.parse_frames(r, limits, data) if data else cls.parse(r, limits)
        r.done()
    except ProtocolError as exc:
        exc.request_id = rid
        raise
    return rid, req


def encode_reply(request_id: int | None, reply: Reply) -> bytes:
    """One success reply frame."""
    return msgpack.packb(
        {"v": PROTOCOL_VERSION, "id": request_id, "ok": True, "body": reply.body()},
        use_bin_type=True,
    )


def encode_error(request_id: int | None, error: ErrorReply) -> bytes:
    """One typed error reply frame."""
    return msgpack.packb(
        {
            "v": PROTOCOL_VERSION,
            "id": request_id,
            "ok": False,
            "error": {"code": error.code.value, "field": error.field, "message": error.message},
        },
        use_bin_type=True,
    )


@dataclass(frozen=True)
class DecodedReply:
    """A decoded reply frame: its request ``id`` and either ``reply`` or ``error``."""

    request_id: int | None
    reply: Reply | None = None
    error: ErrorReply | None = None


def decode_reply(
    raw: bytes | memoryview, reply_type: type[Reply], limits: Limits = DEFAULT_LIMITS
) -> DecodedReply:
    """Check and decode one reply frame expected to carry ``reply_type``."""
    obj, rid = _envelope(_unpack(raw, limits), _REPLY_KEYS)
    if "id" not in obj or (obj["id"] is not None and rid is None):
        raise ProtocolError(ErrorCode.BAD_MESSAGE, "id", "missing or not an integer or nil")
    ok = obj.get("ok")
    if ok is True:
        if "error" in obj:
            raise ProtocolError(ErrorCode.BAD_MESSAGE, "error", "a success reply carries no error")
        if reply_type is QueryReply:
            rep_fast = _fast_query_reply(obj.get("body"))
            if rep_fast is not None:
                return DecodedReply(rid, reply=rep_fast)
        r = Reader(obj.get("body"), "body")
        rep = reply_type.parse(r)
        r.done()
        return DecodedReply(rid, reply=rep)
    if ok is False:
        if "body" in obj:
            raise ProtocolError(ErrorCode.BAD_MESSAGE, "body", "an error reply carries no body")
        e = Reader(obj.get("error"), "error")
        code_s = check_text(e.get("code"), e.path("code"), 64)
        try:
            code = ErrorCode(code_s)
        except ValueError:
            raise ProtocolError(
                ErrorCode.BAD_MESSAGE, e.path("code"), f"unknown error code {safe_repr(code_s)}"
            ) from None
        err = ErrorReply(
            code,
            check_text(e.get("field"), e.path("field")),
            check_text(e.get("message"), e.path("message")),
        )
        e.done()
        return DecodedReply(rid, error=err)
    raise ProtocolError(ErrorCode.BAD_MESSAGE, "ok", "missing or not a boolean")
