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
requires: {example-robot-data: robots}   # optional: packages (and the extra) it needs
robots:
  - name: boom              # name in the scene (clouds are "boom/link_k")
    robot: sb60             # built-in robot or robot file, or a file with options:
    # robot: {file: package://example-robot-data/robots/ur_description/urdf/ur5_robot.urdf,
    #         tip: tool0, package_dirs: [], lenient: false}
    base: {xyz: [0, 0, 1.5], rpy_deg: [0, 0, 0]}   # optional: replaces the robot's base
    q0: [0, 0.2, 0.5, 0, 0, 0, 0, 0.5]             # start, one value per joint variable,
                            # or the name of a group_state of the robot's SRDF (q0: ready)
    links: [link_2, link_8] # links that get clouds (default: every link with geometry)
    points: 1000            # points per link cloud (default: the geometry's, 1000)
    density: 20000          # or: points per m² of the link's shapes
    resolution: 0.01        # or: every point of the shapes within this of the cloud (m;
                            #   the default of a URDF robot, 1 cm)
    seed: 0
    link_clouds: {link_6: {mesh: meshes/grabber.obj, points: 1000}}  # replace a link's shape
    tool_links: [link_8, tool]                      # parts avoided in task space (P-V Eq. 6)
    controller: {kv: 1.0, v_max: 0.5, mu: 2e-4}     # ControllerConfig fields
    plant: {kind: hydraulic, time_constant: 0.1}    # PlantConfig fields
    goals:                  # in order; q: the tool pose at those joint values, or xyz (+ quat
      - {q: [...], mirror_y: true, dims: 6}       #  (x, y, z, w) or rpy_deg); work: s locked
objects:                    # clouds not on a robot: scanner, mesh, box or file
  - {name: scan, scanner: p5-floor-obstacle, seed: 0}
  - name: shelf             # the scanner on meshes of our own (ScanSpec)
    scanner: {meshes: [{mesh: meshes/shelf.obj, pose: {xyz: [0.6, 0, 0]}}], floor: 0.0,
              pose: {xyz: [-0.6, 0, 1.6]}, azimuth_deg: [-30, 30], tilt_deg: [15, 60],
              crop: [[0.3, -0.6, 0.02], [1.0, 0.6, 1.2]], voxel: 0.02}
  - {name: scan2, scanner: p5-floor-obstacle, noise: 0.01,  # range noise (m)
     occlusion: {fill: true, depth: 1.0},   # unseen space behind returns is occupied
     rescan: {every: 1.0}}                  # re-scanned every 1 s (new seed)
  - {name: rock, mesh: rock.stl, points: 1000, pose: {xyz: [3, 0, 0]}}
  - {name: wall, file: wall.ply, pose: {xyz: [0, 0, 0]}}
  - name: person            # a moving box: poses at times (linear + slerp), or
    box: [0.5, 0.5, 1.8]    #   motion: {velocity: [0.5, 0, 0], start: 1, stop: 9}
    points: 2000
    motion: {waypoints: [{t: 0, xyz: [3, -3, 0.9]}, {t: 12, xyz: [3, 3, 0.9],
             rpy_deg: [0, 0, 90]}], loop: false}
  - {name: heap, file: heap0.ply, clouds: [{t: 5, file: heap1.ply}]}  # deforming
  - {name: walker, mesh: person.obj, scene: false, motion: ...}  # only sensors see it
sensors:                    # depth cameras: each streams its cloud into the
  - kind: depth             #   scene object `name` at `rate` frames/s of simulated time
    name: camera            # watch it like an object: environment: [camera]
    pose: {xyz: [2, 0, 2]}  # camera -> world, optical frame (z forward, x right, y down):
    look_at: [0, 0, 0.5]    #   rpy, or look_at (image x kept horizontal); or instead
    # link: {robot: boom, link: link_6, offset: {xyz: [0, 0, 0.1], rpy: [0, 0, 0]}}
    rate: 30                # frames/s (at most one per tick)
    latency: 0.03           # s from capture to the scene (the frame keeps its capture stamp)
    width: 160              # pixels (default 640 x 480; fewer cast faster)
    height: 120
    fov_deg: 60             # horizontal field of view (or fov, rad)
    near: 0.2               # range limits (m)
    far: 6.0
    noise: 0.002            # depth noise sigma at 1 m (sigma = noise * z^2)
    dropout: 0.0            # fraction of pixels lost
    voxel: 0.02             # optional voxel downsampling of each frame (m)
    seed: 0
    self_filter: true       # drop the pixels that see a robot (robot-body filter)
watch:                      # pairs and their collision margins rho_O
  - {self: boom, margin: 0.3, pairs: [[link_8, link_2]]}
  - {self: {robot: arm, pairs: auto, samples: 10000}, margin: 0.05}   # picked for you
  - {self: {robot: arm, pairs: {srdf: arm.srdf}}, margin: 0.05}  # all but MoveIt's disabled
  - {robot: crane, environment: [scan], links: [link_6], margin: 0.3}
  - {robots: [a, b], links: [link_7, link_8], margin: 0.3}
jobs:                       # shared work list (P-IV): each idle robot takes the first
  robots: [a, b]            # free one, in order, and is locked for `work` seconds there
  work: 3.0
  goals: [{xyz: [8, 0, 1], rpy_deg: [0, 90, 0]}]
escape: {planner: ompl, time_limit: 5.0}   # or `escape: ompl`: plan out of a stall
size_limits:                # bounds against counts that would only exhaust memory
  max_points: 5000000       # points sampled on one mesh, box or link (default 5 000 000)
  max_image_side: 8192      # a camera's width or height (pixels, default 8192)
  max_cloud_points: 50000000  # points of one cloud file or scan (default 50 000 000)
```
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

from pydantic import Field, ValidationError, field_validator, model_validator

from reachwise.errors import InputError
from reachwise.io._builtin import builtin_names, load_named
from reachwise.io.text_input import parse_text, read_text
from reachwise.io.validation import StrictModel, input_error
from reachwise.sim.scenario_fields import MAX_IMAGE_SIDE, STRICT, LimitsSpec
from reachwise.sim.scenario_memory import BoxSpec, MemorySpec
from reachwise.sim.scenario_objects import (
    CloudAtSpec,
    MotionSpec,
    ObjectSpec,
    OcclusionSpec,
    RescanSpec,
    ScanMeshSpec,
    ScanSpec,
    WaypointSpec,
)
from reachwise.sim.scenario_pairs import SrdfPairsSpec, WatchSpec
from reachwise.sim.scenario_robots import (
    ControllerSpec,
    GoalSpec,
    PlantSpec,
    RobotFileSpec,
    RobotSpec,
)
from reachwise.sim.scenario_sensors import MountSpec, SensorSpec

__all__ = [
    "MAX_IMAGE_SIDE",
    "BoxSpec",
    "CloudAtSpec",
    "ControllerSpec",
    "EscapeSpec",
    "GoalSpec",
    "JobsSpec",
    "LimitsSpec",
    "MemorySpec",
    "MotionSpec",
    "MountSpec",
    "ObjectSpec",
    "OcclusionSpec",
    "PlantSpec",
    "RescanSpec",
    "RobotFileSpec",
    "RobotSpec",
    "ScanMeshSpec",
    "ScanSpec",
    "Scenario",
    "ScenarioSpec",
    "SensorSpec",
    "SrdfPairsSpec",
    "WatchSpec",
    "WaypointSpec",
    "builtin_scenarios",
    "load_scenario",
    "scenario_from_dict",
]


class EscapeSpec(StrictModel):
    """Local-minimum escape (:mod:`reachwise.sim.escape`): when a robot's
    controller reports ``stalled``, plan a joint path with ``planner`` (OMPL
    RRT-Connect, the ``plan`` extra) within ``time_limit`` s of planning, follow it with
    the same controller at ``speed`` × the joint, tool and angular speed bounds, then
    resume; at most ``attempts`` plans per goal. ``step`` (m): the most a watched point
    moves between two checked states (default half the smallest margin); ``seed``:
    OMPL's random seed. ``escape: ompl`` takes every default."""

    model_config = STRICT
    planner: Literal["ompl"] = "ompl"
    time_limit: float = Field(default=5.0, gt=0.0)
    speed: float = Field(default=0.5, gt=0.0, le=1.0)
    attempts: int = Field(default=2, ge=1)
    step: float | None = Field(default=None, gt=0.0)
    seed: int = Field(default=1, ge=1, lt=2**32)


class JobsSpec(StrictModel):
    model_config = STRICT
    robots: list[str] = Field(min_length=1)
    work: float = Field(default=0.0, ge=0.0)
    goals: list[GoalSpec] = Field(min_length=1)


class ScenarioSpec(StrictModel):
    model_config = STRICT
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
    escape: EscapeSpec | None = None
    requires: dict[str, str] = {}
    sensors: list[SensorSpec] = []
    memory: list[MemorySpec] = []
    size_limits: LimitsSpec = LimitsSpec()

    @field_validator("escape", mode="before")
    @classmethod
    def _escape(cls, v: Any) -> Any:
        return {"planner": v} if isinstance(v, str) else v

    @model_validator(mode="after")
    def _names(self) -> ScenarioSpec:
        robots = [r.name for r in self.robots]
        if len(set(robots)) != len(robots):
            raise ValueError(f"robot names must be unique, got {robots}")
        objects = [o.name for o in self.objects]
        if len(set(objects)) != len(objects):
            raise ValueError(f"object names must be unique, got {objects}")
        sensors = self._sensor_names(robots, objects)
        fed = self._memory_names(sensors, objects)
        hidden = {o.name for o in self.objects if not o.scene}
        clouds = (
            [o for o in objects if o not in hidden]
            + [s for s in sensors if s not in fed]
            + [m.name for m in self.memory]
        )
        for w in self.watch:
            for r in (w.self_, w.robot, *(w.robots or ())):
                if r is not None and r not in robots:
                    raise ValueError(f"watch names unknown robot {r!r}; robots: {robots}")
            for o in w.environment or ():
                if o in hidden:
                    raise ValueError(
                        f"watch names {o!r}, which is not in the scene (scene: false); "
                        "watch the sensor that sees it"
                    )
                if o in fed:
                    raise ValueError(
                        f"watch names sensor {o!r}, which feeds memory {fed[o]!r}: watch the memory"
                    )
                if o not in clouds:
                    raise ValueError(
                        f"watch names unknown object {o!r}; objects, sensors and memories: {clouds}"
                    )
        if self.jobs is not None:
            for r in self.jobs.robots:
                if r not in robots:
                    raise ValueError(f"jobs name unknown robot {r!r}; robots: {robots}")
        return self

    def _memory_names(self, sensors: list[str], objects: list[str]) -> dict[str, str]:
        """The memories checked (unique names, none an object's or a sensor's, each
        sensor known and feeding one memory); returns ``{sensor: memory}``."""
        fed: dict[str, str] = {}
        names = [m.name for m in self.memory]
        if len(set(names)) != len(names):
            raise ValueError(f"memory names must be unique, got {names}")
        for m in self.memory:
            if m.name in objects or m.name in sensors:
                raise ValueError(f"memory {m.name!r} has the name of an object or a sensor")
            for s in m.sensors:
                if s not in sensors:
                    raise ValueError(
                        f"memory {m.name!r} names unknown sensor {s!r}; sensors: {sensors}"
                    )
                if s in fed:
                    raise ValueError(f"sensor {s!r} feeds two memories: {fed[s]!r}, {m.name!r}")
                fed[s] = m.name
        return fed

    def _sensor_names(self, robots: list[str], objects: list[str]) -> list[str]:
        """The sensors' names (the scene objects they feed), checked: unique, no
        object's name, on a known robot, at most one frame per tick."""
        names = [s.name for s in self.sensors]
        if len(set(names)) != len(names):
            raise ValueError(f"sensor names must be unique, got {names}")
        for s in self.sensors:
            if s.name in objects:
                raise ValueError(f"sensor {s.name!r} has the name of an object")
            if s.link is not None and s.link.robot not in robots:
                raise ValueError(
                    f"sensor {s.name!r} hangs on unknown robot {s.link.robot!r}; robots: {robots}"
                )
            if s.rate * self.dt > 1.0 + 1e-9:
                raise ValueError(
                    f"sensor {s.name!r}: rate {s.rate:g}/s exceeds one frame per tick "
                    f"(1/dt = {1.0 / self.dt:g}/s)"
                )
        return names


class Scenario:
    """A validated scenario and the folder its relative paths start from."""

    def __init__(self, spec: ScenarioSpec, source: str, folder: Path) -> None:
        self.spec = spec
        self.source = source
        self.folder = folder
        #: Where results of this scenario go (``reachwise simulate --out``): computed
        #: helpers such as automatic self-collision pairs are cached there.
        self.cache_dir: Path | None = None

    @property
    def name(self) -> str:
        return self.spec.name

    def path(self, rel: str) -> Path:
        """A path from the file, relative to the scenario's folder."""
        p = Path(rel)
        return p if p.is_absolute() else self.folder / p

    def __repr__(self) -> str:
        return f"Scenario({self.name!r}, source={self.source!r})"


def scenario_from_dict(data: Any, source: str = "scenario", folder: Path | None = None) -> Scenario:
    """Validate a scenario given as a dict (the parsed YAML)."""
    if not isinstance(data, dict):
        raise InputError(source, "", "a scenario file must hold a mapping")
    try:  # the limits first: they bound the other fields
        limits: LimitsSpec | None = LimitsSpec.model_validate(data.get("size_limits", {}))
    except ValidationError:
        limits = None  # reported, with its place, by the whole scenario's validation
    try:
        spec = ScenarioSpec.model_validate(data, context={"size_limits": limits})
    except ValidationError as exc:
        raise input_error(exc, source, model=ScenarioSpec) from None
    return Scenario(spec, source, folder or Path.cwd())


def builtin_scenarios() -> list[str]:
    """Names of the scenarios shipped with reachwise."""
    return builtin_names("scenarios")


def load_scenario(name_or_path: str | Path | Scenario) -> Scenario:
    """A built-in scenario by name (``p3-self-collision``, ``p4-dual-drilling``,
    ``p5-crane-obstacle``) or a scenario YAML file."""
    if isinstance(name_or_path, Scenario):
        return name_or_path
    return load_named(
        "scenarios",
        name_or_path,
        from_builtin=lambda b: _parse(b.text(), b.label, b.folder),
        from_file=_load_scenario_file,
        suffixes=(".yaml", ".yml"),
    )


def _load_scenario_file(path: Path) -> Scenario:
    if not path.is_file():
        raise InputError(str(path), "", "no such file")
    return _parse(read_text(path, str(path)), str(path), path.parent)


def _parse(text: str, source: str, folder: Path) -> Scenario:
    return scenario_from_dict(parse_text(text, source, "yaml"), source, folder)
