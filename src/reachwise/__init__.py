"""reachwise: design serial robotic manipulators from their task, move them without collisions.

Public API (stable names, see DESIGN.md): ``load_robot``, ``link_clouds``, ``Robot``,
``Joint``, ``PointCloud``; ``reachwise.distance.closest_points``.

The names below are imported on first use (PEP 562): ``import reachwise`` loads none of
numpy, numba or the compiled kernels, so the command line's start-up stays short and
answers Ctrl-C before it imports them (``reachwise.__main__``).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from reachwise._version import __version__

if TYPE_CHECKING:
    from reachwise.api import replay, simulate, synthesize
    from reachwise.geometry.cloud import PointCloud
    from reachwise.io.robot_clouds import link_clouds
    from reachwise.io.robot_file import load_robot, save_robot
    from reachwise.io.task_file import load_task
    from reachwise.kinematics.ik import IKResult
    from reachwise.kinematics.robot import Joint, Robot
    from reachwise.sim.log import SimulationLog
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

#: The module each public name is defined in.
_HOME = {
    "IKResult": "reachwise.kinematics.ik",
    "Joint": "reachwise.kinematics.robot",
    "PointCloud": "reachwise.geometry.cloud",
    "Robot": "reachwise.kinematics.robot",
    "SimulationLog": "reachwise.sim.log",
    "SynthesisResult": "reachwise.synthesis.synthesize",
    "Task": "reachwise.tasks.task",
    "TaskPoint": "reachwise.tasks.task",
    "link_clouds": "reachwise.io.robot_clouds",
    "load_robot": "reachwise.io.robot_file",
    "load_task": "reachwise.io.task_file",
    "replay": "reachwise.api",
    "save_robot": "reachwise.io.robot_file",
    "simulate": "reachwise.api",
    "synthesize": "reachwise.api",
}


def __getattr__(name: str) -> Any:
    """A public name (imported from its module and kept), or a subpackage."""
    home = _HOME.get(name)
    if home is not None:
        value = getattr(importlib.import_module(home), name)
        globals()[name] = value
        return value
    if not name.startswith("_"):
        try:
            return importlib.import_module(f"{__name__}.{name}")
        except ModuleNotFoundError as exc:
            if exc.name != f"{__name__}.{name}":
                raise
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *_HOME})
