"""The validating URDF reader: everything reachwise takes from a URDF, checked.

:func:`read_urdf` parses a URDF file safely (:mod:`reachwise.io.xml_tree`: no entities,
nothing read from elsewhere) and checks every element reachwise uses. A wrong value
never becomes a robot: each problem is a :class:`~reachwise.errors.RobotFileError`
naming the file, the element (with the attribute as written and its line) and the
reason, e.g.::

    ur5_robot.urdf: joint 'shoulder_lift_joint' <limit velocity="-1"> (line 31):
        must be ≥ 0 (0 means no bound)

(one line; broken here to fit).

The rules:

- the root element is ``<robot name=…>``; link names and joint names are unique;
- a joint has a ``type`` (``revolute``, ``continuous``, ``prismatic``, ``fixed``,
  ``floating``, ``planar``), exactly one ``<parent link>`` and ``<child link>`` naming
  links of the file, at most one ``<origin>``, ``<axis>``, ``<limit>``, ``<mimic>``;
- ``<origin xyz rpy>``: exactly three finite numbers each (default zeros);
- ``<axis xyz>``: exactly three finite numbers (default ``1 0 0``), not all zero on a
  moving joint (it is normalised);
- ``<limit>``: on revolute and prismatic joints ``lower`` and ``upper`` are required,
  finite, ``lower ≤ upper``; ``velocity`` is required on them, finite and ≥ 0, where
  **0 means no bound** (reachwise's own export writes ``velocity="0"`` for an unbounded
  joint); ``effort`` (unused by reachwise) finite and ≥ 0 when given; a negative
  velocity or effort is an error, never "unbounded";
- ``<mimic joint=…>`` names a joint of the file; ``multiplier``/``offset`` finite;
- ``<collision>``/``<visual>``: at most one ``<origin>``, exactly one ``<geometry>``
  with exactly one shape: ``<box size>`` (three finite numbers > 0), ``<cylinder
  radius length>``, ``<capsule radius length>``, ``<sphere radius>`` (finite, > 0),
  ``<mesh filename [scale]>`` (a non-empty URI; ``scale`` one or three finite,
  non-zero numbers — a negative factor mirrors the mesh);
- the links form one tree: every link has at most one parent joint, there is exactly
  one root, and every link is reached from it (no cycles).

Elements reachwise does not use are checked too, so that a broken file is never taken
for a good one: ``<inertial>`` (``mass value`` ≥ 0, six finite ``inertia`` numbers),
``<material><color rgba>`` (four numbers in [0, 1]), ``<dynamics>``,
``<safety_controller>``, ``<calibration>`` (finite numbers).

With ``lenient=True`` a problem inside a ``<collision>`` or ``<visual>`` element drops
that element instead, a problem in an unused element is ignored, and the log (logger
``reachwise.io.urdf``) says so, with the same message; everything else stays an error.
Numbers are decimal (``1``, ``-0.5``, ``2.5e-3``); ``nan``/``inf`` are read but rejected
as not finite.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import RobotFileError
from reachwise.io.urdf_attributes import (
    XmlErrors,
    attr_numbers,
    attr_required,
    attr_scalar,
    one_child,
    optional_child,
    origin_pose,
)
from reachwise.io.xml_tree import XmlElement, read_xml
from reachwise.kinematics.link_geometry import ShapeKind

__all__ = [
    "JOINT_TYPES",
    "PASSIVE_MARK",
    "UrdfJoint",
    "UrdfLink",
    "UrdfModel",
    "UrdfShape",
    "log",
    "read_urdf",
]

log = logging.getLogger("reachwise.io.urdf")

#: The comment that marks a joint passive (written by :func:`reachwise.io.urdf.export_urdf`).
PASSIVE_MARK = "reachwise: passive"
JointKind = Literal["revolute", "continuous", "prismatic", "fixed", "floating", "planar"]
JOINT_TYPES: tuple[str, ...] = (
    "revolute",
    "continuous",
    "prismatic",
    "fixed",
    "floating",
    "planar",
)

Mat = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class UrdfShape:
    """One ``<collision>`` or ``<visual>`` element: the shape, in its link's frame."""

    element: Literal["collision", "visual"]
    index: int  # 1-based among the link's elements of this kind
    kind: ShapeKind
    origin: Mat
    line: int
    size: tuple[float, float, float] | None = None
    radius: float | None = None
    length: float | None = None
    mesh: str | None = None
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    link: str = ""

    @property
    def where(self) -> str:
        """``link 'x' <collision #2>``: the element, for messages."""
        return f"link {self.link!r} <{self.element} #{self.index}>"


@dataclass(frozen=True, eq=False)
class UrdfLink:
    name: str
    collisions: tuple[UrdfShape, ...]
    visuals: tuple[UrdfShape, ...]
    line: int


@dataclass(frozen=True, eq=False)
class UrdfJoint:
    """One joint. ``axis`` is a unit vector; ``lower``/``upper`` are ``None`` when the
    file gives none; ``velocity`` is ``inf`` for no bound (absent or 0)."""

    name: str
    type: JointKind
    parent: str
    child: str
    origin: Mat
    axis: NDArray[np.float64]
    lower: float | None
    upper: float | None
    velocity: float
    mimic: tuple[str, float, float] | None  # (joint, multiplier, offset)
    passive: bool
    line: int
    has_limit: bool


@dataclass(frozen=True, eq=False)
class UrdfModel:
    """A validated URDF: its links and joints (file order) and the tree they form."""

    name: str
    source: str
    path: Path
    links: dict[str, UrdfLink]
    joints: dict[str, UrdfJoint]
    root: str

    def parent_joint(self, link: str) -> UrdfJoint | None:
        for j in self.joints.values():
            if j.child == link:
                return j
        return None


# ---- links and shapes -----------------------------------------------------------------
def _shape(
    err: XmlErrors, link: str, el: XmlElement, kind: Literal["collision", "visual"], index: int
) -> UrdfShape:
    what = f"link {link!r} <{kind} #{index}>"
    origin = origin_pose(err, what, el)
    geo = one_child(err, what, el, "geometry")
    shapes = [c for c in geo.children if c.tag in ("box", "cylinder", "sphere", "mesh", "capsule")]
    others = [c.tag for c in geo.children if c.tag not in ("box", "cylinder", "sphere", "mesh",
                                                           "capsule")]  # fmt: skip
    if others and not shapes:
        raise err(what, geo, f"unknown shape <{others[0]}> (box, cylinder, capsule, sphere, mesh)")
    if len(shapes) != 1:
        raise err(what, geo, f"needs exactly one shape, found {len(shapes)}")
    s = shapes[0]
    common = {"element": kind, "index": index, "origin": origin, "line": s.line, "link": link}

    def positive(attr: str, values: list[float]) -> None:
        if any(v <= 0 for v in values):
            raise err(what, s, f"{attr} must be > 0", attr)

    if s.tag == "box":
        size = attr_numbers(err, what, s, "size", (3,), None)
        positive("size", size)
        return UrdfShape(kind="box", size=(size[0], size[1], size[2]), **common)  # type: ignore[arg-type]
    if s.tag in ("cylinder", "capsule"):
        r = attr_required(err, what, s, "radius")
        h = attr_required(err, what, s, "length")
        positive("radius", [r])
        positive("length", [h])
        return UrdfShape(kind=s.tag, radius=r, length=h, **common)  # type: ignore[arg-type]
    if s.tag == "sphere":
        r = attr_required(err, what, s, "radius")
        positive("radius", [r])
        return UrdfShape(kind="sphere", radius=r, **common)  # type: ignore[arg-type]
    filename = s.get("filename")
    if filename is None or not filename.strip():
        raise err(what, s, "filename is required (a package://, file:// or relative path)")
    scale = attr_numbers(err, what, s, "scale", (1, 3), "1 1 1")
    if any(v == 0 for v in scale):
        raise err(what, s, "scale factors must be ≠ 0 (a negative factor mirrors)", "scale")
    sc = (scale[0],) * 3 if len(scale) == 1 else (scale[0], scale[1], scale[2])
    return UrdfShape(kind="mesh", mesh=filename.strip(), scale=sc, **common)  # type: ignore[arg-type]


def _numbers_of(err: XmlErrors, what: str, el: XmlElement, attrs: dict[str, int | None]) -> None:
    """Check the numeric attributes ``attrs`` of ``el`` (name -> how many numbers; ``None``:
    one, optional)."""
    for attr, count in attrs.items():
        if count is None:
            attr_scalar(err, what, el, attr)
        else:
            attr_numbers(err, what, el, attr, (count,), None)


def _unused(err: XmlErrors, what: str, el: XmlElement, lenient: bool) -> None:
    """Elements reachwise does not use are still checked, so a broken file is not
    taken for a good one: ``<inertial>`` (``origin``, ``mass value`` ≥ 0, the six
    ``inertia`` numbers), ``<material><color rgba>`` (four numbers in [0, 1]),
    ``<dynamics>``, ``<safety_controller>``, ``<calibration>`` (finite numbers). With
    ``lenient`` a problem is logged and ignored."""
    try:
        if el.tag == "link":
            inertial = optional_child(err, what, el, "inertial")
            if inertial is not None:
                origin_pose(err, what, inertial)
                mass = one_child(err, what, inertial, "mass")
                if attr_required(err, what, mass, "value") < 0:
                    raise err(what, mass, "must be ≥ 0", "value")
                inertia = one_child(err, what, inertial, "inertia")
                names = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
                _numbers_of(err, what, inertia, dict.fromkeys(names, 1))
            for vis in el.findall("visual"):
                for mat in vis.findall("material"):
                    for color in mat.findall("color"):
                        rgba = attr_numbers(err, what, color, "rgba", (4,), None)
                        if not all(0.0 <= v <= 1.0 for v in rgba):
                            raise err(what, color, "rgba values must lie in [0, 1]", "rgba")
        else:
            for tag, attrs in (
                ("dynamics", ("damping", "friction")),
                ("safety_controller", ("soft_lower_limit", "soft_upper_limit", "k_position",
                                       "k_velocity")),
                ("calibration", ("rising", "falling", "reference_position")),
            ):  # fmt: skip
                sub = optional_child(err, what, el, tag)
                if sub is not None:
                    _numbers_of(err, what, sub, dict.fromkeys(attrs))
    except RobotFileError as exc:
        if not lenient:
            raise
        log.warning("%s (lenient: ignored; reachwise does not use it)", exc)


def _link(err: XmlErrors, el: XmlElement, lenient: bool) -> UrdfLink:
    name = el.get("name")
    if name is None or not name.strip():
        raise err("link", el, "name is required")
    _unused(err, f"link {name!r}", el, lenient)
    out: dict[str, list[UrdfShape]] = {"collision": [], "visual": []}
    for kind in ("collision", "visual"):
        for i, c in enumerate(el.findall(kind), start=1):
            try:
                out[kind].append(_shape(err, name, c, kind, i))  # type: ignore[arg-type]
            except RobotFileError as exc:
                if not lenient:
                    raise
                log.warning("%s (lenient: this <%s> element is left out)", exc, kind)
    return UrdfLink(name, tuple(out["collision"]), tuple(out["visual"]), el.line)


# ---- joints ---------------------------------------------------------------------------
def _joint(err: XmlErrors, el: XmlElement, lenient: bool) -> UrdfJoint:
    name = el.get("name")
    if name is None or not name.strip():
        raise err("joint", el, "name is required")
    what = f"joint {name!r}"
    _unused(err, what, el, lenient)
    jtype = el.get("type")
    if jtype is None:
        raise err(what, None, "type is required (revolute, continuous, prismatic, fixed, …)")
    if jtype not in JOINT_TYPES:
        raise RobotFileError(
            err.source,
            f'{what} type="{jtype}" (line {el.line})',
            f"unknown joint type; URDF joint types are {', '.join(JOINT_TYPES)}",
        )
    ends = {}
    for tag in ("parent", "child"):
        e = one_child(err, what, el, tag)
        link = e.get("link")
        if link is None or not link.strip():
            raise err(what, e, "link is required", "link")
        ends[tag] = link
    origin = origin_pose(err, what, el)
    moving = jtype not in ("fixed", "floating")
    ax_el = optional_child(err, what, el, "axis")
    axis = np.array([1.0, 0.0, 0.0])
    if ax_el is not None:
        axis = np.array(attr_numbers(err, what, ax_el, "xyz", (3,), None))
    norm = float(np.linalg.norm(axis))
    if moving and not norm > 0:
        raise err(what, ax_el, "the axis must not be zero", "xyz")
    if norm > 0:
        axis = axis / norm
    lim = optional_child(err, what, el, "limit")
    lower, upper, velocity = _limits(err, what, el, lim, jtype)
    mimic = None
    m = optional_child(err, what, el, "mimic")
    if m is not None:
        leader = m.get("joint")
        if leader is None or not leader.strip():
            raise err(what, m, "joint is required", "joint")
        mult = attr_scalar(err, what, m, "multiplier")
        off = attr_scalar(err, what, m, "offset")
        mimic = (leader, 1.0 if mult is None else mult, 0.0 if off is None else off)
    passive = any(PASSIVE_MARK in c for c in el.comments)
    return UrdfJoint(
        name=name,
        type=jtype,  # type: ignore[arg-type]
        parent=ends["parent"],
        child=ends["child"],
        origin=origin,
        axis=axis,
        lower=lower,
        upper=upper,
        velocity=velocity,
        mimic=mimic,
        passive=passive,
        line=el.line,
        has_limit=lim is not None,
    )


def _limits(
    err: XmlErrors, what: str, el: XmlElement, lim: XmlElement | None, jtype: str
) -> tuple[float | None, float | None, float]:
    """A joint's ``<limit>``: its lower and upper bounds (rad or m, ``None`` when not
    given) and its speed bound (rad/s or m/s, ``inf`` for none or 0); a revolute or
    prismatic joint needs all three, with lower ≤ upper."""
    lower = upper = None
    velocity = math.inf
    if lim is not None:
        lower = attr_scalar(err, what, lim, "lower")
        upper = attr_scalar(err, what, lim, "upper")
        vel = attr_scalar(err, what, lim, "velocity")
        if vel is None and jtype in ("revolute", "prismatic"):
            raise err(what, lim, "velocity is required (write 0 for no bound)")
        eff = attr_scalar(err, what, lim, "effort")
        if vel is not None and vel < 0:
            raise err(what, lim, "must be ≥ 0 (0 means no bound)", "velocity")
        if eff is not None and eff < 0:
            raise err(what, lim, "must be ≥ 0 (0 means not given)", "effort")
        if vel is not None and vel > 0:
            velocity = vel
    if jtype in ("revolute", "prismatic"):
        if lim is None:
            raise err(what, el, f"a {jtype} joint needs <limit lower=… upper=… velocity=…>")
        if lower is None or upper is None:
            missing = "lower" if lower is None else "upper"
            raise err(what, lim, f"a {jtype} joint needs {missing}", missing)
        if lower > upper:
            raise err(what, lim, f"lower {lower!r} > upper {upper!r}", "lower")
    return lower, upper, velocity


# ---- the file -------------------------------------------------------------------------
def read_urdf(path: str | Path, *, lenient: bool = False, source: str | None = None) -> UrdfModel:
    """Read and check the URDF file ``path`` (rules in the module docstring)."""
    p = Path(path)
    src = str(path) if source is None else source
    if not p.is_file():
        raise RobotFileError(src, "", "no such file")
    err = XmlErrors(src)
    root = read_xml(p, src, RobotFileError)
    if root.tag != "robot":
        raise err("", root, "the root element of a URDF must be <robot>")
    name = root.get("name")
    if name is None or not name.strip():
        raise err("", root, "name is required")
    links: dict[str, UrdfLink] = {}
    for el in root.findall("link"):
        lk = _link(err, el, lenient)
        if lk.name in links:
            raise err(f"link {lk.name!r}", el, f"a second link named {lk.name!r} "
                      f"(the first is on line {links[lk.name].line})")  # fmt: skip
        links[lk.name] = lk
    if not links:
        raise err("", root, "a robot needs at least one <link>")
    joints: dict[str, UrdfJoint] = {}
    for el in root.findall("joint"):
        j = _joint(err, el, lenient)
        if j.name in joints:
            raise err(f"joint {j.name!r}", el, f"a second joint named {j.name!r} "
                      f"(the first is on line {joints[j.name].line})")  # fmt: skip
        joints[j.name] = j
    root_link = _tree(src, links, joints)
    return UrdfModel(name.strip(), src, p, links, joints, root_link)


def _tree(source: str, links: dict[str, UrdfLink], joints: dict[str, UrdfJoint]) -> str:
    """Check that links and joints form one tree; return its root link."""
    parent_of: dict[str, UrdfJoint] = {}
    children: dict[str, list[str]] = {}
    for j in joints.values():
        where = f"joint {j.name!r} (line {j.line})"
        for end in (j.parent, j.child):
            if end not in links:
                raise RobotFileError(source, where, f"no such link {end!r}")
        if j.child in parent_of:
            raise RobotFileError(
                source,
                f"link {j.child!r}",
                f"has several parent joints ({parent_of[j.child].name!r}, {j.name!r}): not a tree",
            )
        if j.mimic is not None and j.mimic[0] not in joints:
            raise RobotFileError(source, f"{where} <mimic>", f"no such joint {j.mimic[0]!r}")
        parent_of[j.child] = j
        children.setdefault(j.parent, []).append(j.child)
    roots = [lk for lk in links if lk not in parent_of]
    if not roots:  # every link has a parent: name a joint of a cycle
        link = next(iter(links))
        visited: set[str] = set()
        while link not in visited:
            visited.add(link)
            link = parent_of[link].parent
        j = parent_of[link]
        raise RobotFileError(
            source,
            f"joint {j.name!r} (line {j.line})",
            f"closes a cycle through link {link!r}: the links have no root",
        )
    if len(roots) > 1:
        raise RobotFileError(
            source,
            "links",
            f"expected one root link, found {len(roots)}: {roots[:5]} (a link no joint "
            "connects, or a joint naming the wrong parent)",
        )
    seen = {roots[0]}
    todo = [roots[0]]
    while todo:
        for c in children.get(todo.pop(), []):
            if c not in seen:
                seen.add(c)
                todo.append(c)
    lost = [lk for lk in links if lk not in seen]
    if lost:
        raise RobotFileError(
            source,
            f"link {lost[0]!r}",
            "is not connected to the root link (the joints form a cycle)",
        )
    return roots[0]
