"""``sensor_msgs/JointState`` to a robot's joint vector, by joint name.

A JointState lists ``name[i]`` with ``position[i]``; publishers order and subset their
joints as they like (a gripper's fingers first, two arms in one message), so the only
sound match is by name, never by index. The robot's joint names are its movable
joints' names (:func:`robot_joint_names`); a joint without a name (a robot file that
gives none) is called ``<robot>_joint<k>`` (``k`` from 1, base to tool), the name the
simulation's recorder writes too.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from reachwise.io.ros.recording_error import RecordingError
from reachwise.io.ros.stamps import header_stamp

if TYPE_CHECKING:
    from reachwise.kinematics.robot import Robot

__all__ = ["JointMatcher", "robot_joint_names"]


def robot_joint_names(robot: Robot) -> tuple[str, ...]:
    """The name of each entry of ``robot``'s ``q`` (its movable joints, base to tool)."""
    movable = [j for j in robot.joints if j.movable]
    return tuple(j.name or f"{robot.name}_joint{k + 1}" for k, j in enumerate(movable))


class JointMatcher:
    """Picks a robot's joints out of JointState messages by name (see the module
    docstring). ``names``: the robot's joint names in ``q`` order. The index of each
    name in a message is remembered for the next message with the same name list, so
    a 1 kHz stream costs one gather per message."""

    def __init__(self, names: tuple[str, ...] | list[str]) -> None:
        self.names = tuple(names)
        self._layout: tuple[str, ...] | None = None
        self._index: NDArray[np.intp] = np.zeros(0, np.intp)

    def positions(self, msg: Any, *, topic: str = "JointState") -> NDArray[np.float64]:
        """The robot's ``q`` from ``msg``'s ``position`` (a new array)."""
        layout = tuple(msg.name)
        if layout != self._layout:
            self._index = self._match(layout, msg, topic)
            self._layout = layout
        pos = np.asarray(msg.position, dtype=np.float64)
        if pos.shape != (len(layout),):
            raise RecordingError(
                topic,
                _stamp(msg),
                "position",
                f"has {pos.size} values for {len(layout)} names",
            )
        q = pos[self._index]
        if not np.isfinite(q).all():
            bad = [self.names[i] for i in np.flatnonzero(~np.isfinite(q))]
            raise RecordingError(topic, _stamp(msg), "position", f"not finite for {bad}")
        return q

    def _match(self, layout: tuple[str, ...], msg: Any, topic: str) -> NDArray[np.intp]:
        where = {n: i for i, n in enumerate(layout)}
        if len(where) != len(layout):
            dup = sorted({n for n in layout if layout.count(n) > 1})
            raise RecordingError(topic, _stamp(msg), "name", f"lists {dup} more than once")
        missing = [n for n in self.names if n not in where]
        if missing:
            raise RecordingError(
                topic,
                _stamp(msg),
                "name",
                f"lacks the robot's joints {missing} (the message names {list(layout)})",
            )
        return np.array([where[n] for n in self.names], dtype=np.intp)


def _stamp(msg: Any) -> float | None:
    try:
        return header_stamp(msg)
    except AttributeError:
        return None
