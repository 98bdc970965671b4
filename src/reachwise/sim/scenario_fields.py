"""Field types shared by the sections of a scenario file
(:mod:`reachwise.sim.scenarios`): the strict model config, frames (the robot file's
``xyz`` + ``rpy | rpy_deg``), and the counts bounded by the file's ``size_limits:``
(:class:`LimitsSpec`)."""

from __future__ import annotations

from typing import Annotated

from pydantic import AfterValidator, ConfigDict, Field, ValidationInfo

from reachwise.geometry.cloud import MAX_SAMPLED_POINTS
from reachwise.io.cloud_headers import MAX_CLOUD_POINTS
from reachwise.io.robot_file import FrameModel
from reachwise.io.validation import StrictModel

__all__ = [
    "MAX_IMAGE_SIDE",
    "STRICT",
    "V3",
    "FrameSpec",
    "ImageSide",
    "LimitsSpec",
    "SampledPoints",
]

#: The model config of every section: unknown keys and NaN or infinite numbers refused.
STRICT = ConfigDict(extra="forbid", allow_inf_nan=False)
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

    model_config = STRICT
    max_points: int = Field(default=MAX_SAMPLED_POINTS, gt=0)
    max_image_side: int = Field(default=MAX_IMAGE_SIDE, gt=0)
    max_cloud_points: int = Field(default=MAX_CLOUD_POINTS, gt=0)


def _within(limit: str) -> AfterValidator:
    """A validator refusing a value above the scenario's ``size_limits.<limit>``
    (passed as the validation context by
    :func:`~reachwise.sim.scenarios.scenario_from_dict`; the default without one)."""

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
