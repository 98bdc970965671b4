"""The ``geometry:`` section of a YAML robot file: each link's collision shapes.

```yaml
geometry:
  link_3: {mesh: parts/boom.stl, points: 1000}          # one shape
  link_4:                                                # or a list of shapes
    - {box: [0.1, 0.1, 0.5], xyz: [0, 0, 0.25]}          # edge lengths x, y, z (m)
    - {cylinder: [0.05, 0.4], rpy: [0, 1.5708, 0]}       # radius, length along z
    - {capsule: [0.05, 0.3]}                             # radius, cylinder length
    - {sphere: 0.06, xyz: [0, 0, 0.5]}                   # radius
    - {mesh: package://my_arm/meshes/wrist.stl, scale: 0.001}   # or [sx, sy, sz]
```

The rules are those of a URDF's shapes (:mod:`reachwise.io.urdf_model`): sizes, radii
and lengths finite and > 0; a mesh ``scale`` of one or three finite, non-zero factors
(a negative one mirrors); ``xyz``/``rpy`` three finite numbers; ``points`` (the link's
cloud size, default 1000) an integer > 0. Mesh names are resolved like a URDF's
(``package://``, ``file://``, or relative to the robot file's folder) when the link's
cloud is built.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from reachwise.errors import RobotFileError
from reachwise.geometry.cloud import MAX_SAMPLED_POINTS
from reachwise.io.mesh_uri import resolve_uri
from reachwise.kinematics.link_geometry import LinkGeometry
from reachwise.kinematics.transforms import pose_from_xyz_rpy, xyz_rpy_from_pose

if TYPE_CHECKING:
    from reachwise.kinematics.robot import Robot

__all__ = ["GeometryModel", "geometry_to_dict", "resolve_meshes"]

log = logging.getLogger("reachwise.io.robot_file")

_STRICT = ConfigDict(extra="forbid", allow_inf_nan=False, strict=False)
_KINDS = ("mesh", "box", "cylinder", "capsule", "sphere")


class GeometryModel(BaseModel):
    """One shape of a link (see the module docstring)."""

    model_config = _STRICT
    mesh: str | None = None
    box: tuple[float, float, float] | None = None
    cylinder: tuple[float, float] | None = None  # radius, length (along z)
    capsule: tuple[float, float] | None = None  # radius, cylinder length (along z)
    sphere: float | None = None  # radius
    scale: float | tuple[float, float, float] | None = None
    points: int = Field(default=1000, gt=0, le=MAX_SAMPLED_POINTS)
    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @field_validator("scale")
    @classmethod
    def _scale(cls, v: Any) -> Any:
        values = [v] if isinstance(v, int | float) else list(v or ())
        if v is not None and any(x == 0 for x in values):
            raise ValueError("scale factors must be ≠ 0 (a negative factor mirrors)")
        return v

    @model_validator(mode="after")
    def _one_shape(self) -> GeometryModel:
        given = [k for k in _KINDS if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError(f"give exactly one of {', '.join(_KINDS)}")
        for k in ("box", "cylinder", "capsule"):
            v = getattr(self, k)
            if v is not None and min(v) <= 0:
                raise ValueError(f"{k} sizes must be > 0")
        if self.sphere is not None and self.sphere <= 0:
            raise ValueError("sphere radius must be > 0")
        if self.scale is not None and self.mesh is None:
            raise ValueError("scale is for meshes")
        return self

    def geometry(self) -> LinkGeometry:
        origin = tuple(
            tuple(float(x) for x in row) for row in pose_from_xyz_rpy(self.xyz, self.rpy)
        )
        if self.mesh is not None:
            s = self.scale if self.scale is not None else 1.0
            sx, sy, sz = (s, s, s) if isinstance(s, int | float) else s
            return LinkGeometry(
                "mesh",
                mesh=self.mesh,
                scale=(float(sx), float(sy), float(sz)),
                points=self.points,
                origin=origin,
            )
        if self.box is not None:
            return LinkGeometry("box", size=self.box, points=self.points, origin=origin)
        if self.sphere is not None:
            return LinkGeometry("sphere", radius=self.sphere, points=self.points, origin=origin)
        if self.cylinder is not None:
            r, length = self.cylinder
            return LinkGeometry(
                "cylinder", radius=r, length=length, points=self.points, origin=origin
            )
        if self.capsule is None:
            raise ValueError(f"give exactly one of {', '.join(_KINDS)}")
        r, length = self.capsule
        return LinkGeometry("capsule", radius=r, length=length, points=self.points, origin=origin)


def _shape_to_dict(g: LinkGeometry) -> dict[str, Any]:
    xyz, rpy = xyz_rpy_from_pose(g.origin_matrix)
    entry: dict[str, Any] = {"points": g.points, "xyz": xyz.tolist(), "rpy": rpy.tolist()}
    if g.shape == "mesh":
        entry["mesh"] = g.mesh
        if tuple(g.scale) != (1.0, 1.0, 1.0):
            entry["scale"] = [float(v) for v in g.scale]
    elif g.shape == "box":
        entry["box"] = list(g.size or ())
    elif g.shape == "sphere":
        entry["sphere"] = g.radius
    else:
        entry[g.shape] = [g.radius, g.length]
    return entry


def geometry_to_dict(shapes: tuple[LinkGeometry, ...]) -> dict[str, Any] | list[dict[str, Any]]:
    """The YAML entry of one link's shapes: a mapping for one shape, else a list."""
    out = [_shape_to_dict(g) for g in shapes]
    return out[0] if len(out) == 1 else out


def resolve_meshes(
    robot: Robot,
    folder: Path,
    package_dirs: Sequence[str | os.PathLike[str]] = (),
    lenient: bool = False,
) -> Robot:
    """``robot`` with every mesh shape's file resolved (``LinkGeometry.path``), names
    relative to ``folder``; a mesh that cannot be found is a
    :class:`~reachwise.errors.RobotFileError` naming the URI and every place searched
    (left out, and logged, with ``lenient``)."""
    if not any(g.shape == "mesh" for shapes in robot.geometry.values() for g in shapes):
        return robot
    source = robot.source or robot.name
    out: dict[str, tuple[LinkGeometry, ...]] = {}
    for link, shapes in robot.geometry.items():
        kept = []
        for i, g in enumerate(shapes):
            if g.shape != "mesh" or g.path is not None:
                kept.append(g)
                continue
            field = f"geometry.{link}" + (f"[{i}]" if len(shapes) > 1 else "") + ".mesh"
            try:
                path = resolve_uri(
                    str(g.mesh),
                    robot_file=folder / "robot",
                    package_dirs=package_dirs,
                    source=source,
                    field=field,
                    folder=folder,
                )
            except RobotFileError as exc:
                if not lenient:
                    raise
                log.warning("%s (lenient: this shape is left out)", exc)
                continue
            kept.append(replace(g, path=str(path)))
        if kept:
            out[link] = tuple(kept)
    return replace(robot, geometry=out)
