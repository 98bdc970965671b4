"""The optional package :mod:`rosbags`, imported on first use."""

from __future__ import annotations

from types import ModuleType
from typing import Any

from reachwise.errors import MissingDependency

__all__ = ["rosbags_module", "typestore"]

_NEEDED = ("rosbags", "ros", "reading and writing ROS bags")


def rosbags_module(name: str) -> ModuleType:
    """``rosbags.<name>`` (e.g. ``"highlevel"``), or
    :class:`~reachwise.errors.MissingDependency`."""
    import importlib

    try:
        return importlib.import_module(f"rosbags.{name}")
    except ImportError:
        raise MissingDependency(*_NEEDED) from None


def typestore(store: str = "ros2_humble") -> Any:
    """A :mod:`rosbags` typestore (``"ros2_humble"``, ``"ros1_noetic"``, ``"latest"``, …)."""
    ts = rosbags_module("typesys")
    return ts.get_typestore(ts.Stores(store))
