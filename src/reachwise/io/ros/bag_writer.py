"""Writing a recording with :mod:`rosbags` (the ``ros`` extra): ROS 2 (sqlite3 or MCAP)
or ROS 1.

A path ending in ``.bag`` becomes a ROS 1 bag (one file, format 2.0, what ``rosbag
play`` and RViz on ROS 1 read), one ending in ``.mcap`` an MCAP bag, anything else a
sqlite3 bag; the two ROS 2 kinds are bag folders (``metadata.yaml`` beside the storage
file) that ``ros2 bag play`` and Foxglove read. :class:`~reachwise.io.ros.bag.Recording`
reads all three. An existing path is never overwritten. Messages are ROS 2 Humble
types, or ROS 1 Noetic types in a ROS 1 bag, made by ``BagWriter.factory``
(:class:`~reachwise.io.ros.messages.MessageFactory`) with the same calls.
"""

from __future__ import annotations

from pathlib import Path
from types import TracebackType
from typing import Any, Literal

from reachwise.errors import InputError
from reachwise.io.ros.messages import MessageFactory
from reachwise.io.ros.rosbags_lib import rosbags_module, typestore

__all__ = ["BagWriter", "StorageFormat"]

StorageFormat = Literal["sqlite3", "mcap", "ros1"]
#: ``tf2_msgs/TFMessage`` (ROS 1), as its package defines it.
_TF_MESSAGE = "geometry_msgs/TransformStamped[] transforms"


class BagWriter:
    """A bag being written (a context manager; ``storage``: as the path's suffix says,
    see the module docstring). ``write(topic, msgtype, msg, t)`` adds a message
    received at ``t`` (s >= 0), ``msgtype`` in ROS 2 spelling
    (``std_msgs/msg/Float64``) for either; topics are registered on first use."""

    def __init__(self, path: str | Path, storage: StorageFormat | None = None) -> None:
        self.path = Path(path)
        if self.path.exists():
            raise InputError(str(self.path), "", "exists already; not overwriting a recording")
        if storage is None:
            suffix = self.path.suffix
            storage = "ros1" if suffix == ".bag" else "mcap" if suffix == ".mcap" else "sqlite3"
        if storage not in ("sqlite3", "mcap", "ros1"):
            raise InputError(
                str(self.path), "storage", f"must be sqlite3, mcap or ros1, got {storage!r}"
            )
        self.storage = storage
        if storage == "ros1":
            self.store = typestore("ros1_noetic")
            # Noetic's store lacks tf2_msgs (a fresh store each call: registered here only)
            typesys = rosbags_module("typesys")
            self.store.register(typesys.get_types_from_msg(_TF_MESSAGE, "tf2_msgs/msg/TFMessage"))
            self._writer = rosbags_module("rosbag1").Writer(self.path)
            self._serialize = self.store.serialize_ros1
        else:
            rosbag2 = rosbags_module("rosbag2")
            plugin = (
                rosbag2.StoragePlugin.MCAP if storage == "mcap" else rosbag2.StoragePlugin.SQLITE3
            )
            self.store = typestore("ros2_humble")
            self._writer = rosbag2.Writer(self.path, version=9, storage_plugin=plugin)
            self._serialize = self.store.serialize_cdr
        self.factory = MessageFactory(self.store)
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
        self._writer.write(conn, stamp, self._serialize(msg, msgtype))

    def close(self) -> None:
        """Finish the bag (its index and metadata)."""
        self._writer.close()
