"""The per-cloud index kept by the distance layer: built once per cloud, a pure function
of the points, gone with its cloud; the PointCloud itself holds nothing but points."""

from __future__ import annotations

import dataclasses
import gc
import threading
import weakref

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from reachwise.distance import PairQuery, Scene, closest_points
from reachwise.distance.index import INDICES, IndexRegistry, build_index, cloud_index
from reachwise.errors import InputError
from reachwise.geometry.cloud import PointCloud
from tests.distance.test_build import check_tree


def clouds(seed: int = 0) -> tuple[PointCloud, PointCloud]:
    rng = np.random.default_rng(seed)
    return PointCloud(rng.normal(size=(300, 3))), PointCloud(rng.normal(size=(200, 3)) + 4.0)


def test_repeated_queries_do_not_rebuild_the_index() -> None:
    a, b = clouds()
    before = INDICES.builds
    first = closest_points(a, b)
    assert INDICES.builds == before + 2  # one per cloud, on first use
    index_a, index_b = cloud_index(a), cloud_index(b)
    for strategy in ("default", "thesis", "brute", "default"):
        res = closest_points(a, b, strategy=strategy)
        assert res.distance == pytest.approx(first.distance, abs=1e-12)
    PairQuery(a, b)(None, None)
    scene = Scene()
    scene.add_object("a", a)
    scene.add_object("b", b)
    scene.watch("a", "b", 10.0)
    scene.query_all()
    assert INDICES.builds == before + 2
    assert cloud_index(a) is index_a and cloud_index(b) is index_b


def test_arrays_are_indexed_anew_on_every_call() -> None:
    # the counter moves when an index is built (so the test above can fail)
    rng = np.random.default_rng(1)
    A, B = rng.normal(size=(50, 3)), rng.normal(size=(40, 3)) + 3.0
    before = INDICES.builds
    closest_points(A, B)
    closest_points(A, B)
    assert INDICES.builds == before + 4


def test_an_index_lives_as_long_as_its_cloud() -> None:
    a, b = clouds(2)
    closest_points(a, b)
    gone = weakref.ref(cloud_index(a))
    del a
    gc.collect()
    assert gone() is None
    assert cloud_index(b) is not None


def test_point_cloud_holds_only_its_points() -> None:
    a, _ = clouds(3)
    closest_points(a, a.points + 1.0)
    # its data and the coverage it guarantees, never the index built for it
    assert [f.name for f in dataclasses.fields(a)] == ["points", "frame", "name", "resolution"]
    with pytest.raises(dataclasses.FrozenInstanceError):
        a.points = np.zeros((1, 3))  # type: ignore[misc]
    with pytest.raises(ValueError, match="read-only"):
        a.points[0, 0] = 1.0


def test_index_contents_against_the_points() -> None:
    a, _ = clouds(4)
    ix = build_index(a.points, leaf_size=4)
    n = len(a)
    assert len(ix) == n
    np.testing.assert_array_equal(np.sort(ix.perm), np.arange(n))
    np.testing.assert_array_equal(ix.points, a.points[ix.perm])
    np.testing.assert_array_equal(ix.inverse[ix.perm], np.arange(n))
    np.testing.assert_array_equal(ix.centroid, a.points.mean(axis=0))
    np.testing.assert_array_equal(ix.aabb.lo, a.points.min(axis=0))
    np.testing.assert_array_equal(ix.aabb.hi, a.points.max(axis=0))
    # the tree's layout itself is checked node by node in test_build.py
    with pytest.raises(InputError, match="leaf_size"):
        build_index(a.points, leaf_size=0)


def test_an_index_built_on_another_thread_is_installed_and_used() -> None:
    # the seam for non-blocking cloud replacement: build off the querying thread
    # (a pure function of the points), hand the finished index over
    a, b = clouds(5)
    built: list = []
    worker = threading.Thread(target=lambda: built.append(build_index(a.points, version=3)))
    worker.start()
    worker.join()
    here = build_index(a.points)
    for f in ("points", "perm", "inverse", "boxes", "info", "centroid"):
        np.testing.assert_array_equal(getattr(built[0], f), getattr(here, f))
    assert built[0].version == 3 and here.version == 0
    registry = IndexRegistry()
    registry.put(a, built[0])
    assert registry.get(a) is built[0] and registry.builds == 0
    INDICES.put(a, built[0])
    before = INDICES.builds
    res = closest_points(a, b)
    assert INDICES.builds == before + 1  # b only
    ref = closest_points(a.points, b.points, strategy="brute")
    assert res.distance == pytest.approx(ref.distance, abs=1e-12)
    with pytest.raises(InputError, match="index"):
        registry.put(b, built[0])


def test_a_lookup_never_returns_another_clouds_index() -> None:
    """Entries are keyed by identity: an entry under a cloud's id whose reference gives
    back another cloud (an id reused before the entry was dropped) is not its index,
    and a freed cloud's entry goes with it."""
    from reachwise.distance.index import IndexRegistry

    reg = IndexRegistry()
    a, b = clouds(2)
    index_a = reg.get(a)
    reg._entries[id(b)] = reg._entries[id(a)]  # b's id now points at a's entry
    index_b = reg.get(b)
    assert index_b is not index_a and len(index_b) == len(b)
    np.testing.assert_allclose(index_b.centroid, b.points.mean(axis=0))
    assert reg.builds == 2
    del a, index_a
    gc.collect()
    assert list(reg._entries) == [id(b)]


def _interleave(u: int, v: int) -> int:
    """The Morton code of grid cell (u, v), bit by bit (u's bits in the even places)."""
    return sum(((u >> b) & 1) << (2 * b) | ((v >> b) & 1) << (2 * b + 1) for b in range(20))


@settings(max_examples=40, deadline=None)
@given(
    h=st.integers(1, 13),
    w=st.integers(1, 17),
    leaf_size=st.integers(1, 9),
    seed=st.integers(0, 2**32 - 1),
)
def test_an_index_over_a_grid_order_is_a_valid_tree_and_exact(
    h: int, w: int, leaf_size: int, seed: int
) -> None:
    """Points of a height field sampled on a grid, some cells missing, taken in the
    grid's Z-order: the index built over that order without sorting has the layout
    every query relies on, and distances on it equal brute force."""
    from scipy.spatial.distance import cdist

    from reachwise.distance.index import index_of_ordered

    rng = np.random.default_rng(seed)
    cells = sorted((_interleave(u, v), u, v) for v in range(h) for u in range(w))
    keep = [c for c in cells if rng.random() > 0.3] or cells[:1]
    codes = np.array([c for c, _, _ in keep], dtype=np.int64)
    uv = np.array([(u, v) for _, u, v in keep], dtype=np.float64)
    pts = np.column_stack([0.1 * uv, rng.uniform(0.5, 3.0, len(keep))])
    # far outliers: a box over a range of pixels may be deep; the tree stays exact
    pts[rng.random(len(keep)) < 0.1, 2] += 50.0
    given_pts = pts.copy()
    ix = index_of_ordered(pts, codes, pts.mean(axis=0), version=4, leaf_size=leaf_size)
    check_tree(given_pts, (ix.points, ix.perm, ix.boxes, ix.info), leaf_size)
    np.testing.assert_array_equal(ix.perm, np.arange(len(keep)))  # kept in the given order
    assert ix.version == 4 and len(ix) == len(keep)
    np.testing.assert_array_equal(ix.aabb.lo, given_pts.min(axis=0))
    cloud = PointCloud(given_pts)
    INDICES.put(cloud, ix)
    for _ in range(3):
        other = rng.normal(scale=0.5, size=(40, 3)) + rng.uniform(-1.0, 3.0, 3)
        res = closest_points(PointCloud(other), cloud)
        assert res.distance == pytest.approx(cdist(other, given_pts).min(), abs=1e-12)


def test_an_ordered_index_needs_one_code_per_point() -> None:
    from reachwise.distance.index import index_of_ordered

    pts = np.zeros((3, 3))
    with pytest.raises(InputError, match="codes"):
        index_of_ordered(pts, np.arange(2, dtype=np.int64), pts[0])
