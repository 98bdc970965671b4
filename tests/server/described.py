"""The scene a service holds, asked for as a client asks: the registered ``describe``
operation sent through :meth:`SceneService.handle` and its reply decoded."""

from __future__ import annotations

import reachwise.server.protocol as P
from reachwise.distance.scene_queries import SceneDescription
from reachwise.server.service import SceneService


def described(svc: SceneService, clouds: bool = False) -> SceneDescription:
    """``svc``'s scene as the ``describe`` operation answers it over the wire."""
    reply = svc.handle(P.OperationCall.of("describe", clouds=clouds))
    assert isinstance(reply, P.OperationResult)
    op = P.operation("describe", "operation")
    result = P.decode_value(reply.result, op.result, "body.result")
    assert isinstance(result, SceneDescription)
    return result
