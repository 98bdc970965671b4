"""Client of the collision server, with the in-process scene's interface.

One concept per module:

- :mod:`~reachwise.server.client.channel` — the request channel: one ZeroMQ REQ
  socket, a deadline per call, a fresh socket after a lost reply (Lazy Pirate).
- :mod:`~reachwise.server.client.remote_scene` — :class:`SceneClient`, the scene on the
  server with the :class:`~reachwise.distance.scene.SceneLike` interface (deadlines,
  missing data as an invalid result, time stamps, ``batch_inputs``, ``mirror``).
- :mod:`~reachwise.server.client.results` — the replies as the in-process scene's
  result types (:class:`ServerSceneResult`, :data:`MISSING`).
- :mod:`~reachwise.server.client.owned` — :func:`owned_scene`, a client that owns the
  server's scene, as a simulator does, and its :class:`ServerOptions`.
- :mod:`~reachwise.server.client.errors` — what a call raises.
"""

from reachwise.distance.scene import SceneLike
from reachwise.server.client.channel import CLIENT_LIMITS, Channel
from reachwise.server.client.errors import ServerError, ServerInputError, ServerUnavailable
from reachwise.server.client.owned import SIMULATION_DEADLINE, ServerOptions, owned_scene
from reachwise.server.client.remote_scene import SETUP_DEADLINE, TICK_DEADLINE, SceneClient
from reachwise.server.client.results import MISSING, ServerSceneResult

__all__ = [
    "CLIENT_LIMITS",
    "MISSING",
    "SETUP_DEADLINE",
    "SIMULATION_DEADLINE",
    "TICK_DEADLINE",
    "Channel",
    "SceneClient",
    "SceneLike",
    "ServerError",
    "ServerInputError",
    "ServerOptions",
    "ServerSceneResult",
    "ServerUnavailable",
    "owned_scene",
]
