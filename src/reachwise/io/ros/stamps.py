"""Message time stamps as seconds."""

from __future__ import annotations

from typing import Any

__all__ = ["header_frame", "header_stamp", "seconds"]


def seconds(stamp: Any) -> float:
    """A ``builtin_interfaces/Time`` (ROS 1 ``time`` as :mod:`rosbags` reads it: ``sec``,
    ``nanosec``) in seconds."""
    return float(stamp.sec) + float(stamp.nanosec) / 1e9


def header_stamp(msg: Any) -> float:
    """The ``header.stamp`` of a message, in seconds."""
    return seconds(msg.header.stamp)


def header_frame(msg: Any) -> str:
    """The ``header.frame_id`` of a message, without a leading ``/`` (ROS 1 style)."""
    return str(msg.header.frame_id).lstrip("/")
