"""The arms of ``example-robot-data`` (the ``robots`` extra) that the tests load.

``ERD`` is the package's ``robots`` folder, or ``None`` when the package is not
installed; ``needs_erd`` skips a test then (one clear reason).
"""

from __future__ import annotations

from importlib import metadata
from pathlib import Path

import pytest


def _robots_dir() -> Path | None:
    try:
        dist = metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        return None
    p = Path(str(dist.locate_file("cmeel.prefix/share/example-robot-data/robots")))
    return p if p.is_dir() else None


ERD = _robots_dir()
needs_erd = pytest.mark.skipif(
    ERD is None, reason='example-robot-data is not installed (pip install "reachwise[robots]")'
)

#: name -> (URDF path inside the robots folder, tip link)
ARMS: dict[str, tuple[str, str]] = {
    "ur5": ("ur_description/urdf/ur5_robot.urdf", "tool0"),
    "ur10": ("ur_description/urdf/ur10_robot.urdf", "tool0"),
    "panda": ("panda_description/urdf/panda.urdf", "panda_hand"),
    "xarm7": ("xarm_description/urdf/xarm7.urdf", "link_eef"),
    "z1": ("z1_description/urdf/z1.urdf", "gripperStator"),
    "kinova": ("kinova_description/robots/kinova.urdf", "j2s6s200_end_effector"),
    "so101": ("so_arm_description/urdf/so101.urdf", "gripper_frame_link"),
}


def arm_path(name: str) -> Path:
    """The URDF file of arm ``name`` (call only under ``needs_erd``)."""
    if ERD is None:
        pytest.skip("example-robot-data is not installed")
    return ERD / ARMS[name][0]


def package_file(uri: str) -> Path:
    """The file of a ``package://example-robot-data/…`` URI, found by string (the test's
    own resolution, independent of reachwise's)."""
    if ERD is None:
        pytest.skip("example-robot-data is not installed")
    prefix = "package://example-robot-data/"
    assert uri.startswith(prefix), uri
    return ERD.parent / uri[len(prefix) :]
