"""Wire protocol of the collision server: versioned msgpack messages, strictly validated.

The collision server of the thesis (P-III §4.1 Fig. 2, P-IV, P-V §I–II) keeps the point
clouds, updates their poses from joint sensors and scans, and answers the control system
every cycle. This module is the language the two speak. One request and one reply are
each a single ZeroMQ frame holding one msgpack map:

- request ``{"v": 1, "id": <int>, "op": <str>, "body": <map>}``
- reply ``{"v": 1, "id": <int | nil>, "ok": true, "body": <map>}`` or
  ``{"v": 1, "id": <int | nil>, "ok": false, "error": {"code", "field", "message"}}``

The operations follow the phases of P-V Table 1: the *initialization phase* registers
robots (their YAML mapping, :func:`reachwise.io.robot_file.robot_to_dict`; never a
pickle) and part clouds, whose spatial indices the server builds once
(``add_robot``, ``add_object``, ``replace_cloud`` for a new scan, the ``watch*`` pair
rules); the *calculation phase* takes the inputs "object poses" — joint states the
server turns into link poses by forward kinematics, or run-time object poses
(``set_joints``, ``set_pose``) — and answers every watched pair (``query``).

Rules every decoder here follows (the server and the client alike):

- the frame's size is checked *before* decoding (:attr:`Limits.max_message_bytes`),
  and msgpack itself is given length limits, so a hostile frame cannot make it allocate;
- numpy arrays travel as ``[dtype, shape, bytes]`` (little-endian ``"<f8"`` floats,
  ``"<i8"`` integers, ``"|b1"`` booleans); the byte count must match the shape, and the
  row count of a cloud is checked against :attr:`Limits.max_cloud_points` before any
  array is made;
- every field is checked for presence, type, shape and finiteness; unknown fields are
  errors; nothing is ever unpickled or evaluated.

A bad message becomes a :class:`ProtocolError` with an :class:`ErrorCode` and the name
of the offending field, which the server sends back as a typed error reply.

Units are SI: lengths in metres, angles in radians, times in seconds. Time stamps are
readings of the *sender's* clock (by default :func:`time.monotonic`, shared by every
process on one host; clients on several hosts must share a synchronized clock).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from enum import StrEnum
from typing import Any, ClassVar, Self

import msgpack
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

FLOAT = "<f8"
INT = "<i8"
BOOL = "|b1"

Body = dict[str, Any]


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
        self.field = field
        self.message = message
        self.request_id = request_id
        where = f" ({field})" if field else ""
        super().__init__(f"{self.code.value}{where}: {message}")


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
            ErrorCode.WRONG_TYPE, where, f"dtype {dt!r} not accepted; send {dtype!r}"
        )
    ok = type(shp) is list and len(shp) == len(shape)
    if ok:
        for s, w in zip(shp, shape, strict=True):
            if type(s) is not int or s < 0 or (w is not None and s != w):
                ok = False
                break
    if not ok:
        raise ProtocolError(
            ErrorCode.WRONG_SHAPE, where, f"expected shape {_fmt_shape(shape)}, got {shp!r}"
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


def _omit_none(body: Body) -> Body:
    return {k: v for k, v in body.items() if v is not None}


def _pose_or_none(r: Reader, key: str) -> NDArray[np.float64] | None:
    v = r.opt(key)
    return None if v is None else check_array(v, r.path(key), shape=(4, 4))


def _stamp(r: Reader) -> float | None:
    v = r.opt("stamp")
    return None if v is None else check_float(v, r.path("stamp"))


# --------------------------------------------------------------------------- requests


@dataclass(frozen=True)
class Request:
    """Base of every request; ``OP`` is its wire name."""

    OP: ClassVar[str] = ""
    #: Requests that change the scene's structure (run in order on the server's writer
    #: thread and persisted before the reply); the rest are answered at once.
    STRUCTURAL: ClassVar[bool] = False

    def body(self) -> Body:
        return {}

    @classmethod
    def parse(cls, r: Reader, limits: Limits) -> Self:
        return cls()


@dataclass(frozen=True)
class Hello(Request):
    """Say who the client is and which protocol versions it speaks."""

    OP: ClassVar[str] = "hello"
    client: str = "reachwise"
    versions: tuple[int, ...] = SUPPORTED_VERSIONS

    def body(self) -> Body:
        return {"client": self.client, "versions": list(self.versions)}

    @classmethod
    def parse(cls, r: Reader, limits: Limits) -> Self:
        client = check_text(r.get("client"), r.path("client"), MAX_NAME_LENGTH)
        vs = check_list(r.get("versions"), r.path("versions"), 64)
        versions = tuple(check_int(v, f"{r.path('versions')}[{i}]") for i, v in enumerate(vs))
        return cls(client, versions)


@dataclass(frozen=True)
class Health(Request):
    """Readiness and a sequence number that only grows (across restarts too)."""

    OP: ClassVar[str] = "health"


@dataclass(frozen=True)
class Metrics(Request):
    """Request counts, error counts and the query latency histograms."""

    OP: ClassVar[str] = "metrics"


@dataclass(frozen=True, eq=False)
class AddRobot(Request):
    """Register a robot (its YAML mapping), optionally with its joint state ``q``."""

    OP: ClassVar[str] = "add_robot"
    STRUCTURAL: ClassVar[bool] = True
    robot: dict[str, Any]
    q: NDArray[np.float64] | None = None
    stamp: float | None = None

    def body(self) -> Body:
        return _omit_none(
            {
                "robot": self.robot,
                "q": None if self.q is None else encode_array(self.q),
                "stamp": self.stamp,
            }
        )

    @classmethod
    def parse(cls, r: Reader, limits: Limits) -> Self:
        robot = check_model(r.get("robot"), r.path("robot"))
        q = r.opt("q")
        qa = None if q is None else check_array(q, r.path("q"), shape=(None,))
        return cls(robot, qa, _stamp(r))


@dataclass(frozen=True, eq=False)
class AddObject(Request):
    """Add a cloud (P-V Table 1 initialization: its index is built once): fixed in world
    at ``pose``; on ``robot``'s ``link`` with ``pose`` its offset; or ``dynamic`` (pose
    set at run time, ``pose`` the initial one)."""

    OP: ClassVar[str] = "add_object"
    STRUCTURAL: ClassVar[bool] = True
    name: str
    cloud: NDArray[np.float64]
    pose: NDArray[np.float64] | None = None
    robot: str | None = None
    link: str | None = None
    dynamic: bool = False

    def body(self) -> Body:
        return _omit_none(
            {
                "name": self.name,
                "cloud": encode_array(self.cloud),
                "pose": None if self.pose is None else encode_array(self.pose),
                "robot": self.robot,
                "link": self.link,
                "dynamic": self.dynamic or None,
            }
        )

    @classmethod
    def parse(cls, r: Reader, limits: Limits) -> Self:
        name = check_name(r.get("name"), r.path("name"))
        cloud = check_array(
            r.get("cloud"), r.path("cloud"), shape=(None, 3), max_rows=limits.max_cloud_points
        )
        if cloud.shape[0] == 0:
            raise ProtocolError(ErrorCode.WRONG_SHAPE, r.path("cloud"), "the cloud is empty")
        pose = _pose_or_none(r, "pose")
        robot = r.opt("robot")
        link = r.opt("link")
        dyn = r.opt("dynamic")
        return cls(
            name,
            cloud,
            pose,
            None if robot is None else check_name(robot, r.path("robot")),
            None if link is None else check_name(link, r.path("link")),
            False if dyn is None else check_bool(dyn, r.path("dynamic")),
        )


@dataclass(frozen=True, eq=False)
class ReplaceCloud(Request):
    """Swap an object's cloud, e.g. the environment after a new scan (index rebuilt)."""

    OP: ClassVar[str] = "replace_cloud"
    STRUCTURAL: ClassVar[bool] = True
    name: str
    cloud: NDArray[np.float64]

    def body(self) -> Body:
        return {"name": self.name, "cloud": encode_array(self.cloud)}

    @classmethod
    def parse(cls, r: Reader, limits: Limits) -> Self:
        name = check_name(r.get("name"), r.path("name"))
        cloud = check_array(
            r.get("cloud"), r.path("cloud"), shape=(None, 3), max_rows=limits.max_cloud_points
        )
        if cloud.shape[0] == 0:
            raise ProtocolError(ErrorCode.WRONG_SHAPE, r.path("cloud"), "the cloud is empty")
        return cls(name, cloud)


@dataclass(frozen=True, eq=False)
class SetJoints(Request):
    """A robot's joint state (one value per non-fixed joint), measured at ``stamp``."""

    OP: ClassVar[str] = "set_joints"
    robot: str
    q: NDArray[np.float64]
    stamp: float | None = None

    def body(self) -> Body:
        return _omit_none({"robot": self.robot, "q": encode_array(self.q), "stamp": self.stamp})

    @classmethod
    def parse(cls, r: Reader, limits: Limits) -> Self:
        robot = check_name(r.get("robot"), r.path("robot"))
        q = check_array(r.get("q"), r.path("q"), shape=(None,))
        return cls(robot, q, _stamp(r))


@dataclass(frozen=True, eq=False)
class SetPose(Request):
    """The world pose (4x4) of a run-time object, measured at ``stamp``."""

    OP: ClassVar[str] = "set_pose"
    name: str
    pose: NDArray[np.float64]
    stamp: float | None = None

    def body(self) -> Body:
        return _omit_none({"name": self.name, "pose": encode_array(self.pose), "stamp": self.stamp})

    @classmethod
    def parse(cls, r: Reader, limits: Limits) -> Self:
        name = check_name(r.get("name"), r.path("name"))
        pose = check_array(r.get("pose"), r.path("pose"), shape=(4, 4))
        return cls(name, pose, _stamp(r))


def _margin(r: Reader) -> float:
    return check_float(r.get("margin"), r.path("margin"), finite=False, minimum=0.0)


@dataclass(frozen=True)
class Watch(Request):
    """Watch objects ``a`` and ``b`` with ``margin`` metres (inf allowed)."""

    OP: ClassVar[str] = "watch"
    STRUCTURAL: ClassVar[bool] = True
    a: str
    b: str
    margin: float
    kind: str = "custom"

    def body(self) -> Body:
        return {"a": self.a, "b": self.b, "margin": self.margin, "kind": self.kind}

    @classmethod
    def parse(cls, r: Reader, limits: Limits) -> Self:
        return cls(
            check_name(r.get("a"), r.path("a")),
            check_name(r.get("b"), r.path("b")),
            _margin(r),
            check_name(r.get("kind"), r.path("kind")),
        )


@dataclass(frozen=True)
class WatchSelf(Request):
    """Self-collision pairs of a robot except adjacent links and ``exclude``."""

    OP: ClassVar[str] = "watch_self"
    STRUCTURAL: ClassVar[bool] = True
    robot: str
    margin: float
    exclude: tuple[tuple[str, str], ...] = ()

    def body(self) -> Body:
        return {
            "robot": self.robot,
            "margin": self.margin,
            "exclude": [list(e) for e in self.exclude],
        }

    @classmethod
    def parse(cls, r: Reader, limits: Limits) -> Self:
        ex = check_list(r.get("exclude"), r.path("exclude"))
        return cls(
            check_name(r.get("robot"), r.path("robot")),
            _margin(r),
            tuple(check_name_pair(e, f"{r.path('exclude')}[{i}]") for i, e in enumerate(ex)),
        )


@dataclass(frozen=True)
class WatchEnvironment(Request):
    """A robot's objects against every object not on a robot (or the named ones)."""

    OP: ClassVar[str] = "watch_environment"
    STRUCTURAL: ClassVar[bool] = True
    robot: str
    margin: float
    objects: tuple[str, ...] | None = None

    def body(self) -> Body:
        return _omit_none(
            {
                "robot": self.robot,
                "margin": self.margin,
                "objects": None if self.objects is None else list(self.objects),
            }
        )

    @classmethod
    def parse(cls, r: Reader, limits: Limits) -> Self:
        robot = check_name(r.get("robot"), r.path("robot"))
        margin = _margin(r)
        objs = r.opt("objects")
        names = None
        if objs is not None:
            lst = check_list(objs, r.path("objects"))
            names = tuple(check_name(v, f"{r.path('objects')}[{i}]") for i, v in enumerate(lst))
        return cls(robot, margin, names)


@dataclass(frozen=True)
class WatchRobots(Request):
    """Every object of ``robot_a`` against every object of ``robot_b``."""

    OP: ClassVar[str] = "watch_robots"
    STRUCTURAL: ClassVar[bool] = True
    robot_a: str
    robot_b: str
    margin: float

    def body(self) -> Body:
        return {"robot_a": self.robot_a, "robot_b": self.robot_b, "margin": self.margin}

    @classmethod
    def parse(cls, r: Reader, limits: Limits) -> Self:
        return cls(
            check_name(r.get("robot_a"), r.path("robot_a")),
            check_name(r.get("robot_b"), r.path("robot_b")),
            _margin(r),
        )


@dataclass(frozen=True)
class Unwatch(Request):
    """Stop watching a pair (either order); like the in-process scene, no error if it
    was not watched."""

    OP: ClassVar[str] = "unwatch"
    STRUCTURAL: ClassVar[bool] = True
    a: str
    b: str

    def body(self) -> Body:
        return {"a": self.a, "b": self.b}

    @classmethod
    def parse(cls, r: Reader, limits: Limits) -> Self:
        return cls(check_name(r.get("a"), r.path("a")), check_name(r.get("b"), r.path("b")))


@dataclass(frozen=True, eq=False)
class Query(Request):
    """Answer the watched pairs (P-V Table 1's calculation phase).

    ``joints`` and ``poses`` are applied first, atomically with the query (one round
    trip per control tick); ``pairs`` restricts the answer to watched pairs (an
    unwatched one is :attr:`ErrorCode.UNKNOWN_PAIR`); ``stamp`` is the time the
    request was made and stamps the inputs it carries. ``layout`` names the pair list
    the client already holds (from an earlier :class:`QueryReply`): if it is still
    current the reply leaves the list out.
    """

    OP: ClassVar[str] = "query"
    stamp: float | None = None
    joints: dict[str, NDArray[np.float64]] | None = None
    poses: dict[str, NDArray[np.float64]] | None = None
    pairs: tuple[tuple[str, str], ...] | None = None
    layout: str | None = None

    def body(self) -> Body:
        return _omit_none(
            {
                "stamp": self.stamp,
                "joints": None
                if not self.joints
                else {k: encode_array(v) for k, v in self.joints.items()},
                "poses": None
                if not self.poses
                else {k: encode_array(v) for k, v in self.poses.items()},
                "pairs": None if self.pairs is None else [list(p) for p in self.pairs],
                "layout": self.layout,
            }
        )

    @classmethod
    def parse(cls, r: Reader, limits: Limits) -> Self:
        stamp = _stamp(r)
        lv = r.opt("layout")
        layout = None if lv is None else check_text(lv, r.path("layout"), MAX_NAME_LENGTH)
        joints = _array_map(r, "joints", (None,))
        poses = _array_map(r, "poses", (4, 4))
        pv = r.opt("pairs")
        pairs = None
        if pv is not None:
            lst = check_list(pv, r.path("pairs"))
            pairs = tuple(check_name_pair(p, f"{r.path('pairs')}[{i}]") for i, p in enumerate(lst))
        return cls(stamp, joints, poses, pairs, layout)


def _array_map(
    r: Reader, key: str, shape: tuple[int | None, ...]
) -> dict[str, NDArray[np.float64]] | None:
    v = r.opt(key)
    if v is None:
        return None
    m = check_map(v, r.path(key))
    if len(m) > MAX_LIST:
        raise ProtocolError(ErrorCode.WRONG_SHAPE, r.path(key), f"at most {MAX_LIST} entries")
    out = {}
    for name, item in m.items():
        where = f"{r.path(key)}.{name}"
        out[check_name(name, where)] = check_array(item, where, shape=shape)
    return out


@dataclass(frozen=True)
class Clear(Request):
    """Remove every robot, object and pair (and their saved state): a simulator that
    owns the server's scene starts each run from an empty one."""

    OP: ClassVar[str] = "clear"
    STRUCTURAL: ClassVar[bool] = True


@dataclass(frozen=True)
class Describe(Request):
    """The scene's contents: robots, objects (with their clouds if ``clouds``), pairs."""

    OP: ClassVar[str] = "describe"
    clouds: bool = False

    def body(self) -> Body:
        return {"clouds": self.clouds}

    @classmethod
    def parse(cls, r: Reader, limits: Limits) -> Self:
        return cls(check_bool(r.get("clouds"), r.path("clouds")))


@dataclass(frozen=True)
class Poses(Request):
    """The current world pose of every object."""

    OP: ClassVar[str] = "poses"


REQUESTS: dict[str, type[Request]] = {
    cls.OP: cls
    for cls in (
        Hello,
        Health,
        Metrics,
        AddRobot,
        AddObject,
        ReplaceCloud,
        SetJoints,
        SetPose,
        Watch,
        WatchSelf,
        WatchEnvironment,
        WatchRobots,
        Unwatch,
        Clear,
        Query,
        Describe,
        Poses,
    )
}


# --------------------------------------------------------------------------- replies


@dataclass(frozen=True)
class Reply:
    """Base of every reply body."""

    def body(self) -> Body:
        return {}

    @classmethod
    def parse(cls, r: Reader) -> Self:
        return cls()


@dataclass(frozen=True)
class Ack(Reply):
    """Done; nothing to report."""


@dataclass(frozen=True)
class HelloReply(Reply):
    server: str
    version: str
    protocol: int
    instance: str
    ready: bool

    def body(self) -> Body:
        return {
            "server": self.server,
            "version": self.version,
            "protocol": self.protocol,
            "instance": self.instance,
            "ready": self.ready,
        }

    @classmethod
    def parse(cls, r: Reader) -> Self:
        return cls(
            check_text(r.get("server"), r.path("server")),
            check_text(r.get("version"), r.path("version")),
            check_int(r.get("protocol"), r.path("protocol")),
            check_text(r.get("instance"), r.path("instance")),
            check_bool(r.get("ready"), r.path("ready")),
        )


@dataclass(frozen=True)
class HealthReply(Reply):
    """``state``: ``loading`` (restoring the state directory), ``ready`` or ``failed``
    (with ``reason``). ``sequence`` grows with every health and query reply, also
    across restarts when the server has a state directory; ``instance`` changes at
    every start; ``uptime`` in seconds."""

    ready: bool
    state: str
    reason: str
    sequence: int
    instance: str
    uptime: float
    robots: int
    objects: int
    pairs: int

    def body(self) -> Body:
        return dict(self.__dict__)

    @classmethod
    def parse(cls, r: Reader) -> Self:
        return cls(
            check_bool(r.get("ready"), r.path("ready")),
            check_text(r.get("state"), r.path("state")),
            check_text(r.get("reason"), r.path("reason")),
            check_int(r.get("sequence"), r.path("sequence"), minimum=0),
            check_text(r.get("instance"), r.path("instance")),
            check_float(r.get("uptime"), r.path("uptime")),
            check_int(r.get("robots"), r.path("robots"), minimum=0),
            check_int(r.get("objects"), r.path("objects"), minimum=0),
            check_int(r.get("pairs"), r.path("pairs"), minimum=0),
        )


@dataclass(frozen=True)
class MetricsReply(Reply):
    """``requests`` and ``errors``: counts per op and per error code. Histograms of
    queries in microseconds over ``edges_us`` (bucket k counts values in
    [edges[k-1], edges[k]), the last bucket everything above): ``query_compute``
    the distance computation alone, ``query_handling`` from receipt to reply."""

    uptime: float
    sequence: int
    requests: dict[str, int]
    errors: dict[str, int]
    edges_us: tuple[float, ...]
    query_compute: tuple[int, ...]
    query_handling: tuple[int, ...]

    def body(self) -> Body:
        return {
            "uptime": self.uptime,
            "sequence": self.sequence,
            "requests": dict(self.requests),
            "errors": dict(self.errors),
            "edges_us": list(self.edges_us),
            "query_compute": list(self.query_compute),
            "query_handling": list(self.query_handling),
        }

    @classmethod
    def parse(cls, r: Reader) -> Self:
        def counts(key: str) -> dict[str, int]:
            m = check_map(r.get(key), r.path(key))
            return {
                check_text(k, r.path(key)): check_int(v, f"{r.path(key)}.{k}", minimum=0)
                for k, v in m.items()
            }

        def ints(key: str) -> tuple[int, ...]:
            return tuple(
                check_int(v, r.path(key), minimum=0) for v in check_list(r.get(key), r.path(key))
            )

        return cls(
            check_float(r.get("uptime"), r.path("uptime")),
            check_int(r.get("sequence"), r.path("sequence"), minimum=0),
            counts("requests"),
            counts("errors"),
            tuple(
                check_float(v, r.path("edges_us"))
                for v in check_list(r.get("edges_us"), r.path("edges_us"))
            ),
            ints("query_compute"),
            ints("query_handling"),
        )


@dataclass(frozen=True)
class RobotReply(Reply):
    """A registered robot: its frame names (``link_0`` … ``tool``) and joint count."""

    name: str
    links: tuple[str, ...]
    dof: int

    def body(self) -> Body:
        return {"name": self.name, "links": list(self.links), "dof": self.dof}

    @classmethod
    def parse(cls, r: Reader) -> Self:
        links = check_list(r.get("links"), r.path("links"))
        return cls(
            check_name(r.get("name"), r.path("name")),
            tuple(check_name(v, r.path("links")) for v in links),
            check_int(r.get("dof"), r.path("dof"), minimum=0),
        )


@dataclass(frozen=True)
class ObjectReply(Reply):
    """An object after ``add_object``/``replace_cloud``: its point count."""

    name: str
    points: int

    def body(self) -> Body:
        return {"name": self.name, "points": self.points}

    @classmethod
    def parse(cls, r: Reader) -> Self:
        return cls(
            check_name(r.get("name"), r.path("name")),
            check_int(r.get("points"), r.path("points"), minimum=1),
        )


@dataclass(frozen=True)
class PairInfo:
    """A watched pair: object names, margin (m) and kind."""

    a: str
    b: str
    margin: float
    kind: str

    def wire(self) -> list[Any]:
        return [self.a, self.b, self.margin, self.kind]

    @classmethod
    def parse(cls, value: object, where: str) -> PairInfo:
        v = check_list(value, where, 4)
        if len(v) != 4:
            raise ProtocolError(ErrorCode.WRONG_SHAPE, where, "expected [a, b, margin, kind]")
        return cls(
            check_name(v[0], f"{where}[0]"),
            check_name(v[1], f"{where}[1]"),
            check_float(v[2], f"{where}[2]", finite=False, minimum=0.0),
            check_name(v[3], f"{where}[3]"),
        )


def _pairs(r: Reader, key: str = "pairs") -> tuple[PairInfo, ...]:
    lst = check_list(r.get(key), r.path(key))
    return tuple(PairInfo.parse(p, f"{r.path(key)}[{i}]") for i, p in enumerate(lst))


@dataclass(frozen=True)
class PairsReply(Reply):
    """The pairs a ``watch*`` request created or updated."""

    pairs: tuple[PairInfo, ...]

    def body(self) -> Body:
        return {"pairs": [p.wire() for p in self.pairs]}

    @classmethod
    def parse(cls, r: Reader) -> Self:
        return cls(_pairs(r))


#: Columns of :attr:`QueryReply.rows`: distance, point_a (3), point_b (3), direction (3),
#: index_a, index_b, no_risk (0 or 1).
ROW_COLUMNS = 13


@dataclass(frozen=True, eq=False)
class QueryReply(Reply):
    """Every answered pair, in watch order, one row of :data:`ROW_COLUMNS` float64 per
    pair (one array: the cheapest to encode and check): the distance (m; inf beyond
    the margin), the closest point on a, on b, the unit direction from b to a (world
    frame; NaN beyond the margin), the closest points' rows in the clouds (-1 beyond
    the margin; exact as floats, clouds have far fewer than 2**53 points) and the
    no-risk flag. :attr:`values`, :attr:`index` and :attr:`no_risk` give the parts.

    ``sequence`` grows with every query (and health) reply; ``measured_at`` is the
    oldest time stamp among the joint states and run-time poses the answer depends on
    and the query's own stamp (sender's clock, s); ``compute_time`` the server's
    computation time (s).

    ``layout`` names the list of watched pairs (it changes whenever a pair, its
    margin or the order changes, and at every server start; empty for a query of
    chosen pairs). ``pairs`` is None when the request named the current layout: the
    rows are then in the order of the list the client holds.
    """

    sequence: int
    measured_at: float
    compute_time: float
    layout: str
    pairs: tuple[PairInfo, ...] | None
    rows: NDArray[np.float64]

    @property
    def values(self) -> NDArray[np.float64]:
        """(P, 10): distance, point_a, point_b, direction."""
        return self.rows[:, :10]

    @property
    def index(self) -> NDArray[np.int64]:
        """(P, 2): index_a, index_b."""
        return self.rows[:, 10:12].astype(np.int64)

    @property
    def no_risk(self) -> NDArray[np.bool_]:
        return self.rows[:, 12] == 1.0

    def body(self) -> Body:
        return _omit_none(
            {
                "sequence": self.sequence,
                "measured_at": self.measured_at,
                "compute_time": self.compute_time,
                "layout": self.layout,
                "pairs": None if self.pairs is None else [p.wire() for p in self.pairs],
                "rows": encode_array(self.rows),
            }
        )

    @classmethod
    def parse(cls, r: Reader) -> Self:
        pairs = None if r.opt("pairs") is None else _pairs(r)
        where = r.path("rows")
        rows = check_array(r.get("rows"), where, shape=(None, ROW_COLUMNS), finite=False)
        n = rows.shape[0]
        if pairs is not None and len(pairs) != n:
            raise ProtocolError(
                ErrorCode.WRONG_SHAPE, r.path("pairs"), f"{len(pairs)} pairs for {n} rows"
            )
        for ia, ib, flag in rows[:, 10:13].tolist():
            if not (ia.is_integer() and ib.is_integer() and ia >= -1.0 and ib >= -1.0):
                raise ProtocolError(
                    ErrorCode.WRONG_TYPE, where, "columns 10-11 must be indices >= -1"
                )
            if flag != 0.0 and flag != 1.0:
                raise ProtocolError(
                    ErrorCode.WRONG_TYPE, where, "column 12 (no_risk) must be 0 or 1"
                )
        return cls(
            check_int(r.get("sequence"), r.path("sequence"), minimum=0),
            check_float(r.get("measured_at"), r.path("measured_at")),
            check_float(r.get("compute_time"), r.path("compute_time"), minimum=0.0),
            check_text(r.get("layout"), r.path("layout"), MAX_NAME_LENGTH),
            pairs,
            rows,
        )


@dataclass(frozen=True, eq=False)
class ObjectInfo:
    """One object of the scene: ``source`` is ``fixed`` (``pose`` in world), ``link``
    (``pose`` the offset from ``robot``'s ``link``) or ``runtime`` (``pose`` the current
    world pose); ``cloud`` only when asked for."""

    name: str
    points: int
    source: str
    pose: NDArray[np.float64]
    robot: str | None = None
    link: str | None = None
    cloud: NDArray[np.float64] | None = None

    def wire(self) -> Body:
        return _omit_none(
            {
                "name": self.name,
                "points": self.points,
                "source": self.source,
                "pose": encode_array(self.pose),
                "robot": self.robot,
                "link": self.link,
                "cloud": None if self.cloud is None else encode_array(self.cloud),
            }
        )

    @classmethod
    def parse(cls, value: object, where: str) -> ObjectInfo:
        r = Reader(value, where)
        source = r.get("source")
        if source not in ("fixed", "link", "runtime"):
            raise ProtocolError(
                ErrorCode.WRONG_TYPE, r.path("source"), "expected fixed, link or runtime"
            )
        robot, link, cloud = r.opt("robot"), r.opt("link"), r.opt("cloud")
        out = cls(
            check_name(r.get("name"), r.path("name")),
            check_int(r.get("points"), r.path("points"), minimum=1),
            source,
            check_array(r.get("pose"), r.path("pose"), shape=(4, 4)),
            None if robot is None else check_name(robot, r.path("robot")),
            None if link is None else check_name(link, r.path("link")),
            None if cloud is None else check_array(cloud, r.path("cloud"), shape=(None, 3)),
        )
        r.done()
        return out


@dataclass(frozen=True, eq=False)
class DescribeReply(Reply):
    """The scene: distance ``strategy``, robots (YAML mappings) and their joint
    states, objects in insertion order, watched pairs in query order, the sequence."""

    strategy: str
    robots: dict[str, dict[str, Any]]
    joints: dict[str, NDArray[np.float64]]
    objects: tuple[ObjectInfo, ...]
    pairs: tuple[PairInfo, ...]
    sequence: int

    def body(self) -> Body:
        return {
            "strategy": self.strategy,
            "robots": dict(self.robots),
            "joints": {k: encode_array(v) for k, v in self.joints.items()},
            "objects": [o.wire() for o in self.objects],
            "pairs": [p.wire() for p in self.pairs],
            "sequence": self.sequence,
        }

    @classmethod
    def parse(cls, r: Reader) -> Self:
        robots = check_map(r.get("robots"), r.path("robots"))
        models = {
            check_name(k, r.path("robots")): check_model(v, f"{r.path('robots')}.{k}")
            for k, v in robots.items()
        }
        objs = check_list(r.get("objects"), r.path("objects"))
        return cls(
            check_name(r.get("strategy"), r.path("strategy")),
            models,
            _array_map(r, "joints", (None,)) or {},
            tuple(ObjectInfo.parse(o, f"{r.path('objects')}[{i}]") for i, o in enumerate(objs)),
            _pairs(r),
            check_int(r.get("sequence"), r.path("sequence"), minimum=0),
        )


@dataclass(frozen=True, eq=False)
class PosesReply(Reply):
    """World pose (4x4) of every object."""

    poses: dict[str, NDArray[np.float64]]

    def body(self) -> Body:
        return {"poses": {k: encode_array(v) for k, v in self.poses.items()}}

    @classmethod
    def parse(cls, r: Reader) -> Self:
        return cls(_array_map(r, "poses", (4, 4)) or {})


#: The reply type of every request op.
REPLIES: dict[str, type[Reply]] = {
    "hello": HelloReply,
    "health": HealthReply,
    "metrics": MetricsReply,
    "add_robot": RobotReply,
    "add_object": ObjectReply,
    "replace_cloud": ObjectReply,
    "set_joints": Ack,
    "set_pose": Ack,
    "watch": PairsReply,
    "watch_self": PairsReply,
    "watch_environment": PairsReply,
    "watch_robots": PairsReply,
    "unwatch": Ack,
    "clear": Ack,
    "query": QueryReply,
    "describe": DescribeReply,
    "poses": PosesReply,
}


@dataclass(frozen=True)
class ErrorReply:
    """A typed error: ``code``, the offending ``field`` and a ``message``."""

    code: ErrorCode
    field: str
    message: str

    @classmethod
    def of(cls, exc: ProtocolError) -> ErrorReply:
        return cls(exc.code, exc.field, exc.message)


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
        return msgpack.unpackb(
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
    """One request frame."""
    return msgpack.packb(
        {"v": PROTOCOL_VERSION, "id": request_id, "op": request.OP, "body": request.body()},
        use_bin_type=True,
    )


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


def _fast_query_reply(body: object) -> QueryReply | None:
    if type(body) is not dict or not body.keys() == _QUERY_REPLY_FAST_KEYS:
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
    return QueryReply(seq, measured, compute, layout, None, arr)


def decode_request(raw: bytes | memoryview, limits: Limits = DEFAULT_LIMITS) -> tuple[int, Request]:
    """Check and decode one request frame; raises :class:`ProtocolError` (with the
    request id when it could be read)."""
    obj, rid = _envelope(_unpack(raw, limits), _REQUEST_KEYS)
    if rid is None:
        raise ProtocolError(ErrorCode.BAD_MESSAGE, "id", "missing or not an integer in [0, 2**63)")
    op = obj.get("op")
    fast = _FAST_REQUESTS.get(op) if type(op) is str else None
    if fast is not None:
        req_fast = fast(obj.get("body"))
        if req_fast is not None:
            return rid, req_fast
    cls = REQUESTS.get(op) if isinstance(op, str) else None
    if cls is None:
        raise ProtocolError(
            ErrorCode.UNKNOWN_OP, "op", f"unknown op {op!r}; known: {sorted(REQUESTS)}", rid
        )
    if "body" not in obj:
        raise ProtocolError(ErrorCode.MISSING_FIELD, "body", "required field is missing", rid)
    try:
        r = Reader(obj["body"])
        req = cls.parse(r, limits)
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
                ErrorCode.BAD_MESSAGE, e.path("code"), f"unknown error code {code_s!r}"
            ) from None
        err = ErrorReply(
            code,
            check_text(e.get("field"), e.path("field")),
            check_text(e.get("message"), e.path("message")),
        )
        e.done()
        return DecodedReply(rid, error=err)
    raise ProtocolError(ErrorCode.BAD_MESSAGE, "ok", "missing or not a boolean")


__all__ = [
    "BOOL",
    "DEFAULT_LIMITS",
    "FLOAT",
    "INPUT_CODES",
    "INT",
    "MAX_CLOUD_POINTS",
    "MAX_MESSAGE_BYTES",
    "PROTOCOL_VERSION",
    "REPLIES",
    "REQUESTS",
    "SUPPORTED_VERSIONS",
    "Ack",
    "AddObject",
    "AddRobot",
    "Clear",
    "DecodedReply",
    "Describe",
    "DescribeReply",
    "ErrorCode",
    "ErrorReply",
    "Health",
    "HealthReply",
    "Hello",
    "HelloReply",
    "Limits",
    "Metrics",
    "MetricsReply",
    "ObjectInfo",
    "ObjectReply",
    "PairInfo",
    "PairsReply",
    "Poses",
    "PosesReply",
    "ProtocolError",
    "Query",
    "QueryReply",
    "Reader",
    "ReplaceCloud",
    "Reply",
    "Request",
    "RobotReply",
    "SetJoints",
    "SetPose",
    "Unwatch",
    "Watch",
    "WatchEnvironment",
    "WatchRobots",
    "WatchSelf",
    "check_array",
    "decode_reply",
    "decode_request",
    "encode_array",
    "encode_error",
    "encode_reply",
    "encode_request",
]
