"""PointCloud operations against independent truth (plain-Python loops, analytic shapes)."""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from reachwise.errors import CloudError
from reachwise.geometry.cloud import (
    PointCloud,
    crop,
    crop_mask,
    merge,
    sample_mesh_surface,
    voxel_downsample,
    voxel_keys,
)

coords = st.floats(-20.0, 20.0, allow_nan=False, allow_infinity=False, width=64)
clouds = st.integers(1, 120).flatmap(lambda n: arrays(np.float64, (n, 3), elements=coords))
voxels = st.floats(0.01, 5.0, allow_nan=False, allow_infinity=False)


def python_voxels(points: np.ndarray, voxel: float) -> dict[tuple[int, int, int], list[int]]:
    """Group point indices by voxel with a plain loop (the reference)."""
    groups: dict[tuple[int, int, int], list[int]] = defaultdict(list)
    for i, p in enumerate(points):
        key = (math.floor(p[0] / voxel), math.floor(p[1] / voxel), math.floor(p[2] / voxel))
        groups[key].append(i)
    return groups


# ---------------------------------------------------------------------- PointCloud core


def test_pointcloud_rejects_non_finite_with_count() -> None:
    pts = np.zeros((5, 3))
    pts[1, 0] = np.nan
    pts[3, 2] = np.inf
    with pytest.raises(CloudError, match=r"scanA: points: 2 of 5 points are not finite"):
        PointCloud(pts, name="scanA")


@pytest.mark.parametrize(
    ("data", "reason"),
    [
        (np.zeros((0, 3)), "empty"),
        (np.zeros((4, 2)), r"shape \(N, 3\)"),
        ([["a", 1, 2]], "numeric"),
    ],
)
def test_pointcloud_rejects_bad_arrays(data: object, reason: str) -> None:
    with pytest.raises(CloudError, match=reason):
        PointCloud(data)  # type: ignore[arg-type]


# ------------------------------------------------------------------------ voxel downsample


@settings(max_examples=150, deadline=None)
@given(clouds, voxels)
def test_voxel_downsample_one_point_per_occupied_voxel(pts: np.ndarray, voxel: float) -> None:
    out = voxel_downsample(pts, voxel).points
    groups = python_voxels(pts, voxel)
    # count matches the reference grouping and numpy's unique on the voxel keys
    assert len(out) == len(groups)
    assert len(out) == len(np.unique(np.floor(pts / voxel), axis=0))
    out_keys = [tuple(int(k) for k in np.floor(p / voxel)) for p in out]
    assert len(set(out_keys)) == len(out_keys)  # one per voxel
    assert set(out_keys) == set(groups)  # every occupied voxel, no other
    for p, key in zip(out, out_keys, strict=True):
        members = pts[groups[key]]
        # the kept point is one of the inputs of its voxel ...
        assert (members == p).all(axis=1).any()
        # ... and (to rounding) the one nearest the centroid of that voxel's inputs
        centroid = members.mean(axis=0)
        d = np.linalg.norm(members - centroid, axis=1)
        assert np.linalg.norm(p - centroid) <= d.min() + 1e-9 * max(1.0, d.max())
        # so it lies inside the voxel it represents
        lo = np.array(key) * voxel
        assert (p >= lo - 1e-12).all() and (p < lo + voxel + 1e-12).all()


@settings(max_examples=80, deadline=None)
@given(clouds, voxels, st.randoms(use_true_random=False))
def test_voxel_downsample_ignores_input_order(pts: np.ndarray, voxel: float, rnd) -> None:
    perm = list(range(len(pts)))
    rnd.shuffle(perm)
    a = voxel_downsample(pts, voxel).points
    b = voxel_downsample(pts[perm], voxel).points
    np.testing.assert_array_equal(a, b)


@settings(max_examples=60, deadline=None)
@given(clouds, voxels)
def test_voxel_downsample_is_idempotent(pts: np.ndarray, voxel: float) -> None:
    once = voxel_downsample(pts, voxel)
    np.testing.assert_array_equal(voxel_downsample(once, voxel).points, once.points)


def test_voxel_downsample_two_points_tie_is_smallest_coordinates() -> None:
    pts = np.array([[0.02, 0.01, 0.01], [0.01, 0.01, 0.01], [0.5, 0.5, 0.5]])
    out = voxel_downsample(PointCloud(pts, frame="link_3", name="part"), 0.03)
    np.testing.assert_array_equal(out.points, [[0.01, 0.01, 0.01], [0.5, 0.5, 0.5]])
    assert out.frame == "link_3" and out.name == "part"


def test_voxel_origin_shifts_the_grid() -> None:
    # a floor exactly on z = 0 with rounding noise either side: anchored at the frame
    # origin it splits into two layers; anchored 1 cm lower it stays one layer.
    rng = np.random.default_rng(1)
    xy = rng.uniform(0, 0.3, (400, 2))
    z = rng.choice([-1e-16, 0.0, 1e-16], 400)
    pts = np.column_stack([xy, z])
    split = len(voxel_downsample(pts, 0.03))
    one = len(voxel_downsample(pts, 0.03, origin=(0.0, 0.0, -0.01)))
    assert one == len(np.unique(np.floor(xy / 0.03), axis=0))
    assert split > one
    assert (voxel_keys(pts, 0.03, origin=(0, 0, -0.01))[:, 2] == 0).all()


@pytest.mark.parametrize("voxel", [0.0, -0.03, float("nan"), float("inf"), "3cm", True])
def test_voxel_downsample_rejects_bad_voxel(voxel: object) -> None:
    with pytest.raises(CloudError, match="voxel"):
        voxel_downsample(np.zeros((3, 3)), voxel)  # type: ignore[arg-type]


def test_voxel_too_small_for_coordinates() -> None:
    with pytest.raises(CloudError, match="too small"):
        voxel_downsample(np.array([[1e6, 0.0, 0.0]]), 1e-300)


# ------------------------------------------------------------------------------- crop

box_corners = st.tuples(coords, coords, coords)


@settings(max_examples=100, deadline=None)
@given(clouds, box_corners, box_corners)
def test_crop_keeps_exactly_the_points_inside(pts: np.ndarray, a: tuple, b: tuple) -> None:
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    inside = [
        i for i, p in enumerate(pts) if all(lo[k] <= p[k] <= hi[k] for k in range(3))
    ]  # reference
    np.testing.assert_array_equal(np.flatnonzero(crop_mask(pts, lo, hi)), inside)
    if inside:
        np.testing.assert_array_equal(crop(pts, lo, hi).points, pts[inside])
    else:
        with pytest.raises(CloudError, match="crop box: no point of"):
            crop(pts, lo, hi)


def test_crop_bounds_are_inclusive_and_keep_frame() -> None:
    cloud = PointCloud([[0, 0, 0], [1, 1, 1], [1.0000001, 0, 0]], frame="base", name="c")
    out = crop(cloud, (0, 0, 0), (1, 1, 1))
    assert len(out) == 2 and out.frame == "base" and out.name == "c"


@pytest.mark.parametrize(
    ("lo", "hi", "match"),
    [
        ((1, 0, 0), (0, 1, 1), "crop box: min"),
        ((0, 0), (1, 1, 1), "crop min: expected 3 coordinates"),
        ((0, 0, 0), (1, np.nan, 1), "crop max: coordinates must be finite"),
        ((0, "a", 0), (1, 1, 1), "crop min: not numeric"),
    ],
)
def test_crop_rejects_bad_boxes(lo: object, hi: object, match: str) -> None:
    with pytest.raises(CloudError, match=match):
        crop(PointCloud(np.zeros((2, 3)), name="scan"), lo, hi)  # type: ignore[arg-type]


# ------------------------------------------------------------------------------ merge


def test_merge_concatenates_in_order() -> None:
    a = PointCloud(np.zeros((2, 3)), frame="world")
    b = PointCloud(np.ones((3, 3)), frame="world")
    m = merge([a, b, [[2.0, 2.0, 2.0]]], name="both")
    assert m.frame == "world" and m.name == "both"
    np.testing.assert_array_equal(m.points, np.vstack([a.points, b.points, [[2, 2, 2]]]))


def test_merge_refuses_mixed_frames_and_empty() -> None:
    a = PointCloud(np.zeros((1, 3)), frame="world")
    b = PointCloud(np.zeros((1, 3)), frame="link_2")
    with pytest.raises(CloudError, match=r"frame: clouds are in different frames"):
        merge([a, b])
    with pytest.raises(CloudError, match="frame"):
        merge([a], frame="link_2")
    with pytest.raises(CloudError, match="non-empty sequence"):
        merge([])
    assert merge([np.zeros((1, 3))], frame="link_2").frame == "link_2"


# ---------------------------------------------------------------------- mesh sampling


def _box_surface_distance(p: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Distance of points inside/on an origin-centred box to its surface (analytic)."""
    return np.min(half - np.abs(p), axis=1)


def test_samples_lie_on_the_box_surface_and_are_reproducible() -> None:
    extents = np.array([0.4, 1.0, 2.0])
    box = trimesh.creation.box(extents=extents)
    a = sample_mesh_surface(box, n=1000, seed=7, frame="link_3", name="boom")
    assert len(a) == 1000 and a.frame == "link_3" and a.name == "boom"
    assert np.all(np.abs(a.points) <= extents / 2 + 1e-12)
    assert np.abs(_box_surface_distance(a.points, extents / 2)).max() < 1e-12
    b = sample_mesh_surface(box.vertices, box.faces, n=1000, seed=7)
    np.testing.assert_array_equal(a.points, b.points)
    c = sample_mesh_surface(box, n=1000, seed=np.random.default_rng(7))
    np.testing.assert_array_equal(a.points, c.points)
    assert not np.array_equal(a.points, sample_mesh_surface(box, n=1000, seed=8).points)


def test_sampling_is_area_weighted() -> None:
    # two disjoint triangles in z = 0 and z = 1 with areas 1 and 3
    v = np.array([[0, 0, 0], [2, 0, 0], [0, 1, 0], [0, 0, 1], [6, 0, 1], [0, 1, 1]], dtype=float)
    f = np.array([[0, 1, 2], [3, 4, 5]])
    n = 40_000
    pts = sample_mesh_surface(v, f, n=n, seed=3).points
    share = float(np.mean(pts[:, 2] > 0.5))
    sigma = math.sqrt(0.75 * 0.25 / n)
    assert abs(share - 0.75) < 5 * sigma
    # uniform inside a triangle: the mean of the samples is the centroid
    low = pts[pts[:, 2] < 0.5]
    np.testing.assert_allclose(low.mean(axis=0), v[:3].mean(axis=0), atol=0.02)


@pytest.mark.parametrize(
    ("vertices", "faces", "n", "match"),
    [
        (np.zeros((3, 3)), [[0, 1, 2]], 10, "zero surface area"),
        (np.eye(3), [[0, 1, 3]], 10, r"faces: vertex indices must lie in \[0, 2\]"),
        (np.eye(3), [[0.0, 1.0, 2.0]], 10, "faces: expected integer"),
        (np.eye(3), np.zeros((0, 3), int), 10, r"faces: expected shape \(F, 3\)"),
        (np.array([[0, 0, 0], [1, 0, np.nan], [0, 1, 0]]), [[0, 1, 2]], 10, "1 of 3 vertices"),
        (np.eye(3), [[0, 1, 2]], 0, "n: must be >= 1"),
        (np.eye(3), [[0, 1, 2]], 2.5, "n: expected a whole number"),
        (np.eye(3), None, 10, "faces: required"),
    ],
)
def test_sampling_rejects_bad_meshes(vertices, faces, n, match) -> None:
    with pytest.raises(CloudError, match=match):
        sample_mesh_surface(vertices, faces, n=n, name="part.stl")


def test_sampling_rejects_bad_seed() -> None:
    with pytest.raises(CloudError, match="seed"):
        sample_mesh_surface(np.eye(3), [[0, 1, 2]], n=5, seed=1.5)  # type: ignore[arg-type]
