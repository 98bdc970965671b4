"""The collision server's answers: queries, binary ticks and the layout they refer to.

A ``query`` request, or a binary tick (:mod:`reachwise.server.protocol.tick`) on the
per-tick path, applies its joint states and poses (every input checked before any is
applied), answers every watched pair with the scene's
:meth:`~reachwise.distance.Scene.query_all` and replies with the rows in the order of
the current layout (the watched pairs, objects and robots under one key, renewed when
one of them changes), the cloud table (version and stamp of each object's cloud) and
the stamp of the oldest input the answer depends on. A query of chosen pairs answers
those alone, with their own list.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

import reachwise.server.protocol as P
from reachwise.distance.answers import rows_of
from reachwise.distance.scene import SceneResult
from reachwise.server.service_core import ServiceCore, protocol_error_of, wire_error


class SceneAnswering(ServiceCore):
    """The query and tick handlers of :class:`reachwise.server.service.SceneService`."""

    def _query(self, req: P.Query) -> P.Reply:
        stamp = self.clock() if req.stamp is None else req.stamp
        with self.lock:
            if req.pairs is not None:
                return self._query_pairs(req, stamp)
            layout = self._layout or self._current_layout()
            seq, measured, compute, rows, clouds, _ = self._answer_every(
                stamp, req.joints, req.poses, layout
            )
            if req.layout == layout.name:  # the per-tick answer: every field made here
                return P.tick_query_reply(layout, seq, measured, compute, rows, clouds)
            return P.QueryReply(
                seq,
                measured,
                compute,
                layout.name,
                layout.pairs,
                rows,
                layout.objects,
                layout.robots,
                clouds,
            )

    def _checked_inputs(
        self,
        joints: Mapping[str, NDArray[np.float64]] | None,
        poses: Mapping[str, NDArray[np.float64]] | None,
    ) -> dict[str, NDArray[np.float64]]:
        """Check a query's joint states and poses (call under the lock); the checked
        poses. Every input is checked before any is applied: a query's inputs are
        atomic."""
        if joints:
            robots = self._robots
            for name, q in joints.items():
                robot = robots.get(name)
                if robot is None or q.shape != (robot.n,):  # the error, named
                    where = f"body.joints.{name}"
                    self._check_q(self._robot(name, where), q, where)
        if not poses:
            return {}
        return {
            name: self._checked_pose(name, pose, f"body.poses.{name}", f"body.poses.{name}")
            for name, pose in poses.items()
        }

    def _apply_inputs(
        self,
        joints: Mapping[str, NDArray[np.float64]] | None,
        poses: Mapping[str, NDArray[np.float64]],
        stamp: float,
    ) -> None:
        """Apply checked joint states and poses (call under the lock)."""
        for name, q in (joints or {}).items():
            self._store_joints(name, q, stamp)
        for name, pose in poses.items():
            self._store_pose(name, pose, stamp)

    def _answer_every(
        self,
        stamp: float,
        joints: Mapping[str, NDArray[np.float64]] | None,
        poses: Mapping[str, NDArray[np.float64]] | None,
        layout: P.Layout,
    ) -> tuple[int, float, float, NDArray[np.float64], NDArray[np.float64], bytes]:
        """Apply a query's inputs and answer every watched pair (call under the lock,
        ``layout`` the current one): sequence, measured_at, compute time, the rows (in
        the layout's pair order), the cloud table and its bytes."""
        if joints or poses:
            self._apply_inputs(joints, self._checked_inputs(joints, poses), stamp)
        res, compute = self._query_all()
        measured = self._measured_at(None, stamp, self._all_sources)
        clouds, cloud_bytes = self._cloud_table(res.versions, res.cloud_stamps, layout)
        return self.sequence.take(), measured, compute, res.rows, clouds, cloud_bytes

    def _query_all(self) -> tuple[SceneResult, float]:
        """Every watched pair's answer and its computation time (s)."""
        t0 = time.perf_counter()
        res = self.scene.query_all()
        return res, time.perf_counter() - t0

    def _query_pairs(self, req: P.Query, stamp: float) -> P.Reply:
        """A query of chosen watched pairs (call under the lock): their rows alone,
        with their own list (no layout a tick can refer to)."""
        poses = self._checked_inputs(req.joints, req.poses)
        watched = {frozenset((p.a, p.b)) for p in self.scene.pairs}
        for i, (a, b) in enumerate(req.pairs or ()):
            if frozenset((a, b)) not in watched:
                raise wire_error(
                    P.ErrorCode.UNKNOWN_PAIR,
                    f"body.pairs[{i}]",
                    f"pair ({a!r}, {b!r}) is not watched",
                )
        wanted = {frozenset(p) for p in req.pairs or ()}
        self._apply_inputs(req.joints, poses, stamp)
        res, compute = self._query_all()
        layout = self._current_layout()
        pairs = tuple(p for p in res.pairs if frozenset((p.a, p.b)) in wanted)
        measured = self._measured_at(pairs, stamp)
        seq = self.sequence.take()
        clouds, _ = self._cloud_table(res.versions, res.cloud_stamps, layout)
        return P.QueryReply(
            seq,
            measured,
            compute,
            "",
            tuple(P.PairInfo(p.a, p.b, p.margin, p.kind) for p in pairs),
            rows_of(pairs),
            layout.objects,
            layout.robots,
            clouds,
        )

    def tick(self, raw: P.Buffer, limits: P.Limits) -> tuple[bytes, float | None]:
        """Answer one binary tick (:mod:`reachwise.server.protocol.tick`): the reply
        frame (a tick, or a typed error frame) and the answer's computation time (s;
        None for an error). The layout is held (the lock) from decoding to answering,
        so the indices mean what the client meant.

        The per-tick path: the frame is read straight into the inputs and the reply
        written from the answer's parts (no :class:`~reachwise.server.protocol.Query`
        or :class:`~reachwise.server.protocol.QueryReply` is made); the answer, the
        checks and the typed errors are :meth:`handle`'s for that query."""
        rid = None
        try:
            with self.lock:
                if self.state != "ready":
                    why = f": {self.reason}" if self.reason else ""
                    raise wire_error(
                        P.ErrorCode.NOT_READY, "op", f"the server is {self.state}{why}"
                    )
                layout = self._layout or self._current_layout()
                rid, stamp, joints, poses = P.read_tick(raw, layout, limits)
                self.metrics.tick()
                seq, measured, compute, rows, clouds, cloud_bytes = self._answer_every(
                    self.clock() if stamp is None else stamp, joints, poses, layout
                )
        except Exception as exc:
            err = protocol_error_of(exc, "query")
            if err.request_id is None:
                err.request_id = rid
            self.metrics.error(err.code)
            return P.encode_error(err.request_id, P.ErrorReply.of(err)), None
        frame = P.tick_reply_frame(
            rid, seq, layout.key, measured, compute, rows, clouds.shape[0], cloud_bytes
        )
        return frame, compute

    def _current_layout(self) -> P.Layout:
        """The layout of the answers: watched pairs, objects, robots (call under the lock)."""
        if self._layout is None:
            infos = tuple(P.PairInfo(p.a, p.b, p.margin, p.kind) for p in self.scene.pairs)
            key = (self._layout_tag << 32) | (self._layout_count & 0xFFFFFFFF)
            self._layout = P.Layout(key, infos, tuple(self._meta), tuple(self._robots))
            self._all_sources = self._sources(infos)
        return self._layout

    def _cloud_table(
        self, versions: Mapping[str, int], stamps: Mapping[str, float], layout: P.Layout
    ) -> tuple[NDArray[np.float64], bytes]:
        """Version and stamp of each object's cloud in layout order, and the table's
        bytes in a tick reply (call under the lock); the scene replaces its version map
        at every swap, so one table serves every answer until the next swap or layout
        change."""
        cached = self._clouds
        if cached is not None and cached[0] is versions and cached[1] == layout.key:
            return cached[2], cached[3]
        base = self._version_base
        table = np.array(
            [
                (versions.get(n, 0) + base.get(n, 0), stamps.get(n, math.nan))
                for n in layout.objects
            ],
            dtype=np.float64,
        ).reshape(len(layout.objects), P.CLOUD_COLUMNS)
        table.setflags(write=False)
        self._clouds = (versions, layout.key, table, table.tobytes())
        return table, self._clouds[3]

    def _measured_at(
        self,
        pairs: tuple[Any, ...] | None,
        stamp: float,
        every: tuple[tuple[str, str], ...] = (),
    ) -> float:
        """The oldest of ``stamp`` and the stamps of the inputs the poses of ``pairs``'
        objects come from (``pairs`` None: those of every watched pair, ``every``)."""
        sources = every if pairs is None else self._sources(pairs)
        oldest = stamp
        for kind, key in sources:
            entry = self._joints.get(key) if kind == "robot" else self._runtime.get(key)
            if entry is not None and entry[1] < oldest:
                oldest = entry[1]
        return oldest

    def _sources(self, pairs: Iterable[Any]) -> tuple[tuple[str, str], ...]:
        """The inputs (``("robot", name)`` or ``("object", name)``) the poses of the
        pairs' objects come from, each once."""
        out: dict[tuple[str, str], None] = {}
        for p in pairs:
            for name in (p.a, p.b):
                src = self._meta[name].stamp_of
                if src is not None:
                    out[src] = None
        return tuple(out)
