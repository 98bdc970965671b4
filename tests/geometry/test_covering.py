"""A greedy cover keeps points so that every point lies within the radius of a kept
one and no two kept ones lie within it of each other (brute-force distances)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.distance import cdist

from reachwise.errors import InputError
from reachwise.geometry.covering import greedy_cover


@settings(max_examples=40, deadline=None)
@given(
    n=st.integers(1, 400),
    radius=st.floats(0.01, 0.6),
    seed=st.integers(0, 2**31),
    scale=st.sampled_from([1e-3, 1.0, 50.0]),
)
def test_every_point_is_covered_and_kept_points_are_apart(
    n: int, radius: float, seed: int, scale: float
) -> None:
    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(n, 3)) * scale - 3.0 * scale
    r = radius * scale
    kept = greedy_cover(pts, r, seed=seed)
    assert np.all(np.diff(kept) > 0) and 1 <= len(kept) <= n
    d = cdist(pts, pts[kept])
    assert d.min(axis=1).max() <= r * (1 + 1e-12)  # covered
    apart = cdist(pts[kept], pts[kept]) + np.eye(len(kept)) * 2 * r
    assert apart.min() > r  # maximal packing: no kept point covers another


def test_a_fine_grid_keeps_about_one_point_per_radius_squared() -> None:
    g = np.linspace(0.0, 1.0, 201)
    x, y = np.meshgrid(g, g)
    pts = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    kept = greedy_cover(pts, 0.05)
    # discs of radius r/2 around kept points do not overlap: at most area / (pi r^2 / 4)
    assert 100 < len(kept) < (1.05**2) / (np.pi * 0.025**2)
    assert len(greedy_cover(pts, 0.0)) == len(pts)


def test_bad_input_is_a_typed_error() -> None:
    with pytest.raises(InputError, match="radius"):
        greedy_cover(np.zeros((3, 3)), -1.0)
    with pytest.raises(InputError, match="points"):
        greedy_cover(np.full((3, 3), np.nan), 1.0)
