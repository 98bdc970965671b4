"""The server's replies as the in-process scene's result types: a query reply's rows as
:class:`~reachwise.distance.scene.PairResult` values equal to the in-process scene's
(built when first asked for), the invalid result that stands for missing data, and the
described objects and pairs."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

import numpy as np
from numpy.typing import NDArray

import reachwise.server.protocol as P
from reachwise.distance._common import NO_RISK, DistanceResult
from reachwise.distance.scene import (
    Fixed,
    OnLink,
    PairResult,
    Runtime,
    SceneObject,
    SceneResult,
    WatchedPair,
)
from reachwise.distance.scene_queries import ObjectInfo
from reachwise.geometry.cloud import PointCloud
from reachwise.server.client.errors import ServerError

__all__ = [
    "MISSING",
    "ServerSceneResult",
    "missing_result",
    "pair_results",
    "scene_object",
]


@dataclass(frozen=True)
class ServerSceneResult(SceneResult):
    """A :class:`~reachwise.distance.scene.SceneResult` from the server. The fields a
    controller reads are the in-process result's: ``sequence``, ``measured_at`` (s,
    the oldest joint state or run-time pose the answer depends on, and the query's
    own stamp), ``computed_at`` (s, when the reply arrived), both on the client's
    clock, ``versions`` and ``cloud_stamps`` (the version of each object's cloud the
    server used and its stamp, on the clock of the client that sent it: see
    :mod:`reachwise.server.protocol`), and ``valid`` False with a ``reason`` when the
    data is missing (then every distance is NaN and ``sequence`` is the last one
    received). Added: ``compute_time`` (s, the computation on the server).

    A result made by :meth:`of_reply` keeps the reply's arrays and builds ``pairs``,
    ``versions`` and ``cloud_stamps`` the first time one of them is read (a 1 kHz
    loop that reads a few fields pays for those alone); it is equal to one built
    eagerly, field by field. :attr:`rows` and :attr:`clouds` give the arrays as they
    came (read-only); ``clouds`` is None for a result built otherwise."""

    compute_time: float = math.nan

    @classmethod
    def of_reply(
        cls,
        reply: P.QueryReply,
        layout: P.Layout,
        *,
        computed_at: float,
        valid: bool = True,
        reason: str = "",
    ) -> ServerSceneResult:
        """The result of ``reply`` to a query answered under ``layout``."""
        return cls.of_rows(
            layout,
            reply.sequence,
            reply.measured_at,
            reply.compute_time,
            reply.rows,
            reply.clouds,
            computed_at,
            valid,
            reason,
        )

    @classmethod
    def of_rows(
        cls,
        layout: P.Layout,
        sequence: int,
        measured_at: float,
        compute_time: float,
        rows: NDArray[np.float64],
        clouds: NDArray[np.float64] | None,
        computed_at: float,
        valid: bool = True,
        reason: str = "",
    ) -> ServerSceneResult:
        """:meth:`of_reply` from the reply's parts (a tick reply's, read without
        making the :class:`~reachwise.server.protocol.QueryReply`)."""
        out = object.__new__(cls)
        out.__dict__.update(
            sequence=sequence,
            measured_at=measured_at,
            computed_at=computed_at,
            valid=valid,
            reason=reason,
            compute_time=compute_time,
            _reply=(layout, rows, clouds),
        )
        return out

    @property
    def rows(self) -> NDArray[np.float64]:
        """The reply's rows as they came (:class:`~reachwise.server.protocol.QueryReply`:
        the in-process scene's row layout, so the controller's converter reads them in
        one compiled call); for a result built otherwise, the rows of its ``pairs``."""
        src = self.__dict__.get("_reply")
        return super().rows if src is None else src[1]

    @property
    def clouds(self) -> NDArray[np.float64] | None:
        """The reply's cloud table: version and stamp per object of the layout."""
        src = self.__dict__.get("_reply")
        return None if src is None else src[2]

    def __getattr__(self, name: str) -> Any:
        # reached only for a field not set yet: the lazy ones of an of_reply result
        src = self.__dict__.get("_reply")
        if src is None or name not in _LAZY:
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        layout, rows, clouds = src
        if name == "pairs":
            self.__dict__["pairs"] = pair_results(layout, rows, clouds)
        else:
            versions, stamps = cloud_maps(layout, clouds)
            self.__dict__.update(versions=versions, cloud_stamps=stamps)
        return self.__dict__[name]


_LAZY = frozenset({"pairs", "versions", "cloud_stamps"})


def _nan3() -> NDArray[np.float64]:
    v = np.full(3, np.nan)
    v.setflags(write=False)
    return v


#: The result of a pair whose answer is missing: every number NaN, not "no risk".
MISSING = DistanceResult(math.nan, _nan3(), _nan3(), _nan3(), -1, -1, False)


def missing_result(
    pairs: tuple[P.PairInfo | WatchedPair, ...], sequence: int, measured_at: float, reason: str
) -> ServerSceneResult:
    """The invalid result that stands for data that did not arrive: every pair
    :data:`MISSING`, the last ``sequence`` and ``measured_at`` received."""
    return ServerSceneResult(
        sequence,
        tuple(PairResult(p.a, p.b, p.margin, p.kind, MISSING) for p in pairs),
        measured_at=measured_at,
        valid=False,
        reason=reason,
    )


def scene_object(o: ObjectInfo) -> SceneObject:
    """A described object (sent with its cloud) as a :class:`SceneObject`."""
    if o.cloud is None:
        raise ServerError(f"object {o.name!r} came without its cloud")
    cloud = PointCloud(o.cloud, frame=o.link or "world", name=o.name)
    source: Fixed | OnLink | Runtime
    if o.source == "link":
        source = OnLink(str(o.robot), str(o.link), np.array(o.pose))
    elif o.source == "runtime":
        source = Runtime()
    else:
        source = Fixed(np.array(o.pose))
    return SceneObject(o.name, cloud, source)


def cloud_maps(
    layout: P.Layout, clouds: NDArray[np.float64] | None
) -> tuple[Mapping[str, int], Mapping[str, float]]:
    """Per object, the version of its cloud and that cloud's stamp (read-only maps, as
    the in-process scene gives them); empty without a cloud table."""
    if clouds is None or clouds.shape[0] != len(layout.objects):
        return MappingProxyType({}), MappingProxyType({})
    table = clouds.tolist()
    return (
        MappingProxyType({n: int(v) for n, (v, _) in zip(layout.objects, table, strict=True)}),
        MappingProxyType({n: t for n, (_, t) in zip(layout.objects, table, strict=True)}),
    )


def _index(v: float) -> int:
    """A row index as sent (a whole number >= -1); anything else reads as -1."""
    return int(v) if v.is_integer() and v >= -1.0 else -1


def pair_results(
    layout: P.Layout, rows: NDArray[np.float64], clouds: NDArray[np.float64] | None = None
) -> tuple[PairResult, ...]:
    """The reply's rows (in ``layout``'s pair order) as PairResults, equal to the
    in-process scene's, each with the versions of its two clouds from ``clouds``."""
    out = []
    flags = rows[:, 10:13].tolist()
    versions: list[tuple[int, int]]
    if clouds is not None and clouds.shape[0] == len(layout.objects) and len(layout.objects):
        ver = clouds[:, 0].tolist()
        versions = [
            (int(ver[ia]) if ia >= 0 else 0, int(ver[ib]) if ib >= 0 else 0)
            for ia, ib in layout.pair_objects.tolist()
        ]
    else:
        versions = [(0, 0)] * len(layout.pairs)
    for k, p in enumerate(layout.pairs):
        ia, ib, flag = flags[k]
        if flag == 1.0:
            res = NO_RISK
        else:
            row = rows[k]
            res = DistanceResult(
                float(row[0]), row[1:4], row[4:7], row[7:10], _index(ia), _index(ib), False
            )
        out.append(PairResult(p.a, p.b, p.margin, p.kind, res, versions[k]))
    return tuple(out)
