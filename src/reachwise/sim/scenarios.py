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

import itertools
import math
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import (
    AfterValidator,
    ConfigDict,
    Field,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)
from scipy.spatial.transform import Rotation

from reachwise.errors import InputError
from reachwise.geometry.cloud import MAX_SAMPLED_POINTS
from reachwise.io._builtin import builtin_names, load_named
from reachwise.io.cloud_headers import MAX_CLOUD_POINTS
from reachwise.io.robot_file import FrameModel
from reachwise.io.text_input import parse_text, read_text
from reachwise.io.validation import StrictModel, input_error
from reachwise.sim.motion import ConstantVelocity, Trajectory, WaypointTrajectory
from reachwise.sim.plant import PlantKind

__all__ = [
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

_STRICT = ConfigDict(extra="forbid", allow_inf_nan=False)
V3 = tuple[float, float, float]
#: Largest width or height of a simulated depth camera (pixels).
MAX_IMAGE_SIDE = 8192


class LimitsSpec(StrictModel):
    """The scenario's ``size_limits:``: upper bounds on counts that would only exhaust
    memory, each raisable (or lowered) in the file. ``max_points``: points sampled on
    one mesh, box or link (default :data:`~reachwise.geometry.cloud.MAX_SAMPLED_POINTS`);
    ``max_image_side``: a camera's width or height in pixels (default
    :data:`MAX_IMAGE_SIDE`); ``max_cloud_points``: points of one cloud file or scan
    (default :data:`~reachwise.io.cloud_headers.MAX_CLOUD_POINTS`)."""

    model_config = _STRICT
    max_points: int = Field(default=MAX_SAMPLED_POINTS, gt=0)
    max_image_side: int = Field(default=MAX_IMAGE_SIDE, gt=0)
    max_cloud_points: int = Field(default=MAX_CLOUD_POINTS, gt=0)


def _within(limit: str) -> AfterValidator:
    """A validator refusing a value above the scenario's ``size_limits.<limit>`` (passed as
    the validation context by :func:`scenario_from_dict`; the default without one)."""

    def check(value: int | None, info: ValidationInfo) -> int | None:
        limits = (info.context or {}).get("size_limits") or LimitsSpec()
        bound = getattr(limits, limit)
        if value is not None and value > bound:
            raise ValueError(f"at most {bound} (size_limits.{limit}), got {value}")
        return value

    return AfterValidator(check)


#: A count of sampled points, bounded by ``size_limits.max_points``.
SampledPoints = Annotated[int, Field(gt=0), _within("max_points")]
#: A camera image side in pixels, bounded by ``size_limits.max_image_side``.
ImageSide = Annotated[int, Field(gt=0), _within("max_image_side")]


# Frames in scenario files use the robot file's schema: xyz + rpy | rpy_deg.
FrameSpec = FrameModel


class GoalSpec(StrictModel):
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


class ControllerSpec(StrictModel):
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
    stop_ticks: int | None = Field(default=None, ge=1)
    velocity_aware: bool | None = None
    reaction_time: float | None = None


class PlantSpec(StrictModel):
    model_config = _STRICT
    kind: PlantKind = "kinematic"
    time_constant: float = Field(default=0.1, gt=0.0)
    rate_limit: float = Field(default=math.inf, gt=0.0, allow_inf_nan=True)
    hang_axis: V3 = (1.0, 0.0, 0.0)
    hang_time_constant: float = Field(default=0.0, ge=0.0)


class LinkCloudSpec(StrictModel):
    model_config = _STRICT
    mesh: str
    points: SampledPoints = 1000
    pose: FrameSpec = FrameSpec()


class RobotFileSpec(StrictModel):
    """A robot file with options: ``file`` (YAML or URDF; a path relative to the
    scenario, ``file://`` or ``package://PKG/…``), ``tip`` (the link that ends the
    chain of a branched URDF), ``package_dirs`` (searched first for ``package://``
    URIs, relative to the scenario), ``lenient`` (leave out, and log, invalid shapes)."""

    model_config = _STRICT
    file: str = Field(min_length=1)
    tip: str | None = None
    package_dirs: list[str] = []
    lenient: bool = False


class RobotSpec(StrictModel):
    model_config = _STRICT
    name: str = Field(min_length=1)
    robot: RobotFileSpec | str  # RobotFileSpec first: its errors are the ones shown
    base: FrameSpec | None = None
    #: Joint values, or the name of a ``group_state`` of the SRDF a ``self`` watch of
    #: this robot names (replaced by its values when the scenario is resolved).
    q0: list[float] | str
    links: list[str] | None = None
    points: SampledPoints | None = None
    density: float | None = Field(default=None, gt=0.0)
    resolution: float | None = Field(default=None, gt=0.0)
    seed: int = Field(default=0, ge=0)
    link_clouds: dict[str, LinkCloudSpec] = {}
    tool_links: list[str] | None = None
    controller: ControllerSpec = ControllerSpec()
    plant: PlantSpec = PlantSpec()
    goals: list[GoalSpec] = []

    @property
    def start(self) -> list[float]:
        """``q0`` as joint values; a named start (``q0: ready``) is replaced by its values
        when the scenario is resolved (:func:`reachwise.sim.resolve.resolve_scenario`),
        before that it is an :class:`~reachwise.errors.InputError`."""
        if isinstance(self.q0, str):
            raise InputError(
                "scenario", f"robots.{self.name}.q0", f"the pose {self.q0!r} is not resolved yet"
            )
        return self.q0

    @model_validator(mode="after")
    def _count(self) -> RobotSpec:
        if sum(x is not None for x in (self.points, self.density, self.resolution)) > 1:
            raise ValueError("give one of points, density and resolution")
        return self


class WaypointSpec(FrameModel):
    """A pose of a moving object at time ``t`` (s): ``xyz`` and ``rpy``/``rpy_deg``."""

    t: float = Field(ge=0.0)


class MotionSpec(StrictModel):
    """How an object moves (:mod:`reachwise.sim.motion`): ``waypoints`` (world poses at
    times; linear position, slerp orientation; ``loop`` repeats them) or a constant
    ``velocity`` (m/s) and ``angular_velocity_deg`` (deg/s, world axes) from the
    object's ``pose``, between ``start`` and ``stop`` (s)."""

    model_config = _STRICT
    waypoints: list[WaypointSpec] | None = Field(default=None, min_length=1)
    loop: bool = False
    velocity: V3 | None = None
    angular_velocity_deg: V3 | None = None
    start: float = Field(default=0.0, ge=0.0)
    stop: float | None = None

    @model_validator(mode="after")
    def _kind(self) -> MotionSpec:
        constant = self.velocity is not None or self.angular_velocity_deg is not None
        if (self.waypoints is not None) == constant:
            raise ValueError("give waypoints or velocity/angular_velocity_deg, not both")
        if self.waypoints is not None:
            if "start" in self.model_fields_set or self.stop is not None:
                raise ValueError("start and stop are for a constant velocity")
            ts = [w.t for w in self.waypoints]
            if any(b <= a for a, b in itertools.pairwise(ts)):
                raise ValueError(f"waypoint times must increase strictly, got {ts}")
        elif self.loop:
            raise ValueError("loop is for waypoints")
        if self.stop is not None and not self.stop > self.start:
            raise ValueError(f"stop ({self.stop}) must be after start ({self.start})")
        return self

    def trajectory(self, pose: np.ndarray) -> Trajectory:
        """The trajectory; ``pose`` is the object's pose (the start of a constant
        velocity; waypoints give their own poses)."""
        if self.waypoints is not None:
            mats = [w.matrix() for w in self.waypoints]
            return WaypointTrajectory(
                np.array([w.t for w in self.waypoints]),
                np.array([m[:3, 3] for m in mats]),
                Rotation.from_matrix(np.array([m[:3, :3] for m in mats])).as_quat(),
                loop=self.loop,
            )
        w = np.radians(self.angular_velocity_deg or (0.0, 0.0, 0.0))
        stop = math.inf if self.stop is None else self.stop
        return ConstantVelocity(
            pose, np.array(self.velocity or (0.0, 0.0, 0.0)), w, self.start, stop
        )


class CloudAtSpec(StrictModel):
    """A cloud that replaces an object's cloud from time ``t`` (s) on (a deforming
    obstacle): ``file``, ``mesh`` (``points`` samples) or ``box`` (size, m)."""

    model_config = _STRICT
    t: float = Field(gt=0.0)
    file: str | None = None
    mesh: str | None = None
    box: V3 | None = None
    points: SampledPoints = 1000

    @model_validator(mode="after")
    def _one(self) -> CloudAtSpec:
        if sum(getattr(self, k) is not None for k in ("file", "mesh", "box")) != 1:
            raise ValueError("give exactly one source: file, mesh or box")
        if self.box is not None and not min(self.box) > 0:
            raise ValueError("box sizes must be > 0")
        return self


class RescanSpec(StrictModel):
    """Re-run the object's scanner every ``every`` seconds (new seed each time)."""

    model_config = _STRICT
    every: float = Field(gt=0.0)


class OcclusionSpec(StrictModel):
    """Occlusion fill of a scanned object (:func:`reachwise.geometry.occlusion.shadow_points`):
    the unseen space up to ``depth`` (m) behind every return counts as occupied;
    ``spacing`` (m, default the scan's voxel) between virtual points; ``ground`` (world
    z, default the scene's floor) below which none is kept."""

    model_config = _STRICT
    fill: bool = True
    depth: float = Field(default=1.0, gt=0.0)
    spacing: float | None = Field(default=None, gt=0.0)
    ground: float | None = None


class ScanMeshSpec(StrictModel):
    """A mesh in a scanned scene: ``mesh`` (a file, relative to the scenario) at
    ``pose`` (world), its vertices times ``scale``."""

    model_config = _STRICT
    mesh: str
    pose: FrameSpec = FrameSpec()
    scale: float | V3 = 1.0


class ScanSpec(StrictModel):
    """A scene of our own for the simulated scanner (:class:`reachwise.geometry.scanner.
    LaserScanner`, the P-V resolutions by default): ``meshes`` in world, an optional
    ``floor`` (a plane at that z), the scanner at ``pose`` (zero tilt; optical centre at
    the origin of the frame, x forward, tilt about y, positive looks down), beams over
    ``azimuth_deg``, tilt over ``tilt_deg``, ``resolution_deg`` between beams and
    ``line_step_deg`` between lines (the tilt rate over the line rate); the cloud is
    cropped to ``crop`` ([min xyz, max xyz]) and downsampled to ``voxel`` (m)."""

    model_config = _STRICT
    meshes: list[ScanMeshSpec] = Field(min_length=1)
    floor: float | None = None
    pose: FrameSpec
    azimuth_deg: tuple[float, float] = (-45.0, 45.0)
    tilt_deg: tuple[float, float] = (0.0, 60.0)
    resolution_deg: float = Field(default=0.25, gt=0.0)
    line_step_deg: float = Field(default=0.2, gt=0.0)
    crop: tuple[V3, V3]
    voxel: float = Field(default=0.03, gt=0.0)

    @model_validator(mode="after")
    def _ranges(self) -> ScanSpec:
        for name in ("azimuth_deg", "tilt_deg"):
            lo, hi = getattr(self, name)
            if lo > hi:
                raise ValueError(f"{name}: min {lo} > max {hi}")
        if any(a >= b for a, b in zip(self.crop[0], self.crop[1], strict=True)):
            raise ValueError("crop: each min must be below its max")
        return self

    @model_validator(mode="after")
    def _size(self, info: ValidationInfo) -> ScanSpec:
        bound = ((info.context or {}).get("size_limits") or LimitsSpec()).max_cloud_points
        beams = (self.azimuth_deg[1] - self.azimuth_deg[0]) / self.resolution_deg + 1
        lines = (self.tilt_deg[1] - self.tilt_deg[0]) / self.line_step_deg + 1
        if beams * lines > bound:
            raise ValueError(
                f"{beams:.0f} beams x {lines:.0f} lines is more than {bound} points "
                "(size_limits.max_cloud_points)"
            )
        return self


class ObjectSpec(StrictModel):
    """A cloud not on a robot: ``scanner`` (a built-in scan scene; ``noise`` m,
    ``occlusion`` fill, ``rescan``), ``mesh`` or ``box`` (``points`` surface samples,
    the box centred on the object frame) or ``file``; placed at ``pose``, moving by
    ``motion``, its cloud replaced by ``clouds`` at given times. ``scene: false``
    keeps it out of the distance scene (a mesh or box only): no cloud of it reaches a
    controller, the sensors see its surface and the run judges the robots' clearance
    on that surface."""

    model_config = _STRICT
    name: str = Field(min_length=1)
    scanner: ScanSpec | str | None = None  # ScanSpec first: its errors are the ones shown
    mesh: str | None = None
    file: str | None = None
    box: V3 | None = None
    points: SampledPoints = 1000
    seed: int = Field(default=0, ge=0)
    pose: FrameSpec = FrameSpec()
    noise: float | None = Field(default=None, ge=0.0)
    occlusion: OcclusionSpec | None = None
    motion: MotionSpec | None = None
    rescan: RescanSpec | None = None
    clouds: list[CloudAtSpec] = []
    scene: bool = True

    @model_validator(mode="after")
    def _one(self) -> ObjectSpec:
        given = [k for k in ("scanner", "mesh", "file", "box") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError("give exactly one source: scanner, mesh, box or file")
        if not self.scene and self.mesh is None and self.box is None:
            raise ValueError(
                "an object outside the scene (scene: false) needs a surface: mesh or box"
            )
        if self.box is not None and not min(self.box) > 0:
            raise ValueError("box sizes must be > 0")
        if self.scanner is None:
            for k in ("noise", "occlusion", "rescan"):
                if getattr(self, k) is not None:
                    raise ValueError(f"{k} is for scanned objects (scanner: ...)")
        if self.rescan is not None and self.clouds:
            raise ValueError("give rescan or clouds, not both")
        if self.scanner is not None and self.motion is not None:
            raise ValueError("a scan is in world coordinates: it cannot move (use rescan)")
        ts = [c.t for c in self.clouds]
        if any(b <= a for a, b in itertools.pairwise(ts)):
            raise ValueError(f"cloud times must increase strictly, got {ts}")
        if (
            self.motion is not None
            and self.motion.waypoints is not None
            and "pose" in self.model_fields_set
        ):
            raise ValueError("waypoints give the object's poses: leave out pose")
        return self


class SrdfPairsSpec(StrictModel):
    """``pairs: {srdf: FILE}``: every pair of the robot's link clouds that the MoveIt
    SRDF ``FILE`` (relative to the scenario) does not disable
    (:mod:`reachwise.sim.srdf_inputs`)."""

    model_config = _STRICT
    srdf: str = Field(min_length=1)


class WatchSpec(StrictModel):
    """``self: R`` (pairs among R's links; ``pairs`` lists link pairs, ``pairs: auto``
    picks them (:mod:`reachwise.sim.self_pairs`: adjacent and never-close pairs
    excluded over ``samples`` random configurations, ``seed``), ``pairs: {srdf: FILE}``
    watches all but the pairs a MoveIt SRDF disables, else every
    non-adjacent pair of ``links``; ``self: {robot: R, pairs: auto}`` is the same),
    ``robot: R, environment: [objects]`` or ``robots: [A, B]``; ``links`` restricts
    the robots' links, ``margin`` is ρ_O."""

    model_config = _STRICT
    self_: str | None = Field(default=None, alias="self")
    robot: str | None = None
    environment: list[str] | None = None
    robots: tuple[str, str] | None = None
    links: list[str] | None = None
    pairs: list[tuple[str, str]] | Literal["auto"] | SrdfPairsSpec | None = None
    samples: int = Field(default=10_000, ge=1)
    seed: int = Field(default=0, ge=0)
    margin: float = Field(gt=0.0)

    @model_validator(mode="before")
    @classmethod
    def _nested_self(cls, data: Any) -> Any:
        """``self: {robot: R, pairs: …, …}`` is ``self: R, pairs: …, …``."""
        if isinstance(data, dict) and isinstance(data.get("self"), dict):
            inner = dict(data["self"])
            out = {k: v for k, v in data.items() if k != "self"}
            if "robot" not in inner:
                raise ValueError("self: {robot: NAME, …} needs robot")
            out["self"] = inner.pop("robot")
            for k, v in inner.items():
                if k in out:
                    raise ValueError(f"{k} given twice (inside self and beside it)")
                out[k] = v
            return out
        return data

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


class EscapeSpec(StrictModel):
    """Local-minimum escape (:mod:`reachwise.sim.escape`): when a robot's
    controller reports ``stalled``, plan a joint path with ``planner`` (OMPL
    RRT-Connect, the ``plan`` extra) within ``time_limit`` s of planning, follow it with
    the same controller at ``speed`` × the joint, tool and angular speed bounds, then
    resume; at most ``attempts`` plans per goal. ``step`` (m): the most a watched point
    moves between two checked states (default half the smallest margin); ``seed``:
    OMPL's random seed. ``escape: ompl`` takes every default."""

    model_config = _STRICT
    planner: Literal["ompl"] = "ompl"
    time_limit: float = Field(default=5.0, gt=0.0)
    speed: float = Field(default=0.5, gt=0.0, le=1.0)
    attempts: int = Field(default=2, ge=1)
    step: float | None = Field(default=None, gt=0.0)
    seed: int = Field(default=1, ge=1, lt=2**32)


class MountSpec(StrictModel):
    """Where a sensor hangs on a robot: ``link`` of ``robot`` (the scenario's robot
    name), at ``offset`` (its pose in the link frame)."""

    model_config = _STRICT
    robot: str = Field(min_length=1)
    link: str = Field(min_length=1)
    offset: FrameSpec = FrameSpec()


class SensorSpec(StrictModel):
    """A depth camera (:class:`reachwise.geometry.depth_camera.DepthCamera`) that streams
    its cloud into the scene object ``name`` during a run (:mod:`reachwise.sim.sensors`):
    fixed at ``pose`` (camera → world, optical frame: z forward, x right, y down; with
    ``look_at`` only ``pose.xyz`` counts and the optical axis points at ``look_at``,
    image x horizontal) or on a robot ``link``; ``rate`` frames/s, ``latency`` s from
    capture to the scene; ``width`` × ``height`` pixels, horizontal field of view
    ``fov`` (rad) or ``fov_deg``; ``near``/``far`` range limits (m); ``noise`` (σ at
    1 m, σ = noise·z²); ``dropout`` fraction; ``voxel`` downsampling (m); ``seed``;
    ``self_filter`` drops the pixels that see a robot."""

    model_config = _STRICT
    kind: Literal["depth"]
    name: str = Field(min_length=1)
    pose: FrameSpec | None = None
    look_at: V3 | None = None
    link: MountSpec | None = None
    rate: float = Field(default=30.0, gt=0.0)
    latency: float = Field(default=0.0, ge=0.0)
    width: ImageSide = 640
    height: ImageSide = 480
    fov: float | None = Field(default=None, gt=0.0, lt=math.pi)
    fov_deg: float | None = Field(default=None, gt=0.0, lt=180.0)
    near: float = Field(default=0.2, ge=0.0)
    far: float = Field(default=6.0, gt=0.0)
    noise: float = Field(default=0.0, ge=0.0)
    dropout: float = Field(default=0.0, ge=0.0, lt=1.0)
    voxel: float | None = Field(default=None, gt=0.0)
    seed: int = Field(default=0, ge=0)
    self_filter: bool = True

    @model_validator(mode="after")
    def _check(self) -> SensorSpec:
        if (self.pose is None) == (self.link is None):
            raise ValueError("give the camera a pose or a link to hang on, not both")
        if self.look_at is not None:
            if self.pose is None:
                raise ValueError("look_at is for a camera with a pose")
            if self.pose.rpy is not None or self.pose.rpy_deg is not None:
                raise ValueError("give pose rpy or look_at, not both")
            axis = np.subtract(self.look_at, self.pose.xyz)
            if not np.linalg.norm(axis) > 1e-9:
                raise ValueError("look_at must differ from the camera's position")
            if np.linalg.norm(np.cross(axis, (0.0, 0.0, 1.0))) < 1e-9 * np.linalg.norm(axis):
                raise ValueError("look_at straight up or down: give pose rpy instead")
        if self.fov is not None and self.fov_deg is not None:
            raise ValueError("give fov or fov_deg, not both")
        if not self.near < self.far:
            raise ValueError(f"far ({self.far}) must exceed near ({self.near})")
        return self

    @property
    def fov_rad(self) -> float:
        """The horizontal field of view (rad; default 60°)."""
        if self.fov is not None:
            return self.fov
        return math.radians(self.fov_deg if self.fov_deg is not None else 60.0)

    def matrix(self) -> np.ndarray:
        """The fixed camera → world pose (``pose`` with ``look_at``), or the link
        offset of a camera on a link."""
        if self.link is not None:
            return self.link.offset.matrix()
        pose = self.pose or FrameSpec()
        T = pose.matrix()
        if self.look_at is not None:
            z = np.subtract(self.look_at, pose.xyz)
            z = z / np.linalg.norm(z)
            x = np.cross(z, (0.0, 0.0, 1.0))  # image x horizontal, image y (down) below
            x = x / np.linalg.norm(x)
            T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
        return T


class BoxSpec(StrictModel):
    """An axis-aligned box, ``lower`` … ``upper`` corners (m, world)."""

    model_config = _STRICT
    lower: V3
    upper: V3

    @model_validator(mode="after")
    def _check(self) -> BoxSpec:
        if not all(h > lo for lo, h in zip(self.lower, self.upper, strict=True)):
            raise ValueError(f"upper {list(self.upper)} must exceed lower {list(self.lower)}")
        return self


class MemorySpec(StrictModel):
    """A scene memory (:mod:`reachwise.sim.memory_feed`): the depth cameras named in
    ``sensors`` fuse their frames into one voxel map of ``box`` (``voxel`` edge, m)
    instead of each replacing a cloud; its occupied and shadow voxels are the scene
    object ``name``, watched like any object. ``shadow_depth`` (m) behind every observed
    surface counts as occupied until a camera sees it free; occupied voxels not seen
    again for ``memory_s`` (s) fade to shadow, never to free; a voxel seen free is not
    shadowed again for ``free_hold_s`` (s)."""

    model_config = _STRICT
    name: str = Field(min_length=1)
    box: BoxSpec
    sensors: list[str] = Field(min_length=1)
    voxel: float = Field(default=0.03, gt=0.0)
    shadow_depth: float = Field(default=0.5, ge=0.0)
    memory_s: float = Field(default=3.0, ge=0.0)
    free_hold_s: float = Field(default=0.1, ge=0.0)


class JobsSpec(StrictModel):
    model_config = _STRICT
    robots: list[str] = Field(min_length=1)
    work: float = Field(default=0.0, ge=0.0)
    goals: list[GoalSpec] = Field(min_length=1)


class ScenarioSpec(StrictModel):
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
