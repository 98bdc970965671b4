"""The realtime bench's baseline ingestion (the path of commit 9be9138): it must still
compile from a cold cache and build the same tree as today's Morton build, which only
changed the sort and the copies around it."""

from __future__ import annotations

import numpy as np

from reachwise.benchmarks._baseline_build import ingest_baseline
from reachwise.distance._build import build_tree_as, summary


def test_the_baseline_builds_todays_morton_tree_and_its_index() -> None:
    rng = np.random.default_rng(11)
    points = rng.normal(size=(5000, 3)) ** 3  # skewed: uneven cells
    cloud, tp, perm, inverse, boxes, info, centroid = ingest_baseline(points)
    ref = build_tree_as(points, summary(points)[1], 8, False)
    for got, want in zip((tp, perm, boxes, info), ref, strict=True):
        np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(inverse[perm], np.arange(points.shape[0]))
    np.testing.assert_allclose(centroid, points.mean(axis=0))
    np.testing.assert_array_equal(cloud.points, points)
