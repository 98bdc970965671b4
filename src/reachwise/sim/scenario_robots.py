"""A scenario's ``robots:`` section: each robot's file, base, link clouds, controller
gains, plant and goals (:mod:`reachwise.sim.scenarios` holds the whole schema)."""

from __future__ import annotations

import math
from typing import Any, Literal

import numpy as np
from pydantic import Field, model_validator
from scipy.spatial.transform import Rotation

from reachwise.errors import InputError
from reachwise.io.validation import StrictModel
from reachwise.sim.plant import PlantKind
from reachwise.sim.scenario_fields import STRICT, V3, FrameSpec, SampledPoints

__all__ = ["ControllerSpec", "GoalSpec", "LinkCloudSpec", "PlantSpec", "RobotFileSpec", "RobotSpec"]


class GoalSpec(StrictModel):
    """A tool goal: ``q`` (the tool pose there) or ``xyz`` with ``quat`` (x, y, z, w) or
    ``rpy_deg``; ``mirror_y`` negates the goal's y coordinate; ``work`` (s) locks the
    robot at the goal (drilling)."""

    model_config = STRICT
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

    model_config = STRICT
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
    model_config = STRICT
    kind: PlantKind = "kinematic"
    time_constant: float = Field(default=0.1, gt=0.0)
    rate_limit: float = Field(default=math.inf, gt=0.0, allow_inf_nan=True)
    hang_axis: V3 = (1.0, 0.0, 0.0)
    hang_time_constant: float = Field(default=0.0, ge=0.0)


class LinkCloudSpec(StrictModel):
    model_config = STRICT
    mesh: str
    points: SampledPoints = 1000
    pose: FrameSpec = FrameSpec()


class RobotFileSpec(StrictModel):
    """A robot file with options: ``file`` (YAML or URDF; a path relative to the
    scenario, ``file://`` or ``package://PKG/…``), ``tip`` (the link that ends the
    chain of a branched URDF), ``package_dirs`` (searched first for ``package://``
    URIs, relative to the scenario), ``lenient`` (leave out, and log, invalid shapes)."""

    model_config = STRICT
    file: str = Field(min_length=1)
    tip: str | None = None
    package_dirs: list[str] = []
    lenient: bool = False


class RobotSpec(StrictModel):
    model_config = STRICT
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
