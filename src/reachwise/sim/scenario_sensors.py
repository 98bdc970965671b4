"""A scenario's ``sensors:`` section: depth cameras fixed in the world or mounted on a
robot's link, each streaming its cloud into the scene (:mod:`reachwise.sim.scenarios`
holds the whole schema)."""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from reachwise.io.validation import StrictModel
from reachwise.sim.scenario_fields import STRICT, V3, FrameSpec, ImageSide

__all__ = ["MountSpec", "SensorSpec"]


class MountSpec(StrictModel):
    """Where a sensor hangs on a robot: ``link`` of ``robot`` (the scenario's robot
    name), at ``offset`` (its pose in the link frame)."""

    model_config = STRICT
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

    model_config = STRICT
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
