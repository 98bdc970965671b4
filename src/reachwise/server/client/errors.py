"""What a collision-server call raises: the server could not answer, did not answer in
time, or rejected the request's content."""

from __future__ import annotations

import reachwise.errors as errors
import reachwise.server.protocol as P
from reachwise.errors import InputError

__all__ = ["ServerError", "ServerInputError", "ServerUnavailable"]


class ServerError(errors.ServerUnavailable):
    """The collision server could not answer: ``code`` (None when there was no reply).
    An unavailable service to the caller (:class:`reachwise.errors.ServerUnavailable`)."""

    def __init__(self, message: str, code: P.ErrorCode | None = None, field: str = "") -> None:
        self.code = code
        self.field = field
        super().__init__(message)


class ServerUnavailable(ServerError):
    """No reply within the deadline (the socket has been recreated)."""


class ServerInputError(InputError):
    """The server rejected the request's content: ``code`` and ``field`` as sent."""

    def __init__(self, address: str, error: P.ErrorReply) -> None:
        self.code = error.code
        super().__init__(
            f"collision server {address}", error.field, f"{error.message} [{error.code}]"
        )
