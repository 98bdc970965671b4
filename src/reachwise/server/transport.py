"""The collision server on the wire: :class:`CollisionServer`, one ZeroMQ ROUTER
socket, bound locally or with CURVE (:mod:`reachwise.server.security`), in front of the
:class:`reachwise.server.service.SceneService`.

Threads, so that one request never blocks another longer than its own work:

- the *I/O thread* (the one running :meth:`CollisionServer.serve_forever`) receives,
  checks the size, decodes and answers at once everything that is short: hello, health,
  metrics, joint states, poses, queries (binary ticks and full ones), descriptions, and
  handed-over clouds. A cloud arrives as a raw frame received without a copy
  (``copy=False``) and goes to the scene's indexing worker as a view of that frame; the
  reply with its version goes out at once. A ``block`` hand-over's reply is parked
  until the cloud is indexed (checked between messages), holding up nothing else.
  The scene lock is held only for the scene work itself.
- the scene's *indexing worker* (:class:`reachwise.distance.ingest.CloudIngest`) checks
  and indexes handed-over clouds; the first query after a build swaps the new cloud in.
- the *writer thread* does, in arrival order, everything that registers or persists:
  restoring the state directory at start, registering robots and clouds (the cloud and
  its k-d tree are built *outside* the lock and swapped in under it), pair rules,
  staged scene operations (a depth frame fused into a scene memory, outside the lock,
  its cloud swapped in under it), the
  batched write of the latest joint states and poses, and the lazy save of the newest
  streamed clouds. Its replies go back to the I/O thread over an ``inproc://`` socket.
  The distance kernels release the GIL (numba ``nogil``), so an index being built does
  not stall queries.
"""

from __future__ import annotations

import contextlib
import errno
import logging
import math
import os
import queue
import threading
import time
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

import zmq
import zmq.auth.thread

import reachwise.server.protocol as P
from reachwise.distance.engine import StrategyName
from reachwise.errors import InputError, ServerUnavailable
from reachwise.runtime.realtime import fifo_refusal
from reachwise.server.security import DEFAULT_BIND, BindPlan, plan_bind, secure_server_socket
from reachwise.server.service import LIVE_INTERVAL, CloudWait, SceneService, answer
from reachwise.server.state import StateStore

log = logging.getLogger("reachwise.server")


@dataclass(frozen=True)
class _Job:
    route: list[zmq.Frame]
    request_id: int
    request: P.Request


@dataclass(frozen=True, eq=False)
class _Parked:
    """A ``block`` hand-over whose reply waits until its cloud is indexed."""

    route: list[zmq.Frame]
    request_id: int
    wait: CloudWait


_STOP = object()
#: How often parked replies are looked at while there are any (ms).
PARKED_POLL_MS = 2
#: Body frames below this size (bytes) are copied out of ZeroMQ (cheaper than a view
#: for a tick or a short request); larger ones, a cloud's points, are used in place.
COPY_BELOW = 65536
#: At a clean stop, how long to wait for clouds still being indexed before saving (s).
CLOSE_BUILD_WAIT = 5.0

_F = TypeVar("_F", bytes, zmq.Frame)


def split_frames(frames: list[_F]) -> tuple[list[_F], list[_F]]:
    """(routing envelope, body frames) of a ROUTER message: the envelope runs up to
    and including the first empty delimiter frame (REQ peers), else it is the peer
    identity alone (DEALER peers)."""
    if len(frames) == 3 and len(frames[1]) == 0:  # a REQ peer's one-frame request
        return frames[:2], frames[2:]
    for k in range(1, len(frames)):
        if len(frames[k]) == 0:
            return frames[: k + 1], frames[k + 1 :]
    return frames[:1], frames[1:]


def bind_error(address: str, exc: zmq.ZMQError) -> InputError | ServerUnavailable:
    """A failed bind as a typed error naming ``address``: an address ZeroMQ cannot
    parse or a protocol it does not know is bad input (:class:`InputError`); an
    address in use, not on this host or refused by the system leaves the server
    unavailable (:class:`ServerUnavailable`)."""
    why = P.failure_text(exc).split(": ", 1)[-1]
    if exc.errno in (errno.EINVAL, errno.EPROTONOSUPPORT, zmq.EPROTONOSUPPORT):
        return InputError("server", "bind", f"cannot bind {address}: {why}")
    return ServerUnavailable(f"the collision server cannot bind {address}: {why}")


class CollisionServer:
    """The collision server on one ZeroMQ ROUTER socket.

    ``bind`` is checked by :func:`reachwise.server.security.plan_bind` (local by
    default; CURVE with ``keys``; ``insecure`` to bind a non-local address without).
    ``state_dir`` makes the scene durable. :meth:`start` binds and returns the
    endpoint; :meth:`serve_forever` runs the I/O loop until :meth:`stop` (from any
    thread or a signal handler) or ``max_runtime`` seconds; :meth:`close` frees the
    port and every thread. ``with server.background() as endpoint:`` does all of that
    on a thread.
    """

    def __init__(
        self,
        bind: str = DEFAULT_BIND,
        state_dir: str | Path | None = None,
        *,
        keys: str | Path | None = None,
        insecure: bool = False,
        strategy: StrategyName = "default",
        limits: P.Limits = P.DEFAULT_LIMITS,
        live_interval: float = LIVE_INTERVAL,
        io_threads: int = 2,
        io_priority: int | None = None,
    ) -> None:
        if not (isinstance(io_threads, int) and io_threads >= 1):
            raise InputError("server", "io_threads", f"must be an integer >= 1, got {io_threads!r}")
        if io_priority is not None:
            refused = fifo_refusal(io_priority)
            if refused:
                raise InputError("server", "io_priority", f"SCHED_FIFO {refused}")
        #: ZeroMQ I/O threads (2: a camera's frames and a controller's queries arrive on
        #: different connections, so a frame being read does not hold up a query) and
        #: their SCHED_FIFO priority (None: the normal policy).
        self.io_threads = io_threads
        self.io_priority = io_priority
        self.plan: BindPlan = plan_bind(bind, keys, insecure)
        self.limits = limits
        self.live_interval = live_interval
        store = StateStore(state_dir) if state_dir is not None else None
        self.service = SceneService(strategy, store)
        self.endpoint: str | None = None
        self._stop = threading.Event()
        self._jobs: queue.Queue[object] = queue.Queue()
        self._ctx: zmq.Context[zmq.Socket[bytes]] | None = None
        self._router: zmq.Socket[bytes] | None = None
        self._replies: zmq.Socket[bytes] | None = None
        self._auth: zmq.auth.thread.ThreadAuthenticator | None = None
        self._writer: threading.Thread | None = None
        self._parked: list[_Parked] = []
        self._inproc = f"inproc://reachwise-replies-{uuid.uuid4().hex}"

    # ------------------------------------------------------------------ life cycle
    def start(self) -> str:
        """Bind (CURVE if planned), start the writer thread (which restores the state
        directory first) and return the bound endpoint."""
        if self._ctx is not None:
            raise RuntimeError("the server is already started")
        ctx: zmq.Context[zmq.Socket[bytes]] = zmq.Context(self.io_threads)
        if self.io_priority is not None:  # permitted: checked in __init__
            ctx.set(zmq.THREAD_SCHED_POLICY, os.SCHED_FIFO)
            ctx.set(zmq.THREAD_PRIORITY, self.io_priority)
        self._ctx = ctx
        try:
            if self.plan.keys is not None:
                self._auth = zmq.auth.thread.ThreadAuthenticator(ctx, log=log)
                self._auth.start()
                self._auth.configure_curve(domain="*", location=str(self.plan.keys.authorized))
            router = ctx.socket(zmq.ROUTER)
            self._router = router
            router.linger = 0
            # a hard cap far above the checked one: beyond it ZeroMQ drops the peer
            router.setsockopt(zmq.MAXMSGSIZE, 2 * self.limits.max_message_bytes + 4096)
            if self.plan.keys is not None:
                secure_server_socket(router, self.plan.keys)
            try:
                router.bind(self.plan.address)
            except zmq.ZMQError as exc:
                raise bind_error(self.plan.address, exc) from None
            self.endpoint = router.getsockopt_string(zmq.LAST_ENDPOINT)
            replies = ctx.socket(zmq.PULL)
            replies.linger = 0
            replies.bind(self._inproc)
            self._replies = replies
        except BaseException:
            self.close()
            raise
        self._writer = threading.Thread(
            target=self._write_loop, name="reachwise-writer", daemon=True
        )
        self._writer.start()
        log.info(
            "listening on %s (%s%s)",
            self.endpoint,
            "CURVE" if self.plan.curve else "no encryption",
            "" if self.plan.local else ", reachable from other machines",
        )
        return self.endpoint

    def stop(self) -> None:
        """Ask :meth:`serve_forever` to return (thread- and signal-safe)."""
        self._stop.set()

    def close(self) -> None:
        """Stop the writer (saving the latest joint states), close sockets, stop the
        authenticator and terminate the context: the port is free afterwards."""
        self._stop.set()
        if self._writer is not None:
            self._jobs.put(_STOP)
            self._writer.join()
            self._writer = None
        for sock in (self._router, self._replies):
            if sock is not None:
                sock.close(linger=0)
        self._router = self._replies = None
        if self._auth is not None:
            self._auth.stop()
            self._auth = None
        if self._ctx is not None:
            self._ctx.term()
            self._ctx = None
        self._parked = []
        self.service.close()

    def __enter__(self) -> CollisionServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @contextlib.contextmanager
    def background(self) -> Iterator[str]:
        """Start, serve on a thread, yield the endpoint; stop and close on exit."""
        endpoint = self.start()
        thread = threading.Thread(target=self.serve_forever, name="reachwise-io", daemon=True)
        thread.start()
        try:
            yield endpoint
        finally:
            self.stop()
            thread.join()
            self.close()

    # ------------------------------------------------------------------ I/O thread
    def serve_forever(self, max_runtime: float | None = None) -> None:
        """Run the I/O loop until :meth:`stop` or ``max_runtime`` seconds."""
        router, replies = self._router, self._replies
        if router is None or replies is None:
            raise RuntimeError("start() the server first")
        poller = zmq.Poller()
        poller.register(router, zmq.POLLIN)
        poller.register(replies, zmq.POLLIN)
        end = math.inf if max_runtime is None else time.monotonic() + max_runtime
        stop, monotonic, on_message = self._stop, time.monotonic, self._on_message
        events_opt, pollin, noblock = zmq.EVENTS, zmq.POLLIN, zmq.NOBLOCK
        while not stop.is_set() and monotonic() < end:
            for sock, _ in poller.poll(PARKED_POLL_MS if self._parked else 100):
                if sock is replies:
                    while True:
                        try:
                            router.send_multipart(replies.recv_multipart(noblock))
                        except zmq.Again:
                            break
                    continue
                for _ in range(256):  # then look at the replies again
                    try:
                        # no copy: a cloud's points are used where ZeroMQ received them
                        frames = router.recv_multipart(noblock, copy=False)
                    except zmq.Again:
                        break
                    on_message(router, frames)
                    if not int(router.getsockopt(events_opt)) & pollin:
                        break
            if self._parked:
                self._settle_parked(router)

    def _on_message(self, router: zmq.Socket[bytes], frames: list[zmq.Frame]) -> None:
        """Answer one message; whatever fails while handling it (a bug, a
        ``RecursionError``, a ``MemoryError``) becomes an ``internal`` error reply and
        the server keeps serving."""
        try:
            self._handle(router, frames)
        except Exception as exc:
            text = P.failure_text(exc)
            log.error("handling a message failed: %s", text, exc_info=exc)
            err = P.ProtocolError(P.ErrorCode.INTERNAL, "", text)
            try:
                route, _ = split_frames(frames)
                self._send_error(router, route, err)
            except Exception as again:  # the peer is gone or the route is broken
                log.error("could not send the error reply: %s", P.failure_text(again))

    def _handle(self, router: zmq.Socket[bytes], frames: list[zmq.Frame]) -> None:
        t0 = time.perf_counter()
        data: list[P.Buffer]
        if len(frames) == 3 and len(frames[1]) == 0:  # a REQ peer's one-frame request
            route = frames[:2]
            body = frames[2]
            # a small frame is cheaper copied than viewed
            data = [body.bytes if len(body) < COPY_BELOW else body.buffer]
        else:
            route, rest = split_frames(frames)
            data = [f.buffer for f in rest]
        if len(data) == 1 and P.is_tick(data[0]):
            payload, compute = self.service.tick(data[0], self.limits)
            for f in route:  # the parts one by one: no send_multipart checks per tick
                router.send(f, zmq.SNDMORE)
            router.send(payload)
            if compute is not None:  # after the reply is on its way
                self.service.metrics.query(compute, time.perf_counter() - t0)
            return
        try:
            rid, req = P.decode_frames(data, self.limits)
        except P.ProtocolError as exc:
            self._send_error(router, route, exc)
            return
        self.service.metrics.request(req.OP)
        if isinstance(req, P.ReplaceCloud) and req.block:
            try:
                wait = self.service.hand_over(req)
            except P.ProtocolError as exc:
                exc.request_id = rid
                self._send_error(router, route, exc)
                return
            self._parked.append(_Parked(route, rid, wait))
            return
        # a staged operation (a depth frame fused) is slow: on the writer thread, so
        # that this thread answers the queries meanwhile
        if req.structural or (isinstance(req, P.OperationCall) and req.staged):
            if not self.service.ready:
                why = P.ProtocolError(
                    P.ErrorCode.NOT_READY, "op", f"the server is {self.service.state}", rid
                )
                self._send_error(router, route, why)
            else:
                self._jobs.put(_Job(route, rid, req))
            return
        payload, reply = answer(self.service, rid, req)
        router.send_multipart([*route, payload])
        if isinstance(reply, P.QueryReply):
            self.service.metrics.query(reply.compute_time, time.perf_counter() - t0)

    def _settle_parked(self, router: zmq.Socket[bytes]) -> None:
        """Send the replies of the parked ``block`` hand-overs whose clouds are indexed
        (or refused, or too late)."""
        keep = []
        now = time.monotonic()
        for p in self._parked:
            try:
                try:
                    reply = self.service.settle(p.wait)
                except P.ProtocolError:
                    raise
                except Exception as exc:
                    log.error("settling a hand-over failed: %s", P.failure_text(exc))
                    raise P.ProtocolError(
                        P.ErrorCode.INTERNAL, "cloud", P.failure_text(exc)
                    ) from None
                if reply is None and now > p.wait.deadline:
                    raise P.ProtocolError(
                        P.ErrorCode.INTERNAL,
                        "cloud",
                        f"version {p.wait.version} of {p.wait.name!r} was not indexed in time",
                    )
            except P.ProtocolError as exc:
                exc.request_id = p.request_id
                self._send_error(router, p.route, exc)
                continue
            if reply is None:
                keep.append(p)
            else:
                router.send_multipart([*p.route, P.encode_reply(p.request_id, reply)])
        self._parked = keep

    def _send_error(
        self, router: zmq.Socket[bytes], route: list[zmq.Frame], exc: P.ProtocolError
    ) -> None:
        self.service.metrics.error(exc.code)
        router.send_multipart([*route, P.encode_error(exc.request_id, P.ErrorReply.of(exc))])

    # ------------------------------------------------------------------ writer thread
    def _write_loop(self) -> None:
        ctx = self._ctx
        if ctx is None:
            return
        push = ctx.socket(zmq.PUSH)
        push.linger = 0
        push.connect(self._inproc)
        try:
            self.service.load()
            while True:
                try:
                    job = self._jobs.get(timeout=self.live_interval)
                except queue.Empty:
                    job = None
                if job is _STOP:
                    break
                if isinstance(job, _Job):
                    payload, _ = answer(self.service, job.request_id, job.request)
                    push.send_multipart([*job.route, payload])
                self._housekeeping()
        finally:
            with contextlib.suppress(Exception):
                self.service.flush_live(force=True)
            with contextlib.suppress(Exception):
                self.service.flush_clouds(force=True, timeout=CLOSE_BUILD_WAIT)
            push.close(linger=0)

    def _housekeeping(self) -> None:
        try:
            self.service.flush_live()
            self.service.flush_clouds()
            if self.service.store is not None and self.service.sequence.wants_extension:
                self.service.sequence.extend()
        except Exception:  # the writer thread must live on; the next round retries
            log.exception("saving the live state failed")
