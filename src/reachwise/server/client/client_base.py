"""The collision-server client's connection: its settings, socket and setup calls.

:class:`ClientBase` holds what every call of :class:`~reachwise.server.client.SceneClient`
shares: the deadlines, the CURVE keys, the clock, the ZeroMQ channel
(:class:`~reachwise.server.client.channel.Channel`), the joint states and poses held
back by ``batch_inputs``, the layout of the last answer and the local copy of a
``mirror`` client; :meth:`ClientBase.call` sends one request within its deadline.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Self, TypeVar

import numpy as np
from numpy.typing import NDArray

import reachwise.server.protocol as P
from reachwise.distance.scene import (
    Scene,
)
from reachwise.errors import InputError
from reachwise.server.client.channel import Channel
from reachwise.server.client.errors import ServerError
from reachwise.server.security import ClientKeys, load_client_keys

__all__ = ["SETUP_DEADLINE", "TICK_DEADLINE", "ClientBase"]

#: Default deadline of the per-tick calls (s): one 10 ms control cycle of P-V.
TICK_DEADLINE = 0.010
#: Default deadline of setup calls (s): building a large cloud's index takes a while.
SETUP_DEADLINE = 30.0

_R = TypeVar("_R", bound=P.Reply)


class ClientBase:
    """The connection of a :class:`~reachwise.server.client.SceneClient` to the
    collision server at ``address`` (see that class for the arguments)."""

    def __init__(
        self,
        address: str,
        *,
        deadline: float = TICK_DEADLINE,
        setup_deadline: float = SETUP_DEADLINE,
        keys: str | Path | ClientKeys | None = None,
        clock: Callable[[], float] = time.monotonic,
        batch_inputs: bool = False,
        mirror: bool = False,
        name: str = "reachwise",
    ) -> None:
        for label, value in (("deadline", deadline), ("setup_deadline", setup_deadline)):
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise InputError("SceneClient", label, f"must be a time > 0 s, got {value!r}")
        self.address = address
        self.deadline = float(deadline)
        self.setup_deadline = float(setup_deadline)
        self.keys = load_client_keys(keys) if isinstance(keys, str | Path) else keys
        self.clock = clock
        self.batch_inputs = batch_inputs
        self.name = name
        self._channel = Channel(address, self.keys)
        self._pending_joints: dict[str, tuple[NDArray[np.float64], float]] = {}
        self._pending_poses: dict[str, tuple[NDArray[np.float64], float]] = {}
        self._lost: str | None = None
        self._last_sequence = 0
        self._last_measured = math.nan
        self._layout: P.Layout | None = None
        self._last_pairs: tuple[P.PairInfo, ...] = ()
        self._mirror: Scene | None = Scene() if mirror else None

    # ------------------------------------------------------------------ channel
    @property
    def reconnects(self) -> int:
        """How many times the socket was recreated after a lost reply."""
        return self._channel.reconnects

    @property
    def ticks(self) -> int:
        """How many queries were answered through the binary tick path."""
        return self._channel.ticks

    def call(self, request: P.Request, deadline: float | None = None) -> P.Reply:
        """Send one request and wait for its reply until ``deadline`` seconds (default
        ``setup_deadline``); see :meth:`Channel.call` for what it raises."""
        limit = self.setup_deadline if deadline is None else float(deadline)
        return self._channel.call(request, limit)

    def _setup(self, request: P.Request, kind: type[_R], deadline: float | None = None) -> _R:
        """A setup call whose reply must be of type ``kind``."""
        rep = self.call(request, self.setup_deadline if deadline is None else deadline)
        if not isinstance(rep, kind):  # decode_reply parsed it as REPLIES[op]
            raise ServerError(f"unexpected reply {type(rep).__name__} to {request.OP}")
        return rep

    def close(self) -> None:
        """Close the socket and the client's ZeroMQ context (and the mirror's worker)."""
        self._channel.close()
        if self._mirror is not None:
            self._mirror.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
