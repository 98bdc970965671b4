"""The server's replies as the in-process scene's result types: a query reply's rows as
:class:`~reachwise.distance.scene.PairResult` values equal to the in-process scene's,
the invalid result that stands for missing data, and the described objects and pairs."""

from __future__ import annotations

import math
from dataclasses import dataclass

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
from reachwise.geometry.cloud import PointCloud
from reachwise.server.client.errors import ServerError

__all__ = [
    "MISSING",
    "ServerSceneResult",
    "missing_result",
    "pair_results",
    "scene_object",
    "watched_pair",
]


@dataclass(frozen=True)
class ServerSceneResult(SceneResult):
    """A :class:`~reachwise.distance.scene.SceneResult` from the server. The fields a
    controller reads are the in-process result's: ``sequence``, ``measured_at`` (s,
    the oldest joint state or run-time pose the answer depends on, and the query's
    own stamp), ``computed_at`` (s, when the reply arrived), both on the client's
    clock, and ``valid`` False with a ``reason`` when the data is missing (then every
    distance is NaN and ``sequence`` is the last one received). Added:
    ``compute_time`` (s, the computation on the server)."""

    compute_time: float = math.nan


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


def watched_pair(p: P.PairInfo) -> WatchedPair:
    """A pair the server watches, as the in-process scene's :class:`WatchedPair`."""
    return WatchedPair(p.a, p.b, p.margin, p.kind)


def scene_object(o: P.ObjectInfo) -> SceneObject:
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


def pair_results(infos: tuple[P.PairInfo, ...], rep: P.QueryReply) -> tuple[PairResult, ...]:
    """The reply's rows as PairResults, equal to the in-process scene's."""
    out = []
    rows = rep.rows
    for k, p in enumerate(infos):
        row = rows[k]
        if row[12] == 1.0:
            res = NO_RISK
        else:
            res = DistanceResult(
                float(row[0]), row[1:4], row[4:7], row[7:10], int(row[10]), int(row[11]), False
            )
        out.append(PairResult(p.a, p.b, p.margin, p.kind, res))
    return tuple(out)
