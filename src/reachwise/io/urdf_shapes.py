"""Every collision and visual shape of a URDF, placed on the reachwise link frames.

A reachwise robot built from a URDF chain (:func:`reachwise.io.urdf.load_urdf`) has one
frame per moving joint; every URDF link is a body of its own
(:class:`~reachwise.kinematics.bodies.Body`, keyed by its URDF name, with its parent link
and joint) that rides rigidly on one of them:

- a link **on the chain** rides on the frame right after the last moving joint above
  it (the root and links fixed to it on ``link_0``, the tip on ``tool``);
- a link **off the chain** (a finger, a second end-effector frame, a sensor) rides on
  the frame of its nearest chain ancestor, with the joints between held where they are
  at rest: 0, moved into the joint's limits when 0 lies outside them; a mimic joint at
  ``multiplier × leader + offset``. The log says so for every such link with shapes
  (the shape is kept, at that pose, rather than dropped). A floating or planar joint
  off the chain cannot be held anywhere: the shapes below it are an error (left out,
  and logged, with ``lenient=True``).

A link's shapes are given in the frame it rides on and stay the link's own. Each
``<collision>`` element becomes one :class:`~reachwise.kinematics.link_geometry.
LinkGeometry` with its own origin; a link with no ``<collision>`` element lends its
``<visual>`` shapes for collision, and the log says so. Every ``<visual>`` element also
goes into ``Robot.visual`` for the viewer. Mesh URIs are resolved now
(:func:`reachwise.io.mesh_uri.resolve_uri`): a mesh that cannot be found is an error
naming the URI and every place searched (left out, and logged, with ``lenient=True``);
the file itself is read when a cloud or a view needs it.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import RobotFileError
from reachwise.io.mesh_uri import resolve_uri
from reachwise.io.urdf_model import UrdfJoint, UrdfModel, UrdfShape, log
from reachwise.kinematics.bodies import Body
from reachwise.kinematics.link_geometry import LinkGeometry

if TYPE_CHECKING:
    from reachwise.kinematics.robot import Robot

__all__ = ["held_value", "joint_motion", "place_shapes"]

Mat = NDArray[np.float64]
Shapes = dict[str, tuple[LinkGeometry, ...]]


def joint_motion(j: UrdfJoint, value: float) -> Mat:
    """The motion of URDF joint ``j`` at ``value`` (after its origin): a rotation about
    or a translation along its unit axis (identity for fixed joints)."""
    M = np.eye(4)
    if j.type in ("revolute", "continuous"):
        u = j.axis
        K = np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])
        M[:3, :3] = np.eye(3) + math.sin(value) * K + (1.0 - math.cos(value)) * (K @ K)
    elif j.type == "prismatic":
        M[:3, 3] = value * j.axis
    return M


def held_value(model: UrdfModel, j: UrdfJoint, on_chain: set[str]) -> float:
    """Where an off-chain joint is held: 0 moved into its limits, or its mimic value
    (``multiplier × leader + offset``, the leader held the same way, a chain joint at 0)."""
    if j.mimic is not None:
        leader = model.joints[j.mimic[0]]
        base = 0.0 if leader.name in on_chain else held_value(model, leader, on_chain)
        return j.mimic[1] * base + j.mimic[2]
    if j.type in ("revolute", "prismatic") and j.lower is not None and j.upper is not None:
        return float(np.clip(0.0, j.lower, j.upper))
    return 0.0


def _inv(T: Mat) -> Mat:
    out = np.eye(4)
    out[:3, :3] = T[:3, :3].T
    out[:3, 3] = -T[:3, :3].T @ T[:3, 3]
    return out


def place_shapes(
    model: UrdfModel,
    chain: Sequence[UrdfJoint],
    robot: Robot,
    *,
    package_dirs: Sequence[str | os.PathLike[str]] = (),
    lenient: bool = False,
) -> tuple[Shapes, Shapes, dict[str, Body]]:
    """``(geometry, visual, bodies)`` of ``robot`` (built from ``chain`` of ``model``):
    every shape of every link, keyed by the link, in the reachwise frame it rides on,
    and every link's body (see the module docstring)."""
    source = model.source
    on_chain = {j.name for j in chain}
    frame_of = {model.root: 0}
    k = 0
    for j in chain:
        if j.type != "fixed":
            k += 1
        frame_of[j.child] = 0 if k == 0 else robot.movable_joints[k - 1] + 1
    tip = chain[-1].child if chain else model.root
    P, ride, held, blocked = _link_poses(model, on_chain)
    F = robot.fk_all(np.zeros(robot.n))
    geometry: dict[str, list[LinkGeometry]] = {}
    visual: dict[str, list[LinkGeometry]] = {}
    parent_joint = {j.child: j for j in model.joints.values()}
    bodies: dict[str, Body] = {}
    for name, link in model.links.items():
        r = ride[name]
        row = len(robot.link_names) - 1 if r == tip else frame_of[r]
        target = robot.link_names[row]
        pj = parent_joint.get(name)
        bodies[name] = Body(target, pj.parent if pj else "", pj.name if pj else "")
        C = _inv(F[row]) @ P[name]
        collisions = link.collisions
        if not collisions and link.visuals:
            log.warning(
                "%s: link %r has no <collision> element: its %d <visual> shape(s) are used "
                "for collision",
                source,
                name,
                len(link.visuals),
            )
            collisions = link.visuals
        if (collisions or link.visuals) and name in blocked:
            j = blocked[name]
            reason = (
                f"the shapes of link {name!r} hang below this {j.type} joint off the chain "
                "and cannot be placed"
            )
            if not lenient:
                raise RobotFileError(
                    source, f'joint {j.name!r} type="{j.type}" (line {j.line})', reason
                )
            log.warning("%s: joint %r: %s (lenient: left out)", source, j.name, reason)
            continue
        if collisions and r != name:
            how = held.get(name)
            (log.warning if how else log.debug)(
                "%s: link %r is not on the chain to %r: its shapes ride on %s (%s)",
                source,
                name,
                tip,
                target,
                how or "rigidly",
            )
        for s in collisions:
            g = _geometry(model, s, C, package_dirs, lenient)
            if g is not None:
                geometry.setdefault(name, []).append(g)
        for s in link.visuals:
            g = _geometry(model, s, C, package_dirs, lenient)
            if g is not None:
                visual.setdefault(name, []).append(g)
    return (
        {k: tuple(v) for k, v in geometry.items()},
        {k: tuple(v) for k, v in visual.items()},
        bodies,
    )


def _link_poses(
    model: UrdfModel, on_chain: set[str]
) -> tuple[dict[str, Mat], dict[str, str], dict[str, str], dict[str, UrdfJoint]]:
    """Walking the tree from the root with the off-chain joints held: each link's pose
    at zero, the chain link it rides on, how it is held (for the log), and the
    floating or planar off-chain joint it hangs below, if any."""
    children: dict[str, list[UrdfJoint]] = {}
    for j in model.joints.values():
        children.setdefault(j.parent, []).append(j)
    P: dict[str, Mat] = {model.root: np.eye(4)}
    ride = {model.root: model.root}
    held: dict[str, str] = {}  # off-chain link -> how it is held (for the log)
    blocked: dict[str, UrdfJoint] = {}  # links below a floating/planar off-chain joint
    todo = [model.root]
    while todo:
        parent = todo.pop()
        for j in children.get(parent, []):
            c = j.child
            todo.append(c)
            if j.name in on_chain:
                P[c] = P[parent] @ j.origin
                ride[c] = c
                continue
            ride[c] = ride[parent]
            if parent in blocked:
                blocked[c] = blocked[parent]
            if j.type in ("floating", "planar"):
                blocked[c] = j
            value = held_value(model, j, on_chain)
            P[c] = P[parent] @ j.origin @ joint_motion(j, value)
            note = "" if j.type == "fixed" else f"joint {j.name!r} held at {value:g}"
            up = held.get(parent, "")
            held[c] = ", ".join(x for x in (up, note) if x)
    return P, ride, held, blocked


def _geometry(
    model: UrdfModel,
    s: UrdfShape,
    C: Mat,
    package_dirs: Sequence[str | os.PathLike[str]],
    lenient: bool,
) -> LinkGeometry | None:
    G = C @ s.origin
    origin = tuple(tuple(float(x) for x in row) for row in G)
    path = None
    if s.kind == "mesh" and s.mesh is not None:
        field = f'{s.where} <mesh filename="{s.mesh}"> (line {s.line})'
        try:
            path = str(
                resolve_uri(
                    s.mesh,
                    robot_file=model.path,
                    package_dirs=package_dirs,
                    source=model.source,
                    field=field,
                )
            )
        except RobotFileError as exc:
            if not lenient:
                raise
            log.warning("%s (lenient: this <%s> element is left out)", exc, s.element)
            return None
    return LinkGeometry(
        s.kind,
        mesh=s.mesh,
        size=s.size,
        radius=s.radius,
        length=s.length,
        origin=origin,
        scale=s.scale,
        path=path,
        label=s.where,
    )
