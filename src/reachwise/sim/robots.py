"""The robot models a scenario names: a built-in robot, a robot file, or a robot file
with options (``{file, tip, package_dirs, lenient}``; ``package://`` and ``file://``
URIs resolved like mesh URIs, :func:`reachwise.io.mesh_uri.resolve_uri`), placed at the
scenario's base pose and renamed to the scenario's robot name."""

from __future__ import annotations

from dataclasses import replace

from reachwise.errors import InputError, MissingDependency
from reachwise.io.mesh_uri import resolve_uri
from reachwise.io.robot_file import builtin_robots, load_robot
from reachwise.kinematics.robot import Robot
from reachwise.sim.scenarios import RobotFileSpec, RobotSpec, Scenario

__all__ = ["robot_of"]


def robot_of(spec: RobotSpec, scenario: Scenario) -> Robot:
    """The robot of ``spec`` (a robot entry of ``scenario``); a bad robot file is an
    :class:`~reachwise.errors.InputError` naming the scenario and the entry."""
    where = f"robots.{spec.name}.robot"
    r = spec.robot
    try:
        if isinstance(r, RobotFileSpec):
            dirs = [scenario.path(d) for d in r.package_dirs]
            if "://" in r.file:
                path = resolve_uri(
                    r.file, robot_file=None, source=scenario.source, field=f"{where}.file",
                    folder=scenario.folder, package_dirs=dirs,
                )  # fmt: skip
            else:
                path = scenario.path(r.file)
            robot = load_robot(path, tip=r.tip, package_dirs=dirs, lenient=r.lenient)
        else:
            robot = load_robot(r if r in builtin_robots() else scenario.path(r))
    except MissingDependency:
        raise
    except InputError as exc:
        raise InputError(scenario.source, where, str(exc)) from None
    if spec.base is not None:
        robot = robot.with_parameters(base=spec.base.matrix())
    return replace(robot, name=spec.name)
