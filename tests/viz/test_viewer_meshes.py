"""The viewer draws a URDF robot's visual meshes on its link frames, where yourdfpy puts
them (the meshes read by trimesh directly, not through reachwise)."""

from __future__ import annotations

import numpy as np
import trimesh
import yourdfpy

import reachwise
from reachwise.viz.modes import show_robot
from reachwise.viz.viewer import Viewer
from tests._real_arms import arm_path, needs_erd, package_file

pytestmark = needs_erd


def test_ur5_visual_meshes_sit_where_yourdfpy_puts_them(
    viewer: Viewer, rng: np.random.Generator
) -> None:
    path = arm_path("ur5")
    robot = reachwise.load_robot(path, tip="tool0")
    show_robot(viewer, robot)
    view = viewer.robots["ur5"]
    assert not view.mesh_notes
    nodes = {n: h for n, h in viewer.nodes.items() if "/mesh_" in n}
    assert len(nodes) == sum(len(v) for v in robot.visual.values()) == 7
    assert all(n in viewer.categories["robot meshes"] for n in nodes)
    model = yourdfpy.URDF.load(str(path), load_meshes=False)
    q = rng.uniform(robot.lower, robot.upper)
    model.update_cfg(
        dict(zip([robot.joints[i].name for i in robot.movable_joints], q, strict=True))
    )
    F = robot.fk_all(q)
    drawn = []
    for name, h in nodes.items():
        link = name.split("/")[3]
        V = np.asarray(h.vertices, dtype=float)
        drawn.append(V @ F[robot.link_index(link), :3, :3].T + F[robot.link_index(link), :3, 3])
    truth = []
    for link in model.robot.links:
        for vis in link.visuals:
            m = trimesh.load(str(package_file(vis.geometry.mesh.filename)), force="mesh")
            T = model.get_transform(link.name, model.base_link) @ (
                np.eye(4) if vis.origin is None else vis.origin
            )
            truth.append(np.asarray(m.vertices) @ T[:3, :3].T + T[:3, 3])
    key = [np.r_[v.min(axis=0), v.max(axis=0)] for v in drawn]  # world bounding boxes
    want = [np.r_[v.min(axis=0), v.max(axis=0)] for v in truth]
    for k in key:
        assert any(np.allclose(k, w, atol=2e-4) for w in want)
