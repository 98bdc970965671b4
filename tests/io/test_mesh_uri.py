"""Mesh URIs resolved where users keep their packages: ``package://PKG`` found in a
folder named ``PKG`` beside the robot file or among any ancestor folder's children."""

from __future__ import annotations

from pathlib import Path

import pytest

from reachwise.errors import RobotFileError
from reachwise.io.mesh_uri import resolve_uri
from reachwise.io.urdf import load_urdf

URDF = """<?xml version="1.0"?>
<robot name="arm">
  <link name="base"><collision><geometry>
    <mesh filename="package://xarm_description/meshes/base.stl"/></geometry></collision></link>
  <link name="tip"/>
  <joint name="j1" type="revolute"><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
    <parent link="base"/><child link="tip"/></joint>
</robot>
"""


def _mesh(path: Path) -> None:
    import trimesh

    path.parent.mkdir(parents=True, exist_ok=True)
    trimesh.creation.box(extents=(0.1, 0.1, 0.1)).export(path)


@pytest.mark.parametrize(
    ("urdf_at", "package_at"),
    [
        ("xarm/xarm6_robot.urdf", "xarm/xarm_description"),  # beside the file (pybullet)
        ("data/xarm/xarm6_robot.urdf", "data/xarm_description"),  # a parent's child
        ("a/b/c/arm.urdf", "xarm_description"),  # three levels up
    ],
)
def test_package_beside_the_file_or_an_ancestor_is_found(
    tmp_path: Path, urdf_at: str, package_at: str
) -> None:
    urdf = tmp_path / urdf_at
    urdf.parent.mkdir(parents=True)
    urdf.write_text(URDF)
    mesh = tmp_path / package_at / "meshes" / "base.stl"
    _mesh(mesh)
    robot = load_urdf(urdf)  # no package_dirs
    (shape,) = [g for shapes in robot.geometry.values() for g in shapes]
    assert Path(shape.path or "").resolve() == mesh.resolve()


def test_the_nearest_package_folder_wins_and_a_missing_one_is_named(tmp_path: Path) -> None:
    urdf = tmp_path / "x" / "y" / "arm.urdf"
    urdf.parent.mkdir(parents=True)
    near = tmp_path / "x" / "xarm_description" / "meshes" / "base.stl"
    far = tmp_path / "xarm_description" / "meshes" / "base.stl"
    _mesh(near)
    _mesh(far)
    kw = {"robot_file": urdf, "source": "arm.urdf", "field": "mesh"}
    got = resolve_uri("package://xarm_description/meshes/base.stl", **kw)  # type: ignore[arg-type]
    assert got.resolve() == near.resolve()
    with pytest.raises(RobotFileError, match="no such file in package 'xarm_description'"):
        resolve_uri("package://xarm_description/meshes/gone.stl", **kw)  # type: ignore[arg-type]
    with pytest.raises(RobotFileError, match="unknown package 'other_description'"):
        resolve_uri("package://other_description/meshes/base.stl", **kw)  # type: ignore[arg-type]
