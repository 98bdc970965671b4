"""The design bodies cut into convex *parts* for the clearance (``clearance``): anchors
(points fixed in a link frame, or at an elbow that follows its DH row), segments with a
radius and boxes, the terms' container, and which pairs of bodies are watched.

Pure maths: numpy in and out.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import InputError
from reachwise.kinematics.design_bodies import DesignBody
from reachwise.kinematics.robot import Robot

Array = NDArray[np.float64]
ENVIRONMENT = "environment"


@dataclass(frozen=True)
class Anchor:
    """A point fixed in frame ``frame`` at ``local`` (link frame, m); ``elbow`` is the
    DH row whose elbow it is (its local coordinate then follows that row), else -1."""

    frame: int
    local: tuple[float, float, float] = (0.0, 0.0, 0.0)
    elbow: int = -1


@dataclass(frozen=True)
class Part:
    """A convex piece of body ``body``: a segment between anchors ``ends`` with radius
    ``radius`` (``env_ends``: the anchors its environment terms use), or a box on
    ``frame`` with ``half`` sizes placed by ``origin`` (corners: anchors ``ends``)."""

    body: int
    kind: Literal["segment", "box"]
    ends: tuple[int, ...]
    radius: float = 0.0
    env_ends: tuple[int, ...] = ()
    frame: int = -1
    half: tuple[float, float, float] = (0.0, 0.0, 0.0)
    origin: tuple[tuple[float, ...], ...] = ()


@dataclass(frozen=True)
class ClearanceTerms:
    """Clearance terms at every task pose: ``distance (K, m)`` (m), their gradients
    w.r.t. the design variables ``(K, m, p)`` and the free joints ``(K, m, n_f)``, and
    per term the pair it measures (``pairs[i] = (body, other body or "environment")``)."""

    distance: Array
    grad_design: Array
    grad_joints: Array
    pairs: tuple[tuple[str, str], ...]

    def smallest(self) -> tuple[Array, list[tuple[str, str]]]:
        """Per pose: the smallest clearance and the pair it belongs to."""
        if self.distance.shape[1] == 0:
            K = self.distance.shape[0]
            return np.full(K, np.inf), [("", "")] * K
        i = np.argmin(self.distance, axis=1)
        return self.distance[np.arange(i.size), i], [self.pairs[k] for k in i]


def as_vec3(v: Array) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


def body_frame(robot: Robot, body: DesignBody) -> int:
    """Row of ``fk_all`` of the link a body sits on."""
    return robot.link_names.index(body.link)


def _carries_extent(robot: Robot, body: DesignBody) -> bool:
    return not body.follows_design or bool(segments_of(robot, body))


def watched_pairs(robot: Robot) -> list[tuple[int, int]]:
    """Pairs of bodies (indices into ``robot.design.bodies``) whose clearance is kept.

    Bodies on one link, on consecutive frames, on frames joined through frames that
    carry no body (as MoveIt treats links without geometry), or with no moving joint
    between them are adjacent; every other pair is watched.
    """
    bodies = robot.design.bodies
    frames = [body_frame(robot, b) for b in bodies]
    occupied = {f for f, b in zip(frames, bodies, strict=True) if _carries_extent(robot, b)}
    movable = set(robot.movable_joints)
    out = []
    for i in range(len(bodies)):
        for j in range(i + 1, len(bodies)):
            fa, fb = sorted((frames[i], frames[j]))
            if fa == fb or not any(f in occupied for f in range(fa + 1, fb)):
                continue
            if not any(r in movable for r in range(fa, fb)):
                continue  # rigidly connected: no pose changes their distance
            if bodies[i].shape == "box" and bodies[j].shape == "box":
                raise InputError(
                    robot.name,
                    f"design.bodies.{bodies[i].name}",
                    f"a watched pair needs a capsule on one side ({bodies[j].name} is a box too)",
                )
            out.append((i, j))
    return out


def segments_of(robot: Robot, body: DesignBody) -> list[tuple[Anchor, Anchor]]:
    """The segments of a design-following capsule, skipping those whose length is 0 in
    every design (the parameter is not free, 0, and no prismatic joint drives it)."""
    j = body_frame(robot, body) - 1
    free = {(r, p) for kind, r, p in robot.design.free if kind == "joint"}
    a, d = robot.dh[j, 0], robot.dh[j, 2]
    has_a = a != 0.0 or (j, "a") in free
    has_d = d != 0.0 or (j, "d") in free or robot.joints[j].type == "prismatic"
    origin, elbow, nxt = Anchor(j), Anchor(j, elbow=j), Anchor(j + 1)
    classic = robot.convention == "classic"
    out = []
    for seg in body.along:
        if seg == "a" and has_a:
            out.append((elbow, nxt) if classic else (origin, elbow))
        elif seg == "d" and has_d:
            out.append((origin, elbow) if classic else (elbow, nxt))
    return out
