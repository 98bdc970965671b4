"""Reading a recording: a ROS 1 ``.bag``, a ROS 2 bag folder, or a lone ROS 2 storage
file (``.db3`` sqlite3, ``.mcap``), through :mod:`rosbags` (the ``ros`` extra).

:class:`Recording` opens it and yields :class:`BagMessage` objects (topic, receive time,
deserialized message) in the order of their receive times. A path that is not a
recording, a truncated file, or bytes that do not decode raise
:class:`~reachwise.io.ros.recording_error.RecordingError` (an
:class:`~reachwise.errors.InputError`) naming the file, and, once messages flow, the
topic and time of the last message read — never a traceback of the reader.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any

from reachwise.errors import InputError, ReachwiseError, UnknownName
from reachwise.io.ros.recording_error import RecordingError
from reachwise.io.ros.rosbags_lib import rosbags_module, typestore

__all__ = ["BagMessage", "Recording"]


@dataclass(frozen=True)
class BagMessage:
    """One message: its ``topic``, ``msgtype`` (``sensor_msgs/msg/JointState``), the
    time it was recorded ``t`` (s, the bag's receive time) and the deserialized
    ``msg``."""

    topic: str
    msgtype: str
    t: float
    msg: Any


class Recording:
    """A recording opened for reading (a context manager; see the module docstring)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.source = str(self.path)
        if not self.path.exists():
            raise InputError(self.source, "", "no such file or folder")
        highlevel = rosbags_module("highlevel")
        try:
            reader = highlevel.AnyReader([self.path], default_typestore=typestore("latest"))
            reader.open()
        except ReachwiseError:
            raise
        except Exception as exc:  # the reader's many ways to refuse bytes
            raise InputError(
                self.source, "", f"not a readable ROS 1 or ROS 2 recording: {_why(exc)}"
            ) from None
        self._reader = reader
        self.topics: dict[str, str] = {c.topic: c.msgtype for c in reader.connections}
        #: A ROS 1 bag (else ROS 2).
        self.ros1: bool = not reader.is2

    def __enter__(self) -> Recording:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def close(self) -> None:
        """Close the files."""
        try:
            self._reader.close()
        except Exception:  # closing a broken file must not hide the error that broke it
            pass

    @property
    def start(self) -> float:
        """The first receive time (s)."""
        return float(self._reader.start_time) / 1e9

    def check_topic(self, topic: str, msgtypes: Iterable[str] = ()) -> str:
        """``topic``'s message type, checked against ``msgtypes`` when given."""
        msgtype = self.topics.get(topic)
        if msgtype is None:
            raise UnknownName(self.source, "topic", topic, self.topics)
        allowed = tuple(msgtypes)
        if allowed and msgtype not in allowed:
            raise RecordingError(
                topic,
                None,
                "type",
                f"is {msgtype}, expected one of {list(allowed)}",
                bag=self.source,
            )
        return msgtype

    def messages(self, topics: Iterable[str]) -> Iterator[BagMessage]:
        """The messages of ``topics`` in the order of their receive times."""
        wanted = set(topics)
        for t in wanted:
            self.check_topic(t)
        reader = self._reader
        conns = [c for c in reader.connections if c.topic in wanted]
        last_topic, last_t = "", None
        it = reader.messages(connections=conns)
        while True:
            try:
                item = next(it, None)
                if item is None:
                    return
                conn, stamp, raw = item
                last_topic, last_t = conn.topic, stamp / 1e9
                msg = reader.deserialize(raw, conn.msgtype)
            except ReachwiseError:
                raise
            except Exception as exc:
                raise RecordingError(
                    last_topic or "(any)",
                    last_t,
                    "data",
                    f"the recording breaks off or does not decode: {_why(exc)}",
                    bag=self.source,
                ) from None
            yield BagMessage(conn.topic, conn.msgtype, stamp / 1e9, msg)


def _why(exc: BaseException) -> str:
    text = str(exc).strip() or type(exc).__name__
    return text if len(text) < 300 else text[:300] + " …"
