"""The building blocks of every message: limits, error codes, and the checks of
arrays, scalars and maps that turn a bad field into a typed :class:`ProtocolError`."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import ReachwiseError

#: Version of this message schema; a request with another ``v`` is refused.
PROTOCOL_VERSION = 1
#: Versions this implementation speaks (the ``hello`` exchange reports them).
SUPPORTED_VERSIONS: tuple[int, ...] = (1,)
#: Default size cap of one message (bytes): 2 M points of float64 fit.
MAX_MESSAGE_BYTES = 64 * 2**20
#: Default cap on the points of one cloud (P-V: 1000 per part, ≈5500 per scan).
MAX_CLOUD_POINTS = 2_000_000
#: Longest accepted object, robot or kind name (characters).
MAX_NAME_LENGTH = 200
#: Most joints a registered robot may have.
MAX_ROBOT_JOINTS = 64
#: Deepest nesting and most nodes of a robot mapping.
MAX_MODEL_DEPTH = 12
MAX_MODEL_NODES = 20_000
#: Most names in one list (pairs to query, objects to pair with, exclusions).
MAX_LIST = 100_000
#: Deepest nesting of lists and maps in one message (the deepest valid one, a robot
#: mapping inside a request, is :data:`MAX_MODEL_DEPTH` + 2 levels).
MAX_DEPTH = 32
#: Longest field path and message of an error reply (characters; longer ones are cut).
MAX_FIELD_LENGTH = 300
MAX_ERROR_LENGTH = 2000

FLOAT = "<f8"
INT = "<i8"
BOOL = "|b1"

Body = dict[str, Any]
#: One ZeroMQ frame's memory: bytes, or a view of a frame or an array (no copy).
Buffer = bytes | memoryview


class ErrorCode(StrEnum):
    """Codes of typed error replies."""

    BAD_MESSAGE = "bad_message"  # not msgpack, not a map, bad envelope or frames
    TOO_LARGE = "too_large"  # the frame exceeds the message size cap
    UNSUPPORTED_VERSION = "unsupported_version"
    UNKNOWN_OP = "unknown_op"
    MISSING_FIELD = "missing_field"
    UNKNOWN_FIELD = "unknown_field"
    WRONG_TYPE = "wrong_type"
    WRONG_SHAPE = "wrong_shape"
    NON_FINITE = "non_finite"
    OVERSIZED_CLOUD = "oversized_cloud"
    UNKNOWN_ID = "unknown_id"  # no robot or object of that name
    UNKNOWN_PAIR = "unknown_pair"  # the pair is not watched
    EXISTS = "exists"  # a robot or object of that name is already registered
    INVALID = "invalid"  # well-formed but rejected by the scene (bad robot file, pose …)
    NOT_READY = "not_ready"  # the server is still restoring its state
    STALE_LAYOUT = "stale_layout"  # a binary tick names a layout the server no longer has
    INTERNAL = "internal"  # a server fault; the server keeps serving


#: Codes caused by the request's content (the client raises an ``InputError`` for them).
INPUT_CODES = frozenset(
    {
        ErrorCode.TOO_LARGE,
        ErrorCode.MISSING_FIELD,
        ErrorCode.UNKNOWN_FIELD,
        ErrorCode.WRONG_TYPE,
        ErrorCode.WRONG_SHAPE,
        ErrorCode.NON_FINITE,
        ErrorCode.OVERSIZED_CLOUD,
        ErrorCode.UNKNOWN_ID,
        ErrorCode.UNKNOWN_PAIR,
        ErrorCode.EXISTS,
        ErrorCode.INVALID,
    }
)


class ProtocolError(ReachwiseError):
    """A message that breaks the protocol: ``code``, the offending ``field`` (a dotted
    path such as ``body.cloud`` or ``body.joints.crane``) and a ``message``.

    ``request_id`` is the request's ``id`` when it could be read (echoed in the reply).
    """

    def __init__(
        self, code: ErrorCode, field: str, message: str, request_id: int | None = None
    ) -> None:
        self.code = ErrorCode(code)
        self.field = _cut(field, MAX_FIELD_LENGTH)
        self.message = _cut(message, MAX_ERROR_LENGTH)
        self.request_id = request_id
        where = f" ({self.field})" if self.field else ""
        super().__init__(f"{self.code.value}{where}: {self.message}")


def _cut(text: str, limit: int) -> str:
    """``text`` cut to ``limit`` characters (an ellipsis marks the cut)."""
    return text if len(text) <= limit else text[: limit - 1] + "…"


def failure_text(exc: BaseException) -> str:
    """``"<type>: <message>"`` of an unexpected failure for an error reply, bounded
    (:data:`MAX_ERROR_LENGTH`); an exception whose ``str`` fails itself gives its type."""
    try:
        text = str(exc)
    except Exception:
        text = "(its message could not be formatted)"
    return _cut(f"{type(exc).__name__}: {_cut(text, MAX_ERROR_LENGTH)}", MAX_ERROR_LENGTH)


def safe_repr(value: object, limit: int = 60) -> str:
    """A bounded description of a value received from the wire, for an error message:
    the ``repr`` of a scalar cut to ``limit`` characters, the kind and length of a
    container or binary (never its contents: a nested value could be deep or huge)."""
    if isinstance(value, list | dict | tuple):
        return f"{_kind(value)} of {len(value)} entries"
    if isinstance(value, bytes | bytearray | memoryview):
        return f"binary data of {len(value)} bytes"
    if isinstance(value, str):
        return repr(_cut(value, limit))
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 128:
        return f"an integer of {value.bit_length()} bits"
    if value is None or isinstance(value, bool | int | float):
        return _cut(repr(value), limit)
    return _kind(value)


def check_depth(obj: object, limit: int = MAX_DEPTH) -> None:
    """Refuse a decoded message whose lists and maps nest deeper than ``limit`` levels
    (:attr:`ErrorCode.BAD_MESSAGE`), before anything walks or formats it recursively.
    Walks level by level without recursion; every node is visited once."""
    level = [obj] if type(obj) is dict or type(obj) is list else []
    depth = 0
    while level:
        depth += 1
        if depth > limit:
            raise ProtocolError(
                ErrorCode.BAD_MESSAGE, "message", f"lists and maps nest deeper than {limit} levels"
            )
        inner = []
        for v in level:
            for x in v.values() if type(v) is dict else v:
                if type(x) is dict or type(x) is list:
                    inner.append(x)
        level = inner


@dataclass(frozen=True)
class Limits:
    """Caps checked while decoding: message size (bytes) and points per cloud."""

    max_message_bytes: int = MAX_MESSAGE_BYTES
    max_cloud_points: int = MAX_CLOUD_POINTS

    def __post_init__(self) -> None:
        if self.max_message_bytes < 1024:
            raise ValueError(f"max_message_bytes must be >= 1024, got {self.max_message_bytes}")
        if self.max_cloud_points < 1:
            raise ValueError(f"max_cloud_points must be >= 1, got {self.max_cloud_points}")


DEFAULT_LIMITS = Limits()


# --------------------------------------------------------------------------- arrays


_DTYPES = {name: np.dtype(name) for name in (FLOAT, INT, BOOL)}


def encode_array(a: NDArray[Any], dtype: str = FLOAT) -> list[Any]:
    """``[dtype, shape, bytes]`` of ``a`` converted to ``dtype`` (C order)."""
    arr = np.ascontiguousarray(a, dtype=_DTYPES[dtype])
    return [dtype, list(arr.shape), arr.tobytes()]


def _fmt_shape(shape: Sequence[int | None]) -> str:
    inner = ", ".join("N" if s is None else str(s) for s in shape)
    return f"({inner},)" if len(shape) == 1 else f"({inner})"


def _shape_text(shp: object) -> str:
    """A received shape for an error message: its entries when they are a few plain
    scalars, else :func:`safe_repr`."""
    if type(shp) is list and len(shp) <= 8 and all(not isinstance(s, list | dict) for s in shp):
        return "[" + ", ".join(safe_repr(s, 24) for s in shp) + "]"
    return safe_repr(shp)


def check_array(
    value: object,
    where: str,
    *,
    shape: tuple[int | None, ...],
    dtype: str = FLOAT,
    finite: bool = True,
    max_rows: int | None = None,
) -> NDArray[Any]:
    """Decode and check one ``[dtype, shape, bytes]`` array (read-only, no copy).

    ``shape`` entries that are ``None`` are free; ``max_rows`` caps the first one
    (:attr:`ErrorCode.OVERSIZED_CLOUD`). ``finite`` rejects NaN and inf.
    """
    if not isinstance(value, list) or len(value) != 3:
        raise ProtocolError(
            ErrorCode.WRONG_TYPE, where, "expected an array as [dtype, shape, bytes]"
        )
    dt, shp, data = value
    if dt != dtype:
        raise ProtocolError(
            ErrorCode.WRONG_TYPE, where, f"dtype {safe_repr(dt)} not accepted; send {dtype!r}"
        )
    ok = type(shp) is list and len(shp) == len(shape)
    if ok:
        for s, w in zip(shp, shape, strict=True):
            if type(s) is not int or s < 0 or (w is not None and s != w):
                ok = False
                break
    if not ok:
        raise ProtocolError(
            ErrorCode.WRONG_SHAPE,
            where,
            f"expected shape {_fmt_shape(shape)}, got {_shape_text(shp)}",
        )
    if max_rows is not None and shp[0] > max_rows:
        raise ProtocolError(
            ErrorCode.OVERSIZED_CLOUD, where, f"{shp[0]} points exceed the cap of {max_rows}"
        )
    if not isinstance(data, bytes):
        raise ProtocolError(ErrorCode.WRONG_TYPE, where, "array data must be binary")
    dt_ = _DTYPES[dtype]
    count = math.prod(shp)
    itemsize = dt_.itemsize
    if len(data) != count * itemsize:
        raise ProtocolError(
            ErrorCode.WRONG_SHAPE,
            where,
            f"data holds {len(data)} bytes; shape {tuple(shp)} of {dtype} needs {count * itemsize}",
        )
    arr = np.frombuffer(data, dtype=dt_).reshape(shp)
    if finite and dtype == FLOAT:
        bad = count - int(np.count_nonzero(np.isfinite(arr)))
        if bad:
            raise ProtocolError(
                ErrorCode.NON_FINITE, where, f"{bad} of {count} values are not finite (NaN or inf)"
            )
    return arr


# --------------------------------------------------------------------------- scalars


def check_name(value: object, where: str) -> str:
    """A non-empty name of at most :data:`MAX_NAME_LENGTH` printable characters."""
    if not isinstance(value, str):
        raise ProtocolError(
            ErrorCode.WRONG_TYPE, where, f"expected a name (string), got {_kind(value)}"
        )
    if not value or len(value) > MAX_NAME_LENGTH or not value.isprintable():
        raise ProtocolError(
            ErrorCode.WRONG_TYPE,
            where,
            f"a name must be 1..{MAX_NAME_LENGTH} printable characters",
        )
    return value


_S = TypeVar("_S", bound=str)


def check_choice(value: object, valid: tuple[_S, ...], where: str) -> _S:
    """One of the ``valid`` names (a ``Literal`` mode such as a pair kind)."""
    name = check_name(value, where)
    for v in valid:
        if name == v:
            return v
    raise ProtocolError(
        ErrorCode.INVALID, where, f"unknown name {safe_repr(name)}; valid: {', '.join(valid)}"
    )


def check_text(value: object, where: str, max_length: int = 4096) -> str:
    if not isinstance(value, str) or len(value) > max_length:
        raise ProtocolError(
            ErrorCode.WRONG_TYPE, where, f"expected a string of at most {max_length} characters"
        )
    return value


def check_float(
    value: object, where: str, *, finite: bool = True, minimum: float | None = None
) -> float:
    """A number (int or float; not bool); ``finite`` rejects NaN/inf, ``minimum`` bounds it."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ProtocolError(ErrorCode.WRONG_TYPE, where, f"expected a number, got {_kind(value)}")
    out = float(value)
    if math.isnan(out) or (finite and math.isinf(out)):
        raise ProtocolError(ErrorCode.NON_FINITE, where, f"must be finite, got {out!r}")
    if minimum is not None and out < minimum:
        raise ProtocolError(ErrorCode.WRONG_TYPE, where, f"must be >= {minimum:g}, got {out!r}")
    return out


def check_int(value: object, where: str, *, minimum: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise ProtocolError(ErrorCode.WRONG_TYPE, where, f"expected an integer, got {_kind(value)}")
    if minimum is not None and value < minimum:
        raise ProtocolError(ErrorCode.WRONG_TYPE, where, f"must be >= {minimum}, got {value}")
    return value


def check_bool(value: object, where: str) -> bool:
    if not isinstance(value, bool):
        raise ProtocolError(
            ErrorCode.WRONG_TYPE, where, f"expected true or false, got {_kind(value)}"
        )
    return value


def check_list(value: object, where: str, max_length: int = MAX_LIST) -> list[Any]:
    if not isinstance(value, list):
        raise ProtocolError(ErrorCode.WRONG_TYPE, where, f"expected a list, got {_kind(value)}")
    if len(value) > max_length:
        raise ProtocolError(
            ErrorCode.WRONG_SHAPE, where, f"at most {max_length} entries, got {len(value)}"
        )
    return value


def check_map(value: object, where: str) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise ProtocolError(ErrorCode.WRONG_TYPE, where, f"expected a map, got {_kind(value)}")
    return value


def check_name_pair(value: object, where: str) -> tuple[str, str]:
    v = check_list(value, where, 2)
    if len(v) != 2:
        raise ProtocolError(ErrorCode.WRONG_SHAPE, where, f"expected [a, b], got {len(v)} names")
    return check_name(v[0], f"{where}[0]"), check_name(v[1], f"{where}[1]")


def check_model(value: object, where: str) -> dict[str, Any]:
    """A robot's YAML mapping: plain data only (maps with string keys, lists, strings,
    numbers, booleans, nil), bounded in depth and size; its meaning is checked by
    :func:`reachwise.io.robot_file.robot_from_dict`."""
    top = check_map(value, where)
    joints = top.get("joints")
    if isinstance(joints, list) and len(joints) > MAX_ROBOT_JOINTS:
        raise ProtocolError(
            ErrorCode.WRONG_SHAPE,
            f"{where}.joints",
            f"at most {MAX_ROBOT_JOINTS} joints, got {len(joints)}",
        )
    nodes = 0
    stack: list[tuple[object, str, int]] = [(top, where, 0)]
    while stack:
        v, path, depth = stack.pop()
        nodes += 1
        if nodes > MAX_MODEL_NODES or depth > MAX_MODEL_DEPTH:
            raise ProtocolError(
                ErrorCode.WRONG_SHAPE, where, "the robot mapping is too large or too deep"
            )
        if isinstance(v, dict):
            for k, item in v.items():
                if not isinstance(k, str):
                    raise ProtocolError(ErrorCode.WRONG_TYPE, path, "map keys must be strings")
                stack.append((item, f"{path}.{k}", depth + 1))
        elif isinstance(v, list):
            stack.extend((item, f"{path}[{i}]", depth + 1) for i, item in enumerate(v))
        elif v is not None and not isinstance(v, bool | int | float | str):
            raise ProtocolError(ErrorCode.WRONG_TYPE, path, f"plain data only, got {_kind(v)}")
    return top


def _kind(value: object) -> str:
    if value is None:
        return "nil"
    return _KINDS.get(type(value), type(value).__name__)


_KINDS: dict[type, str] = {
    bool: "a boolean",
    int: "an integer",
    float: "a number",
    str: "a string",
    bytes: "binary data",
    list: "a list",
    dict: "a map",
}


class Reader:
    """Reads the fields of one message body, recording which were used; :meth:`done`
    rejects the rest (strict schema)."""

    def __init__(self, body: object, where: str = "body") -> None:
        self.where = where
        self.body = check_map(body, where)
        self._used: set[str] = set()

    def path(self, key: str) -> str:
        return f"{self.where}.{key}"

    def get(self, key: str, optional: bool = False) -> Any:
        self._used.add(key)
        if key not in self.body:
            if optional:
                return None
            raise ProtocolError(
                ErrorCode.MISSING_FIELD, self.path(key), "required field is missing"
            )
        return self.body[key]

    def opt(self, key: str) -> Any:
        """The value of an optional field (absent and nil both give None)."""
        return self.get(key, optional=True)

    def done(self) -> None:
        extra = sorted(str(k) for k in self.body if k not in self._used)
        if extra:
            raise ProtocolError(
                ErrorCode.UNKNOWN_FIELD,
                self.path(extra[0]),
                f"unknown field; known: {sorted(self._used)}",
            )


_D = TypeVar("_D")


def unchecked(cls: type[_D], /, **fields: Any) -> _D:
    """An instance of the frozen dataclass ``cls`` holding ``fields`` as given, made
    without its generated ``__init__`` (which sets each field through
    ``object.__setattr__``): half the cost, for the per-tick messages whose decoders
    have checked every field. ``fields`` must name every field of ``cls``, and ``cls``
    must have no ``__post_init__``."""
    obj = object.__new__(cls)
    obj.__dict__.update(fields)
    return obj


def omit_none(body: Body) -> Body:
    """``body`` without its absent (None) optional fields."""
    return {k: v for k, v in body.items() if v is not None}


def stamp_of(r: Reader) -> float | None:
    """The optional ``stamp`` field (seconds on the sender's clock)."""
    v = r.opt("stamp")
    return None if v is None else check_float(v, r.path("stamp"))
