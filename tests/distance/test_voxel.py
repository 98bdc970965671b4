"""Compiled voxel thinning of handed-over clouds against geometry's voxel_downsample:
the same voxels in the same order, each keeping a point nearest to its voxel's centroid."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from reachwise.distance.voxel import voxel_thin
from reachwise.errors import CloudError
from reachwise.geometry.cloud import PointCloud, voxel_downsample


def _check_against_reference(points: np.ndarray, voxel: float) -> None:
    got = voxel_thin(points, voxel).points
    ref = voxel_downsample(PointCloud(points), voxel).points
    assert got.shape == ref.shape
    cells = np.floor(got / voxel)
    np.testing.assert_array_equal(cells, np.floor(ref / voxel))  # same voxels, same order
    # each kept point is one of its voxel's points nearest to their centroid (the two
    # implementations may round a tie between equidistant points differently)
    all_cells = np.floor(points / voxel)
    for k in range(len(got)):
        members = points[(all_cells == cells[k]).all(axis=1)]
        assert (members == got[k]).all(axis=1).any()
        c = members.sum(axis=0) / len(members)
        d2 = ((members - c) ** 2).sum(axis=1)
        assert ((got[k] - c) ** 2).sum() <= d2.min() * (1 + 1e-12) + 1e-300
        if not np.array_equal(got[k], ref[k]):
            assert ((ref[k] - c) ** 2).sum() == pytest.approx(((got[k] - c) ** 2).sum())


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 2**32 - 1), st.booleans())
def test_thinning_keeps_the_reference_voxels(seed: int, rounded: bool) -> None:
    rng = np.random.default_rng(seed)
    pts = rng.normal(scale=rng.uniform(0.01, 2.0), size=(int(rng.integers(1, 400)), 3))
    if rounded:  # duplicates and exact ties
        pts = np.round(pts, 1)
    _check_against_reference(pts, float(rng.uniform(0.01, 0.6)))


def test_thinning_without_ties_gives_the_reference_points(rng: np.random.Generator) -> None:
    pts = rng.uniform(-1.0, 1.0, size=(20000, 3))
    got = voxel_thin(pts, 0.2).points  # ~80 points a voxel: no two equidistant
    np.testing.assert_array_equal(got, voxel_downsample(PointCloud(pts), 0.2).points)
    f32 = pts.astype(np.float32)
    np.testing.assert_array_equal(
        voxel_thin(f32, 0.2).points,
        voxel_downsample(PointCloud(f32.astype(np.float64)), 0.2).points,
    )


def test_thinning_keeps_frame_and_name_and_reports_bad_input(rng: np.random.Generator) -> None:
    cloud = PointCloud(rng.normal(size=(100, 3)), frame="camera", name="cam")
    out = voxel_thin(cloud, 0.5)
    assert (out.frame, out.name) == ("camera", "cam")
    spread = np.vstack([rng.uniform(0.0, 1e6, size=(50, 3)), [[0.0, 0.0, 0.0]] * 2])
    np.testing.assert_array_equal(  # 1e36 voxels: too many for 63-bit keys, numpy's path
        voxel_thin(spread, 1e-6).points, voxel_downsample(PointCloud(spread), 1e-6).points
    )
    with pytest.raises(CloudError, match="not finite"):
        voxel_thin(np.array([[0.0, np.nan, 0.0]]), 0.1)
    with pytest.raises(CloudError, match="voxel"):
        voxel_thin(cloud, -1.0)
    with pytest.raises(CloudError, match="voxel"):
        voxel_thin(cloud, True)  # type: ignore[arg-type]
