"""The error of a bad recording: which bag, topic, time and field, and why."""

from __future__ import annotations

import math

from reachwise.errors import InputError

__all__ = ["RecordingError", "stamp_text"]


def stamp_text(t: float | None) -> str:
    """A time (s) as the errors print it: ``t = 12.345678901 s`` (``unknown time`` for
    None or NaN)."""
    if t is None or math.isnan(t):
        return "unknown time"
    return f"t = {t:.9f} s"


class RecordingError(InputError):
    """A message of a recording cannot be used: ``topic`` at time ``t`` (s, the message's
    stamp, None when unknown), its ``field``, and the ``reason``. ``source`` names the
    bag and the topic."""

    def __init__(
        self, topic: str, t: float | None, field: str, reason: str, *, bag: str = ""
    ) -> None:
        self.topic = topic
        self.t = t
        self.bag = bag
        self._parts = (field, reason)
        where = f"{bag}: topic {topic}" if bag else f"topic {topic}"
        super().__init__(where, field, f"{reason} ({stamp_text(t)})")

    def in_bag(self, bag: str) -> RecordingError:
        """The same error naming the recording ``bag`` (itself when it names one)."""
        if self.bag:
            return self
        return RecordingError(self.topic, self.t, *self._parts, bag=bag)
