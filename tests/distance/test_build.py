"""The tree build (linear BVH in Morton order; a k-d tree for small clouds): the layout
every query kernel relies on, checked node by node for both split rules, and exact
queries on clouds that stress the build."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from reachwise.distance._build import (
    MEDIAN_UP_TO,
    build_tree,
    build_tree_as,
    morton_order,
    summary,
)
from reachwise.distance._morton import _sorted_lsd, _sorted_msd


def check_layout(points: np.ndarray, leaf_size: int, median: bool | None = None) -> None:
    """Every property of the tree layout, against the input points (``median``: that
    split rule; None: the one ``build_tree`` picks for the cloud's size)."""
    pts = np.ascontiguousarray(points, dtype=np.float64)
    if median is None:
        tree = build_tree(pts, leaf_size)
    else:
        tree = build_tree_as(pts, summary(pts)[1], leaf_size, median)
    check_tree(points, tree, leaf_size)


def check_tree(points: np.ndarray, tree: tuple, leaf_size: int) -> None:
    """Every property of the tree layout ``(tree points, perm, boxes, info)`` against
    the input ``points``."""
    tp, perm, boxes, info = tree
    n = points.shape[0]
    assert sorted(perm.tolist()) == list(range(n))
    np.testing.assert_array_equal(tp, points[perm])
    assert info[0, 0] == 0 and info[0, 1] == n
    seen = np.zeros(n, int)
    for k in range(info.shape[0]):
        s, e, r = info[k]
        assert 0 <= s < e <= n
        np.testing.assert_array_equal(boxes[k, :3], tp[s:e].min(axis=0))
        np.testing.assert_array_equal(boxes[k, 3:], tp[s:e].max(axis=0))
        if r < 0:
            assert e - s <= leaf_size
            seen[s:e] += 1
        else:
            left = k + 1
            assert left < r < info.shape[0]
            # the children split the parent's range in two, left first
            assert info[left, 0] == s and info[left, 1] == info[r, 0] and info[r, 1] == e
    assert (seen == 1).all()  # the leaves partition the points


coords = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)


@settings(max_examples=60, deadline=None)
@given(
    arrays(np.float64, st.tuples(st.integers(1, 300), st.just(3)), elements=coords),
    st.integers(1, 16),
    st.booleans(),
)
def test_layout_on_random_clouds(points: np.ndarray, leaf_size: int, median: bool) -> None:
    check_layout(points, leaf_size, median)


def test_layout_on_clouds_that_share_cells() -> None:
    rng = np.random.default_rng(3)
    dense = rng.normal(scale=1e-3, size=(2000, 3))
    outliers = np.array([[1e4, 0, 0], [-1e4, 5e3, 0]])  # coarse cells: one holds all
    duplicates = np.repeat(rng.normal(size=(5, 3)), 200, axis=0)
    line = np.c_[np.linspace(0, 1, 1000), np.zeros(1000), np.zeros(1000)]
    for cloud in (np.vstack([dense, outliers]), duplicates, line, np.zeros((50, 3))):
        for median in (False, True):
            check_layout(cloud, 8, median)


def test_small_clouds_get_median_splits_and_large_ones_morton_cells() -> None:
    """At and below MEDIAN_UP_TO points every split is at the median (the halves differ
    by at most one point); above it the Morton rule's splits follow the octree cells."""
    rng = np.random.default_rng(4)
    for n, median in ((MEDIAN_UP_TO, True), (MEDIAN_UP_TO + 1, False)):
        pts = rng.uniform(size=(n, 3)) ** 3  # skewed: cell splits are uneven
        _, perm, _, info = build_tree(pts, 8)
        ref = build_tree_as(pts, summary(pts)[1], 8, median)
        np.testing.assert_array_equal(perm, ref[1])
        inner = info[info[:, 2] >= 0]
        sizes = inner[:, 1] - inner[:, 0]
        # the left child holds info[right, 0] - start points: half of the range
        balanced = np.abs(2 * (info[inner[:, 2], 0] - inner[:, 0]) - sizes) <= 1
        assert balanced.all() == median


def test_morton_order_sorts_by_interleaved_cell_bits() -> None:
    rng = np.random.default_rng(4)
    pts = rng.uniform(0, 1, size=(500, 3))
    order, codes = morton_order(pts)
    assert (np.diff(codes) >= 0).all()
    # independent Morton codes: interleave the 10-bit cell coordinates bit by bit
    lo = pts.min(axis=0)
    span = (pts.max(axis=0) - lo).max()
    cell = ((pts - lo) * ((1 << 10) - 1e-3) / span).astype(np.int64)
    ref = np.zeros(len(pts), np.int64)
    for bit in range(10):
        for axis, shift in ((0, 2), (1, 1), (2, 0)):
            ref |= ((cell[:, axis] >> bit) & 1) << (3 * bit + shift)
    np.testing.assert_array_equal(codes, ref[order])
    assert sorted(order.tolist()) == list(range(500))


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(0, 3))
def test_both_sorts_give_the_same_order(seed: int, kind: int) -> None:
    """The LSD sort (camera frames) and the top-down sort (a million points and more)
    order the rows identically: by Morton code, then by row."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 6000))
    pts = rng.normal(size=(n, 3)) * rng.uniform(1e-3, 10.0)
    if kind == 1:  # ties in every cell
        pts = np.round(pts, 1)
    elif kind == 2:  # a few points repeated: one cell holds all
        pts = np.repeat(pts[:3], n // 3 + 1, axis=0)[:n]
    elif kind == 3:  # a raster-ordered sheet, as a camera gives it
        u, v = np.meshgrid(np.linspace(0, 1, 80), np.linspace(0, 1, 60))
        pts = np.column_stack([u.ravel(), v.ravel(), 0.1 * np.sin(5 * u.ravel())])
    _, bounds, _ = summary(pts)
    lsd = _sorted_lsd(pts, bounds)
    msd = _sorted_msd(pts, bounds)
    for a, b in zip(lsd, msd, strict=True):
        np.testing.assert_array_equal(a, b)
    order, codes = morton_order(pts)
    np.testing.assert_array_equal(lsd[1], order)
    np.testing.assert_array_equal(lsd[2], codes)
    np.testing.assert_array_equal(lsd[0], pts[order])
