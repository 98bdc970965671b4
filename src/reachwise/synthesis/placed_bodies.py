"""The design bodies of a finished design as concrete shapes, for any other kinematics.

A template's body may follow the design (a capsule along a DH row's ``a`` and ``d``
segments, ``kinematics.design_bodies``); once the design is fixed every body is a
concrete shape. Each convex part of the clearance model (``clearance.ClearanceModel``)
is listed with its end points, each **in the frame of the link it is fixed to** (a name
of ``Robot.link_names``), so that a forward kinematics that knows the links' frames
places it without reachwise:

* a capsule part: its radius and two end points ``(link, xyz)``, plus the contact zone
  (the last ``contact`` metres before ``end`` exempt from the environment clearance).
  A design-following capsule gives one part per segment (named ``body.a``,
  ``body.d`` when it has both); the *elbow* between the segments is fixed to the link
  before the body's link in modified DH (``(a, 0, 0)`` in frame ``j``) and to the
  body's link in classic DH (``(−a, 0, 0)`` in frame ``j + 1``), so a segment whose
  length a prismatic joint changes runs between end points on two links;
* a box: its link, edge lengths ``size`` and its 4×4 ``origin`` in the link frame.

Pure data and maths.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from reachwise.synthesis.clearance import Anchor, ClearanceModel

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class LinkPoint:
    """A point fixed to link ``link`` at ``xyz`` (link frame, m)."""

    link: str
    xyz: Vec3


@dataclass(frozen=True)
class PlacedPart:
    """One convex part of body ``body`` (module docstring): a capsule from ``start`` to
    ``end`` with ``radius`` and ``contact``, or a box on ``link`` of ``size`` placed by
    ``origin``."""

    name: str
    body: str
    kind: Literal["capsule", "box"]
    radius: float = 0.0
    start: LinkPoint | None = None
    end: LinkPoint | None = None
    contact: float = 0.0
    link: str = ""
    size: Vec3 = (0.0, 0.0, 0.0)
    origin: tuple[tuple[float, ...], ...] = ()


def _point(model: ClearanceModel, a: Anchor) -> LinkPoint:
    robot = model.robot
    names = robot.link_names
    if a.elbow < 0:
        return LinkPoint(names[a.frame], (float(a.local[0]), float(a.local[1]), float(a.local[2])))
    j = a.elbow
    a_len = float(robot.dh[j, 0])
    if robot.convention == "classic":
        return LinkPoint(names[j + 1], (-a_len, 0.0, 0.0))
    return LinkPoint(names[j], (a_len, 0.0, 0.0))


def placed_parts(model: ClearanceModel) -> list[PlacedPart]:
    """Every part of ``model``'s bodies at its robot's design (module docstring)."""
    robot = model.robot
    bodies = robot.design.bodies
    per_body: dict[int, int] = {}
    for part in model.parts:
        per_body[part.body] = per_body.get(part.body, 0) + 1
    out = []
    for part in model.parts:
        b = bodies[part.body]
        if part.kind == "box":
            size = tuple(2.0 * h for h in part.half)
            out.append(
                PlacedPart(
                    b.name, b.name, "box", link=robot.link_names[part.frame],
                    size=(size[0], size[1], size[2]), origin=part.origin,
                )
            )  # fmt: skip
            continue
        a0, a1 = (model.anchors[i] for i in part.ends)
        name = b.name
        if b.follows_design and per_body[part.body] > 1:
            first_is_elbow = a0.elbow >= 0
            classic = robot.convention == "classic"
            seg = ("a" if classic else "d") if first_is_elbow else ("d" if classic else "a")
            name = f"{b.name}.{seg}"
        out.append(
            PlacedPart(
                name, b.name, "capsule", radius=part.radius, start=_point(model, a0),
                end=_point(model, a1), contact=b.contact,
            )
        )  # fmt: skip
    return out
