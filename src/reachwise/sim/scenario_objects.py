"""A scenario's ``objects:`` section: clouds not on a robot (scanner, mesh, box or file),
their motion, rescans, recorded clouds and occlusion (:mod:`reachwise.sim.scenarios` holds
the whole schema)."""

from __future__ import annotations

import itertools
import math

import numpy as np
from pydantic import Field, ValidationInfo, model_validator
from scipy.spatial.transform import Rotation

from reachwise.io.robot_file import FrameModel
from reachwise.io.validation import StrictModel
from reachwise.sim.motion import ConstantVelocity, Trajectory, WaypointTrajectory
from reachwise.sim.scenario_fields import STRICT, V3, FrameSpec, LimitsSpec, SampledPoints

__all__ = [
    "CloudAtSpec",
    "MotionSpec",
    "ObjectSpec",
    "OcclusionSpec",
    "RescanSpec",
    "ScanMeshSpec",
    "ScanSpec",
    "WaypointSpec",
]


class WaypointSpec(FrameModel):
    """A pose of a moving object at time ``t`` (s): ``xyz`` and ``rpy``/``rpy_deg``."""

    t: float = Field(ge=0.0)


class MotionSpec(StrictModel):
    """How an object moves (:mod:`reachwise.sim.motion`): ``waypoints`` (world poses at
    times; linear position, slerp orientation; ``loop`` repeats them) or a constant
    ``velocity`` (m/s) and ``angular_velocity_deg`` (deg/s, world axes) from the
    object's ``pose``, between ``start`` and ``stop`` (s)."""

    model_config = STRICT
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

    model_config = STRICT
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

    model_config = STRICT
    every: float = Field(gt=0.0)


class OcclusionSpec(StrictModel):
    """Occlusion fill of a scanned object (:func:`reachwise.geometry.occlusion.shadow_points`):
    the unseen space up to ``depth`` (m) behind every return counts as occupied;
    ``spacing`` (m, default the scan's voxel) between virtual points; ``ground`` (world
    z, default the scene's floor) below which none is kept."""

    model_config = STRICT
    fill: bool = True
    depth: float = Field(default=1.0, gt=0.0)
    spacing: float | None = Field(default=None, gt=0.0)
    ground: float | None = None


class ScanMeshSpec(StrictModel):
    """A mesh in a scanned scene: ``mesh`` (a file, relative to the scenario) at
    ``pose`` (world), its vertices times ``scale``."""

    model_config = STRICT
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

    model_config = STRICT
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

    model_config = STRICT
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
