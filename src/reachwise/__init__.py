"""reachwise: design serial robotic manipulators from their task, move them without collisions.

Public API (stable names, see DESIGN.md): ``load_robot``, ``link_clouds``, ``Robot``,
``Joint``, ``PointCloud``; ``reachwise.distance.closest_points``.
"""

from __future__ import annotations

from reachwise._version import __version__
from reachwise.api import replay, synthesize
from reachwise.geometry.cloud import PointCloud
from reachwise.io.robot_clouds import link_clouds
from reachwise.io.robot_file import load_robot, save_robot
from reachwise.io.task_file import load_task
from reachwise.kinematics.ik import IKResult
from reachwise.kinematics.robot import Joint, Robot
from reachwise.sim.log import SimulationLog
from reachwise.sim.simulate import simulate
from reachwise.synthesis.synthesize import SynthesisResult
from reachwise.tasks.task import Task, TaskPoint

__all__ = [
    "IKResult",
    "Joint",
    "PointCloud",
    "Robot",
    "SimulationLog",
    "SynthesisResult",
    "Task",
    "TaskPoint",
    "__version__",
    "link_clouds",
    "load_robot",
    "load_task",
    "replay",
    "save_robot",
    "simulate",
    "synthesize",
]
