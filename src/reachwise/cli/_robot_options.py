"""The options every command that takes a robot shares: ``--tip``, ``--package-dir``,
``--lenient``, and the loader that applies them."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import typer

if TYPE_CHECKING:
    from reachwise.kinematics.robot import Robot

__all__ = ["LENIENT", "PACKAGE_DIRS", "TIP", "load_with_options"]

TIP = typer.Option(
    None,
    "--tip",
    help="URDF: the link that ends the chain (the tool frame) of a branched robot, "
    "e.g. tool0 or panda_hand.",
)
PACKAGE_DIRS = typer.Option(
    [],
    "--package-dir",
    help="Folder searched first for package:// mesh URIs (repeat for several); then "
    "ROS_PACKAGE_PATH, AMENT_PREFIX_PATH, the Python environment, the file's folders.",
)
LENIENT = typer.Option(
    False,
    "--lenient",
    help="Leave out (and log) invalid shapes and meshes that cannot be found instead of "
    "stopping; kinematic errors still stop.",
)


def load_with_options(
    robot: str | Path, tip: str | None, package_dirs: list[Path], lenient: bool
) -> Robot:
    """``reachwise.load_robot`` with the shared options."""
    from reachwise.io.robot_file import load_robot

    return load_robot(robot, tip=tip, package_dirs=package_dirs or None, lenient=lenient)
