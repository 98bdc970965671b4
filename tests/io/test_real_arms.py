"""Real arms from example-robot-data (UR5, UR10, Panda, xArm7, Z1, Kinova Gen2, SO-101)
loaded with ``reachwise.load_robot(path, tip=...)`` against an independent reader,
yourdfpy: the tool pose at 200 random joint vectors, and every collision shape of every
link (placed by yourdfpy, its mesh read by trimesh directly) against the link clouds
placed by ``fk_all``.
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import trimesh
import yourdfpy
from scipy.spatial import cKDTree

import reachwise
from reachwise.errors import ReachwiseError, RobotFileError
from tests._real_arms import ARMS, arm_path, needs_erd, package_file

pytestmark = needs_erd

TOL = 1e-10


def _model(path: Path) -> yourdfpy.URDF:
    return yourdfpy.URDF.load(str(path), load_meshes=False, load_collision_meshes=False)


def _chain_names(robot: reachwise.Robot) -> list[str]:
    return [robot.joints[i].name for i in robot.movable_joints]


@pytest.mark.parametrize("arm", list(ARMS))
def test_tool_pose_equals_yourdfpy(arm: str, rng: np.random.Generator) -> None:
    path = arm_path(arm)
    tip = ARMS[arm][1]
    robot = reachwise.load_robot(path, tip=tip)
    model = _model(path)
    root = model.base_link
    names = _chain_names(robot)
    Q = rng.uniform(robot.lower, robot.upper, (200, robot.n))
    T = robot.fk(Q)
    worst = 0.0
    for q, t in zip(Q, T, strict=True):
        model.update_cfg(dict(zip(names, q, strict=True)))
        worst = max(worst, float(np.abs(model.get_transform(tip, root) - t).max()))
    assert worst <= TOL, f"{arm}: tool pose differs from yourdfpy's by {worst:.2e}"


# ---- every collision shape, placed by yourdfpy ----------------------------------------
def _sdf_box(x: np.ndarray, size: np.ndarray) -> np.ndarray:
    q = np.abs(x) - size / 2
    outside = np.linalg.norm(np.maximum(q, 0), axis=1)
    return outside + np.minimum(q.max(axis=1), 0)


def _truth_shapes(model: yourdfpy.URDF) -> list[tuple[str, str, Any, np.ndarray]]:
    """(link, kind, geometry, pose in the root frame) for every shape reachwise must keep:
    a link's collision elements, or its visual ones when it has none."""
    out = []
    root = model.base_link
    for link in model.robot.links:
        items = list(link.collisions) or list(link.visuals)
        for item in items:
            g = item.geometry
            kind = next(k for k in ("box", "cylinder", "sphere", "mesh") if getattr(g, k))
            origin = np.eye(4) if item.origin is None else np.asarray(item.origin, float)
            out.append(
                (link.name, kind, getattr(g, kind), model.get_transform(link.name, root) @ origin)
            )
    return out


def _surface(kind: str, g: Any, pose: np.ndarray) -> trimesh.Trimesh | None:
    """A mesh of the shape for sampling (primitives finely tessellated), in the root frame."""
    if kind == "box":
        m = trimesh.creation.box(extents=np.asarray(g.size, float))
    elif kind == "cylinder":
        m = trimesh.creation.cylinder(radius=g.radius, height=g.length, sections=256)
    elif kind == "sphere":
        m = trimesh.creation.icosphere(subdivisions=5, radius=g.radius)
    else:
        m = trimesh.load(str(package_file(g.filename)), force="mesh")
        scale = np.ones(3) if g.scale is None else np.broadcast_to(np.asarray(g.scale, float), 3)
        m.apply_scale(scale)
    m.apply_transform(pose)
    return m


def _distance_to(
    kind: str, g: Any, pose: np.ndarray, mesh: trimesh.Trimesh, P: np.ndarray
) -> np.ndarray:
    """Distance of world points ``P`` to the shape's surface: exact for primitives,
    nearest triangle for meshes."""
    x = (P - pose[:3, 3]) @ pose[:3, :3]
    if kind == "box":
        return np.abs(_sdf_box(x, np.asarray(g.size, float)))
    if kind == "sphere":
        return np.abs(np.linalg.norm(x, axis=1) - g.radius)
    if kind == "cylinder":
        r = np.hypot(x[:, 0], x[:, 1]) - g.radius
        h = np.abs(x[:, 2]) - g.length / 2
        inside = np.minimum(np.maximum(r, h), 0)
        return np.abs(np.hypot(np.maximum(r, 0), np.maximum(h, 0)) + inside)
    _, d, _ = trimesh.proximity.closest_point(mesh, P)
    return np.asarray(d)


def _placement_errors(
    robot: reachwise.Robot, model: yourdfpy.URDF, q: np.ndarray
) -> tuple[float, dict[str, float]]:
    """The farthest any cloud point lies from every shape yourdfpy places (m), and the
    fraction of 400 points sampled on each shape with a cloud point within 3 cm."""
    clouds = reachwise.link_clouds(robot, seed=1)
    model.update_cfg(dict(zip(_chain_names(robot), q, strict=True)))
    F = robot.fk_all(q)
    world = np.vstack(
        [c.points @ F[robot.link_index(k)][:3, :3].T + F[robot.link_index(k)][:3, 3]
         for k, c in clouds.items()]
    )  # fmt: skip
    near = np.full(len(world), np.inf)
    tree = cKDTree(world)
    covered = {}
    for i, (link, kind, g, pose) in enumerate(_truth_shapes(model)):
        mesh = _surface(kind, g, pose)
        lo, hi = mesh.bounds[0] - 2e-3, mesh.bounds[1] + 2e-3
        todo = np.flatnonzero((near > 1e-3) & np.all((world >= lo) & (world <= hi), axis=1))
        if len(todo):  # only points not yet placed on a shape, near this one
            near[todo] = np.minimum(near[todo], _distance_to(kind, g, pose, mesh, world[todo]))
        gap, _ = tree.query(np.asarray(mesh.sample(400, seed=7)))
        covered[f"{link} {kind} #{i}"] = float(np.mean(gap <= 0.03))
    return float(near.max()), covered


@pytest.mark.parametrize("arm", list(ARMS))
def test_link_clouds_lie_on_and_cover_every_collision_shape(
    arm: str, rng: np.random.Generator
) -> None:
    path = arm_path(arm)
    robot = reachwise.load_robot(path, tip=ARMS[arm][1])
    model = _model(path)
    for j in model.robot.joints:  # off-chain joints rest at 0, inside their limits here
        if j.name not in _chain_names(robot) and j.limit is not None and j.type != "fixed":
            assert j.limit.lower <= 0 <= j.limit.upper
    assert sum(len(g) for g in robot.geometry.values()) == len(_truth_shapes(model))
    off, covered = _placement_errors(robot, model, rng.uniform(robot.lower, robot.upper))
    assert off <= 1e-3, f"{arm}: a cloud point lies {off * 1e3:.2f} mm off every shape"
    worst = min(covered, key=covered.__getitem__)
    assert covered[worst] >= 0.99, f"{arm}: {worst}: only {covered[worst]:.1%} within 3 cm"


def test_the_placement_check_sees_a_shifted_and_a_missing_shape(rng: np.random.Generator) -> None:
    """The judge above on known violations: one UR5 shape moved by 5 mm, one left out."""
    from dataclasses import replace

    path = arm_path("ur5")
    robot = reachwise.load_robot(path, tip="tool0")
    model = _model(path)
    q = rng.uniform(robot.lower, robot.upper)
    (g,) = robot.geometry["upper_arm_link"]
    O = g.origin_matrix
    O[:3, 3] += (0.005, 0.0, 0.0)
    shifted = dict(robot.geometry, upper_arm_link=(replace(g, origin=tuple(map(tuple, O))),))
    off, _ = _placement_errors(replace(robot, geometry=shifted), model, q)
    assert off > 2e-3
    missing = {k: v for k, v in robot.geometry.items() if k != "forearm_link"}
    _, covered = _placement_errors(replace(robot, geometry=missing), model, q)
    assert min(covered.values()) < 0.5


# ---- errors naming the file and the URI ---------------------------------------------------
def _copy_with(tmp_path: Path, arm: str, old: str, new: str) -> Path:
    src = arm_path(arm)
    text = src.read_text()
    assert old in text
    dst = tmp_path / src.name
    dst.write_text(text.replace(old, new))
    return dst


def test_missing_mesh_unknown_package_and_broken_dae_name_file_and_uri(tmp_path: Path) -> None:
    mesh = "package://example-robot-data/robots/kinova_description/meshes/base.dae"
    gone = "package://example-robot-data/robots/kinova_description/meshes/gone.dae"
    path = _copy_with(tmp_path, "kinova", mesh, gone)
    with pytest.raises(RobotFileError) as info:
        reachwise.load_robot(path, tip="j2s6s200_end_effector")
    msg = str(info.value)
    assert str(path) in msg and gone in msg and "no such file in package" in msg
    assert "searched:" in msg and "gone.dae" in msg.split("searched:")[1]

    unknown = "package://no_such_pkg/meshes/base.dae"
    path = _copy_with(tmp_path, "kinova", mesh, unknown)
    with pytest.raises(RobotFileError, match=r"unknown package 'no_such_pkg'") as info:
        reachwise.load_robot(path, tip="j2s6s200_end_effector")
    assert str(path) in str(info.value) and unknown in str(info.value)

    pkg = tmp_path / "my_arm"
    (pkg / "meshes").mkdir(parents=True)
    (pkg / "package.xml").write_text("<package><name>my_arm</name></package>")
    shutil.copy(package_file(mesh), pkg / "meshes" / "base.dae")
    broken = pkg / "meshes" / "base.dae"
    broken.write_text(broken.read_text()[:5000])  # a truncated COLLADA document
    path = _copy_with(tmp_path, "kinova", mesh, "package://my_arm/meshes/base.dae")
    robot = reachwise.load_robot(path, tip="j2s6s200_end_effector", package_dirs=[tmp_path])
    with pytest.raises(RobotFileError) as info:
        reachwise.link_clouds(robot)
    msg = str(info.value)
    assert str(path) in msg and "package://my_arm/meshes/base.dae" in msg
    assert "link 'j2s6s200_link_base'" in msg  # the URDF link the shape belongs to


def test_a_branched_urdf_needs_a_tip_and_yaml_takes_none(tmp_path: Path) -> None:
    with pytest.raises(RobotFileError, match=r"branches into joints .*--tip LINK"):
        reachwise.load_robot(arm_path("panda"))
    yaml_robot = tmp_path / "r.yaml"
    yaml_robot.write_text("name: r\njoints:\n  - {type: revolute}\n")
    with pytest.raises(RobotFileError, match="tip selects the chain of a URDF"):
        reachwise.load_robot(yaml_robot, tip="x")


def test_lenient_leaves_out_a_missing_mesh_and_logs_it(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    mesh = "package://example-robot-data/robots/panda_description/meshes/collision/link3.stl"
    gone = "package://example-robot-data/robots/panda_description/meshes/collision/gone.stl"
    path = _copy_with(tmp_path, "panda", mesh, gone)
    with pytest.raises(ReachwiseError, match=r"gone\.stl"):
        reachwise.load_robot(path, tip="panda_hand")
    with caplog.at_level("WARNING", logger="reachwise.io.urdf"):
        robot = reachwise.load_robot(path, tip="panda_hand", lenient=True)
    assert "link_3" not in robot.geometry  # its only collision shape is gone
    assert any(
        "gone.stl" in r.getMessage() and "left out" in r.getMessage() for r in caplog.records
    )


def test_visual_only_links_lend_their_visuals_and_say_so(caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level("WARNING", logger="reachwise.io.urdf"):
        robot = reachwise.load_robot(arm_path("z1"), tip="gripperStator")
    said = [r.getMessage() for r in caplog.records if "has no <collision>" in r.getMessage()]
    assert len(said) == 2 and any("'link01'" in m for m in said)  # link01 and link05
    assert all(robot.visual.get(k) for k in robot.geometry)
    assert math.isfinite(float(robot.vmax.max()))


RESOLUTION = 0.01
#: The round shapes' surface meshes lie within r (1 - cos(π/64)) of the true surface.
_FACETS = 1.0 - math.cos(math.pi / 64)


def _coverage_gaps(arm: str, clouds_of: Any) -> dict[str, float]:
    """The largest distance (m) from a point sampled densely on each true shape (yourdfpy
    places them; round ones finely tessellated) to its own link's cloud, less the facet
    error our round-shape meshes may have."""
    if arm == "baxter":
        path = arm_path("panda").parents[2] / "baxter_description/urdf/baxter.urdf"
        tip = "left_gripper"
    else:
        path, tip = arm_path(arm), ARMS[arm][1]
    robot = reachwise.load_robot(path, tip=tip)
    model = _model(path)
    clouds = clouds_of(robot)
    q = np.zeros(robot.n).clip(robot.lower, robot.upper)
    model.update_cfg(dict(zip(_chain_names(robot), q, strict=True)))
    F = robot.fk_all(q)
    gaps = {}
    for i, (link, kind, g, pose) in enumerate(_truth_shapes(model)):
        if link not in robot.geometry:  # below a joint the chain cannot hold (left out)
            continue
        T = F[robot.link_index(link)]
        world = clouds[link].points @ T[:3, :3].T + T[:3, 3]
        mesh = _surface(kind, g, pose)
        n = int(min(200_000, max(5_000, mesh.area / RESOLUTION**2 * 20)))
        gap = cKDTree(world).query(np.asarray(mesh.sample(n, seed=11)))[0].max()
        slack = _FACETS * (g.radius if kind in ("cylinder", "sphere") else 0.0)
        gaps[f"{link} {kind} #{i}"] = float(gap - slack)
    assert len(gaps) == sum(len(v) for v in robot.geometry.values())
    return gaps


@pytest.mark.parametrize("arm", [*ARMS, "baxter"])
def test_clouds_with_a_resolution_cover_every_true_shape(arm: str) -> None:
    """Every point of every collision shape lies within the resolution of its own
    link's cloud."""
    gaps = _coverage_gaps(arm, lambda r: reachwise.link_clouds(r, resolution=RESOLUTION))
    worst = max(gaps, key=gaps.__getitem__)
    assert gaps[worst] <= RESOLUTION + 1e-6, f"{arm} {worst}: {gaps[worst] * 1e3:.2f} mm"


def test_the_coverage_check_sees_a_sparse_cloud() -> None:
    """The judge above on a known violation: Baxter's 1000-point clouds leave gaps."""
    gaps = _coverage_gaps("baxter", lambda r: reachwise.link_clouds(r, points=1000))
    assert max(gaps.values()) > 2 * RESOLUTION
