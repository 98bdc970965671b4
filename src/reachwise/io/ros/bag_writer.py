"""Writing a ROS 2 recording (sqlite3 or MCAP) with :mod:`rosbags` (the ``ros`` extra).

A path ending in ``.mcap`` becomes an MCAP bag, anything else a sqlite3 bag; either is
a ROS 2 bag folder (``metadata.yaml`` beside the storage file) that ``ros2 bag play``,
Foxglove and :class:`~reachwise.io.ros.bag.Recording` read. An existing path is never
overwritten. Messages are ROS 2 Humble types (:class:`~reachwise.io.ros.messages.MessageFactory`).
"""

from __future__ import annotations

from pathlib import Path
from types import TracebackType
from typing import Any, Literal

from reachwise.errors import InputError
from reachwise.io.ros.messages import MessageFactory
from reachwise.io.ros.rosbags_lib import rosbags_module, typestore

__all__ = ["BagWriter", "StorageFormat"]

StorageFormat = Literal["sqlite3", "mcap"]


class BagWriter:
    """A ROS 2 bag being written (a context manager). ``write(topic, msgtype, msg, t)``
    adds a message received at ``t`` (s >= 0); topics are registered on first use."""

    def __init__(self, path: str | Path, storage: StorageFormat | None = None) -> None:
        self.path = Path(path)
        if self.path.exists():
            raise InputError(str(self.path), "", "exists already; not overwriting a recording")
        if storage is None:
            storage = "mcap" if self.path.suffix == ".mcap" else "sqlite3"
        if storage not in ("sqlite3", "mcap"):
            raise InputError(str(self.path), "storage", f"must be sqlite3 or mcap, got {storage!r}")
        rosbag2 = rosbags_module("rosbag2")
        plugin = rosbag2.StoragePlugin.MCAP if storage == "mcap" else rosbag2.StoragePlugin.SQLITE3
        self.store = typestore("ros2_humble")
        self.factory = MessageFactory(self.store)
        self._writer = rosbag2.Writer(self.path, version=9, storage_plugin=plugin)
        self._writer.open()
        self._connections: dict[str, Any] = {}

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def write(self, topic: str, msgtype: str, msg: Any, t: float) -> None:
        """Add ``msg`` (of ``msgtype``) on ``topic``, received at ``t`` (s)."""
        conn = self._connections.get(topic)
        if conn is None:
            conn = self._writer.add_connection(topic, msgtype, typestore=self.store)
            self._connections[topic] = conn
        stamp = round(t * 1e9)
        if stamp < 0:
            raise InputError(str(self.path), topic, f"negative time {t} s")
        self._writer.write(conn, stamp, self.store.serialize_cdr(msg, msgtype))

    def close(self) -> None:
        """Finish the bag (its index and metadata)."""
        self._writer.close()
