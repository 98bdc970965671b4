"""A scenario's ``memory:`` section: the scene memory's boxes, which fuse the sensors'
frames into occupied, free and unseen voxels (:mod:`reachwise.sim.scenarios` holds the
whole schema)."""

from __future__ import annotations

from pydantic import Field, model_validator

from reachwise.io.validation import StrictModel
from reachwise.sim.scenario_fields import STRICT, V3

__all__ = ["BoxSpec", "MemorySpec"]


class BoxSpec(StrictModel):
    """An axis-aligned box, ``lower`` … ``upper`` corners (m, world)."""

    model_config = STRICT
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

    model_config = STRICT
    name: str = Field(min_length=1)
    box: BoxSpec
    sensors: list[str] = Field(min_length=1)
    voxel: float = Field(default=0.03, gt=0.0)
    shadow_depth: float = Field(default=0.5, ge=0.0)
    memory_s: float = Field(default=3.0, ge=0.0)
    free_hold_s: float = Field(default=0.1, ge=0.0)
