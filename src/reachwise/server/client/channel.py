"""The request channel to a collision server: one ZeroMQ REQ socket, one request at a
time, each with a deadline.

ZeroMQ REQ sockets cannot tell a slow server from a dead one, so after a missed
deadline the channel closes the socket and makes a new one (the ZeroMQ guide's *Lazy
Pirate*): the next call goes out on a fresh connection, which reaches a restarted
server by itself. A channel belongs to one thread.

A request with data frames (a streamed cloud) is sent without copying its array
(``copy=False``: ZeroMQ reads the caller's memory). A query goes out as a binary tick
(:mod:`reachwise.server.protocol.tick`) when the channel holds the scene's layout
(:attr:`Channel.layout`, set by the remote scene from a full reply); should the server
have moved on to another layout (``stale_layout``), the channel drops it and sends the
same query in full within the same deadline.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np
import zmq
from numpy.typing import NDArray

import reachwise.server.protocol as P
from reachwise.server.client.errors import ServerError, ServerInputError, ServerUnavailable
from reachwise.server.security import ClientKeys, secure_client_socket

__all__ = ["CLIENT_LIMITS", "Channel", "TickAnswer"]

#: A tick reply's parts (:func:`~reachwise.server.protocol.read_tick_reply`): request id,
#: sequence, measured_at, compute_time, the rows and the cloud table.
TickAnswer = tuple[int, int, float, float, NDArray[np.float64], NDArray[np.float64]]

#: Replies the client accepts: describe with clouds can be large.
CLIENT_LIMITS = P.Limits(max_message_bytes=4 * P.MAX_MESSAGE_BYTES)


class Channel:
    """Requests to the server at ``address`` (CURVE with ``keys``), one at a time.

    :meth:`call` sends a request and waits for its typed reply until a deadline;
    :attr:`reconnects` counts the sockets dropped after a lost reply.
    """

    def __init__(self, address: str, keys: ClientKeys | None = None) -> None:
        self.address = address
        self.keys = keys
        self._ctx: zmq.Context[zmq.Socket[bytes]] = zmq.Context()
        self._sock: zmq.Socket[bytes] | None = None
        self._poller = zmq.Poller()  # one per socket, not one per call
        self._next_id = 0
        self._reconnects = 0
        #: The layout binary ticks are sent under (None: queries go in full).
        self.layout: P.Layout | None = None
        #: Queries answered as binary ticks, and ticks the server refused for a stale
        #: layout (each then sent in full).
        self.ticks = 0
        self.stale_ticks = 0

    @property
    def reconnects(self) -> int:
        """How many times the socket was recreated after a lost reply."""
        return self._reconnects

    def _socket(self) -> zmq.Socket[bytes]:
        if self._sock is None:
            sock = self._ctx.socket(zmq.REQ)
            sock.linger = 0
            sock.setsockopt(zmq.RECONNECT_IVL, 20)
            sock.setsockopt(zmq.RECONNECT_IVL_MAX, 200)
            if self.keys is not None:
                secure_client_socket(sock, self.keys)
            sock.connect(self.address)
            self._sock = sock
            self._poller = zmq.Poller()
            self._poller.register(sock, zmq.POLLIN)
        return self._sock

    def reset(self) -> None:
        """Lazy Pirate: drop the socket (and any reply still on its way)."""
        if self._sock is not None:
            self._sock.close(linger=0)
            self._sock = None
            self._reconnects += 1

    def next_id(self) -> int:
        """A new request id."""
        rid = self._next_id = self._next_id + 1
        return rid

    def call(self, request: P.Request, deadline: float) -> P.Reply:
        """Send one request and wait for its reply until ``deadline`` seconds.

        Raises :class:`ServerUnavailable` (no reply in time; the socket is recreated),
        :class:`ServerInputError` (the request's content was rejected) or
        :class:`ServerError` (any other typed error or an invalid reply).
        """
        end = time.monotonic() + deadline
        layout = self.layout
        if layout is None or type(request) is not P.Query:
            return self.call_full(request, end, deadline)
        rid = self.next_id()
        query = request
        got = self.query_every(
            P.encode_tick(rid, query, layout), rid, layout, end, deadline, lambda: query
        )
        if isinstance(got, tuple):
            _, seq, measured, compute, rows, clouds = got
            return P.tick_query_reply(layout, seq, measured, compute, rows, clouds)
        return got

    def query_every(
        self,
        frame: bytes | None,
        rid: int,
        layout: P.Layout,
        end: float,
        deadline: float,
        full: Callable[[], P.Query],
    ) -> TickAnswer | P.Reply:
        """A query of every pair under ``layout``: as the tick ``frame`` (request
        ``rid``; None when a tick cannot carry the query), the parts of its tick reply;
        in the full protocol (the query ``full`` makes) when there is no frame or the
        server has moved on to another layout, its reply. Waits until ``end``
        (monotonic s); raises as :meth:`call`."""
        if frame is not None:
            got = self.tick(frame, rid, layout, end, deadline)
            if isinstance(got, tuple):
                return got
            if got is not None:
                return self.result("query", got)
        return self.call_full(full(), end, deadline)

    def call_full(self, request: P.Request, end: float, deadline: float) -> P.Reply:
        """:meth:`call` in the full protocol (never a tick), waiting until ``end``
        (monotonic s; ``deadline`` is the call's, for the message)."""
        rid = self.next_id()
        raw = self._exchange(request.OP, P.encode_frames(rid, request), end, deadline)
        return self.result(request.OP, self._decode(request.OP, raw, rid))

    def tick(
        self, frame: bytes, rid: int, layout: P.Layout, end: float, deadline: float
    ) -> TickAnswer | P.DecodedReply | None:
        """Send one tick ``frame`` (request ``rid`` under ``layout``) and wait for its
        reply until ``end`` (monotonic s): the parts of a tick reply
        (:func:`~reachwise.server.protocol.read_tick_reply`), the decoded reply of any
        other answer (a typed error), or None when the server has moved on to another
        layout (the channel drops it: send the query in full). Raises as :meth:`call`
        for no reply or an invalid one."""
        raw = self._exchange("query", [frame], end, deadline)
        if P.is_tick_reply(raw):
            try:
                got = P.read_tick_reply(raw, layout)
            except P.ProtocolError as exc:
                self.reset()
                raise ServerError(f"invalid reply to query: {exc}", exc.code, exc.field) from None
            self._check_id(got[0], rid)
            self.ticks += 1
            return got
        decoded = self._decode("query", raw, rid)
        if decoded.error is not None and decoded.error.code == P.ErrorCode.STALE_LAYOUT:
            self.layout = None  # the server moved on: the query again, in full
            self.stale_ticks += 1
            return None
        return decoded

    def _exchange(self, op: str, frames: list[P.Buffer], end: float, deadline: float) -> bytes:
        """Send ``frames`` and receive the reply frame before ``end`` (monotonic s)."""
        sock = self._socket()
        try:
            if len(frames) == 1:
                sock.send(frames[0], zmq.NOBLOCK)
            else:  # data frames: ZeroMQ reads the arrays where they are
                sock.send_multipart(frames, zmq.NOBLOCK, copy=False)
        except zmq.Again:
            self.reset()
            raise ServerUnavailable(f"cannot send {op} to {self.address}") from None
        wait_ms = max(1, math.ceil((end - time.monotonic()) * 1e3))
        if not self._poller.poll(wait_ms):
            self.reset()
            raise ServerUnavailable(
                f"no reply to {op} from {self.address} within {deadline * 1e3:.1f} ms"
            )
        return sock.recv()

    def _check_id(self, got: int | None, rid: int) -> None:
        if got not in (rid, None):
            self.reset()
            raise ServerError(
                f"reply to request {got} received for request {rid}",
                P.ErrorCode.BAD_MESSAGE,
                "id",
            )

    def _decode(self, op: str, raw: bytes, rid: int) -> P.DecodedReply:
        try:
            decoded = P.decode_reply(raw, P.REPLIES[op], CLIENT_LIMITS)
        except P.ProtocolError as exc:
            self.reset()
            raise ServerError(f"invalid reply to {op}: {exc}", exc.code, exc.field) from None
        self._check_id(decoded.request_id, rid)
        return decoded

    def result(self, op: str, decoded: P.DecodedReply) -> P.Reply:
        """The reply of a decoded answer to ``op`` (one that is not a tick reply: see
        :meth:`tick`), or its typed error raised as :meth:`call` raises it."""
        if decoded.error is not None:
            err = decoded.error
            if err.code in P.INPUT_CODES:
                raise ServerInputError(self.address, err)
            raise ServerError(f"{op}: {err.message} [{err.code}]", err.code, err.field)
        if decoded.reply is None:  # decode_reply gives one of the two
            raise ServerError(f"empty reply to {op}", P.ErrorCode.BAD_MESSAGE)
        return decoded.reply

    def close(self) -> None:
        """Close the socket and the channel's ZeroMQ context."""
        if self._sock is not None:
            self._sock.close(linger=0)
            self._sock = None
        if not self._ctx.closed:
            self._ctx.term()
