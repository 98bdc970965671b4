"""The requests a client sends the collision server, one frozen dataclass per ``op``
(P-V Table 1: the initialization phase, then the calculation phase). A request's body
is encoded and checked from its fields' type hints
(:mod:`~reachwise.server.protocol.typed`) unless it writes its own: the per-tick
requests and the streamed cloud do, and so does ``add_object``, whose cloud is
bounded by the server's limits."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Annotated, Any, ClassVar, Self

import numpy as np
from numpy.typing import NDArray

from reachwise.distance.scene_ops import ArrayShape
from reachwise.server.protocol.fields import (
    FLOAT,
    MAX_LIST,
    MAX_NAME_LENGTH,
    SUPPORTED_VERSIONS,
    Body,
    Buffer,
    ErrorCode,
    Limits,
    ProtocolError,
    Reader,
    check_array,
    check_bool,
    check_int,
    check_list,
    check_map,
    check_name,
    check_name_pair,
    check_text,
    encode_array,
    omit_none,
    safe_repr,
    stamp_of,
)
from reachwise.server.protocol.typed import (
    Name,
    decode_fields,
    decode_value,
    encode_fields,
    encode_value,
    operation,
)


@dataclass(frozen=True)
class Request:
    """Base of every request; ``OP`` is its wire name."""

    OP: ClassVar[str] = ""
    #: Requests that change the scene's structure (run in order on the server's writer
    #: thread and persisted before the reply); the rest are answered at once.
    STRUCTURAL: ClassVar[bool] = False

    #: Raw binary frames that follow the msgpack envelope (arrays sent without msgpack).
    DATA_FRAMES: ClassVar[int] = 0

    @property
    def structural(self) -> bool:
        """Whether this request changes the scene's structure (:attr:`STRUCTURAL`)."""
        return self.STRUCTURAL

    def body(self) -> Body:
        """The wire form: every field encoded from its type hint."""
        return encode_fields(self)

    def data(self) -> list[Buffer]:
        """The raw frames after the envelope (:attr:`DATA_FRAMES` of them)."""
        return []

    @classmethod
    def parse(cls, r: Reader, limits: Limits) -> Self:
        """The request read from ``r``, every field checked against its type hint."""
        return decode_fields(cls, r)

    @classmethod
    def parse_frames(cls, r: Reader, limits: Limits, data: Sequence[Buffer]) -> Self:
        """Parse a request whose envelope is followed by ``data`` frames (their number
        is checked by the codec: :attr:`DATA_FRAMES`)."""
        return cls.parse(r, limits)


@dataclass(frozen=True)
class Hello(Request):
    """Say who the client is and which protocol versions it speaks."""

    OP: ClassVar[str] = "hello"
    client: str = "reachwise"
    versions: tuple[int, ...] = SUPPORTED_VERSIONS


@dataclass(frozen=True)
class Health(Request):
    """Readiness and a sequence number that only grows (across restarts too)."""

    OP: ClassVar[str] = "health"


@dataclass(frozen=True)
class Metrics(Request):
    """Request counts, error counts and the query latency histograms."""

    OP: ClassVar[str] = "metrics"


@dataclass(frozen=True, eq=False)
class AddObject(Request):
    """Add a cloud (P-V Table 1 initialization: its index is built once): fixed in world
    at ``pose``; on ``robot``'s ``link`` with ``pose`` its offset; or ``dynamic`` (pose
    set at run time, ``pose`` the initial one). ``stamp`` is when the cloud was measured
    (s, the sender's clock): inf (the default, also when absent) for a cloud that does
    not age, nil for an unknown time (the scene's NaN; NaN itself is no wire number, so
    a NaN given here travels as nil)."""

    OP: ClassVar[str] = "add_object"
    STRUCTURAL: ClassVar[bool] = True
    name: Name
    cloud: Annotated[NDArray[np.float64], ArrayShape((None, 3))]
    pose: Annotated[NDArray[np.float64], ArrayShape((4, 4))] | None = None
    robot: Name | None = None
    link: Name | None = None
    dynamic: bool = False
    stamp: float | None = math.inf

    def __post_init__(self) -> None:
        if isinstance(self.stamp, float) and math.isnan(self.stamp):
            object.__setattr__(self, "stamp", None)

    @property
    def cloud_stamp(self) -> float:
        """The stamp as the scene takes it: NaN for an unknown time."""
        return math.nan if self.stamp is None else self.stamp

    @classmethod
    def parse(cls, r: Reader, limits: Limits) -> Self:
        """The request as its hints check it, its cloud within ``limits``."""
        req = decode_fields(cls, r)
        if req.stamp == -math.inf:
            raise ProtocolError(
                ErrorCode.INVALID, r.path("stamp"), "must be a time in s, inf or nil, got -inf"
            )
        n = req.cloud.shape[0]
        if not 0 < n <= limits.max_cloud_points:
            raise ProtocolError(
                ErrorCode.OVERSIZED_CLOUD if n else ErrorCode.WRONG_SHAPE,
                r.path("cloud"),
                f"{n} points; a cloud holds 1 to {limits.max_cloud_points}",
            )
        return req


#: Element types a streamed cloud may travel in: little-endian float32 or float64.
CLOUD_DTYPES: tuple[str, ...] = ("<f4", FLOAT)


def _wire_cloud(cloud: object) -> NDArray[np.floating[Any]]:
    """``cloud`` as it travels: the array itself when it is already a C-contiguous
    little-endian float32 or float64 array (sent without a copy), else a float64 copy."""
    if (
        isinstance(cloud, np.ndarray)
        and cloud.dtype.str in CLOUD_DTYPES
        and cloud.flags.c_contiguous
    ):
        return cloud
    return np.ascontiguousarray(np.asarray(cloud, dtype=np.float64), dtype=FLOAT)


@dataclass(frozen=True, eq=False)
class ReplaceCloud(Request):
    """Hand over a new cloud for an object (a new scan, a depth camera frame), measured
    at ``stamp``; the server indexes it off its request thread and replies at once
    with the cloud's version, or with ``block`` once that version is indexed (every
    later query uses it).

    The message has two frames: the msgpack envelope, whose body is a small header —
    ``name``, ``points`` (N), ``dtype`` (:data:`CLOUD_DTYPES`), ``stamp``, ``block`` —
    and the N x 3 values themselves, raw, in C order (no per-point msgpack). Both ends
    pass the array's memory to ZeroMQ as it is: sent from the caller's contiguous
    array and viewed in the received frame, never copied on the way.
    """

    OP: ClassVar[str] = "replace_cloud"
    DATA_FRAMES: ClassVar[int] = 1
    name: str
    cloud: NDArray[np.floating[Any]]
    stamp: float | None = None
    block: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "cloud", _wire_cloud(self.cloud))

    def body(self) -> Body:
        n = int(self.cloud.shape[0]) if self.cloud.ndim else 0
        return omit_none(
            {
                "name": self.name,
                "points": n,
                "dtype": self.cloud.dtype.str,
                "stamp": self.stamp,
                "block": self.block or None,
            }
        )

    def data(self) -> list[Buffer]:
        return [self.cloud.data.cast("B")]

    @classmethod
    def parse_frames(cls, r: Reader, limits: Limits, data: Sequence[Buffer]) -> Self:
        name = check_name(r.get("name"), r.path("name"))
        n = check_int(r.get("points"), r.path("points"), minimum=0)
        if n == 0:
            raise ProtocolError(ErrorCode.WRONG_SHAPE, r.path("points"), "the cloud is empty")
        if n > limits.max_cloud_points:
            raise ProtocolError(
                ErrorCode.OVERSIZED_CLOUD,
                r.path("points"),
                f"{n} points exceed the cap of {limits.max_cloud_points}",
            )
        dtype = r.get("dtype")
        if dtype not in CLOUD_DTYPES:
            raise ProtocolError(
                ErrorCode.WRONG_TYPE,
                r.path("dtype"),
                f"dtype {safe_repr(dtype)} not accepted; send one of {list(CLOUD_DTYPES)}",
            )
        stamp = stamp_of(r)
        blk = r.opt("block")
        block = False if blk is None else check_bool(blk, r.path("block"))
        dt = np.dtype(dtype)
        raw = data[0]
        need = n * 3 * dt.itemsize
        size = len(raw) if isinstance(raw, bytes) else raw.nbytes
        if size != need:
            raise ProtocolError(
                ErrorCode.WRONG_SHAPE,
                "cloud",
                f"the data frame holds {size} bytes; {n} points of {dtype} need {need}",
            )
        # a read-only view of the received frame (finiteness is checked by the indexing
        # worker, off the request thread: a cloud with bad points is never swapped in)
        cloud = np.frombuffer(raw, dtype=dt).reshape(n, 3)
        return cls(name, cloud, stamp, block)


@dataclass(frozen=True, eq=False)
class SetJoints(Request):
    """A robot's joint state (one value per non-fixed joint), measured at ``stamp``."""

    OP: ClassVar[str] = "set_joints"
    robot: str
    q: NDArray[np.float64]
    stamp: float | None = None

    def body(self) -> Body:
        return omit_none({"robot": self.robot, "q": encode_array(self.q), "stamp": self.stamp})

    @classmethod
    def parse(cls, r: Reader, limits: Limits) -> Self:
        robot = check_name(r.get("robot"), r.path("robot"))
        q = check_array(r.get("q"), r.path("q"), shape=(None,))
        return cls(robot, q, stamp_of(r))


@dataclass(frozen=True, eq=False)
class SetPose(Request):
    """The world pose (4x4) of a run-time object, measured at ``stamp``."""

    OP: ClassVar[str] = "set_pose"
    name: str
    pose: NDArray[np.float64]
    stamp: float | None = None

    def body(self) -> Body:
        return omit_none({"name": self.name, "pose": encode_array(self.pose), "stamp": self.stamp})

    @classmethod
    def parse(cls, r: Reader, limits: Limits) -> Self:
        name = check_name(r.get("name"), r.path("name"))
        pose = check_array(r.get("pose"), r.path("pose"), shape=(4, 4))
        return cls(name, pose, stamp_of(r))


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
        return omit_none(
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
        stamp = stamp_of(r)
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


@dataclass(frozen=True, eq=False)
class OperationCall(Request):
    """Run the registered scene operation ``operation``
    (:func:`reachwise.distance.scene_ops.scene_operation`) with ``arguments`` by name;
    their wire form and its checks come from the operation's type hints
    (:mod:`~reachwise.server.protocol.typed`)."""

    OP: ClassVar[str] = "call"
    operation: str
    arguments: dict[str, Any]

    @classmethod
    def of(cls, name: str, *args: Any, **kwargs: Any) -> OperationCall:
        """The call of operation ``name`` with its arguments given as the operation's
        function takes them (after the scene)."""
        return cls(name, operation(name, "operation").bind(args, kwargs))

    @property
    def structural(self) -> bool:
        """An operation that changes the scene is structural."""
        return operation(self.operation, "operation").mutates

    @property
    def staged(self) -> bool:
        """A staged operation (``reachwise.distance.scene_ops.staged_operation``): its
        slow first stage runs without the scene lock, off the thread that answers
        queries."""
        return operation(self.operation, "operation").hand_over is not None

    def body(self) -> Body:
        op = operation(self.operation, "operation")
        hints = {a.name: a.hint for a in op.arguments}
        return {
            "operation": self.operation,
            "arguments": {k: encode_value(v, hints[k]) for k, v in self.arguments.items()},
        }

    @classmethod
    def parse(cls, r: Reader, limits: Limits) -> Self:
        name = check_name(r.get("operation"), r.path("operation"))
        op = operation(name, r.path("operation"))
        a = Reader(r.get("arguments"), r.path("arguments"))
        arguments = {}
        for arg in op.arguments:
            raw = a.get(arg.name, optional=arg.has_default)
            if arg.name in a.body:
                arguments[arg.name] = decode_value(raw, arg.hint, a.path(arg.name))
        a.done()
        return cls(name, arguments)


REQUESTS: dict[str, type[Request]] = {
    cls.OP: cls
    for cls in (
        Hello,
        Health,
        Metrics,
        AddObject,
        ReplaceCloud,
        SetJoints,
        SetPose,
        Query,
        OperationCall,
    )
}
