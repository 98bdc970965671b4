"""Robot-file geometry: several shapes per link, every shape kind, mesh files resolved at
load (or left out and logged with lenient), the same rules as a URDF's shapes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

import reachwise
from reachwise.errors import InputError, RobotFileError
from reachwise.io.robot_file import robot_to_dict, save_robot
from reachwise.kinematics.link_geometry import LinkGeometry

ROBOT = """name: r
joints:
  - {type: revolute, a: 0, alpha: 0, d: 0.1, theta: 0}
  - {type: revolute, a: 0.4, alpha: 0, d: 0, theta: 0}
geometry:
  link_1:
    - {box: [0.1, 0.1, 0.2], xyz: [0, 0, 0.1], points: 600}
    - {sphere: 0.05, xyz: [0, 0, 0.25], points: 400}
  link_2:
    - {capsule: [0.04, 0.3], rpy: [0, 1.5707963267948966, 0], xyz: [0.2, 0, 0]}
    - {mesh: part.stl, scale: [1, 2, 1]}
"""


def _write(tmp_path: Path, text: str = ROBOT) -> Path:
    trimesh.creation.box(extents=(0.1, 0.1, 0.1)).export(tmp_path / "part.stl")
    path = tmp_path / "r.yaml"
    path.write_text(text)
    return path


def test_several_shapes_per_link_sampled_by_area_and_round_tripped(tmp_path: Path) -> None:
    robot = reachwise.load_robot(_write(tmp_path))
    assert [g.shape for g in robot.geometry["link_1"]] == ["box", "sphere"]
    assert [g.shape for g in robot.geometry["link_2"]] == ["capsule", "mesh"]
    assert robot.geometry["link_2"][1].path == str(tmp_path / "part.stl")
    clouds = reachwise.link_clouds(robot, seed=2)
    c1 = clouds["link_1"].points
    assert len(c1) == 600  # the link's count: the largest of its shapes'
    on_sphere = np.abs(np.linalg.norm(c1 - (0, 0, 0.25), axis=1) - 0.05) < 1e-3
    box_area, sphere_area = 2 * (0.01 + 0.02 + 0.02), 4 * np.pi * 0.05**2
    share = sphere_area / (box_area + sphere_area)  # the sphere's share of the surface
    assert abs(on_sphere.mean() - share) < 0.06
    mesh_pts = clouds["link_2"].points
    in_mesh = np.all(np.abs(mesh_pts) <= (0.05 + 1e-6, 0.1 + 1e-6, 0.05 + 1e-6), axis=1)
    assert np.abs(mesh_pts[in_mesh][:, 1]).max() == pytest.approx(0.1, abs=1e-6)  # scaled y
    dense = reachwise.link_clouds(robot, density=20_000.0)
    area = box_area + sphere_area
    assert abs(len(dense["link_1"]) - area * 20_000) <= 0.01 * area * 20_000  # faceted sphere
    out = tmp_path / "again.yaml"
    save_robot(robot, out)
    back = reachwise.load_robot(out)
    assert robot_to_dict(back)["geometry"] == robot_to_dict(robot)["geometry"]


@pytest.mark.parametrize(
    ("bad", "match"),
    [
        ("{sphere: -0.05}", "sphere radius must be > 0"),
        ("{box: [0.1, .nan, 0.1]}", "box"),
        ("{capsule: [0.04, 0]}", "capsule sizes must be > 0"),
        ("{mesh: part.stl, scale: 0}", "scale factors must be ≠ 0"),
        ("{box: [0.1, 0.1, 0.1], sphere: 0.1}", "exactly one of"),
        ("{sphere: 0.1, scale: 2}", "scale is for meshes"),
    ],
)
def test_bad_shapes_name_the_file_and_link(tmp_path: Path, bad: str, match: str) -> None:
    path = _write(tmp_path, ROBOT.split("geometry:")[0] + f"geometry:\n  link_1: {bad}\n")
    with pytest.raises(RobotFileError, match=match) as info:
        reachwise.load_robot(path)
    assert str(path) in str(info.value) and "geometry.link_1" in str(info.value)


def test_a_missing_mesh_stops_the_load_unless_lenient(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    path = _write(tmp_path, ROBOT.replace("part.stl", "package://nopkg/part.stl"))
    with pytest.raises(RobotFileError, match=r"geometry\.link_2\[1\]\.mesh.*unknown package"):
        reachwise.load_robot(path)
    with caplog.at_level("WARNING"):
        robot = reachwise.load_robot(path, lenient=True)
    assert [g.shape for g in robot.geometry["link_2"]] == ["capsule"]
    assert any("nopkg" in r.getMessage() and "left out" in r.getMessage() for r in caplog.records)


def test_shape_values_are_checked_when_a_shape_is_made() -> None:
    with pytest.raises(InputError, match="radius"):
        LinkGeometry("sphere", radius=float("nan"))
    with pytest.raises(InputError, match="scale"):
        LinkGeometry("mesh", mesh="a.stl", scale=(1.0, 0.0, 1.0))
    with pytest.raises(InputError, match="size"):
        LinkGeometry("box", size=(0.1, -0.1, 0.1))
    with pytest.raises(InputError, match="unknown shape"):
        LinkGeometry("cone")  # type: ignore[arg-type]
