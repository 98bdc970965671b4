"""A synthesized design as a robot file whose bodies any other kinematics can place.

``design.yaml`` is the robot file of the design (``io.robot_file``) plus, when the
template has design bodies, the ``placed_bodies`` section (``io.design_bodies``): the
clearance kept, the watched pairs, and every convex part of every body as a concrete
shape with its end points in the frames of the links they are fixed to
(``synthesis.placed_bodies``). With the design's own DH table (in the same file) a
forward kinematics written elsewhere places every part and checks the clearance.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from reachwise.io.atomic import atomic_write
from reachwise.io.robot_file import robot_to_dict
from reachwise.kinematics.robot import Robot
from reachwise.synthesis.clearance import ClearanceModel
from reachwise.synthesis.placed_bodies import LinkPoint, placed_parts


def _point(p: LinkPoint | None) -> dict[str, Any]:
    assert p is not None
    return {"link": p.link, "xyz": [float(v) for v in p.xyz]}


def placed_bodies(robot: Robot, clearance: float = 0.0) -> dict[str, Any]:
    """The ``placed_bodies`` mapping of ``robot``'s bodies at its design (empty
    without bodies)."""
    if not robot.design.bodies:
        return {}
    model = ClearanceModel(robot, None, clearance)
    names = [b.name for b in robot.design.bodies]
    parts: dict[str, Any] = {}
    for part in placed_parts(model):
        if part.kind == "box":
            shape: dict[str, Any] = {
                "box": {
                    "link": part.link,
                    "size": [float(v) for v in part.size],
                    "origin": [[float(v) for v in row] for row in part.origin],
                }
            }
        else:
            cap: dict[str, Any] = {
                "radius": float(part.radius),
                "start": _point(part.start),
                "end": _point(part.end),
            }
            if part.contact:
                cap["contact"] = float(part.contact)
            shape = {"capsule": cap}
        parts[part.name] = {"body": part.body, **shape}
    return {
        "clearance": float(clearance),
        "watched": [[names[i], names[j]] for i, j in model.pairs],
        "parts": parts,
    }


def design_dict(robot: Robot, clearance: float = 0.0) -> dict[str, Any]:
    """The robot file mapping of a design with its placed bodies (module docstring)."""
    out = robot_to_dict(robot)
    placed = placed_bodies(robot, clearance)
    if placed:
        out["placed_bodies"] = placed
    return out


def save_design(robot: Robot, path: str | Path, clearance: float = 0.0) -> None:
    """Write ``design_dict(robot, clearance)`` as YAML to ``path``."""
    atomic_write(path, yaml.safe_dump(design_dict(robot, clearance), sort_keys=False))
