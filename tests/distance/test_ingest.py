"""Clouds handed over without blocking: indexed on the scene's worker thread, swapped in
between two queries, and every answer exact on the cloud version it reports."""

from __future__ import annotations

import math
import os
import sys
import threading

import numpy as np
import pytest
from scipy.spatial import cKDTree

from reachwise.distance import Scene
from reachwise.distance.index import build_index
from reachwise.distance.ingest import CloudIngest, ready_cloud
from reachwise.distance.voxel import voxel_thin
from reachwise.errors import CloudError, InputError, ReachwiseError
from reachwise.kinematics.robot import Joint, Robot

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


def test_a_dropped_scene_stops_its_worker(rng: np.random.Generator) -> None:
    import gc

    scene, _ = _camera_scene(rng)
    scene.replace_cloud("camera", rng.normal(size=(100, 3)))
    ingest = scene.ingest
    assert ingest.running
    del scene
    gc.collect()  # the scene may sit in a reference cycle
    assert not ingest.running


def _arm() -> Robot:
    joints = (
        Joint("revolute", a=0.0, alpha=0.0, d=0.3, theta=0.0, limits=(-3.0, 3.0)),
        Joint("revolute", a=0.0, alpha=-1.5708, d=0.0, theta=0.0, limits=(-3.0, 3.0)),
        Joint("revolute", a=0.4, alpha=0.0, d=0.0, theta=0.0, limits=(-3.0, 3.0)),
    )
    return Robot("arm", joints)


def _placed(scene: Scene, name: str, version_cloud: np.ndarray) -> np.ndarray:
    P = scene.poses()[name]
    return np.asarray(version_cloud @ P[:3, :3].T + P[:3, 3])


def test_every_pair_is_exact_on_the_versions_it_reports_while_two_clouds_stream(
    rng: np.random.Generator,
) -> None:
    """A robot's three link clouds against a camera cloud and a scan, both replaced from
    producer threads (floats32 frames too) while the arm moves: every pair of every
    answer equals brute force on the clouds of the versions the answer reports."""
    robot = _arm()
    scene = Scene()
    scene.add_robot(robot, np.zeros(robot.n))
    for link in ("link_1", "link_2", "link_3"):
        scene.add_object(link, rng.normal(scale=0.05, size=(200, 3)), robot="arm", link=link)
    frames: dict[str, dict[int, np.ndarray]] = {"camera": {}, "scan": {}}
    for name, offset in (("camera", [0.5, 0.0, 0.3]), ("scan", [-0.4, 0.2, 0.1])):
        first = rng.normal(scale=0.2, size=(1000, 3)) + offset
        scene.add_object(name, first)
        frames[name][0] = first
        for k in range(1, 16):
            f = rng.normal(scale=0.25, size=(int(rng.integers(500, 3000)), 3)) + offset
            frames[name][k] = f.astype(np.float32) if k % 2 else f
    scene.watch_self("arm", math.inf)
    scene.watch_environment("arm", 0.6)
    scene.watch("camera", "scan", math.inf)

    def produce(name: str) -> None:
        for k in range(1, 16):
            assert scene.replace_cloud(name, frames[name][k], stamp=float(k)) == k

    threads = [threading.Thread(target=produce, args=(n,)) for n in frames]
    seen: dict[str, list[int]] = {"camera": [], "scan": []}
    while True:
        scene.set_joints("arm", rng.uniform(-1.5, 1.5, robot.n))
        res = scene.query_all()
        if not seen["camera"]:
            for t in threads:  # after a first answer on the clouds the scene began with
                t.start()
        for name in frames:
            seen[name].append(res.versions[name])
            if res.versions[name]:
                assert res.cloud_stamps[name] == float(res.versions[name])
        for p in res.pairs:
            clouds = []
            for obj, v in zip((p.a, p.b), p.versions, strict=True):
                assert v == res.versions[obj]
                base = frames[obj][v] if obj in frames else scene.objects[obj].cloud.points
                clouds.append(_placed(scene, obj, np.asarray(base, dtype=np.float64)))
            d = float(cKDTree(clouds[1]).query(clouds[0])[0].min())
            if p.result.no_risk:
                assert d > p.margin - 1e-9
            else:
                assert p.result.distance == pytest.approx(d, abs=1e-9)
                np.testing.assert_allclose(p.result.point_a, clouds[0][p.result.index_a])
                np.testing.assert_allclose(p.result.point_b, clouds[1][p.result.index_b])
        if all(seen[n][-1] == 15 for n in frames):
            break
        if not any(t.is_alive() for t in threads):
            for n in frames:
                assert scene.ingest.wait(n, 15, timeout=WAIT)
    for t in threads:
        t.join(WAIT)
    for n in frames:
        assert seen[n][0] == 0 and seen[n] == sorted(seen[n])
    scene.close()


def test_a_query_never_waits_for_a_build_in_progress(rng: np.random.Generator) -> None:
    """The worker is held inside a build: queries go on, on the previous cloud, and the
    scene counts them; released, the next query swaps the new cloud in."""
    scene, part = _camera_scene(rng)
    inside = threading.Event()
    release = threading.Event()

    def held(*args: object) -> object:
        inside.set()
        assert release.wait(WAIT)
        return ready_cloud(*args)  # type: ignore[arg-type]

    scene.ingest.build = held  # type: ignore[assignment]
    frame = rng.normal(size=(2000, 3)) + np.array([0.8, 0.0, 0.0])
    version = scene.replace_cloud("camera", frame, stamp=1.0)
    assert inside.wait(WAIT)
    before = scene.queries_during_build
    answered: list[int] = []

    def query() -> None:
        for _ in range(25):
            answered.append(scene.query_all().versions["camera"])

    loop = threading.Thread(target=query)
    loop.start()
    loop.join(WAIT)
    finished = not loop.is_alive()
    release.set()
    assert finished, "a query waited for the build"
    assert answered == [0] * 25
    assert scene.queries_during_build - before == 25
    assert scene.ingest.wait("camera", version, timeout=WAIT)
    res = scene.query_all()
    assert res.versions["camera"] == version and scene.swaps == 1
    ref = float(cKDTree(frame).query(part)[0].min())
    assert res.pairs[0].result.distance == pytest.approx(ref, abs=1e-12)
    scene.close()


def test_a_query_never_waits_for_the_workers_lock(rng: np.random.Generator) -> None:
    """A built cloud waits while the hand-over lock is held (here by the test): the
    query answers on the previous cloud at once and counts the swap as deferred."""
    scene, _ = _camera_scene(rng)
    version = scene.replace_cloud("camera", rng.normal(size=(500, 3)) + np.array([1.0, 0.0, 0.0]))
    assert scene.ingest.wait("camera", version, timeout=WAIT)
    assert scene.ingest.has_ready
    answered: list[int] = []
    with scene.ingest._cond:  # the worker's lock, held as the worker would hold it
        loop = threading.Thread(
            target=lambda: answered.append(scene.query_all().versions["camera"])
        )
        loop.start()
        loop.join(WAIT)
        finished = not loop.is_alive()
    assert finished, "a query waited for the hand-over lock"
    assert answered == [0] and scene.swaps_deferred == 1 and scene.swaps == 0
    assert scene.query_all().versions["camera"] == version and scene.swaps == 1
    scene.close()


def test_a_frame_is_checked_and_copied_once_and_indexed_like_a_cloud(
    rng: np.random.Generator,
) -> None:
    frame = rng.normal(size=(3000, 6))[:, ::2]  # strided, as a view into a wider buffer
    ready = ready_cloud("cam", 4, frame, 2.0)
    np.testing.assert_array_equal(ready.cloud.points, frame)
    assert not ready.cloud.points.flags.writeable
    ref = build_index(frame)
    for f in ("points", "perm", "boxes", "info", "centroid"):
        np.testing.assert_array_equal(getattr(ready.index, f), getattr(ref, f))
    np.testing.assert_array_equal(ready.index.centroid, frame.mean(axis=0))
    assert ready.index.version == 4 and ready.stamp == 2.0
    f32 = frame.astype(np.float32)
    np.testing.assert_array_equal(ready_cloud("cam", 1, f32, 0.0).cloud.points, f32)
    bad = frame.copy()
    bad[[3, 9], 1] = [np.nan, np.inf]
    with pytest.raises(CloudError, match="2 of 3000 points are not finite"):
        ready_cloud("cam", 1, bad, 0.0)
    with pytest.raises(CloudError, match="empty"):
        ready_cloud("cam", 1, np.zeros((0, 3)), 0.0)
    with pytest.raises(CloudError, match=r"shape \(N, 3\)"):
        ready_cloud("cam", 1, np.zeros((4, 2)), 0.0)
    with pytest.raises(CloudError, match="not numeric"):
        ready_cloud("cam", 1, np.array([["a", "b", "c"]]), 0.0)


def test_a_scene_with_a_voxel_swaps_in_the_thinned_cloud_and_is_exact_on_it(
    rng: np.random.Generator,
) -> None:
    scene = Scene(voxel=0.05)
    part = rng.normal(scale=0.1, size=(300, 3))
    scene.add_object("part", part)
    scene.add_object("camera", rng.normal(size=(100, 3)) + np.array([2.0, 0.0, 0.0]))
    scene.watch("part", "camera", math.inf)
    frame = rng.normal(scale=0.3, size=(20000, 3)) + np.array([0.9, 0.0, 0.0])
    v = scene.replace_cloud("camera", frame)
    assert scene.ingest.wait("camera", v, timeout=WAIT)
    res = scene.query_all()
    thinned = scene.objects["camera"].cloud.points
    np.testing.assert_array_equal(thinned, voxel_thin(frame, 0.05).points)
    assert len(thinned) < len(frame)
    ref = float(cKDTree(thinned).query(part)[0].min())
    assert res.pairs[0].result.distance == pytest.approx(ref, abs=1e-12)
    with pytest.raises(InputError, match="voxel"):
        Scene(voxel=0.0)
    scene.close()


def test_swap_in_puts_a_built_cloud_in_use_before_the_next_query(
    rng: np.random.Generator,
) -> None:
    scene, _ = _camera_scene(rng)
    v = scene.replace_cloud("camera", rng.normal(size=(300, 3)), stamp=4.0)
    assert scene.ingest.wait("camera", v, timeout=WAIT)
    assert scene.versions["camera"] == 0
    scene.swap_in()
    assert scene.versions["camera"] == v and scene.swaps == 1
    assert scene.query_all().cloud_stamps["camera"] == 4.0
    scene.close()


@pytest.mark.skipif(sys.platform != "linux", reason="per-thread priorities are Linux's")
def test_the_worker_builds_at_a_lower_priority_than_the_loop(rng: np.random.Generator) -> None:
    scene, _ = _camera_scene(rng)
    v = scene.replace_cloud("camera", rng.normal(size=(200, 3)))
    assert scene.ingest.wait("camera", v, timeout=WAIT)
    worker = next(t for t in threading.enumerate() if t.name == "reachwise-cloud-ingest")
    assert worker.native_id is not None
    here = os.getpriority(os.PRIO_PROCESS, threading.get_native_id())
    assert os.getpriority(os.PRIO_PROCESS, worker.native_id) == min(19, here + 10)
    scene.close()


def _fifo_allowed() -> bool:
    if not hasattr(os, "sched_setscheduler"):
        return False
    result: list[bool] = []

    def probe() -> None:
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))
            result.append(True)
        except PermissionError:
            result.append(False)

    t = threading.Thread(target=probe)  # its own thread: the policy dies with it
    t.start()
    t.join()
    return result[0]


@pytest.mark.skipif(not _fifo_allowed(), reason="SCHED_FIFO not permitted here")
def test_a_worker_started_by_a_fifo_loop_builds_under_the_normal_policy(
    rng: np.random.Generator,
) -> None:
    scene, _ = _camera_scene(rng)
    got: dict[str, int] = {}

    def loop() -> None:  # a control loop under SCHED_FIFO makes the first hand-over
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(20))
        got["version"] = scene.replace_cloud("camera", rng.normal(size=(200, 3)))
        got["worker"] = scene.ingest._thread.native_id  # type: ignore[union-attr]

    t = threading.Thread(target=loop)
    t.start()
    t.join()
    try:
        assert scene.ingest.wait("camera", got["version"], timeout=WAIT)
        assert os.sched_getscheduler(got["worker"]) == os.SCHED_OTHER
    finally:
        scene.close()


def test_a_cloud_handed_over_with_its_index_is_not_indexed_again(
    rng: np.random.Generator,
) -> None:
    """A producer that built the index while making the points (a depth image's pixel
    order) hands over a cloud whose index INDICES holds: the scene uses that index,
    numbered with the hand-over's version, and answers exactly on it."""
    from reachwise.distance.index import INDICES
    from reachwise.geometry.cloud import PointCloud

    scene, part = _camera_scene(rng)
    pts = rng.normal(size=(700, 3)) + np.array([1.5, 0.0, 0.0])
    cloud = PointCloud(pts)
    own = build_index(cloud.points, leaf_size=3)  # not what the scene would build
    INDICES.put(cloud, own)
    before = INDICES.builds
    for block in (True, False):
        version = scene.replace_cloud("camera", cloud, block=block, stamp=1.0)
        if not block:
            assert scene.ingest.wait("camera", version, WAIT)
        res = scene.query_all()
        assert res.versions["camera"] == version
        used = INDICES.peek(scene.objects["camera"].cloud)
        assert used is not None and used.version == version
        np.testing.assert_array_equal(used.boxes, own.boxes)  # the same tree, not rebuilt
        assert res.rows[0, 0] == pytest.approx(_brute(part, pts), abs=1e-12)
    ready = ready_cloud("x", 3, PointCloud(pts), 0.0)  # no index kept: built
    assert ready.index.version == 3 and len(ready.index.info) != len(own.info)
    assert INDICES.builds == before
