"""The exact mesh distance against analytic boxes, brute force and FCL."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from reachwise.errors import InputError
from reachwise.geometry.mesh_distance import (
    mesh_distance,
    point_triangle_distance,
    segment_distance,
)


def box(size: np.ndarray, centre: np.ndarray, R: np.ndarray | None = None) -> trimesh.Trimesh:
    m = trimesh.creation.box(extents=size)
    T = np.eye(4)
    T[:3, 3] = centre
    if R is not None:
        T[:3, :3] = R
    m.apply_transform(T)
    return m


def test_axis_aligned_boxes_are_as_far_as_their_gaps_say() -> None:
    rng = np.random.default_rng(7)
    for k in range(200):
        sa, sb = rng.uniform(0.05, 1.0, (2, 3))
        ca, cb = rng.uniform(-1.0, 1.0, (2, 3))
        gap = np.maximum(0.0, np.abs(ca - cb) - 0.5 * (sa + sb))
        if not gap.any():
            continue  # overlapping boxes: below
        R = Rotation.random(random_state=k).as_matrix()  # rotating both changes nothing
        expect = float(np.linalg.norm(gap))
        assert mesh_distance(box(sa, ca), box(sb, cb)) == pytest.approx(expect, abs=1e-12)
        got = mesh_distance(box(sa, R @ ca, R), box(sb, R @ cb, R))
        assert got == pytest.approx(expect, abs=1e-12)


def test_crossing_surfaces_are_at_zero_and_nested_ones_at_their_gap() -> None:
    a = box(np.array([1.0, 1.0, 1.0]), np.zeros(3))
    assert mesh_distance(a, box(np.array([0.4, 0.4, 0.4]), np.array([0.5, 0.1, 0.0]))) == 0.0
    # a thin plate through the cube: edges of the plate pierce no face; the cube's do
    assert mesh_distance(a, box(np.array([2.0, 2.0, 0.1]), np.zeros(3))) == 0.0
    # a box inside the cube: the surfaces are apart by the smallest wall gap
    inner = box(np.array([0.2, 0.4, 0.6]), np.array([0.1, 0.0, -0.05]))
    walls = [0.5 - 0.1 - 0.1, 0.5 - 0.2, 0.5 - 0.05 - 0.3]
    assert mesh_distance(a, inner) == pytest.approx(min(walls), abs=1e-12)


def test_poses_place_the_meshes() -> None:
    a = trimesh.creation.icosphere(subdivisions=2, radius=0.3)
    b = box(np.array([0.2, 0.2, 0.2]), np.zeros(3))
    T = np.eye(4)
    T[:3, 3] = [2.0, 0.0, 0.0]
    moved = b.copy()
    moved.apply_transform(T)
    assert mesh_distance(a, b, None, T) == pytest.approx(mesh_distance(a, moved), abs=1e-12)
    assert mesh_distance((a.vertices, a.faces), moved) == pytest.approx(
        mesh_distance(a, moved), abs=1e-15
    )


def test_point_triangle_and_segment_distances_match_dense_sampling() -> None:
    rng = np.random.default_rng(3)
    p, a, b, c = rng.normal(size=(4, 60, 3))
    d = point_triangle_distance(p, a, b, c)
    uv = rng.random((40000, 2))
    flip = uv.sum(axis=1) > 1
    uv[flip] = 1 - uv[flip]
    for i in range(60):
        pts = a[i] + uv[:, :1] * (b[i] - a[i]) + uv[:, 1:] * (c[i] - a[i])
        sampled = np.linalg.norm(pts - p[i], axis=1).min()
        assert d[i] <= sampled + 1e-12  # exact is never above a sampled point
        assert sampled - d[i] < 0.03  # and the samples come close to it
    p1, q1, p2, q2 = rng.normal(size=(4, 60, 3))
    q1[0] = p1[0]  # a degenerate segment (a point) on either side
    q2[1] = p2[1]
    d = segment_distance(p1, q1, p2, q2)
    s = np.linspace(0.0, 1.0, 1001)
    for i in range(60):
        u = p1[i] + s[:, None] * (q1[i] - p1[i])
        v = p2[i] + s[:, None] * (q2[i] - p2[i])
        sampled = np.linalg.norm(u[:, None] - v[None], axis=2).min()
        assert d[i] <= sampled + 1e-12
        assert sampled - d[i] < 5e-3


def test_parallel_segments() -> None:
    d = segment_distance([[0, 0, 0]], [[1, 0, 0]], [[0.5, 0.2, 0]], [[2, 0.2, 0]])
    assert d[0] == pytest.approx(0.2)
    d = segment_distance([[0, 0, 0]], [[1, 0, 0]], [[1.5, 0.2, 0]], [[2, 0.2, 0]])
    assert d[0] == pytest.approx(np.hypot(0.5, 0.2))


def test_agrees_with_fcl_on_random_poses() -> None:
    fcl = pytest.importorskip("fcl")

    def fcl_distance(
        m: trimesh.Trimesh, T1: np.ndarray, n: trimesh.Trimesh, T2: np.ndarray
    ) -> float:
        def obj(mesh: trimesh.Trimesh, T: np.ndarray) -> object:
            bvh = fcl.BVHModel()
            bvh.beginModel(len(mesh.vertices), len(mesh.faces))
            bvh.addSubModel(mesh.vertices, mesh.faces)
            bvh.endModel()
            return fcl.CollisionObject(bvh, fcl.Transform(T[:3, :3], T[:3, 3]))

        req, res = fcl.DistanceRequest(), fcl.DistanceResult()
        return float(fcl.distance(obj(m, T1), obj(n, T2), req, res))

    rng = np.random.default_rng(11)
    capsule = trimesh.creation.capsule(height=1.0, radius=0.2, count=[12, 12])
    plate = box(np.array([0.3, 0.2, 0.05]), np.zeros(3))
    apart = 0
    for k in range(80):
        T1, T2 = np.eye(4), np.eye(4)
        T1[:3, :3] = Rotation.random(random_state=k).as_matrix()
        T2[:3, :3] = Rotation.random(random_state=500 + k).as_matrix()
        T1[:3, 3], T2[:3, 3] = rng.normal(scale=0.4, size=(2, 3))
        ref = fcl_distance(capsule, T1, plate, T2)
        got = mesh_distance(capsule, plate, T1, T2)
        if ref > 0:
            apart += 1
            assert got == pytest.approx(ref, abs=1e-9)
    assert apart > 30


def test_bad_meshes_are_input_errors() -> None:
    with pytest.raises(InputError, match="vertices"):
        mesh_distance((np.zeros((0, 3)), np.zeros((0, 3), int)), trimesh.creation.box())
    with pytest.raises(InputError, match="face indices"):
        mesh_distance((np.zeros((3, 3)), np.array([[0, 1, 5]])), trimesh.creation.box())
    with pytest.raises(InputError, match="pose"):
        mesh_distance(trimesh.creation.box(), trimesh.creation.box(), np.eye(3))
