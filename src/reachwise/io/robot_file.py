"""Robot files (YAML, schema in DESIGN.md): load with validation, save, built-in robots.

Every mistake in a file is reported as ``RobotFileError`` naming the file, the field
(``joints[2].limits``) and the reason. Degrees are accepted only where the field name
says so (``alpha_deg``, ``theta_deg``, ``limits_deg``, ``vmax_deg``, ``rpy_deg``).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
import yaml
from pydantic import ConfigDict, Field, ValidationError, model_validator

from reachwise.errors import InputError, RobotFileError
from reachwise.io._builtin import Builtin, builtin_names, load_named
from reachwise.io.atomic import atomic_write
from reachwise.io.design_bodies import (
    BodyModel,
    PlacedBodiesModel,
    bodies_from_models,
    bodies_to_dict,
)
from reachwise.io.robot_geometry import GeometryModel, geometry_to_dict, resolve_meshes
from reachwise.io.text_input import parse_text, read_text
from reachwise.io.validation import StrictModel, input_error
from reachwise.kinematics.robot import (
    BASE_PARAMS,
    DH_PARAMS,
    OBJECTIVES,
    DesignSpace,
    Joint,
    LinkGeometry,
    Robot,
)
from reachwise.kinematics.transforms import pose_from_xyz_rpy, xyz_rpy_from_pose

_STRICT = ConfigDict(extra="forbid", allow_inf_nan=False, strict=False)
Pair = tuple[float, float]
# Joint limits may be unbounded (.inf in YAML); NaN is rejected by the validator.
InfFloat = Annotated[float, Field(allow_inf_nan=True)]
LimitPair = tuple[InfFloat, InfFloat]


class FrameModel(StrictModel):
    model_config = _STRICT
    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] | None = None
    rpy_deg: tuple[float, float, float] | None = None

    @model_validator(mode="after")
    def _one_rpy(self) -> FrameModel:
        if self.rpy is not None and self.rpy_deg is not None:
            raise ValueError("give rpy or rpy_deg, not both")
        return self

    def matrix(self) -> np.ndarray:
        rpy = np.radians(self.rpy_deg) if self.rpy_deg is not None else (self.rpy or (0, 0, 0))
        return pose_from_xyz_rpy(self.xyz, rpy)


class JointModel(StrictModel):
    model_config = _STRICT
    type: Literal["revolute", "prismatic", "fixed", "passive"]
    a: float = 0.0
    alpha: float | None = None
    alpha_deg: float | None = None
    d: float = 0.0
    theta: float | None = None
    theta_deg: float | None = None
    limits: LimitPair | None = None
    limits_deg: LimitPair | None = None
    vmax: float | None = Field(default=None, gt=0)
    vmax_deg: float | None = Field(default=None, gt=0)
    passive: bool = False
    name: str = ""

    @model_validator(mode="after")
    def _check(self) -> JointModel:
        for rad, deg in (("alpha", "alpha_deg"), ("theta", "theta_deg"), ("limits", "limits_deg"),
                         ("vmax", "vmax_deg")):  # fmt: skip
            if getattr(self, rad) is not None and getattr(self, deg) is not None:
                raise ValueError(f"give {rad} or {deg}, not both")
        if self.type == "prismatic" and self.limits is None and self.limits_deg is None:
            raise ValueError("a prismatic joint needs limits [lower, upper] in metres")
        if self.type == "prismatic" and (self.limits_deg is not None or self.vmax_deg is not None):
            raise ValueError("a prismatic joint's limits and vmax are in metres, not degrees")
        lim = self.limits if self.limits is not None else self.limits_deg
        if lim is not None and (math.isnan(lim[0]) or math.isnan(lim[1])):
            raise ValueError("limits: NaN is not a limit; use .inf for an unbounded joint")
        if lim is not None and lim[0] > lim[1]:
            raise ValueError(f"limits: lower {lim[0]} > upper {lim[1]}")
        return self

    def joint(self) -> Joint:
        def rad(v: float | None, v_deg: float | None) -> float | None:
            return math.radians(v_deg) if v_deg is not None else v

        lim = self.limits
        if self.limits_deg is not None:
            lim = (math.radians(self.limits_deg[0]), math.radians(self.limits_deg[1]))
        vmax = rad(self.vmax, self.vmax_deg)
        jtype = "revolute" if self.type == "passive" else self.type
        return Joint(
            type=jtype,
            a=self.a,
            alpha=rad(self.alpha, self.alpha_deg) or 0.0,
            d=self.d,
            theta=rad(self.theta, self.theta_deg) or 0.0,
            limits=lim if lim is not None else (-math.pi, math.pi),
            vmax=vmax if vmax is not None else math.inf,
            passive=self.passive or self.type == "passive",
            name=self.name,
        )


class DesignModel(StrictModel):
    model_config = _STRICT
    joints: dict[int, dict[Literal["a", "alpha", "d", "theta"], Pair]] = {}
    base: dict[Literal["x", "y", "z", "roll", "pitch", "yaw"], Pair] = {}
    min_length: float = Field(default=0.0, ge=0.0)
    margin: float = Field(default=0.05, gt=0.0, lt=0.5)
    objective: dict[str, float] = {}
    clearance: float = Field(default=0.0, ge=0.0)
    bodies: dict[str, BodyModel] = {}

    @model_validator(mode="after")
    def _objective_names(self) -> DesignModel:
        for name, w in self.objective.items():
            if name not in OBJECTIVES:
                raise ValueError(f"unknown objective {name!r}; valid: {', '.join(OBJECTIVES)}")
            if w < 0:
                raise ValueError(f"objective {name!r}: weight must be >= 0, got {w}")
        return self


class RobotModel(StrictModel):
    model_config = _STRICT
    name: str = Field(min_length=1)
    convention: Literal["modified", "classic"] = "modified"
    description: str = ""
    joints: list[JointModel] = Field(min_length=1)
    base: FrameModel = FrameModel()
    tool: FrameModel = FrameModel()
    geometry: dict[str, GeometryModel | list[GeometryModel]] = {}
    design: DesignModel = DesignModel()
    placed_bodies: PlacedBodiesModel | None = None  # a synthesized design's, not read


def robot_from_dict(data: Any, source: str = "robot") -> Robot:
    """Build a Robot from parsed YAML, raising ``RobotFileError`` naming ``source``."""
    if not isinstance(data, dict):
        raise RobotFileError(source, "", "a robot file must be a mapping with name and joints")
    try:
        m = RobotModel.model_validate(data)
    except ValidationError as exc:
        raise input_error(exc, source, RobotFileError, model=RobotModel) from None
    joints = []
    for i, jm in enumerate(m.joints):
        try:
            joints.append(jm.joint())
        except InputError as exc:
            raise RobotFileError(source, f"joints[{i}].{exc.field}", exc.reason) from None
    try:
        design = DesignSpace(
            joints={j: {str(p): b for p, b in ps.items()} for j, ps in m.design.joints.items()},
            base={str(p): b for p, b in m.design.base.items()},
            min_length=m.design.min_length,
            margin=m.design.margin,
            objective=dict(m.design.objective),
            bodies=bodies_from_models(m.design.bodies, [j.name for j in joints]),
            clearance=m.design.clearance,
        )
        return Robot(
            name=m.name,
            joints=tuple(joints),
            convention=m.convention,
            base=m.base.matrix(),
            tool=m.tool.matrix(),
            geometry={k: _shapes(g) for k, g in m.geometry.items()},
            design=design,
            source=source,
        )
    except InputError as exc:
        raise RobotFileError(source, exc.field, exc.reason) from None


def _shapes(g: GeometryModel | list[GeometryModel]) -> tuple[LinkGeometry, ...]:
    return (g.geometry(),) if isinstance(g, GeometryModel) else tuple(x.geometry() for x in g)


def robot_to_dict(robot: Robot) -> dict[str, Any]:
    """The YAML mapping of a robot (inverse of ``robot_from_dict``)."""

    def frame(T: np.ndarray) -> dict[str, list[float]]:
        xyz, rpy = xyz_rpy_from_pose(T)
        return {"xyz": [float(v) for v in xyz], "rpy": [float(v) for v in rpy]}

    joints = []
    for j in robot.joints:
        row: dict[str, Any] = {
            "type": j.type,
            "a": j.a,
            "alpha": j.alpha,
            "d": j.d,
            "theta": j.theta,
        }
        if j.movable:
            row["limits"] = [float(j.limits[0]), float(j.limits[1])]
            if math.isfinite(j.vmax):
                row["vmax"] = j.vmax
        if j.passive:
            row["passive"] = True
        if j.name:
            row["name"] = j.name
        joints.append(row)
    out: dict[str, Any] = {
        "name": robot.name,
        "convention": robot.convention,
        "joints": joints,
        "base": frame(robot.base),
        "tool": frame(robot.tool),
    }
    if robot.geometry:
        out["geometry"] = {link: geometry_to_dict(g) for link, g in robot.geometry.items()}
    if robot.design.size:
        out["design"] = {
            "joints": {
                j: {p: list(b) for p, b in ps.items()} for j, ps in robot.design.joints.items()
            },
            "base": {p: list(b) for p, b in robot.design.base.items()},
        }
        if robot.design.min_length:
            out["design"]["min_length"] = robot.design.min_length
        if robot.design.margin != 0.05:
            out["design"]["margin"] = robot.design.margin
        if robot.design.objective:
            out["design"]["objective"] = dict(robot.design.objective)
        if robot.design.bodies:
            out["design"]["bodies"] = bodies_to_dict(robot.design.bodies)
        if robot.design.clearance:
            out["design"]["clearance"] = robot.design.clearance
    return out


def save_robot(robot: Robot, path: str | Path) -> None:
    """Write ``robot`` as a YAML robot file."""
    atomic_write(path, yaml.safe_dump(robot_to_dict(robot), sort_keys=False))


def load_robot_file(
    path: str | Path,
    *,
    tip: str | None = None,
    package_dirs: Sequence[str | os.PathLike[str]] | None = None,
    lenient: bool = False,
) -> Robot:
    """Load a YAML robot file or a URDF (by extension); ``tip``, ``package_dirs`` and
    ``lenient`` as in :func:`load_robot`."""
    p = Path(path)
    if not p.is_file():
        raise RobotFileError(str(p), "", "no such file")
    if p.suffix.lower() == ".urdf":
        from reachwise.io.urdf import load_urdf

        return load_urdf(p, tip, package_dirs=package_dirs, lenient=lenient)
    if tip is not None:
        raise RobotFileError(
            str(p), "tip", "tip selects the chain of a URDF; a YAML robot is one chain"
        )
    text = read_text(p, str(p), RobotFileError)
    robot = robot_from_dict(parse_text(text, str(p), "yaml", RobotFileError), str(p))
    return resolve_meshes(robot, p.parent, package_dirs or (), lenient)


def builtin_robots() -> list[str]:
    """Names of the robots shipped with reachwise."""
    return builtin_names("robots")


def load_robot(
    name_or_path: str | Path,
    *,
    tip: str | None = None,
    package_dirs: Sequence[str | os.PathLike[str]] | None = None,
    lenient: bool = False,
) -> Robot:
    """A built-in robot by name (``panda``, ``sb60`` …) or a YAML/URDF robot file.

    ``tip`` takes the chain of a branched URDF from its root link to that link (the
    tool frame). ``package_dirs`` are searched first for ``package://`` mesh URIs (then
    ``ROS_PACKAGE_PATH``, ``AMENT_PREFIX_PATH``, the Python environment and the file's
    own folders: ``reachwise.io.mesh_uri``). ``lenient=True`` leaves out (and logs)
    shapes that are invalid or whose mesh cannot be found instead of raising."""

    def builtin(b: Builtin) -> Robot:
        if tip is not None:
            raise RobotFileError(b.label, "tip", "tip is for URDF files")
        return robot_from_dict(yaml.safe_load(b.text()), b.label)

    return load_named(
        "robots",
        name_or_path,
        from_builtin=builtin,
        from_file=lambda p: load_robot_file(p, tip=tip, package_dirs=package_dirs, lenient=lenient),
        suffixes=(".yaml", ".yml", ".urdf"),
    )


__all__ = [
    "BASE_PARAMS",
    "DH_PARAMS",
    "builtin_robots",
    "load_robot",
    "load_robot_file",
    "robot_from_dict",
    "robot_to_dict",
    "save_robot",
]
