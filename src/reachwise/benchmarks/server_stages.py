"""Where a query's microseconds go beyond the distance computation: each stage of the
request path timed alone, in this process (no network), for the full msgpack path and
for the binary tick path: how much of a request's time is our own work.

Stages, per query of the benchmark's crane scene carrying one joint state: the
client's request (making the :class:`~reachwise.server.protocol.Query` and encoding
it), the server's decoding, its handling beyond :meth:`Scene.query_all` (checking and
applying the joint state, the sequence, time stamps, the layout and cloud table, the
rows of the reply), its encoding of the reply, the client's decoding, and the result
the client returns (``full``: every pair result built, as the client did before;
``tick``: the lazy result, pairs built when first read; ``tick.result_pairs`` is that
reading). The ``tick`` stages time the functions the per-tick path calls (no
:class:`~reachwise.server.protocol.Query` or
:class:`~reachwise.server.protocol.QueryReply` is made on it). The server's handling
is the median of ``handle(query) − query_all()`` over interleaved pairs of calls
(``full``), which cancels the computation and most load swings; ``tick.server_tick``
is the median of ``SceneService.tick(frame) − query_all()``, the server's whole tick
(decoding, handling, encoding), and the tick's handling is that minus its decoding and
encoding.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

import reachwise.server.protocol as P
from reachwise.benchmarks._harness import BenchReport, time_interleaved
from reachwise.benchmarks.distance import environment_points, part_points
from reachwise.benchmarks.server_setup import ENV_X, LINKS, MARGIN, crane_q
from reachwise.kinematics.robot import Robot
from reachwise.server.client.results import ServerSceneResult
from reachwise.server.service import SceneService

__all__ = ["STAGES", "stage_costs"]

#: The stages, in request order.
STAGES = (
    "client_request",
    "server_decode",
    "server_handling",
    "server_encode",
    "client_decode",
    "client_result",
)


def _service(robot: Robot) -> SceneService:
    svc = SceneService()
    svc.handle(P.OperationCall.of("add_robot", robot, crane_q(robot, 0), stamp=0.0))
    part = part_points(1000, seed=1)
    for link in LINKS:
        svc.handle(P.AddObject(link, part, None, robot.name, link))
    pose = np.eye(4)
    pose[0, 3] = ENV_X
    svc.handle(P.AddObject("environment", environment_points(5500, seed=2), pose))
    svc.handle(P.OperationCall.of("watch_environment", robot.name, MARGIN))
    return svc


@dataclass(frozen=True)
class _Frames:
    """One query of the benchmark scene and its reply, made once in every form the
    stages take as input (encoded request and tick frame, reply, encoded replies)."""

    q: NDArray[np.float64]
    query: P.Query
    layout: P.Layout
    full_raw: bytes
    tick_raw: bytes
    reply: P.QueryReply
    full_reply: bytes
    tick_reply: bytes


def _frames(svc: SceneService, robot: Robot) -> _Frames:
    """The query of :func:`stage_costs` on ``svc`` (its layout sent by a first query),
    encoded both ways, and its reply, encoded both ways."""
    q = crane_q(robot, 2950)  # two of the four pairs within the margin
    first = svc.handle(P.Query(1.0, {robot.name: q}))
    if not isinstance(first, P.QueryReply):
        raise RuntimeError("the first query was not answered")
    layout = P.Layout.of(first)
    if layout is None:
        raise RuntimeError("the first reply sent no layout")
    query = P.Query(1.0, {robot.name: q}, None, None, layout.name)
    full_raw = P.encode_request(1, query)
    tick_raw = P.encode_tick(1, query, layout)
    if tick_raw is None:
        raise RuntimeError("the query does not fit a tick")
    reply = svc.handle(query)
    if not isinstance(reply, P.QueryReply):
        raise RuntimeError("the query was not answered")
    full_reply = P.encode_reply(1, reply)
    tick_reply = P.encode_tick_reply(1, reply, layout)
    return _Frames(q, query, layout, full_raw, tick_raw, reply, full_reply, tick_reply)


def _stage_calls(
    svc: SceneService, robot: Robot, frames: _Frames
) -> dict[str, Callable[[int], object]]:
    """The timed calls: ``full.<stage>`` and ``tick.<stage>``, and the server's whole
    ``handle``, ``tick`` and the ``query_all`` they contain."""
    q, query, layout = frames.q, frames.query, frames.layout
    full_raw, tick_raw, reply = frames.full_raw, frames.tick_raw, frames.reply
    full_reply, tick_reply = frames.full_reply, frames.tick_reply
    name = layout.name
    parts = P.read_tick_reply(tick_reply, layout)
    limits = P.DEFAULT_LIMITS
    if reply.clouds is None:
        raise RuntimeError("the reply has no cloud table")
    clouds, cloud_bytes = reply.clouds, reply.clouds.tobytes()

    def result(r: P.QueryReply) -> ServerSceneResult:
        return ServerSceneResult.of_reply(r, layout, computed_at=1.0)

    def tick_result() -> ServerSceneResult:
        _, seq, measured, compute, rows, table = parts
        return ServerSceneResult.of_rows(layout, seq, measured, compute, rows, table, 1.0)

    full: dict[str, Callable[[int], object]] = {
        "client_request": lambda i: P.encode_request(
            1, P.Query(1.0, {robot.name: q}, None, None, name)
        ),
        "server_decode": lambda i: P.decode_request(full_raw, limits),
        "server_encode": lambda i: P.encode_reply(1, reply),
        "client_decode": lambda i: P.decode_reply(full_reply, P.QueryReply),
        "client_result": lambda i: result(reply).pairs,
    }
    tick: dict[str, Callable[[int], object]] = {
        "client_request": lambda i: P.encode_tick_inputs(1, layout, 1.0, {robot.name: q}),
        "server_decode": lambda i: P.read_tick(tick_raw, layout, limits),
        "server_encode": lambda i: P.tick_reply_frame(
            1,
            reply.sequence,
            layout.key,
            reply.measured_at,
            reply.compute_time,
            reply.rows,
            clouds.shape[0],
            cloud_bytes,
        ),
        "client_decode": lambda i: P.read_tick_reply(tick_reply, layout),
        "client_result": lambda i: tick_result(),
        "result_pairs": lambda i: tick_result().pairs,
    }
    return {
        **{f"full.{k}": v for k, v in full.items()},
        **{f"tick.{k}": v for k, v in tick.items()},
        "handle": lambda i: svc.handle(query),
        "tick": lambda i: svc.tick(tick_raw, limits),
        "query_all": lambda i: svc.scene.query_all(),
    }


def stage_costs(rep: BenchReport, robot: Robot, repeat: int) -> None:
    """Add ``stage.full.<stage>``, ``stage.tick.<stage>`` (medians, µs) and their
    ``.total`` to ``rep``."""
    svc = _service(robot)
    calls = _stage_calls(svc, robot, _frames(svc, robot))
    samples = time_interleaved(calls, repeat, warmup=50)
    med = {k: float(np.median(v)) for k, v in samples.items()}
    server_tick = float(np.median(samples["tick"] - samples["query_all"]))
    handling = {
        "full": float(np.median(samples["handle"] - samples["query_all"])),
        "tick": server_tick - med["tick.server_decode"] - med["tick.server_encode"],
    }
    for path in ("full", "tick"):
        total = 0.0
        for stage in STAGES:
            v = handling[path] if stage == "server_handling" else med[f"{path}.{stage}"]
            rep.metrics[f"stage.{path}.{stage}"] = v
            total += v
        rep.metrics[f"stage.{path}.total"] = total
    rep.metrics["stage.tick.server_tick"] = server_tick
    rep.metrics["stage.tick.result_pairs"] = med["tick.result_pairs"]
    rep.metrics["stage.query_all"] = med["query_all"]
    rep.notes.append(
        "stage.*: each stage of the request path timed alone in this process (no network), "
        "interleaved; full.server_handling = median(handle(query) - query_all()); "
        "tick.server_tick = median(SceneService.tick(frame) - query_all()), "
        "tick.server_handling = that minus the tick's decoding and encoding; "
        "full.client_result builds every pair result, tick.client_result is the lazy "
        "result (tick.result_pairs: reading its pairs)"
    )
