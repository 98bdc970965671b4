"""The options every command that takes a robot shares: ``--tip``, ``--package-dir``,
``--lenient``, and the loader that applies them."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import typer

from reachwise.cli._options import cli

if TYPE_CHECKING:
    from reachwise.kinematics.robot import Robot

__all__ = ["LENIENT", "PACKAGE_DIRS", "TIP", "RobotFileOptions", "load_with_options"]

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


@dataclass(frozen=True)
class RobotFileOptions:
    """The shared robot options as a group: the URDF ``tip`` link (``None``: the
    chain's end), the folders searched first for ``package://`` URIs and ``lenient``
    loading (invalid shapes left out and logged)."""

    #: The link that ends a branched URDF's chain; ``None``: its only end.
    tip: str | None = cli(TIP)
    #: Folders searched first for ``package://`` mesh URIs.
    package_dir: list[Path] = cli(PACKAGE_DIRS)
    #: Leave out (and log) invalid shapes instead of stopping.
    lenient: bool = cli(LENIENT)

    @property
    def given(self) -> bool:
        """Whether any of the options was given."""
        return self.tip is not None or bool(self.package_dir) or self.lenient

    def load(self, robot: str | Path) -> Robot:
        """``robot`` loaded with these options."""
        return load_with_options(robot, self.tip, self.package_dir, self.lenient)
