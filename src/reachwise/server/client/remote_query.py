"""The collision-server client's distance query: every watched pair in one round trip.

:meth:`RemoteQueries.query_all` sends the joint states and poses held back by
``batch_inputs`` with the query. Once the client holds the scene's layout (from its
first full reply) the query goes out as one binary tick
(:mod:`reachwise.server.protocol.tick`) and its answer is one float64 array; otherwise
as a ``query`` request whose reply brings the layout. Missing data (no answer in time,
a server still restoring its state, a pair list that differs from a mirror's) is an
invalid :class:`~reachwise.server.client.results.ServerSceneResult`, never an
exception.
"""

from __future__ import annotations

import time
from collections.abc import Iterable

import numpy as np
from numpy.typing import NDArray

import reachwise.server.protocol as P
from reachwise.distance.scene import (
    WatchedPair,
)
from reachwise.server.client.channel import TickAnswer
from reachwise.server.client.client_base import ClientBase
from reachwise.server.client.errors import ServerError, ServerInputError, ServerUnavailable
from reachwise.server.client.results import (
    ServerSceneResult,
    missing_result,
)


class RemoteQueries(ClientBase):
    """The distance queries of :class:`~reachwise.server.client.SceneClient`."""

    def query_all(
        self,
        *,
        pairs: Iterable[tuple[str, str]] | None = None,
        deadline: float | None = None,
    ) -> ServerSceneResult:
        """Answer every watched pair (or the watched ``pairs`` given) at the current
        joint states and poses; missing data gives an invalid result, never raises."""
        stamp = self.clock()
        joints, poses = self._pending_joints, self._pending_poses
        if joints or poses:
            for _, t in joints.values():
                if t < stamp:
                    stamp = t
            for _, t in poses.values():
                if t < stamp:
                    stamp = t
        held = self._layout
        limit = self.deadline if deadline is None else deadline
        try:
            if (
                pairs is None
                and held is not None
                and self._channel.layout is held
                and (self._mirror is None or held.pairs is self._last_pairs)
            ):
                got = self._tick(stamp, held, joints, poses, limit)
                if isinstance(got, tuple):
                    return self._ticked(got, held)
                rep = got
            else:
                req: P.Query = P.unchecked(  # every field made here, as Query would check it
                    P.Query,
                    stamp=stamp,
                    joints={k: q for k, (q, _) in joints.items()} if joints else None,
                    poses={k: p for k, (p, _) in poses.items()} if poses else None,
                    pairs=None if pairs is None else tuple((str(a), str(b)) for a, b in pairs),
                    layout=None if held is None or pairs is not None else held.name,
                )
                rep = self.call(req, limit)
        except ServerUnavailable as exc:
            return self._missing(str(exc))
        except ServerError as exc:
            if exc.code != P.ErrorCode.NOT_READY:
                raise
            return self._missing(str(exc))
        except ServerInputError:
            # the inputs held back were refused: drop them, or every later tick fails too
            self._pending_joints, self._pending_poses = {}, {}
            raise
        return self._replied(rep, held, pairs is not None, joints, poses)

    def _replied(
        self,
        rep: P.Reply,
        held: P.Layout | None,
        chosen: bool,
        joints: dict[str, tuple[NDArray[np.float64], float]],
        poses: dict[str, tuple[NDArray[np.float64], float]],
    ) -> ServerSceneResult:
        """The result of a full reply to a query sent with the ``held`` layout (None:
        none held), of ``chosen`` pairs or of every pair, carrying the held-back
        ``joints`` and ``poses``: the layout it brings is kept, and a reply that does
        not match the layout or a mirror's pairs is missing data."""
        if not isinstance(rep, P.QueryReply):
            return self._missing(f"unexpected reply {type(rep).__name__} to query")
        arrived = self.clock()
        layout = P.Layout.of(rep)
        if layout is not None:
            if layout.key:
                self._layout = self._channel.layout = layout
        elif held is not None and held.name == rep.layout:
            layout = held
        else:  # the server left out a pair list this client does not hold
            self._layout = self._channel.layout = None
            self._channel.reset()
            return self._missing(f"reply without the pair list of layout {rep.layout!r}")
        infos = layout.pairs
        if len(infos) != rep.rows.shape[0]:
            self._layout = self._channel.layout = None
            return self._missing("reply rows do not match the pair list")
        if self._mirror is not None and not chosen and infos is not self._last_pairs:
            mine = tuple(P.PairInfo(w.a, w.b, w.margin, w.kind) for w in self._mirror.pairs)
            if infos != mine:
                self._layout = self._channel.layout = None
                return self._missing(
                    f"the server watches {len(infos)} pairs that differ from the "
                    f"{len(mine)} this client registered (was its state lost?)"
                )
        if joints:
            self._pending_joints = {}
        if poses:
            self._pending_poses = {}
        self._last_sequence = rep.sequence
        self._last_measured = rep.measured_at
        self._last_pairs = infos
        lost, self._lost = self._lost, None
        return ServerSceneResult.of_reply(
            rep, layout, computed_at=arrived, valid=lost is None, reason=lost or ""
        )

    def _tick(
        self,
        stamp: float,
        layout: P.Layout,
        joints: dict[str, tuple[NDArray[np.float64], float]],
        poses: dict[str, tuple[NDArray[np.float64], float]],
        deadline: float,
    ) -> TickAnswer | P.Reply:
        """Every pair's answer as one binary tick under the held ``layout`` (the
        per-tick path: no :class:`~reachwise.server.protocol.Query` or
        :class:`~reachwise.server.protocol.QueryReply` is made): the tick reply's
        parts, or the reply of the full protocol when the tick cannot carry the inputs
        or the server has moved on to another layout (sent within the same
        ``deadline``); raises as :meth:`call`."""
        ch = self._channel
        end = time.monotonic() + deadline
        rid = ch.next_id()
        jmap = {k: q for k, (q, _) in joints.items()} if joints else None
        pmap = {k: p for k, (p, _) in poses.items()} if poses else None
        frame = P.encode_tick_inputs(rid, layout, stamp, jmap, pmap)
        return ch.query_every(
            frame,
            rid,
            layout,
            end,
            deadline,
            lambda: P.unchecked(
                P.Query, stamp=stamp, joints=jmap, poses=pmap, pairs=None, layout=layout.name
            ),
        )

    def _ticked(self, got: TickAnswer, layout: P.Layout) -> ServerSceneResult:
        """The result of a tick reply's parts (the reply is under the held ``layout``:
        its rows are in that layout's pair order)."""
        arrived = self.clock()
        _, seq, measured, compute, rows, clouds = got
        if self._pending_joints:
            self._pending_joints = {}
        if self._pending_poses:
            self._pending_poses = {}
        self._last_sequence = seq
        self._last_measured = measured
        self._last_pairs = layout.pairs
        lost, self._lost = self._lost, None
        return ServerSceneResult.of_rows(
            layout, seq, measured, compute, rows, clouds, arrived, lost is None, lost or ""
        )

    def _missing(self, reason: str) -> ServerSceneResult:
        """The invalid result that stands for data that did not arrive."""
        pairs: tuple[P.PairInfo | WatchedPair, ...] = self._last_pairs
        if self._mirror is not None:
            pairs = self._mirror.pairs
        return missing_result(pairs, self._last_sequence, self._last_measured, reason)
