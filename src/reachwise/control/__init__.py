"""Collision-avoidance control (thesis §3.3, Eq. 3.8–3.18; P-V Eq. 3–11).

``Controller(robot, config).step(q, goal, distances, now) -> (q̇, ControlStatus)``;
``SceneConverter`` turns a distance scene's answer into the controller's
``AvoidancePoints``; ``potential``, ``limits`` and ``safety`` hold the pieces.
"""

from reachwise.control.avoidance import AvoidancePoints, SceneConverter, default_tool_links
from reachwise.control.controller import Controller, ControllerConfig, ControlStatus, Goal
from reachwise.control.safety import SafetyConfig, protective_separation

__all__ = [
    "AvoidancePoints",
    "ControlStatus",
    "Controller",
    "ControllerConfig",
    "Goal",
    "SafetyConfig",
    "SceneConverter",
    "default_tool_links",
    "protective_separation",
]
