"""Link clouds with a resolution by default: a URDF robot's clouds cover their shapes
within 1 cm with few points (a fine mesh keeps far fewer than its vertices) and say so
(``PointCloud.resolution``); a YAML robot keeps its stated counts; the check made with
every cloud catches a cloud that leaves a gap."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

import reachwise
from reachwise.errors import InputError
from reachwise.io import robot_clouds
from reachwise.io.robot_clouds import RESOLUTION, covering_points, link_cloud
from tests._real_arms import ARMS, arm_path, needs_erd


def test_a_fine_mesh_is_covered_with_few_points() -> None:
    sphere = trimesh.creation.icosphere(subdivisions=6, radius=0.1)  # 40 962 vertices
    pts = covering_points(sphere, 0.01)
    assert len(pts) < len(sphere.vertices) / 20
    # about area / r^2 points: at least a disc packing's worth
    assert len(pts) > sphere.area / (np.pi * 0.01**2)
    dense = trimesh.creation.icosphere(subdivisions=7, radius=0.1).sample(200_000, seed=3)
    assert cKDTree(pts).query(dense)[0].max() <= 0.01
    # every kept point lies on the mesh surface
    assert np.abs(np.linalg.norm(pts, axis=1) - 0.1).max() < 1e-3


def test_the_check_made_with_the_cloud_sees_a_gap(monkeypatch: pytest.MonkeyPatch) -> None:
    box = trimesh.creation.box(extents=[0.3, 0.2, 0.1])
    real = robot_clouds.greedy_cover
    monkeypatch.setattr(robot_clouds, "greedy_cover", lambda v, r: real(v, r)[::3])
    with pytest.raises(InputError, match="misses the surface"):
        covering_points(box, 0.01)


@needs_erd
def test_a_urdf_robot_gets_covering_clouds_by_default() -> None:
    robot = reachwise.load_robot(arm_path("ur5"), tip=ARMS["ur5"][1])
    clouds = reachwise.link_clouds(robot)
    assert clouds and all(c.resolution == RESOLUTION for c in clouds.values())
    sampled = reachwise.link_clouds(robot, points=500)
    assert all(c.resolution == 0.0 and len(c.points) == 500 for c in sampled.values())
    with pytest.raises(InputError, match="one of points, density and resolution"):
        link_cloud(robot, "forearm_link", 500, resolution=0.01)


def test_a_yaml_robot_keeps_its_stated_counts() -> None:
    robot = reachwise.load_robot("hiab-xs033")
    clouds = reachwise.link_clouds(robot)
    stated = {link: max(g.points for g in shapes) for link, shapes in robot.geometry.items()}
    assert {k: len(c.points) for k, c in clouds.items()} == stated
    assert all(c.resolution == 0.0 for c in clouds.values())
    fine = link_cloud(robot, "link_5", resolution=0.02)  # a 0.1 m cube
    assert fine.resolution == 0.02
