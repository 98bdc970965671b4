"""The robot models a scenario names: a built-in robot or a robot file, placed at the
scenario's base pose and renamed to the scenario's robot name."""

from __future__ import annotations

from dataclasses import replace

from reachwise.errors import InputError
from reachwise.io.robot_file import builtin_robots, load_robot
from reachwise.kinematics.robot import Robot
from reachwise.sim.scenarios import RobotSpec, Scenario

__all__ = ["robot_of"]


def robot_of(spec: RobotSpec, scenario: Scenario) -> Robot:
    """The robot of ``spec`` (a robot entry of ``scenario``); a bad robot file is an
    :class:`~reachwise.errors.InputError` naming the scenario and the entry."""
    try:
        r = load_robot(spec.robot if spec.robot in builtin_robots() else scenario.path(spec.robot))
    except InputError as exc:
        raise InputError(scenario.source, f"robots.{spec.name}.robot", str(exc)) from None
    if spec.base is not None:
        r = r.with_parameters(base=spec.base.matrix())
    return replace(r, name=spec.name)
