"""The ``design: bodies:`` section of a robot file: bodies whose size follows the design.

Schema (lengths in m; every body in the frame of its link)::

    design:
      clearance: 0.1                 # every watched pair keeps this at every task pose
      bodies:
        boom:                        # the body's name
          link: boom_extension       # a link (link_3) or the joint that ends at it
          capsule: {along: [a, d], radius: 0.15}
        feed_beam:
          link: link_8
          capsule: {start: [0, -0.1, -3.5], end: [0, -0.1, 2.5], radius: 0.15,
                    contact: 0.6}    # the last 0.6 m before `end` may touch the rock
        bracket:
          link: link_0
          box: {size: [0.5, 0.6, 0.7], xyz: [-0.35, 0, 0], rpy: [0, 0, 0]}

``link`` defaults to the body's name. See
``reachwise.kinematics.design_bodies.DesignBody`` for what each field means.

A synthesized design (``design.yaml`` of ``reachwise synth``) also lists its bodies as
concrete shapes, for any other forward kinematics (``reachwise.results.design_file``)::

    placed_bodies:
      clearance: 0.1                 # what every watched pair keeps
      watched: [[boom_root, feed], [boom, feed]]
      parts:
        boom.a:                      # a part of body `boom`
          body: boom
          capsule: {radius: 0.15, start: {link: link_2, xyz: [0, 0, 0]},
                    end: {link: link_2, xyz: [1.1, 0, 0]}}
        bracket:
          body: bracket
          box: {link: link_0, size: [0.5, 0.6, 0.7], origin: [[1, 0, 0, -0.35], ...]}

Reading a robot file checks this section's form; reachwise recomputes the shapes from
``design: bodies:`` and does not use it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from reachwise.kinematics.design_bodies import DesignBody
from reachwise.kinematics.transforms import pose_from_xyz_rpy, xyz_rpy_from_pose

_STRICT = ConfigDict(extra="forbid", allow_inf_nan=False, strict=False)
Vec3 = tuple[float, float, float]

__all__ = ["BodyModel", "PlacedBodiesModel", "bodies_from_models", "bodies_to_dict"]


class CapsuleModel(BaseModel):
    model_config = _STRICT
    radius: float = Field(gt=0)
    along: list[Literal["a", "d"]] | None = None
    start: Vec3 | None = None
    end: Vec3 | None = None
    contact: float = Field(default=0.0, ge=0)

    @model_validator(mode="after")
    def _one_kind(self) -> CapsuleModel:
        fixed = self.start is not None or self.end is not None
        if self.along is not None and fixed:
            raise ValueError("a capsule follows the design (along) or has start/end, not both")
        if self.along is None and (self.start is None or self.end is None):
            raise ValueError("a fixed capsule needs start and end (or along: [a, d])")
        if self.along is not None and not self.along:
            raise ValueError("along names at least one of a, d")
        return self


class BoxModel(BaseModel):
    model_config = _STRICT
    size: Vec3
    xyz: Vec3 = (0.0, 0.0, 0.0)
    rpy: Vec3 = (0.0, 0.0, 0.0)


class BodyModel(BaseModel):
    model_config = _STRICT
    link: str | None = None
    capsule: CapsuleModel | None = None
    box: BoxModel | None = None

    @model_validator(mode="after")
    def _one_shape(self) -> BodyModel:
        if (self.capsule is None) == (self.box is None):
            raise ValueError("give exactly one shape: capsule or box")
        return self


class LinkPointModel(BaseModel):
    model_config = _STRICT
    link: str
    xyz: Vec3


class PlacedCapsuleModel(BaseModel):
    model_config = _STRICT
    radius: float = Field(gt=0)
    start: LinkPointModel
    end: LinkPointModel
    contact: float = Field(default=0.0, ge=0)


class PlacedBoxModel(BaseModel):
    model_config = _STRICT
    link: str
    size: Vec3
    origin: tuple[
        tuple[float, float, float, float],
        tuple[float, float, float, float],
        tuple[float, float, float, float],
        tuple[float, float, float, float],
    ]


class PlacedPartModel(BaseModel):
    model_config = _STRICT
    body: str
    capsule: PlacedCapsuleModel | None = None
    box: PlacedBoxModel | None = None

    @model_validator(mode="after")
    def _one_shape(self) -> PlacedPartModel:
        if (self.capsule is None) == (self.box is None):
            raise ValueError("give exactly one shape: capsule or box")
        return self


class PlacedBodiesModel(BaseModel):
    """The ``placed_bodies`` section of a synthesized design (module docstring)."""

    model_config = _STRICT
    clearance: float = Field(default=0.0, ge=0)
    watched: list[tuple[str, str]] = []
    parts: dict[str, PlacedPartModel] = {}


def _link_name(link: str, joint_names: Sequence[str]) -> str:
    if link in joint_names and link:
        return f"link_{list(joint_names).index(link) + 1}"
    return link


def bodies_from_models(
    models: dict[str, BodyModel], joint_names: Sequence[str]
) -> tuple[DesignBody, ...]:
    """Bodies from the validated section; a ``link`` given as a joint name becomes the
    link that joint ends at (joint ``j`` → ``link_{j+1}``). Raises ``InputError``."""
    out = []
    for name, m in models.items():
        link = _link_name(m.link or name, joint_names)
        if m.capsule is not None:
            c = m.capsule
            if c.along is not None:
                out.append(DesignBody(name, link, "capsule", along=tuple(c.along), radius=c.radius))
            else:
                assert c.start is not None and c.end is not None
                out.append(
                    DesignBody(
                        name, link, "capsule", radius=c.radius, start=c.start, end=c.end,
                        contact=c.contact,
                    )
                )  # fmt: skip
        else:
            assert m.box is not None
            T = pose_from_xyz_rpy(m.box.xyz, m.box.rpy)
            origin = tuple(tuple(float(v) for v in row) for row in T)
            out.append(DesignBody(name, link, "box", size=m.box.size, origin=origin))
    return tuple(out)


def bodies_to_dict(bodies: Sequence[DesignBody]) -> dict[str, Any]:
    """The YAML mapping of ``bodies`` (inverse of ``bodies_from_models``)."""
    out: dict[str, Any] = {}
    for b in bodies:
        if b.shape == "capsule" and b.along:
            shape: dict[str, Any] = {"capsule": {"along": list(b.along), "radius": b.radius}}
        elif b.shape == "capsule":
            cap: dict[str, Any] = {
                "start": [float(v) for v in b.start],
                "end": [float(v) for v in b.end],
                "radius": b.radius,
            }
            if b.contact:
                cap["contact"] = b.contact
            shape = {"capsule": cap}
        else:
            xyz, rpy = xyz_rpy_from_pose(np.array(b.origin, dtype=float))
            shape = {
                "box": {
                    "size": [float(v) for v in b.size],
                    "xyz": [float(v) for v in xyz],
                    "rpy": [float(v) for v in rpy],
                }
            }
        out[b.name] = {"link": b.link, **shape}
    return out
