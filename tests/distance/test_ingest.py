"""Clouds handed over without blocking: indexed on the scene's worker thread, swapped in
between two queries, and every answer exact on the cloud version it reports."""

from __future__ import annotations

import math
import threading

import numpy as np
import pytest
from scipy.spatial import cKDTree

from reachwise.distance import Scene
from reachwise.distance.ingest import CloudIngest
from reachwise.errors import CloudError, ReachwiseError

WAIT = 60.0  # s: a generous bound on any wait, so a dead worker fails instead of hanging


def _brute(a: np.ndarray, b: np.ndarray) -> float:
    return float(cKDTree(b).query(a)[0].min())


def _camera_scene(rng: np.random.Generator) -> tuple[Scene, np.ndarray]:
    scene = Scene()
    part = rng.normal(scale=0.1, size=(300, 3))
    scene.add_object("part", part)
    scene.add_object("camera", rng.normal(size=(500, 3)) + np.array([2.0, 0.0, 0.0]))
    scene.watch("part", "camera", math.inf, kind="robot-environment")
    return scene, part


def test_a_handed_over_cloud_is_used_from_the_first_query_after_its_build(
    rng: np.random.Generator,
) -> None:
    scene, part = _camera_scene(rng)
    frame = rng.normal(scale=0.2, size=(4000, 3)) + np.array([0.6, 0.0, 0.0])
    before = scene.query_all()
    version = scene.replace_cloud("camera", frame, stamp=12.5)
    assert version == 1
    assert before.versions["camera"] == 0 and before.pairs[0].versions == (0, 0)
    assert before.cloud_stamps["camera"] == math.inf  # added without a stamp: no age
    assert scene.ingest.wait("camera", 1, timeout=WAIT)
    after = scene.query_all()
    assert after.versions["camera"] == 1 and after.pairs[0].versions == (0, 1)
    assert after.cloud_stamps["camera"] == 12.5
    assert after.pairs[0].result.distance == pytest.approx(_brute(part, frame), abs=1e-12)
    # the earlier answer keeps the versions it was computed with
    assert before.versions["camera"] == 0
    scene.close()


def test_a_newer_hand_over_supersedes_a_waiting_one(rng: np.random.Generator) -> None:
    ingest = CloudIngest()
    # occupy the worker with a first build, then queue two more for one object
    big = rng.normal(size=(200_000, 3))
    ingest.submit("scan", 1, big, 0.0)
    ingest.submit("scan", 2, rng.normal(size=(100, 3)), 1.0)
    ingest.submit("scan", 3, rng.normal(size=(100, 3)), 2.0)
    assert ingest.wait("scan", 3, timeout=WAIT)
    ready = ingest.take_ready()
    assert [r.version for r in ready] == [3]
    # version 2 either waited behind 1 and was dropped unbuilt, or 1 had not started
    assert ingest.superseded >= 1
    assert ingest.builds + ingest.superseded == 3
    ingest.close()


def test_bad_points_never_replace_the_cloud(rng: np.random.Generator) -> None:
    scene, _ = _camera_scene(rng)
    bad = rng.normal(size=(100, 3))
    bad[7, 1] = np.nan
    v = scene.replace_cloud("camera", bad)
    assert scene.ingest.wait("camera", v, timeout=WAIT)
    res = scene.query_all()
    assert res.versions["camera"] == 0
    failed_version, error = scene.ingest.errors()["camera"]
    assert failed_version == v and isinstance(error, CloudError)
    assert "not finite" in str(error)
    with pytest.raises(CloudError, match="not finite"):
        scene.replace_cloud("camera", bad, block=True)
    assert scene.query_all().versions["camera"] == 0
    scene.close()


def test_block_true_swaps_before_returning(rng: np.random.Generator) -> None:
    scene, part = _camera_scene(rng)
    frame = rng.normal(size=(800, 3)) + np.array([1.0, 0.0, 0.0])
    assert scene.replace_cloud("camera", frame, block=True, stamp=3.0) == 1
    res = scene.query_all()
    assert res.pairs[0].versions == (0, 1) and res.cloud_stamps["camera"] == 3.0
    assert res.pairs[0].result.distance == pytest.approx(_brute(part, frame), abs=1e-12)
    scene.close()


def test_answers_equal_brute_force_on_their_version_while_frames_stream_in(
    rng: np.random.Generator,
) -> None:
    """A producer thread hands over 40 frames as fast as it can while this thread
    queries: each answer is exact on the frame whose version it reports, and the
    versions never go back."""
    scene, part = _camera_scene(rng)
    frames = {0: scene.objects["camera"].cloud.points}
    for k in range(1, 41):
        frames[k] = rng.normal(scale=0.3, size=(3000, 3)) + np.array([rng.uniform(0.5, 2.0), 0, 0])

    def produce() -> None:
        for k in range(1, 41):
            assert scene.replace_cloud("camera", frames[k]) == k

    producer = threading.Thread(target=produce)
    producer.start()
    seen = []
    while True:
        res = scene.query_all()
        v = res.pairs[0].versions[1]
        seen.append(v)
        assert res.pairs[0].result.distance == pytest.approx(_brute(part, frames[v]), abs=1e-12)
        if v == 40:
            break
        if not producer.is_alive():
            assert scene.ingest.wait("camera", 40, timeout=WAIT)
    producer.join(WAIT)
    assert seen == sorted(seen)
    scene.close()


def test_close_stops_the_worker(rng: np.random.Generator) -> None:
    scene, _ = _camera_scene(rng)
    scene.replace_cloud("camera", rng.normal(size=(100, 3)))
    assert scene.ingest.running
    scene.close()
    assert not scene.ingest.running
    with pytest.raises(ReachwiseError, match="closed"):
        scene.replace_cloud("camera", rng.normal(size=(100, 3)))
