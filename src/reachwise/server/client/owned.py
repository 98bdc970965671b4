"""The owned scene: a client that owns the collision server's scene, as a simulator
does (:func:`owned_scene`), and the options that say how to reach that server
(:class:`ServerOptions`)."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from reachwise.server.client.remote_scene import SceneClient

__all__ = ["SIMULATION_DEADLINE", "ServerOptions", "owned_scene"]

#: Default per-tick deadline of a simulation on a server (s): in simulated time a
#: late reply only has to be told from a lost one.
SIMULATION_DEADLINE = 0.1


@dataclass(frozen=True)
class ServerOptions:
    """How a simulation reaches its collision server: ``address``, the per-tick
    ``deadline`` (s; a reply later than that is missing data), CURVE ``keys`` (a
    ``reachwise serve keygen`` folder) and how long to wait for the server to be
    ready at the start (``ready_timeout``, s)."""

    address: str
    deadline: float = SIMULATION_DEADLINE
    keys: str | Path | None = None
    ready_timeout: float = 30.0


def owned_scene(
    server: str | ServerOptions, clock: Callable[[], float] = time.monotonic
) -> SceneClient:
    """A client that owns the server's scene, as a simulator does: it waits until the
    server is ready, clears its scene, mirrors what it registers (``mirror``), sends
    joint states and poses with the query (``batch_inputs``) and stamps with ``clock``
    (a simulation's simulated time). Raises :class:`ServerUnavailable` if the server
    does not become ready in time."""
    opts = server if isinstance(server, ServerOptions) else ServerOptions(server)
    client = SceneClient(
        opts.address,
        deadline=opts.deadline,
        keys=opts.keys,
        clock=clock,
        batch_inputs=True,
        mirror=True,
        name="reachwise-simulate",
    )
    try:
        client.wait_ready(opts.ready_timeout)
        client.hello()
        client.clear()
    except BaseException:
        client.close()
        raise
    return client
