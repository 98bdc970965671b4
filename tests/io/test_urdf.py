"""URDF export/import against an independent implementation: yourdfpy's own FK.

The exported URDF, evaluated by yourdfpy, must put every frame where ``Robot.fk_all``
does; a URDF with tilted joint axes and arbitrary ``rpy`` origins, read by
``load_urdf``, must move its tip exactly as yourdfpy moves it. Tolerance 1e-10.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yourdfpy

from reachwise.errors import RobotFileError
from reachwise.io.robot_file import builtin_robots, load_robot
from reachwise.io.urdf import (
    PASSIVE_MARK,
    decompose_transform,
    decompose_transform_fallback,
    export_urdf,
    load_urdf,
    matrix_from_rpy,
    rotation_z_to,
    rpy_from_matrix,
)
from reachwise.kinematics.robot import Joint, LinkGeometry, Robot
from reachwise.kinematics.transforms import pose_from_xyz_rpy

TOL = 1e-10


def rx(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def tr(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def joint_names(robot: Robot) -> list[str]:
    return [robot.joints[i].name or f"joint_{i + 1}" for i in robot.movable_joints]


def urdf_model(path: Path) -> yourdfpy.URDF:
    return yourdfpy.URDF.load(str(path), load_meshes=False)


def export_and_read(robot: Robot, tmp_path: Path) -> yourdfpy.URDF:
    path = tmp_path / f"{robot.name}.urdf"
    export_urdf(robot, path)
    return urdf_model(path)


# ---- export: yourdfpy FK of every exported frame equals fk_all ---------------------
@pytest.mark.parametrize("name", ["panda", "puma560", "stanford", "sb60"])
def test_exported_frames_match_yourdfpy(
    name: str, tmp_path: Path, rng: np.random.Generator
) -> None:
    robot = load_robot(name)
    model = export_and_read(robot, tmp_path)
    names = joint_names(robot)
    assert list(model.actuated_joint_names) == names
    Q = rng.uniform(robot.lower, robot.upper, (200, robot.n))
    F = robot.fk_all(Q)
    T = robot.fk(Q)
    # classic rows also export the frame on the joint axis before Tx(a) Rx(alpha)
    axis_links = {
        f"link_{i + 1}_axis": (i + 1, np.linalg.inv(tr(x=j.a) @ rx(j.alpha)))
        for i, j in enumerate(robot.joints)
        if robot.convention == "classic" and j.movable
    }
    assert {lk.name for lk in model.robot.links} == {
        "world",
        *robot.link_names,
        *axis_links,
    }
    worst = 0.0
    for q, frames, tool in zip(Q, F, T, strict=True):
        model.update_cfg(dict(zip(names, q, strict=True)))
        for k, link in enumerate(robot.link_names):
            worst = max(worst, np.abs(model.get_transform(link, "world") - frames[k]).max())
        for link, (k, back) in axis_links.items():
            expect = frames[k] @ back
            worst = max(worst, np.abs(model.get_transform(link, "world") - expect).max())
        worst = max(worst, np.abs(model.get_transform("tool", "world") - tool).max())
    assert worst <= TOL


@pytest.mark.parametrize(
    "name", [n for n in builtin_robots() if n not in ("panda", "puma560", "stanford", "sb60")]
)
def test_other_builtins_export_exactly(name: str, tmp_path: Path, rng: np.random.Generator) -> None:
    robot = load_robot(name)
    model = export_and_read(robot, tmp_path)
    names = joint_names(robot)
    for q in rng.uniform(robot.lower, robot.upper, (20, robot.n)):
        model.update_cfg(dict(zip(names, q, strict=True)))
        F = robot.fk_all(q)
        for k, link in enumerate(robot.link_names):
            np.testing.assert_allclose(model.get_transform(link, "world"), F[k], atol=TOL)


def test_export_returns_string_and_writes_file(tmp_path: Path) -> None:
    robot = load_robot("puma560")
    xml = export_urdf(robot)
    assert xml.startswith("<?xml") and '<robot name="puma560">' in xml
    out = tmp_path / "p.urdf"
    assert export_urdf(robot, out) == xml == out.read_text()


def test_classic_export_has_axis_links_and_limits(tmp_path: Path) -> None:
    robot = load_robot("stanford")
    model = export_and_read(robot, tmp_path)
    links = {lk.name for lk in model.robot.links}
    assert {"world", "tool", "link_3_axis"} <= links
    j3 = model.joint_map["joint_3"]
    assert j3.type == "prismatic"
    assert j3.limit.lower == pytest.approx(0.3048) and j3.limit.upper == pytest.approx(1.27)


def test_passive_joints_marked_and_read_back(tmp_path: Path) -> None:
    robot = load_robot("hiab-xs033")
    path = tmp_path / "hiab.urdf"
    xml = export_urdf(robot, path)
    assert xml.count(PASSIVE_MARK) == 2
    back = load_urdf(path)
    assert back.actuated.tolist() == robot.actuated.tolist() == [True] * 4 + [False] * 2
    assert [j.name for j in back.joints] == [j.name for j in robot.joints]


def test_geometry_exported_as_collision_and_visual(tmp_path: Path) -> None:
    robot = load_robot("hiab-xs033")
    model = export_and_read(robot, tmp_path)
    column = model.link_map["link_1"]
    assert len(column.collisions) == len(column.visuals) == 1
    cyl = column.collisions[0].geometry.cylinder
    assert (cyl.radius, cyl.length) == (0.15, 1.3)
    np.testing.assert_allclose(column.collisions[0].origin[:3, 3], [0, 0, -0.65], atol=1e-15)


def test_unbounded_vmax_round_trips(tmp_path: Path) -> None:
    robot = load_robot("stanford")  # no velocity limits published
    path = tmp_path / "s.urdf"
    export_urdf(robot, path)
    assert np.all(np.isinf(load_urdf(path).vmax))
    sb = load_robot("sb60")
    export_urdf(sb, path)
    np.testing.assert_array_equal(load_urdf(path).vmax, sb.vmax)


# ---- round trips --------------------------------------------------------------------
@pytest.mark.parametrize("name", builtin_robots())
def test_robot_urdf_robot_urdf_round_trip(
    name: str, tmp_path: Path, rng: np.random.Generator
) -> None:
    robot = load_robot(name)
    first = tmp_path / "first.urdf"
    export_urdf(robot, first)
    back = load_urdf(first)
    assert back.n == robot.n
    np.testing.assert_array_equal(back.lower, robot.lower)
    np.testing.assert_array_equal(back.upper, robot.upper)
    second = tmp_path / "second.urdf"
    export_urdf(back, second)
    model = urdf_model(second)
    names = joint_names(back)
    Q = rng.uniform(robot.lower, robot.upper, (30, robot.n))
    np.testing.assert_allclose(back.fk(Q), robot.fk(Q), atol=TOL)
    for q in Q:
        model.update_cfg(dict(zip(names, q, strict=True)))
        np.testing.assert_allclose(model.get_transform("tool", "world"), robot.fk(q), atol=TOL)


def test_round_trip_keeps_geometry_in_place(tmp_path: Path, rng: np.random.Generator) -> None:
    robot = load_robot("sb60")
    path = tmp_path / "sb60.urdf"
    export_urdf(robot, path)
    back = load_urdf(path)
    q = rng.uniform(robot.lower, robot.upper)
    F, B = robot.fk_all(q), back.fk_all(q)
    placed = sorted(
        tuple(np.round((F[robot.link_index(k)] @ g.origin_matrix)[:3].ravel(), 9))
        for k, gs in robot.geometry.items()
        for g in gs
    )
    placed_back = sorted(
        tuple(np.round((B[back.link_index(k)] @ g.origin_matrix)[:3].ravel(), 9))
        for k, gs in back.geometry.items()
        for g in gs
    )
    assert placed == placed_back

    def shapes(r: Robot) -> list[tuple[object, ...]]:  # boxes and cylinders (the feed)
        return sorted((g.shape, g.size or (), g.radius or 0.0, g.length or 0.0)
                      for gs in r.geometry.values() for g in gs)  # fmt: skip

    assert shapes(robot) == shapes(back)


def test_loader_dispatches_urdf_files(tmp_path: Path) -> None:
    path = tmp_path / "puma.urdf"
    export_urdf(load_robot("puma560"), path)
    robot = load_robot(str(path))
    q = np.linspace(-0.5, 0.5, 6)
    np.testing.assert_allclose(robot.fk(q), load_robot("puma560").fk(q), atol=TOL)


# ---- import of general URDFs ------------------------------------------------------
TILTED = """<?xml version="1.0"?>
<robot name="tilted">
  <link name="root"/>
  <link name="a"><collision><origin xyz="0.1 0.2 0.3" rpy="0.3 -0.2 1.0"/>
    <geometry><box size="0.2 0.3 0.4"/></geometry></collision></link>
  <link name="b"/>
  <link name="c"><collision><origin xyz="0 0 0.25" rpy="0 0.4 0"/>
    <geometry><cylinder radius="0.05" length="0.5"/></geometry></collision></link>
  <link name="d"/>
  <link name="e"/>
  <link name="f"/>
  <link name="g"><visual><origin xyz="0.01 0.02 0.03" rpy="0 0 0"/>
    <geometry><mesh filename="package://demo/meshes/g.stl"/></geometry></visual></link>
  <link name="tip"/>
  <joint name="mount" type="fixed"><origin xyz="0.3 -0.2 0.5" rpy="0.1 0.2 0.3"/>
    <parent link="root"/><child link="a"/></joint>
  <joint name="j1" type="revolute"><origin xyz="0.1 0.05 0.2" rpy="-0.7 0.4 2.0"/>
    <axis xyz="0.3 -0.5 0.8"/><limit lower="-2.5" upper="2.5" effort="10" velocity="1.5"/>
    <parent link="a"/><child link="b"/></joint>
  <joint name="j2" type="prismatic"><origin xyz="0.4 0.1 -0.3" rpy="1.1 -0.3 0.25"/>
    <axis xyz="1 0 0"/><limit lower="0.0" upper="0.8" effort="10" velocity="0.2"/>
    <parent link="b"/><child link="c"/></joint>
  <joint name="bracket" type="fixed"><origin xyz="0.0 0.2 0.1" rpy="0.5 0.5 -0.5"/>
    <parent link="c"/><child link="d"/></joint>
  <joint name="j3" type="continuous"><origin xyz="0.2 0.0 0.0" rpy="0 1.5707963267948966 0"/>
    <axis xyz="0 -1 0"/><parent link="d"/><child link="e"/></joint>
  <joint name="j4" type="revolute"><origin xyz="0 0 0.3" rpy="3.0 -1.2 0.7"/>
    <axis xyz="0 0 -1"/><limit lower="-1" upper="1" effort="1" velocity="1"/>
    <parent link="e"/><child link="f"/></joint>
  <joint name="j5" type="revolute"><origin xyz="0.05 0.05 0.05" rpy="0 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/>
    <parent link="f"/><child link="g"/></joint>
  <joint name="flange" type="fixed"><origin xyz="0.0 0.0 0.12" rpy="0.2 0.0 -0.4"/>
    <parent link="g"/><child link="tip"/></joint>
</robot>
"""


def _tilted(tmp_path: Path) -> Path:
    """TILTED in ``tmp_path``, with its package ``demo`` (the mesh of link g) beside it."""
    import trimesh

    (tmp_path / "demo" / "meshes").mkdir(parents=True)
    trimesh.creation.box(extents=(0.1, 0.1, 0.1)).export(tmp_path / "demo/meshes/g.stl")
    path = tmp_path / "tilted.urdf"
    path.write_text(TILTED)
    return path


def test_tilted_axes_and_rpy_origins_match_yourdfpy(
    tmp_path: Path, rng: np.random.Generator
) -> None:
    path = _tilted(tmp_path)
    robot = load_urdf(path, package_dirs=[tmp_path])
    model = urdf_model(path)
    assert robot.name == "tilted" and robot.n == 5
    assert [robot.joints[i].name for i in robot.movable_joints] == ["j1", "j2", "j3", "j4", "j5"]
    assert robot.prismatic.tolist() == [False, True, False, False, False]
    assert robot.joints[robot.movable_joints[2]].limits == (-math.pi, math.pi)  # continuous
    np.testing.assert_array_equal(robot.vmax[:2], [1.5, 0.2])
    for q in rng.uniform(robot.lower, robot.upper, (200, robot.n)):
        model.update_cfg(dict(zip(model.actuated_joint_names, q, strict=True)))
        np.testing.assert_allclose(robot.fk(q), model.get_transform("tip", "root"), atol=TOL)


def test_imported_geometry_sits_where_yourdfpy_puts_it(
    tmp_path: Path, rng: np.random.Generator
) -> None:
    path = _tilted(tmp_path)
    robot = load_urdf(path, package_dirs=[tmp_path])
    model = urdf_model(path)
    shapes = {g.shape: (k, g) for k, gs in robot.geometry.items() for g in gs}
    assert set(shapes) == {"box", "cylinder", "mesh"}
    assert shapes["mesh"][1].mesh == "package://demo/meshes/g.stl"
    assert shapes["mesh"][1].path == str(tmp_path / "demo/meshes/g.stl")
    urdf_side = {
        "box": ("a", model.link_map["a"].collisions[0].origin),
        "cylinder": ("c", model.link_map["c"].collisions[0].origin),
        "mesh": ("g", model.link_map["g"].visuals[0].origin),
    }
    for q in rng.uniform(robot.lower, robot.upper, (20, robot.n)):
        model.update_cfg(dict(zip(model.actuated_joint_names, q, strict=True)))
        F = robot.fk_all(q)
        for shape, (link, g) in shapes.items():
            ulink, uorigin = urdf_side[shape]
            expect = model.get_transform(ulink, "root") @ uorigin
            np.testing.assert_allclose(
                F[robot.link_index(link)] @ g.origin_matrix, expect, atol=TOL
            )


def test_import_hand_computed_case(tmp_path: Path) -> None:
    """One joint about world y at (1, 0, 2), a 0.5 m arm along x: by hand at q = π/2."""
    path = tmp_path / "one.urdf"
    path.write_text(
        """<robot name="one"><link name="w"/><link name="arm"/><link name="tip"/>
        <joint name="j" type="revolute"><origin xyz="1 0 2"/><axis xyz="0 1 0"/>
          <limit lower="-3" upper="3" effort="0" velocity="0"/>
          <parent link="w"/><child link="arm"/></joint>
        <joint name="t" type="fixed"><origin xyz="0.5 0 0"/>
          <parent link="arm"/><child link="tip"/></joint></robot>"""
    )
    robot = load_urdf(path)
    # Ry(π/2) maps x to -z: the tip drops from (1.5, 0, 2) to (1, 0, 1.5)
    expect = np.array([[0, 0, 1, 1.0], [0, 1, 0, 0], [-1, 0, 0, 1.5], [0, 0, 0, 1]])
    np.testing.assert_allclose(robot.fk([math.pi / 2]), expect, atol=1e-15)
    np.testing.assert_allclose(robot.fk([0.0])[:3, 3], [1.5, 0, 2], atol=1e-15)
    assert robot.vmax[0] == math.inf  # velocity="0": not specified


def test_nearly_parallel_axes_use_exact_fallback(tmp_path: Path, rng: np.random.Generator) -> None:
    """Axes 1e-9 rad apart and 0.3 m apart: the common normal is 3e8 m away."""
    path = tmp_path / "par.urdf"
    path.write_text(
        """<robot name="par"><link name="w"/><link name="l1"/><link name="l2"/>
        <joint name="j1" type="revolute"><origin xyz="0 0 0.1"/><axis xyz="0 0 1"/>
          <limit lower="-3" upper="3" effort="0" velocity="1"/>
          <parent link="w"/><child link="l1"/></joint>
        <joint name="j2" type="revolute"><origin xyz="0.3 0.2 0.4" rpy="1e-9 0 0.3"/>
          <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="0" velocity="1"/>
          <parent link="l1"/><child link="l2"/></joint></robot>"""
    )
    robot = load_urdf(path)
    assert [j.type for j in robot.joints] == ["revolute", "fixed", "revolute"]
    model = urdf_model(path)
    for q in rng.uniform(robot.lower, robot.upper, (50, 2)):
        model.update_cfg(dict(zip(["j1", "j2"], q, strict=True)))
        np.testing.assert_allclose(robot.fk(q), model.get_transform("l2", "w"), atol=TOL)


def test_tip_selects_a_chain_of_a_tree(tmp_path: Path) -> None:
    path = tmp_path / "tree.urdf"
    path.write_text(
        """<robot name="tree"><link name="w"/><link name="l1"/><link name="f1"/><link name="f2"/>
        <joint name="j1" type="revolute"><axis xyz="0 0 1"/>
          <limit lower="-3" upper="3" effort="0" velocity="1"/>
          <parent link="w"/><child link="l1"/></joint>
        <joint name="g1" type="prismatic"><origin xyz="0 0.1 0.2"/><axis xyz="0 1 0"/>
          <limit lower="0" upper="0.04" effort="0" velocity="1"/>
          <parent link="l1"/><child link="f1"/></joint>
        <joint name="g2" type="prismatic"><origin xyz="0 -0.1 0.2"/><axis xyz="0 -1 0"/>
          <limit lower="0" upper="0.04" effort="0" velocity="1"/>
          <parent link="l1"/><child link="f2"/></joint></robot>"""
    )
    with pytest.raises(RobotFileError, match=r"link 'l1'.*branches into joints \['g1', 'g2'\]"):
        load_urdf(path)
    robot = load_urdf(path, tip="f2")
    assert [j.name for j in robot.joints] == ["j1", "g2"]
    np.testing.assert_allclose(robot.fk([0.0, 0.03])[:3, 3], [0, -0.13, 0.2], atol=1e-15)


# ---- bad files ---------------------------------------------------------------------
def _two_link(joint: str) -> str:
    return '<robot name="bad"><link name="w"/><link name="l"/>' + joint + "</robot>"


BAD = {
    "floating": (
        _two_link('<joint name="j" type="floating"><parent link="w"/><child link="l"/></joint>'),
        r"joint 'j' type=\"floating\" \(line 1\): unsupported joint type",
    ),
    "planar": (
        _two_link('<joint name="j" type="planar"><parent link="w"/><child link="l"/></joint>'),
        r"joint 'j' type=\"planar\" \(line 1\): unsupported joint type",
    ),
    "missing limit": (
        _two_link(
            '<joint name="j" type="revolute"><axis xyz="0 0 1"/>'
            '<parent link="w"/><child link="l"/></joint>'
        ),
        r"joint 'j' \(line 1\): a revolute joint needs <limit",
    ),
    "lower > upper": (
        _two_link(
            '<joint name="j" type="prismatic"><limit lower="1" upper="0" effort="0" '
            'velocity="1"/><parent link="w"/><child link="l"/></joint>'
        ),
        r"joint 'j' <limit lower=\"1\"> \(line 1\): lower 1\.0 > upper 0\.0",
    ),
    "zero axis": (
        _two_link(
            '<joint name="j" type="revolute"><axis xyz="0 0 0"/><limit lower="-1" upper="1" '
            'effort="0" velocity="1"/><parent link="w"/><child link="l"/></joint>'
        ),
        r"joint 'j' <axis xyz=\"0 0 0\"> \(line 1\): the axis must not be zero",
    ),
    "only fixed": (
        _two_link('<joint name="j" type="fixed"><parent link="w"/><child link="l"/></joint>'),
        r"joints: the chain has no revolute or prismatic joint",
    ),
    "two roots": (
        '<robot name="bad"><link name="w"/><link name="l"/><link name="x"/>'
        '<joint name="j" type="fixed"><parent link="w"/><child link="l"/></joint></robot>',
        r"links: expected one root link, found 2",
    ),
    "unknown link": (
        _two_link('<joint name="j" type="fixed"><parent link="w"/><child link="zz"/></joint>'),
        r"joint 'j' \(line 1\): no such link 'zz'",
    ),
    "mimic": (
        '<robot name="bad"><link name="w"/><link name="l"/><link name="m"/>'
        '<joint name="j" type="revolute"><limit lower="-1" upper="1" effort="0" velocity="1"/>'
        '<parent link="w"/><child link="l"/></joint>'
        '<joint name="k" type="revolute"><limit lower="-1" upper="1" effort="0" velocity="1"/>'
        '<mimic joint="j"/><parent link="l"/><child link="m"/></joint></robot>',
        r"joint 'k' <mimic> \(line 1\): mimic joints on the chain are not supported",
    ),
    "not xml": ("this is <not a urdf", r"not valid XML: syntax error at line 1"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_urdf_raises_clear_error(case: str, tmp_path: Path) -> None:
    text, pattern = BAD[case]
    path = tmp_path / "bad.urdf"
    path.write_text(text)
    with pytest.raises(RobotFileError, match=pattern) as info:
        load_urdf(path)
    assert str(path) in str(info.value)


def test_missing_file_and_unknown_tip(tmp_path: Path) -> None:
    with pytest.raises(RobotFileError, match="no such file"):
        load_urdf(tmp_path / "nope.urdf")
    path = tmp_path / "p.urdf"
    export_urdf(load_robot("puma560"), path)
    with pytest.raises(RobotFileError, match=r"tip: no such link 'hand'"):
        load_urdf(path, tip="hand")


# ---- the decompositions behind import -----------------------------------------------
def _compose(t1: float, d1: float, al: float, a: float, t2: float, d2: float) -> np.ndarray:
    return rz(t1) @ tr(z=d1) @ rx(al) @ tr(x=a) @ rz(t2) @ tr(z=d2)


def _random_pose(rng: np.random.Generator) -> np.ndarray:
    return pose_from_xyz_rpy(rng.uniform(-2, 2, 3), rng.uniform(-np.pi, np.pi, 3))


def test_decompose_random_transforms(rng: np.random.Generator) -> None:
    for _ in range(500):
        G = _random_pose(rng)
        np.testing.assert_allclose(_compose(*decompose_transform(G)), G, atol=1e-12)
        phi, pz, rho, ta, al, tb = decompose_transform_fallback(G)
        back = rz(phi) @ tr(z=pz) @ tr(x=rho) @ rz(ta) @ rx(al) @ rz(tb)
        np.testing.assert_allclose(back, G, atol=1e-12)


@pytest.mark.parametrize(
    "G",
    [
        np.eye(4),
        tr(0.3, -0.4, 0.5),  # parallel axes, offset
        rx(math.pi) @ tr(0.2, 0.0, 0.1),  # antiparallel
        rz(0.7) @ tr(z=0.4),  # coincident axes
        rx(-math.pi / 2) @ tr(x=0.5) @ rz(1.0) @ tr(z=-0.2),  # one DH row, negative twist
    ],
)
def test_decompose_special_cases(G: np.ndarray) -> None:
    np.testing.assert_allclose(_compose(*decompose_transform(G)), G, atol=1e-14)


def test_decompose_one_dh_row_returns_its_parameters() -> None:
    G = rx(-1.2) @ tr(x=0.35) @ rz(0.8) @ tr(z=-0.6)
    t1, d1, al, a, t2, d2 = decompose_transform(G)
    np.testing.assert_allclose([t1, d1, al, a, t2, d2], [0, 0, -1.2, 0.35, 0.8, -0.6], atol=1e-14)


def test_decompose_rejects_far_common_normal() -> None:
    G = tr(0.3, 0.2, 0.0) @ rx(1e-10)
    with pytest.raises(ValueError, match="nearly parallel"):
        decompose_transform(G)


def test_rpy_and_axis_rotation_helpers(rng: np.random.Generator) -> None:
    mats = [_random_pose(rng) for _ in range(200)]
    for pitch in (math.pi / 2, -math.pi / 2, math.pi / 2 - 1e-9, -math.pi / 2 + 1e-12):
        mats.append(pose_from_xyz_rpy((0, 0, 0), (0.4, pitch, -1.1)))
    for M in mats:
        np.testing.assert_allclose(
            matrix_from_rpy(rpy_from_matrix(M))[:3, :3], M[:3, :3], atol=1e-14
        )
    for u in [(0, 0, 1), (0, 0, -1), (1, 0, 0), (0, -1e-9, -1), *rng.normal(size=(50, 3))]:
        v = np.asarray(u, float) / np.linalg.norm(u)
        A = rotation_z_to(v)
        np.testing.assert_allclose(A[:3, 2], v, atol=1e-15)
        np.testing.assert_allclose(A[:3, :3].T @ A[:3, :3], np.eye(3), atol=1e-15)
        assert np.linalg.det(A[:3, :3]) == pytest.approx(1.0)


def test_export_of_a_hand_built_robot_with_mesh(tmp_path: Path) -> None:
    robot = Robot(
        "mini",
        (Joint("revolute", d=0.2, limits=(-1.0, 1.0)), Joint("fixed", a=0.3, name="end")),
        geometry={"link_1": LinkGeometry("mesh", mesh="parts/arm.stl")},
    )
    xml = export_urdf(robot)
    assert '<mesh filename="parts/arm.stl" />' in xml
    assert 'name="end" type="fixed"' in xml and 'name="joint_1" type="revolute"' in xml
