"""Scenario files: robots, clouds, watched pairs, goals and gains of one simulation.

A scenario is a YAML file (schema below), validated with pydantic; every mistake is an
:class:`~reachwise.errors.InputError` naming the file, the field path and the reason.
Relative paths (robot files, meshes, cloud files) are relative to the scenario file;
built-in scenarios live in ``reachwise/data/scenarios``. Lengths in m, angles in rad
(degrees only in fields named ``..._deg``), times in s.

```yaml
name: my-scenario
description: free text
dt: 0.01                    # control and simulation sample time
duration: 30.0              # longest simulated time (stops earlier when all work is done)
monitor: 0.3                # pairs are also measured this far beyond their margin (logs)
robots:
  - name: boom              # name in the scene (clouds are "boom/link_k")
    robot: sb60             # built-in robot or robot file
    base: {xyz: [0, 0, 1.5], rpy_deg: [0, 0, 0]}   # optional: replaces the robot's base
    q0: [0, 0.2, 0.5, 0, 0, 0, 0, 0.5]             # start, one value per joint variable
    links: [link_2, link_8] # links that get clouds (default: every link with geometry)
    points: 1000            # points per link cloud (default: the geometry's, 1000)
    seed: 0
    link_clouds: {link_6: {mesh: meshes/grabber.obj, points: 1000}}  # replace a link's shape
    tool_links: [link_8, tool]                      # parts avoided in task space (P-V Eq. 6)
    controller: {kv: 1.0, v_max: 0.5, mu: 2e-4}     # ControllerConfig fields
    plant: {kind: hydraulic, time_constant: 0.1}    # PlantConfig fields
    goals:                  # in order; q: the tool pose at those joint values, or xyz (+ quat
      - {q: [...], mirror_y: true, dims: 6}       #  (x, y, z, w) or rpy_deg); work: s locked
objects:                    # clouds not on a robot: scanner, mesh or file
  - {name: scan, scanner: p5-floor-obstacle, seed: 0}
  - {name: rock, mesh: rock.stl, points: 1000, pose: {xyz: [3, 0, 0]}}
  - {name: wall, file: wall.ply, pose: {xyz: [0, 0, 0]}}
watch:                      # pairs and their collision margins rho_O
  - {self: boom, margin: 0.3, pairs: [[link_8, link_2]]}
  - {robot: crane, environment: [scan], links: [link_6], margin: 0.3}
  - {robots: [a, b], links: [link_7, link_8], margin: 0.3}
jobs:                       # shared work list (P-IV): each idle robot takes the first
  robots: [a, b]            # free one, in order, and is locked for `work` seconds there
  work: 3.0
  goals: [{xyz: [8, 0, 1], rpy_deg: [0, 90, 0]}]
```
"""

from __future__ import annotations

import math
from importlib import resources
from pathlib import Path
from typing import Any, Literal

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator
from scipy.spatial.transform import Rotation

from reachwise.errors import InputError
from reachwise.io._builtin import builtin_names
from reachwise.io.robot_file import FrameModel

__all__ = [
    "ControllerSpec",
    "GoalSpec",
    "JobsSpec",
    "ObjectSpec",
    "PlantSpec",
    "RobotSpec",
    "Scenario",
    "ScenarioSpec",
    "WatchSpec",
    "builtin_scenarios",
    "load_scenario",
    "scenario_from_dict",
]

_STRICT = ConfigDict(extra="forbid", allow_inf_nan=False)
V3 = tuple[float, float, float]


# Frames in scenario files use the robot file's schema: xyz + rpy | rpy_deg.
FrameSpec = FrameModel


class GoalSpec(BaseModel):
    """A tool goal: ``q`` (the tool pose there) or ``xyz`` with ``quat`` (x, y, z, w) or
    ``rpy_deg``; ``mirror_y`` negates the goal's y coordinate; ``work`` (s) locks the
    robot at the goal (drilling)."""

    model_config = _STRICT
    name: str = ""
    q: list[float] | None = None
    xyz: V3 | None = None
    quat: tuple[float, float, float, float] | None = None
    rpy_deg: V3 | None = None
    dims: Literal[3, 6] = 6
    mirror_y: bool = False
    work: float = Field(default=0.0, ge=0.0)
    position_tolerance: float | None = Field(default=None, gt=0.0)
    orientation_tolerance: float | None = Field(default=None, gt=0.0)

    @model_validator(mode="after")
    def _one(self) -> GoalSpec:
        if (self.q is None) == (self.xyz is None):
            raise ValueError("give exactly one of q and xyz")
        if self.q is not None and (self.quat is not None or self.rpy_deg is not None):
            raise ValueError("a goal given by q takes its orientation from q")
        if self.quat is not None and self.rpy_deg is not None:
            raise ValueError("give quat or rpy_deg, not both")
        if self.quat is not None and not np.linalg.norm(self.quat) > 0:
            raise ValueError("quat must be non-zero")
        return self

    def pose(self, fk: Any) -> np.ndarray:
        """The goal pose; ``fk(q)`` gives the robot's tool pose for ``q`` goals."""
        if self.q is not None:
            T = np.array(fk(np.asarray(self.q, dtype=float)), dtype=float)
        else:
            T = np.eye(4)
            T[:3, 3] = self.xyz
            if self.quat is not None:
                T[:3, :3] = Rotation.from_quat(self.quat).as_matrix()
            elif self.rpy_deg is not None:
                T[:3, :3] = Rotation.from_euler("xyz", np.radians(self.rpy_deg)).as_matrix()
        if self.mirror_y:
            T[1, 3] = -T[1, 3]
        return T


class ControllerSpec(BaseModel):
    """Overrides of :class:`reachwise.control.ControllerConfig` (and its safety)."""

    model_config = _STRICT
    kv: float | None = None
    kw: float | None = None
    v_max: float | None = None
    w_max: float | None = None
    lambda_max: float | None = None
    epsilon: float | None = None
    mu: float | None = None
    v_rep_max: float | None = None
    k_limit: float | None = None
    limit_zone: float | None = None
    guard: bool | None = None
    stop_distance: float | None = None
    approach_speed: float | None = None
    position_tolerance: float | None = None
    orientation_tolerance: float | None = None
    stall_time: float | None = None
    stall_progress: float | None = None
    max_age_ticks: float | None = None
    stop_ticks: int | None = None


class PlantSpec(BaseModel):
    model_config = _STRICT
    kind: Literal["kinematic", "hydraulic"] = "kinematic"
    time_constant: float = Field(default=0.1, gt=0.0)
    rate_limit: float = Field(default=math.inf, gt=0.0, allow_inf_nan=True)
    hang_axis: V3 = (1.0, 0.0, 0.0)
    hang_time_constant: float = Field(default=0.0, ge=0.0)


class LinkCloudSpec(BaseModel):
    model_config = _STRICT
    mesh: str
    points: int = Field(default=1000, gt=0)
    pose: FrameSpec = FrameSpec()


class RobotSpec(BaseModel):
    model_config = _STRICT
    name: str = Field(min_length=1)
    robot: str
    base: FrameSpec | None = None
    q0: list[float]
    links: list[str] | None = None
    points: int | None = Field(default=None, gt=0)
    seed: int = 0
    link_clouds: dict[str, LinkCloudSpec] = {}
    tool_links: list[str] | None = None
    controller: ControllerSpec = ControllerSpec()
    plant: PlantSpec = PlantSpec()
    goals: list[GoalSpec] = []


class ObjectSpec(BaseModel):
    model_config = _STRICT
    name: str = Field(min_length=1)
    scanner: str | None = None
    mesh: str | None = None
    file: str | None = None
    points: int = Field(default=1000, gt=0)
    seed: int = 0
    pose: FrameSpec = FrameSpec()

    @model_validator(mode="after")
    def _one(self) -> ObjectSpec:
        given = [k for k in ("scanner", "mesh", "file") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError("give exactly one source: scanner, mesh or file")
        return self


class WatchSpec(BaseModel):
    """``self: R`` (pairs among R's links; ``pairs`` lists link pairs, else every
    non-adjacent pair of ``links``), ``robot: R, environment: [objects]`` or
    ``robots: [A, B]``; ``links`` restricts the robots' links, ``margin`` is ρ_O."""

    model_config = _STRICT
    self_: str | None = Field(default=None, alias="self")
    robot: str | None = None
    environment: list[str] | None = None
    robots: tuple[str, str] | None = None
    links: list[str] | None = None
    pairs: list[tuple[str, str]] | None = None
    margin: float = Field(gt=0.0)

    @model_validator(mode="after")
    def _kind(self) -> WatchSpec:
        kinds = [self.self_ is not None, self.environment is not None, self.robots is not None]
        if sum(kinds) != 1:
            raise ValueError("give exactly one of self, environment (with robot), robots")
        if self.environment is not None and self.robot is None:
            raise ValueError("environment pairs need robot")
        if self.pairs is not None and self.self_ is None:
            raise ValueError("pairs are for self pairs")
        return self

    @property
    def kind(self) -> str:
        if self.self_ is not None:
            return "self"
        return "robot-environment" if self.environment is not None else "robot-robot"


class JobsSpec(BaseModel):
    model_config = _STRICT
    robots: list[str] = Field(min_length=1)
    work: float = Field(default=0.0, ge=0.0)
    goals: list[GoalSpec] = Field(min_length=1)


class ScenarioSpec(BaseModel):
    model_config = _STRICT
    name: str = Field(min_length=1)
    description: str = ""
    dt: float = Field(default=0.01, gt=0.0)
    duration: float = Field(gt=0.0)
    monitor: float = Field(default=0.3, ge=0.0)
    contact_check: float = Field(default=0.2, ge=0.0)
    robots: list[RobotSpec] = Field(min_length=1)
    objects: list[ObjectSpec] = []
    watch: list[WatchSpec] = []
    jobs: JobsSpec | None = None

    @model_validator(mode="after")
    def _names(self) -> ScenarioSpec:
        robots = [r.name for r in self.robots]
        if len(set(robots)) != len(robots):
            raise ValueError(f"robot names must be unique, got {robots}")
        objects = [o.name for o in self.objects]
        if len(set(objects)) != len(objects):
            raise ValueError(f"object names must be unique, got {objects}")
        for w in self.watch:
            for r in (w.self_, w.robot, *(w.robots or ())):
                if r is not None and r not in robots:
                    raise ValueError(f"watch names unknown robot {r!r}; robots: {robots}")
            for o in w.environment or ():
                if o not in objects:
                    raise ValueError(f"watch names unknown object {o!r}; objects: {objects}")
        if self.jobs is not None:
            for r in self.jobs.robots:
                if r not in robots:
                    raise ValueError(f"jobs name unknown robot {r!r}; robots: {robots}")
        return self


class Scenario:
    """A validated scenario and the folder its relative paths start from."""

    def __init__(self, spec: ScenarioSpec, source: str, folder: Path) -> None:
        self.spec = spec
        self.source = source
        self.folder = folder

    @property
    def name(self) -> str:
        return self.spec.name

    def path(self, rel: str) -> Path:
        """A path from the file, relative to the scenario's folder."""
        p = Path(rel)
        return p if p.is_absolute() else self.folder / p

    def __repr__(self) -> str:
        return f"Scenario({self.name!r}, source={self.source!r})"


def _field_path(loc: tuple[Any, ...]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out or "(top level)"


def scenario_from_dict(data: Any, source: str = "scenario", folder: Path | None = None) -> Scenario:
    """Validate a scenario given as a dict (the parsed YAML)."""
    if not isinstance(data, dict):
        raise InputError(source, "", "a scenario file must hold a mapping")
    try:
        spec = ScenarioSpec.model_validate(data)
    except ValidationError as exc:
        err = exc.errors()[0]
        raise InputError(source, _field_path(tuple(err["loc"])), err["msg"]) from None
    return Scenario(spec, source, folder or Path.cwd())


def _scenario_folder() -> Path:
    return Path(str(resources.files("reachwise.data") / "scenarios"))


def builtin_scenarios() -> list[str]:
    """Names of the scenarios shipped with reachwise."""
    return builtin_names("scenarios")


def load_scenario(name_or_path: str | Path | Scenario) -> Scenario:
    """A built-in scenario by name (``p3-self-collision``, ``p4-dual-drilling``,
    ``p5-crane-obstacle``) or a scenario YAML file."""
    if isinstance(name_or_path, Scenario):
        return name_or_path
    s = str(name_or_path)
    if s in builtin_scenarios():
        p = _scenario_folder() / f"{s}.yaml"
        source = f"built-in scenario {s}"
    else:
        p = Path(s)
        source = str(p)
        if not p.is_file():
            raise InputError(
                s, "", f"no such file or built-in scenario; built-ins: {builtin_scenarios()}"
            )
    try:
        data = yaml.safe_load(p.read_text())
    except yaml.YAMLError as exc:
        raise InputError(source, "", f"not valid YAML: {exc}") from None
    return scenario_from_dict(data, source, p.parent)
