"""URDF export and import of serial chains, exact to floating-point rounding.

Export (``export_urdf``)
------------------------
One URDF link per reachwise frame: ``world`` (the root), ``link_0`` (the base frame,
a fixed joint ``world -> link_0`` carrying ``Robot.base``), ``link_1`` … ``link_N``
(the frame after DH row ``i``, fixed rows included) and ``tool`` (a fixed joint carrying
``Robot.tool``). Every URDF link frame therefore equals the matching row of
``Robot.fk_all`` (P-I Eq. 2–6). Each DH row becomes

* **modified DH** (Craig, P-I Eq. 2–3), ``A = Rx(alpha) Tx(a) Rz(theta + q) Tz(d + q)``:
  one URDF joint ``link_{i-1} -> link_i`` whose origin is the constant part
  ``Rx(alpha) Tx(a) Rz(theta) Tz(d)`` and whose axis is ``z`` — exact, because
  ``Rz`` and ``Tz`` commute, so ``Rz(theta + q) Tz(d) = Rz(theta) Tz(d) Rz(q)`` and
  ``Rz(theta) Tz(d + q) = Rz(theta) Tz(d) Tz(q)``;
* **classic DH**, ``A = Rz(theta + q) Tz(d + q) Tx(a) Rx(alpha)``: the moving joint
  (origin ``Rz(theta) Tz(d)``, axis ``z``) into an intermediate link
  ``link_i_axis``, then a fixed joint ``<name>_dh`` carrying ``Tx(a) Rx(alpha)`` to
  ``link_i``; a fixed classic row is one fixed joint with the whole ``A``.

Joint types map revolute → ``revolute``, prismatic → ``prismatic``, fixed → ``fixed``
and passive → ``revolute`` marked by the comment ``<!-- reachwise: passive -->``
inside the ``<joint>`` element (the grabber of P-V hangs on two such joints).
``<limit lower upper velocity effort>``: ``velocity`` is ``vmax``; reachwise has no
force model, so ``effort="0"`` means "not specified", and an unbounded ``vmax`` is
written as ``velocity="0"`` (read back as unbounded). Every collision shape of a link is
written as a ``<collision>`` element (box, cylinder, sphere, capsule, or mesh by filename
with its ``scale``), its visual shapes as ``<visual>`` elements (the collision shapes
again when it has none). Design bounds and point-cloud sample counts have no URDF
counterpart and are not written.

Import (``load_urdf``)
----------------------
A URDF joint is ``T(q) = O · M(u, q)`` with a general rigid origin ``O`` and a motion
``M`` about/along a unit axis ``u`` (any direction). With a rotation ``A`` taking ``z``
onto ``u``, ``M(u, q) = A · M(z, q) · Aᵀ``. Walking the chain, the constant transform
between two consecutive moving joints is ``G = Aᵀ_prev · O_fixed… · O · A`` and is
decomposed (``decompose_transform``) as

    G = Rz(θ₁) Tz(d₁) · Rx(α) Tx(a) Rz(θ₂) Tz(d₂)                          (★)

(the common normal of the two joint axes, Craig §3.4). ``Rz(θ₁) Tz(d₁)`` commutes
with the previous row's motion ``Rz(q)`` or ``Tz(q)`` and is added to that row's
``theta``/``d`` offsets; ``Rx(α) Tx(a) Rz(θ₂) Tz(d₂)`` is the moving row's constant
part. So every moving URDF joint becomes exactly one modified-DH row. Where (★) is
ill-conditioned (axes parallel but not coincident up to rounding, common normal far
away) the exact fallback ``G = Rz(φ) Tz(p_z) · [fixed row Tx(ρ) Rz(θa)] ·
[Rx(α) Rz(θb)]`` is used (polar translation, then ZXZ Euler angles), which adds one
fixed row. Fixed URDF joints before the first and after the last moving joint go into
``Robot.base`` and ``Robot.tool``. Every shape is re-expressed in the reachwise link
frame it is rigidly attached to (:mod:`reachwise.io.urdf_shapes`); the file is read
and checked first by :mod:`reachwise.io.urdf_model`. ``continuous`` joints become
revolute joints limited to ``[-π, π]`` (every orientation; no wrap-around motion).
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import RobotFileError
from reachwise.io.atomic import atomic_write
from reachwise.io.urdf_dh import (
    decompose_transform,
    decompose_transform_fallback,
    mdh_transform,
    rotation_z_to,
)
from reachwise.io.urdf_model import PASSIVE_MARK, UrdfJoint, UrdfModel, read_urdf
from reachwise.kinematics.robot import Joint, JointType, LinkGeometry, Robot
from reachwise.kinematics.transforms import matrix_from_rpy, rpy_from_matrix
from reachwise.kinematics.transforms import rot_x as _rx
from reachwise.kinematics.transforms import rot_z as _rz
from reachwise.kinematics.transforms import translation as _tr

_SUPPORTED = ("revolute", "continuous", "prismatic", "fixed")

Mat = NDArray[np.float64]


# ---- export ------------------------------------------------------------------------
def _f(v: float) -> str:
    x = float(v)
    if abs(x) < 1e-15:
        x = 0.0
    return repr(x)


def _origin(parent: ET.Element, T: Mat) -> None:
    rpy = rpy_from_matrix(T)
    ET.SubElement(
        parent,
        "origin",
        xyz=" ".join(_f(v) for v in T[:3, 3]),
        rpy=" ".join(_f(v) for v in rpy),
    )


def _unique(name: str, used: set[str]) -> str:
    out, k = name, 2
    while out in used:
        out, k = f"{name}_{k}", k + 1
    used.add(out)
    return out


def _shape_element(parent: ET.Element, tag: str, g: LinkGeometry) -> None:
    el = ET.SubElement(parent, tag)
    _origin(el, g.origin_matrix)
    geo = ET.SubElement(el, "geometry")
    if g.shape == "box":
        ET.SubElement(geo, "box", size=" ".join(_f(v) for v in (g.size or ())))
    elif g.shape in ("cylinder", "capsule"):
        ET.SubElement(geo, g.shape, radius=_f(g.radius or 0.0), length=_f(g.length or 0.0))
    elif g.shape == "sphere":
        ET.SubElement(geo, "sphere", radius=_f(g.radius or 0.0))
    else:
        attrs = {"filename": str(g.mesh)}
        if tuple(g.scale) != (1.0, 1.0, 1.0):
            attrs["scale"] = " ".join(_f(v) for v in g.scale)
        ET.SubElement(geo, "mesh", attrs)


def _geometry_elements(link: ET.Element, robot: Robot, frame: str) -> None:
    """The ``<collision>`` and ``<visual>`` elements of every body riding on ``frame``
    (its collision shapes again when a body has no visual shapes)."""
    for body in robot.body_names:
        if robot.frame_of(body) != frame:
            continue
        collisions = robot.geometry.get(body, ())
        visuals = robot.visual.get(body) or collisions
        for g in visuals:
            _shape_element(link, "visual", g)
        for g in collisions:
            _shape_element(link, "collision", g)


def _joint_element(
    root: ET.Element,
    name: str,
    jtype: str,
    ends: tuple[str, str],
    origin: Mat,
    j: Joint | None = None,
) -> None:
    """Add ``<joint name type>`` to ``root``: its origin, parent and child links
    (``ends``), and for a moving row ``j`` its z axis and limits (a passive joint
    marked by a comment; an unbounded speed written as 0)."""
    el = ET.SubElement(root, "joint", name=name, type=jtype)
    if j is not None and j.passive:
        el.append(ET.Comment(f" {PASSIVE_MARK} "))
    _origin(el, origin)
    ET.SubElement(el, "parent", link=ends[0])
    ET.SubElement(el, "child", link=ends[1])
    if j is not None and jtype != "fixed":
        ET.SubElement(el, "axis", xyz="0 0 1")
        vel = j.vmax if math.isfinite(j.vmax) else 0.0
        ET.SubElement(
            el,
            "limit",
            lower=_f(j.limits[0]),
            upper=_f(j.limits[1]),
            effort="0",
            velocity=_f(vel),
        )


def export_urdf(robot: Robot, path: str | Path | None = None) -> str:
    """The robot as a URDF XML string (written to ``path`` when given).

    yourdfpy's forward kinematics of link ``link_i`` / ``tool`` relative to ``world``
    equals ``robot.fk_all(q)`` / ``robot.fk(q)`` to rounding for every ``q`` (the joint
    values are keyed by the URDF joint names, in ``robot.movable_joints`` order). The
    URDF links are the robot's frames in order, so the shapes of bodies riding on one
    frame (a robot read from a URDF) go into that frame's link.
    See the module docstring for the construction.
    """
    root = ET.Element("robot", name=robot.name)
    root.append(
        ET.Comment(
            f" Generated by reachwise from robot {robot.name!r} ({robot.convention} DH, "
            f"{len(robot.joints)} rows). Link frames link_0..link_{len(robot.joints)} and "
            "tool equal Robot.fk_all. effort='0' = not specified; velocity='0' = unbounded. "
        )
    )
    links: dict[str, ET.Element] = {}

    def add_link(name: str) -> None:
        links[name] = ET.SubElement(root, "link", name=name)

    used: set[str] = set()
    names = [_unique(j.name or f"joint_{i + 1}", used) for i, j in enumerate(robot.joints)]
    base_name = _unique("base_joint", used)
    tool_name = _unique("tool_joint", used)

    def add_joint(
        name: str, jtype: str, parent: str, child: str, origin: Mat, j: Joint | None = None
    ) -> None:
        _joint_element(root, name, jtype, (parent, child), origin, j)

    add_link("world")
    add_link("link_0")
    add_joint(base_name, "fixed", "world", "link_0", np.asarray(robot.base, dtype=float))
    for i, j in enumerate(robot.joints):
        parent, child = f"link_{i}", f"link_{i + 1}"
        jtype = j.type  # a passive joint is a revolute Joint with passive=True
        if robot.convention == "modified":
            add_link(child)
            add_joint(names[i], jtype, parent, child, mdh_transform(j.alpha, j.a, j.theta, j.d), j)
        elif j.type == "fixed":
            add_link(child)
            A = _rz(j.theta) @ _tr(z=j.d) @ _tr(x=j.a) @ _rx(j.alpha)
            add_joint(names[i], "fixed", parent, child, A, j)
        else:
            mid = f"{child}_axis"
            add_link(mid)
            add_joint(names[i], jtype, parent, mid, _rz(j.theta) @ _tr(z=j.d), j)
            add_link(child)
            add_joint(
                _unique(f"{names[i]}_dh", used), "fixed", mid, child, _tr(x=j.a) @ _rx(j.alpha)
            )
    add_link("tool")
    add_joint(
        tool_name, "fixed", f"link_{len(robot.joints)}", "tool", np.asarray(robot.tool, dtype=float)
    )
    rows = [*(f"link_{i}" for i in range(len(robot.joints) + 1)), "tool"]
    for row, frame in zip(rows, robot.link_names, strict=True):
        _geometry_elements(links[row], robot, frame)
    ET.indent(root, space="  ")
    xml = '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"
    if path is not None:
        atomic_write(path, xml)
    return xml


# ---- import ------------------------------------------------------------------------
def _chain(model: UrdfModel, tip: str | None) -> list[UrdfJoint]:
    """The joints from the root link to ``tip`` (or to the single leaf), in order."""
    source = model.source
    parent_of = {j.child: j for j in model.joints.values()}
    by_parent: dict[str, list[UrdfJoint]] = {}
    for j in model.joints.values():
        by_parent.setdefault(j.parent, []).append(j)
    if tip is not None:
        if tip not in model.links:
            leaves = [lk for lk in model.links if lk not in by_parent]
            raise RobotFileError(
                source, "tip", f"no such link {tip!r}; the leaf links are {leaves[:20]}"
            )
        out = []
        link = tip
        while link in parent_of:
            out.append(parent_of[link])
            link = parent_of[link].parent
        return out[::-1]
    out = []
    link = model.root
    while link in by_parent:
        kids = by_parent[link]
        if len(kids) > 1:
            raise RobotFileError(
                source,
                f"link {link!r}",
                f"branches into joints {[k.name for k in kids]}; reachwise handles serial "
                "chains only (pass tip=LINK, or --tip LINK, for the chain from the root to LINK)",
            )
        out.append(kids[0])
        link = kids[0].child
    return out


def _joint_row(source: str, uj: UrdfJoint) -> Joint:
    """Type, limits and vmax of one moving URDF joint (DH parameters set later)."""
    where = f"joint {uj.name!r}"
    if uj.type not in _SUPPORTED:
        raise RobotFileError(
            source,
            f'{where} type="{uj.type}" (line {uj.line})',
            "unsupported joint type on the chain (revolute, continuous, prismatic, fixed)",
        )
    if uj.mimic is not None:
        raise RobotFileError(
            source,
            f"{where} <mimic> (line {uj.line})",
            "mimic joints on the chain are not supported",
        )
    if uj.type == "continuous":
        limits = (-math.pi, math.pi)
    elif uj.lower is None or uj.upper is None:  # read_urdf requires them; kept for safety
        raise RobotFileError(
            source, f"{where} <limit> (line {uj.line})", f"a {uj.type} joint needs lower and upper"
        )
    else:
        limits = (uj.lower, uj.upper)
    kind: JointType = "prismatic" if uj.type == "prismatic" else "revolute"
    return Joint(kind, limits=limits, vmax=uj.velocity, passive=uj.passive, name=uj.name)


def load_urdf(
    path: str | Path,
    tip: str | None = None,
    *,
    package_dirs: Sequence[str | os.PathLike[str]] | None = None,
    lenient: bool = False,
) -> Robot:
    """A ``Robot`` (modified DH) from a URDF serial chain, with all its shapes.

    The file is read and checked by :func:`reachwise.io.urdf_model.read_urdf` (every
    error names the file, the element and the reason). ``tip``: take the chain from the
    root link to this link; by default the URDF must be a single unbranched chain. The
    tool frame is the tip link. The forward kinematics equals the URDF's for that link
    (to rounding) at every ``q``; ``q`` follows the chain's moving joints, root to tip.
    Joints marked ``<!-- reachwise: passive -->`` become passive. Unsupported joint
    types and mimic joints on the chain are errors. Every collision and visual shape of
    every link is kept, placed on the reachwise frame it rides on, mesh URIs resolved
    with ``package_dirs`` (:mod:`reachwise.io.urdf_shapes`, :mod:`reachwise.io.mesh_uri`).
    ``lenient=True`` leaves out (and logs) shapes that are invalid or whose mesh cannot
    be found instead of raising. See the module docstring for the DH decomposition.
    """
    from reachwise.io.urdf_shapes import place_shapes

    p = Path(path)
    source = str(p)
    model = read_urdf(p, lenient=lenient, source=source)
    chain = _chain(model, tip)
    rows_in = [(uj, _joint_row(source, uj)) for uj in chain if uj.type != "fixed"]
    if not rows_in:
        raise RobotFileError(source, "joints", "the chain has no revolute or prismatic joint")
    template = {uj.name: j for uj, j in rows_in}

    joints, after, base, tool = _dh_rows(chain, template)
    tip_link = chain[-1].child if chain else model.root
    first_moving = next(uj for uj in chain if uj.type != "fixed")
    frames = _frame_names(model, chain, [first_moving.parent, *after], tip_link)
    robot = Robot(model.name, joints, base=base, tool=tool, source=source, frame_names=frames)
    geometry, visual, bodies = place_shapes(
        model, chain, robot, package_dirs=package_dirs or (), lenient=lenient
    )
    return replace(robot, geometry=geometry, visual=visual, bodies=bodies)


def _dh_rows(
    chain: list[UrdfJoint], template: dict[str, Joint]
) -> tuple[tuple[Joint, ...], list[str], Mat, Mat]:
    """The modified DH rows of ``chain`` (each moving joint's row from its ``template``;
    a transform :func:`decompose_transform` cannot take adds a fixed row), the URDF
    link or joint each row's frame is named after, the base and the tool transform."""
    rows: list[dict[str, Any]] = []  # DH rows: joint template + a, alpha, d, theta
    after: list[str] = []  # the URDF link or joint each row's frame is named after
    base = np.eye(4)
    acc = np.eye(4)  # constant transform from the last reachwise frame (or the root)
    first = True
    for uj in chain:
        acc = acc @ uj.origin
        if uj.type == "fixed":
            continue
        A = rotation_z_to(uj.axis)
        G = acc @ A
        row: dict[str, Any] = {"joint": template[uj.name], "a": 0.0, "alpha": 0.0, "d": 0.0,
                               "theta": 0.0}  # fmt: skip
        if first:
            base = G
            first = False
        else:
            try:
                t1, d1, al, a, t2, d2 = decompose_transform(G)
                rows[-1]["theta"] += t1
                rows[-1]["d"] += d1
                row.update(alpha=al, a=a, theta=t2, d=d2)
            except ValueError:
                phi, pz, rho, ta, al, tb = decompose_transform_fallback(G)
                rows[-1]["theta"] += phi
                rows[-1]["d"] += pz
                fixed = Joint("fixed", name=f"{uj.name}_offset")
                rows.append({"joint": fixed, "a": rho, "alpha": 0.0, "d": 0.0, "theta": ta})
                after.append(fixed.name)
                row.update(alpha=al, a=0.0, theta=tb, d=0.0)
        rows.append(row)
        after.append(uj.child)
        acc = A.T.copy()

    def clean(v: float) -> float:  # drop rounding dust (|v| < 1e-15) for readable tables
        return 0.0 if abs(v) < 1e-15 else float(v)

    return (
        tuple(
            replace(
                r["joint"],
                a=clean(r["a"]),
                alpha=clean(r["alpha"]),
                d=clean(r["d"]),
                theta=clean(r["theta"]),
            )
            for r in rows
        ),
        after,
        base,
        acc,
    )


def _frame_names(
    model: UrdfModel, chain: Sequence[UrdfJoint], after: list[str], tip: str
) -> tuple[str, ...]:
    """The names of a URDF robot's frames: the base frame after the link the first
    moving joint hangs from, each
    moving joint's frame after the link it moves, the tool frame after the tip link. A
    frame no link rides on of its own (the last joint's, when the tip is the link that
    joint moves; the extra fixed row of a fallback decomposition) is named after its
    URDF joint (``_frame`` appended if a link has that name)."""
    joint_of = {j.child: j.name for j in chain}
    used = set(model.links) | {tip}
    out = []
    for name in after:
        if name == tip or name not in model.links:
            base = joint_of.get(name, name)
            name = _unique(base if base not in used else f"{base}_frame", used)
        out.append(name)
    return (*out, tip)


__all__ = [
    "PASSIVE_MARK",
    "decompose_transform",
    "decompose_transform_fallback",
    "export_urdf",
    "load_urdf",
    "matrix_from_rpy",
    "rotation_z_to",
    "rpy_from_matrix",
]
