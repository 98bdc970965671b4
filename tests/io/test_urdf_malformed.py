"""Malformed variants of real arms (issue 20): wrong URDFs never load.

Variants of the example-robot-data arms (UR5, Panda, xArm7, Z1, Kinova Gen2, SO-101),
one per validation rule and seeded random mutations of the XML (drop, duplicate,
retype or corrupt an attribute), each fed to ``reachwise.load_robot`` and the link-cloud
builder. Every variant must give either a typed ``ReachwiseError`` whose message names
the file and the element, or a robot whose every limit and shape is finite and valid and
equal to what yourdfpy (an independent reader) reads, with the same forward kinematics.
No raw exception, no silent acceptance.
"""

from __future__ import annotations

import copy
import math
import re
import xml.etree.ElementTree as ET
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import yourdfpy

import reachwise
from reachwise.errors import ReachwiseError, RobotFileError
from tests._real_arms import ARMS, arm_path, needs_erd

pytestmark = needs_erd

MALFORMED_ARMS = ["ur5", "panda", "xarm7", "z1", "kinova", "so101"]
Mutate = Callable[[ET.Element, str], str]  # mutates the tree; returns the text to expect


def _tree(arm: str) -> ET.Element:
    return ET.parse(arm_path(arm)).getroot()


def _write(root: ET.Element, tmp_path: Path, arm: str, tag: str) -> Path:
    path = tmp_path / f"{arm}-{tag}.urdf"
    path.write_text(ET.tostring(root, encoding="unicode"))
    return path


def _chain_joints(root: ET.Element, tip: str) -> list[ET.Element]:
    by_child = {j.find("child").get("link"): j for j in root.findall("joint")}  # type: ignore[union-attr]
    out = []
    link = tip
    while link in by_child:
        out.append(by_child[link])
        link = by_child[link].find("parent").get("link")  # type: ignore[union-attr]
    return out[::-1]


def _moving(root: ET.Element, tip: str) -> ET.Element:
    return next(j for j in _chain_joints(root, tip) if j.get("type") == "revolute")


def _shape_el(root: ET.Element) -> ET.Element:
    """The shape element of the first collision (its only <geometry> child)."""
    col = next(c for c in root.iter("collision"))
    geo = col.find("geometry")
    assert geo is not None
    return next(iter(geo))


def _replace_shape(root: ET.Element, tag: str, **attrs: str) -> str:
    old = _shape_el(root)
    geo = next(c for c in root.iter("collision")).find("geometry")
    assert geo is not None
    geo.remove(old)
    ET.SubElement(geo, tag, attrs)
    owner = next(lk for lk in root.findall("link") if geo in lk.iter("geometry"))
    return f"link '{owner.get('name')}' <collision #1> <{tag}"


def _set(el: ET.Element, attr: str, value: str, owner: str) -> str:
    el.set(attr, value)
    return f'{owner} <{el.tag} {attr}="{value}">'


def _joint_attr(child: str, attr: str, value: str) -> Mutate:
    def mutate(root: ET.Element, tip: str) -> str:
        j = _moving(root, tip)
        el = j.find(child)
        if el is None:
            el = ET.SubElement(j, child)
        return _set(el, attr, value, f"joint '{j.get('name')}'")

    return mutate


def _shape(tag: str, **attrs: str) -> Mutate:
    return lambda root, tip: _replace_shape(root, tag, **attrs)


def _root_tag(root: ET.Element, tip: str) -> str:
    root.tag = "robots"
    return "<robots"


def _dup(kind: str) -> Mutate:
    def mutate(root: ET.Element, tip: str) -> str:
        el = root.findall(kind)[0]
        root.append(copy.deepcopy(el))
        return f"a second {kind} named '{el.get('name')}'"

    return mutate


def _no_velocity(root: ET.Element, tip: str) -> str:
    j = _moving(root, tip)
    lim = j.find("limit")
    assert lim is not None
    del lim.attrib["velocity"]
    return f"joint '{j.get('name')}' <limit> (line"


def _mimic(root: ET.Element, tip: str) -> str:
    chain = [j for j in _chain_joints(root, tip) if j.get("type") != "fixed"]
    ET.SubElement(chain[1], "mimic", joint=str(chain[0].get("name")))
    return f"joint '{chain[1].get('name')}' <mimic>"


def _unknown_parent(root: ET.Element, tip: str) -> str:
    j = _moving(root, tip)
    parent = j.find("parent")
    assert parent is not None
    parent.set("link", "no_such_link")
    return f"joint '{j.get('name')}' (line"


def _joint_type(root: ET.Element, tip: str) -> str:
    j = _moving(root, tip)
    j.set("type", "revolut")
    return f"joint '{j.get('name')}' type=\"revolut\""


def _two_shapes(root: ET.Element, tip: str) -> str:
    geo = next(c for c in root.iter("collision")).find("geometry")
    assert geo is not None
    ET.SubElement(geo, "sphere", radius="0.1")
    return "needs exactly one shape"


def _unknown_shape(root: ET.Element, tip: str) -> str:
    return _replace_shape(root, "cone", radius="0.1").replace("<cone", "<geometry> (line")


def _missing_mesh(root: ET.Element, tip: str) -> str:
    return _replace_shape(root, "mesh", filename="package://no_such_pkg/m.stl").split(" <mesh")[0]


#: rule -> mutation (which returns the text the error must contain)
RULES: dict[str, Mutate] = {
    "root is <robots>": _root_tag,
    "two links with one name": _dup("link"),
    "two joints with one name": _dup("joint"),
    "axis with two numbers": _joint_attr("axis", "xyz", "1 0"),
    "axis with four numbers": _joint_attr("axis", "xyz", "0 0 1 0"),
    "zero axis": _joint_attr("axis", "xyz", "0 0 0"),
    "NaN axis": _joint_attr("axis", "xyz", "0 nan 1"),
    "origin xyz with six numbers": _joint_attr("origin", "xyz", "0 0 0 0 0 0"),
    "origin rpy NaN": _joint_attr("origin", "rpy", "nan 0 0"),
    "origin not a number": _joint_attr("origin", "xyz", "0 zero 0"),
    "lower > upper": _joint_attr("limit", "lower", "9"),
    "infinite lower": _joint_attr("limit", "lower", "-inf"),
    "negative velocity": _joint_attr("limit", "velocity", "-1"),
    "NaN velocity": _joint_attr("limit", "velocity", "nan"),
    "-inf velocity": _joint_attr("limit", "velocity", "-inf"),
    "negative effort": _joint_attr("limit", "effort", "-1"),
    "no velocity": _no_velocity,
    "negative box": _shape("box", size="-0.1 0.1 0.1"),
    "infinite box": _shape("box", size="0.1 inf 0.1"),
    "zero box": _shape("box", size="0.1 0 0.1"),
    "NaN cylinder": _shape("cylinder", radius="nan", length="0.2"),
    "cylinder without length": _shape("cylinder", radius="0.05"),
    "zero sphere": _shape("sphere", radius="0"),
    "negative capsule": _shape("capsule", radius="0.05", length="-0.2"),
    "mesh scale of two": _shape("mesh", filename="x.stl", scale="1 1"),
    "mesh scale of four": _shape("mesh", filename="x.stl", scale="1 1 1 1"),
    "mesh scale zero": _shape("mesh", filename="x.stl", scale="0 1 1"),
    "mesh scale NaN": _shape("mesh", filename="x.stl", scale="nan"),
    "mesh without file": _shape("mesh"),
    "unknown shape": _unknown_shape,
    "two shapes": _two_shapes,
    "unknown package": _missing_mesh,
    "unknown joint type": _joint_type,
    "unknown parent": _unknown_parent,
    "mimic on the chain": _mimic,
}


@pytest.mark.parametrize("arm", MALFORMED_ARMS)
@pytest.mark.parametrize("rule", list(RULES))
def test_each_rule_stops_the_load_naming_file_and_element(
    arm: str, rule: str, tmp_path: Path
) -> None:
    root = _tree(arm)
    tip = ARMS[arm][1]
    expect = RULES[rule](root, tip)
    path = _write(root, tmp_path, arm, "rule")
    with pytest.raises(RobotFileError) as info:
        reachwise.load_robot(path, tip=tip)
    msg = str(info.value)
    assert msg.startswith(f"{path}: "), msg
    assert expect in msg, f"{expect!r} not in {msg!r}"


def test_the_message_format_of_the_issue(tmp_path: Path) -> None:
    root = _tree("ur5")
    joint = next(j for j in root.iter("joint") if j.get("name") == "shoulder_lift_joint")
    limit = joint.find("limit")
    assert limit is not None
    limit.set("velocity", "-1")
    path = tmp_path / "ur5_robot.urdf"
    path.write_text(ET.tostring(root, encoding="unicode"))
    with pytest.raises(RobotFileError) as info:
        reachwise.load_robot(path, tip="tool0")
    assert re.fullmatch(
        re.escape(f"{path}: joint 'shoulder_lift_joint' <limit velocity=\"-1\">")
        + r" \(line \d+\): must be ≥ 0 \(0 means no bound\)",
        str(info.value),
    )


ENTITY_FILES = {
    "billion laughs": '<?xml version="1.0"?><!DOCTYPE r [<!ENTITY a "aaaaaaaaaa">'
    + "".join(
        f'<!ENTITY {c} "{("&" + p + ";") * 10}">'
        for p, c in zip("abcdefgh", "bcdefghi", strict=True)
    )
    + ']><robot name="&i;"><link name="l"/></robot>',
    "external entity": '<?xml version="1.0"?><!DOCTYPE r [<!ENTITY x SYSTEM '
    '"file:///etc/hostname">]><robot name="&x;"><link name="l"/></robot>',
    "parameter entity": '<?xml version="1.0"?><!DOCTYPE r [<!ENTITY % p SYSTEM '
    '"http://127.0.0.1:9/x.dtd"> %p;]><robot name="r"><link name="l"/></robot>',
}


@pytest.mark.parametrize("case", list(ENTITY_FILES))
def test_entities_are_refused_and_nothing_is_read(case: str, tmp_path: Path) -> None:
    path = tmp_path / "e.urdf"
    path.write_text(ENTITY_FILES[case])
    with pytest.raises(RobotFileError, match="entit") as info:
        reachwise.load_robot(path)
    assert str(path) in str(info.value)


# ---- seeded random mutations ---------------------------------------------------------
NUMBERS = ["nan", "-inf", "inf", "-1", "0", "1e400", "", "1 2", "0 0 0 0", "abc", "-0.0", "3"]
WORDS = ["", "no_such_link", "3.5", "fixed", "prismatic", "continuous", "floating", "x y"]


def _owner(root: ET.Element, el: ET.Element) -> str:
    """The name of the link or joint ``el`` belongs to (or its own tag)."""
    for kind in ("link", "joint"):
        for top in root.findall(kind):
            if el is top or any(el is d for d in top.iter()):
                return str(top.get("name"))
    return el.tag


def _mutate(root: ET.Element, rng: np.random.Generator) -> tuple[str, str]:
    """One random mutation; returns (what was done, the owner's name)."""
    parents = {c: p for p in root.iter() for c in p}
    elements = [e for e in root.iter() if e is not root and e.tag is not ET.Comment]
    el = elements[int(rng.integers(len(elements)))]
    owner = _owner(root, el)
    op = rng.choice(["drop", "duplicate", "retype", "corrupt"])
    if op == "duplicate" or not el.attrib:
        parent = parents[el]
        parent.insert(list(parent).index(el) + 1, copy.deepcopy(el))
        return f"duplicate <{el.tag}>", owner
    attr = list(el.attrib)[int(rng.integers(len(el.attrib)))]
    old = el.attrib[attr]
    if op == "drop":
        del el.attrib[attr]
        return f"drop <{el.tag} {attr}>", owner
    numeric = all(re.fullmatch(r"[-+0-9.eE]+", t) for t in old.split()) and old.strip() != ""
    pool = WORDS if (op == "retype") == numeric else NUMBERS
    new = pool[int(rng.integers(len(pool)))]
    el.set(attr, new)
    return f'{op} <{el.tag} {attr}="{old}"> to "{new}"', owner


def _shape_key(kind: str, size: object, radius: object, length: object, mesh: object,
               scale: object) -> tuple[object, ...]:  # fmt: skip
    def r(v: object) -> object:
        return None if v is None else tuple(np.round(np.atleast_1d(np.asarray(v, float)), 12))

    sc = (
        None
        if mesh is None
        else r(np.broadcast_to(np.asarray(1.0 if scale is None else scale, float), 3))
    )
    return (kind, r(size), r(radius), r(length), mesh, sc)


def _check_valid(robot: reachwise.Robot, path: Path, tip: str, rng: np.random.Generator) -> None:
    """A loaded variant equals yourdfpy's reading of the same file."""
    model = yourdfpy.URDF.load(str(path), load_meshes=False, load_collision_meshes=False)
    names = [robot.joints[i].name for i in robot.movable_joints]
    for k, name in enumerate(names):
        uj = model.joint_map[name]
        lo, hi = (
            (-math.pi, math.pi) if uj.type == "continuous" else (uj.limit.lower, uj.limit.upper)
        )
        assert (robot.lower[k], robot.upper[k]) == (lo, hi)
        v = uj.limit.velocity if uj.limit is not None else None
        assert robot.vmax[k] == (v if v else math.inf) and robot.vmax[k] > 0
    assert np.isfinite(robot.lower).all() and np.isfinite(robot.upper).all()
    mine = sorted(
        (_shape_key(g.shape, g.size, g.radius, g.length, g.mesh, g.scale)
         for gs in robot.geometry.values() for g in gs), key=repr
    )  # fmt: skip
    theirs = []
    for link in model.robot.links:
        for item in list(link.collisions) or list(link.visuals):
            geo = item.geometry
            if geo.box is not None:
                theirs.append(_shape_key("box", geo.box.size, None, None, None, None))
            elif geo.cylinder is not None:
                c = geo.cylinder
                theirs.append(_shape_key("cylinder", None, c.radius, c.length, None, None))
            elif geo.sphere is not None:
                theirs.append(_shape_key("sphere", None, geo.sphere.radius, None, None, None))
            else:
                m = geo.mesh
                theirs.append(_shape_key("mesh", None, None, None, m.filename, m.scale))
    assert mine == sorted(theirs, key=repr)
    root = model.base_link
    for q in rng.uniform(robot.lower, robot.upper, (3, robot.n)):
        model.update_cfg(dict(zip(names, q, strict=True)))
        np.testing.assert_allclose(robot.fk(q), model.get_transform(tip, root), atol=1e-10)


RANDOM_PER_ARM = 50


@pytest.mark.parametrize("arm", MALFORMED_ARMS)
def test_random_mutations_give_a_typed_error_or_a_valid_robot(arm: str, tmp_path: Path) -> None:
    tip = ARMS[arm][1]
    rng = np.random.default_rng([2017, MALFORMED_ARMS.index(arm)])
    failures: list[str] = []
    loaded = refused = 0
    for k in range(RANDOM_PER_ARM):
        root = _tree(arm)
        what, owner = _mutate(root, rng)
        path = _write(root, tmp_path, arm, str(k))
        try:
            robot = reachwise.load_robot(path, tip=tip)
            reachwise.link_clouds(robot, points=50)
        except ReachwiseError as exc:
            msg = str(exc)
            refused += 1
            if not msg.startswith(str(path)) or not (
                f"'{owner}'" in msg or "(line " in msg or f"<{owner}" in msg
            ):
                failures.append(f"{what}: the message does not name file and element: {msg}")
            continue
        except Exception as exc:  # a raw exception is a failure of its own
            failures.append(f"{what}: raw {type(exc).__name__}: {exc}")
            continue
        loaded += 1
        try:
            _check_valid(robot, path, tip, rng)
        except Exception as exc:
            failures.append(f"{what}: loaded but differs from yourdfpy: {exc}")
    assert not failures, "\n".join(failures)
    assert refused > 0 and loaded > 0  # both outcomes occur


def test_the_validity_check_sees_a_changed_limit_a_lost_shape_and_a_moved_joint(
    rng: np.random.Generator,
) -> None:
    """The judge of accepted variants on known violations."""
    from dataclasses import replace

    path = arm_path("ur5")
    robot = reachwise.load_robot(path, tip="tool0")
    _check_valid(robot, path, "tool0", rng)
    i = robot.movable_joints[1]
    faster = list(robot.joints)
    faster[i] = replace(faster[i], vmax=math.inf)  # velocity read as unbounded
    with pytest.raises(AssertionError):
        _check_valid(replace(robot, joints=tuple(faster)), path, "tool0", rng)
    lost = {k: v for k, v in robot.geometry.items() if k != "upper_arm_link"}
    with pytest.raises(AssertionError):
        _check_valid(replace(robot, geometry=lost), path, "tool0", rng)
    moved = list(robot.joints)
    moved[i] = replace(moved[i], a=moved[i].a + 1e-6)
    with pytest.raises(AssertionError):
        _check_valid(replace(robot, joints=tuple(moved)), path, "tool0", rng)
