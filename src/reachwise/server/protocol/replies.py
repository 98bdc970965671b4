"""The bodies of the server's replies, one frozen dataclass per kind, and the
typed error reply. A reply's body is encoded and checked from its fields' type hints
(:mod:`~reachwise.server.protocol.typed`) unless it writes its own: the query reply,
on the per-tick path, does."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Any, Self

import numpy as np
from numpy.typing import NDArray

from reachwise.distance.scene import PAIR_KINDS, PairKind
from reachwise.distance.scene_ops import ArrayShape
from reachwise.server.protocol.fields import (
    MAX_NAME_LENGTH,
    Body,
    ErrorCode,
    ProtocolError,
    Reader,
    check_array,
    check_choice,
    check_float,
    check_int,
    check_list,
    check_name,
    check_text,
    encode_array,
    omit_none,
)
from reachwise.server.protocol.typed import Count, Name, decode_fields, encode_fields

#: A 4x4 pose, finite.
_Pose = Annotated[NDArray[np.float64], ArrayShape((4, 4))]


@dataclass(frozen=True)
class Reply:
    """Base of every reply body."""

    def body(self) -> Body:
        """The wire form: every field encoded from its type hint."""
        return encode_fields(self)

    @classmethod
    def parse(cls, r: Reader) -> Self:
        """The reply read from ``r``, every field checked against its type hint."""
        return decode_fields(cls, r)


@dataclass(frozen=True)
class Ack(Reply):
    """Done; nothing to report."""


@dataclass(frozen=True)
class HelloReply(Reply):
    """The server's name, version, protocol, ``instance`` and readiness."""

    server: str
    version: str
    protocol: int
    instance: str
    ready: bool


@dataclass(frozen=True)
class HealthReply(Reply):
    """``state``: ``loading`` (restoring the state directory), ``ready`` or ``failed``
    (with ``reason``). ``sequence`` grows with every health and query reply, also
    across restarts when the server has a state directory; ``instance`` changes at
    every start; ``uptime`` in seconds."""

    ready: bool
    state: str
    reason: str
    sequence: Count
    instance: str
    uptime: float
    robots: Count
    objects: Count
    pairs: Count


@dataclass(frozen=True)
class MetricsReply(Reply):
    """``requests`` and ``errors``: counts per op and per error code. Histograms of
    queries in microseconds over ``edges_us`` (bucket k counts values in
    [edges[k-1], edges[k]), the last bucket everything above): ``query_compute``
    the distance computation alone, ``query_handling`` from receipt to reply."""

    uptime: float
    sequence: Count
    requests: dict[str, Count]
    errors: dict[str, Count]
    edges_us: tuple[float, ...]
    query_compute: tuple[Count, ...]
    query_handling: tuple[Count, ...]


@dataclass(frozen=True)
class ObjectReply(Reply):
    """An object after ``add_object`` (``version`` 0) or ``replace_cloud`` (the version
    the server gave the handed-over cloud: 1, 2, … per object): its point count."""

    name: Name
    points: Count
    version: Count = 0


@dataclass(frozen=True)
class PairInfo:
    """A watched pair: object names, margin (m) and kind."""

    a: str
    b: str
    margin: float
    kind: PairKind

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
            check_choice(v[3], PAIR_KINDS, f"{where}[3]"),
        )


def _pairs(r: Reader, key: str = "pairs") -> tuple[PairInfo, ...]:
    lst = check_list(r.get(key), r.path(key))
    return tuple(PairInfo.parse(p, f"{r.path(key)}[{i}]") for i, p in enumerate(lst))


#: Columns of :attr:`QueryReply.rows`: distance, point_a (3), point_b (3), direction (3),
#: index_a, index_b, no_risk (0 or 1).
ROW_COLUMNS = 13


#: Columns of :attr:`QueryReply.clouds`: the version of each object's cloud the answer
#: used, and the time stamp (s, sender's clock) of that cloud's measurement.
CLOUD_COLUMNS = 2


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

    ``layout`` names the list of watched pairs, the objects and the robots (it changes
    whenever one of them changes, and at every server start; empty for a query of
    chosen pairs): a decimal number, the key binary ticks carry
    (:mod:`~reachwise.server.protocol.tick`). ``pairs``, ``objects`` and ``robots``
    are None when the request named the current layout: the rows are then in the order
    of the lists the client holds.

    ``clouds`` has one row of :data:`CLOUD_COLUMNS` per object, in the order of
    ``objects``: the version of the object's cloud the answer used (0 for the cloud it
    was added with) and the time stamp of that cloud's measurement (+inf for a cloud
    that does not age, as the in-process scene reports).
    """

    sequence: int
    measured_at: float
    compute_time: float
    layout: str
    pairs: tuple[PairInfo, ...] | None
    rows: NDArray[np.float64]
    objects: tuple[str, ...] | None = None
    robots: tuple[str, ...] | None = None
    clouds: NDArray[np.float64] | None = None

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
        return omit_none(
            {
                "sequence": self.sequence,
                "measured_at": self.measured_at,
                "compute_time": self.compute_time,
                "layout": self.layout,
                "pairs": None if self.pairs is None else [p.wire() for p in self.pairs],
                "objects": None if self.objects is None else list(self.objects),
                "robots": None if self.robots is None else list(self.robots),
                "rows": encode_array(self.rows),
                "clouds": None if self.clouds is None else encode_array(self.clouds),
            }
        )

    @classmethod
    def parse(cls, r: Reader) -> Self:
        pairs = None if r.opt("pairs") is None else _pairs(r)
        objects = _names(r, "objects")
        robots = _names(r, "robots")
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
        cv = r.opt("clouds")
        clouds = None
        if cv is not None:
            clouds = check_array(cv, r.path("clouds"), shape=(None, CLOUD_COLUMNS), finite=False)
            check_cloud_table(clouds, r.path("clouds"))
            if objects is not None and len(objects) != clouds.shape[0]:
                raise ProtocolError(
                    ErrorCode.WRONG_SHAPE,
                    r.path("clouds"),
                    f"{clouds.shape[0]} rows for {len(objects)} objects",
                )
        return cls(
            check_int(r.get("sequence"), r.path("sequence"), minimum=0),
            check_float(r.get("measured_at"), r.path("measured_at")),
            check_float(r.get("compute_time"), r.path("compute_time"), minimum=0.0),
            check_text(r.get("layout"), r.path("layout"), MAX_NAME_LENGTH),
            pairs,
            rows,
            objects,
            robots,
            clouds,
        )


def check_cloud_table(clouds: NDArray[np.float64], where: str) -> None:
    """Versions (column 0) must be whole numbers >= 0; stamps (column 1) may be any
    number, +inf (does not age) or NaN (unknown)."""
    v = clouds[:, 0]
    if not bool(np.all((v >= 0.0) & (v == np.floor(v)) & (v < 2.0**53))):
        raise ProtocolError(ErrorCode.WRONG_TYPE, where, "column 0 (version) must be integers >= 0")


def _names(r: Reader, key: str) -> tuple[str, ...] | None:
    v = r.opt(key)
    if v is None:
        return None
    lst = check_list(v, r.path(key))
    return tuple(check_name(x, f"{r.path(key)}[{i}]") for i, x in enumerate(lst))


@dataclass(frozen=True, eq=False)
class OperationResult(Reply):
    """The result of an :class:`~reachwise.server.protocol.requests.OperationCall` as
    sent: ``result`` is plain data, which
    :func:`~reachwise.server.protocol.typed.decode_value` checks against the
    operation's result type."""

    result: Any

    def body(self) -> Body:
        return {"result": self.result}

    @classmethod
    def parse(cls, r: Reader) -> Self:
        return cls(r.get("result"))


#: The reply type of every request op.
REPLIES: dict[str, type[Reply]] = {
    "hello": HelloReply,
    "health": HealthReply,
    "metrics": MetricsReply,
    "add_object": ObjectReply,
    "replace_cloud": ObjectReply,
    "set_joints": Ack,
    "set_pose": Ack,
    "query": QueryReply,
    "call": OperationResult,
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
