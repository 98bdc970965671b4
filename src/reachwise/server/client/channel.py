"""The request channel to a collision server: one ZeroMQ REQ socket, one request at a
time, each with a deadline.

ZeroMQ REQ sockets cannot tell a slow server from a dead one, so after a missed
deadline the channel closes the socket and makes a new one (the ZeroMQ guide's *Lazy
Pirate*): the next call goes out on a fresh connection, which reaches a restarted
server by itself. A channel belongs to one thread.
"""

from __future__ import annotations

import math
import time

import zmq

import reachwise.server.protocol as P
from reachwise.server.client.errors import ServerError, ServerInputError, ServerUnavailable
from reachwise.server.security import ClientKeys, secure_client_socket

__all__ = ["CLIENT_LIMITS", "Channel"]

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

    def call(self, request: P.Request, deadline: float) -> P.Reply:
        """Send one request and wait for its reply until ``deadline`` seconds.

        Raises :class:`ServerUnavailable` (no reply in time; the socket is recreated),
        :class:`ServerInputError` (the request's content was rejected) or
        :class:`ServerError` (any other typed error or an invalid reply).
        """
        reply_type = P.REPLIES[request.OP]
        sock = self._socket()
        self._next_id += 1
        rid = self._next_id
        end = time.monotonic() + deadline
        try:
            sock.send(P.encode_request(rid, request), zmq.NOBLOCK)
        except zmq.Again:
            self.reset()
            raise ServerUnavailable(f"cannot send {request.OP} to {self.address}") from None
        wait_ms = max(1, math.ceil((end - time.monotonic()) * 1e3))
        if not self._poller.poll(wait_ms):
            self.reset()
            raise ServerUnavailable(
                f"no reply to {request.OP} from {self.address} within {deadline * 1e3:.1f} ms"
            )
        raw = sock.recv()
        try:
            decoded = P.decode_reply(raw, reply_type, CLIENT_LIMITS)
        except P.ProtocolError as exc:
            self.reset()
            raise ServerError(
                f"invalid reply to {request.OP}: {exc}", exc.code, exc.field
            ) from None
        if decoded.request_id not in (rid, None):
            self.reset()
            raise ServerError(
                f"reply to request {decoded.request_id} received for request {rid}",
                P.ErrorCode.BAD_MESSAGE,
                "id",
            )
        if decoded.error is not None:
            err = decoded.error
            if err.code in P.INPUT_CODES:
                raise ServerInputError(self.address, err)
            raise ServerError(f"{request.OP}: {err.message} [{err.code}]", err.code, err.field)
        if decoded.reply is None:  # decode_reply gives one of the two
            raise ServerError(f"empty reply to {request.OP}", P.ErrorCode.BAD_MESSAGE)
        return decoded.reply

    def close(self) -> None:
        """Close the socket and the channel's ZeroMQ context."""
        if self._sock is not None:
            self._sock.close(linger=0)
            self._sock = None
        if not self._ctx.closed:
            self._ctx.term()
