"""Clouds streamed to a real server process: each answer is brute force on the cloud
version it reports, versions only grow (also across a restart), ``block`` waits for the
swap, malformed frames get typed errors; the binary tick answers as the full protocol
does, on a corpus of scenes."""

from __future__ import annotations

import math
import threading
from pathlib import Path

import msgpack
import numpy as np
import pytest
import zmq
from numpy.typing import NDArray

from reachwise.distance import Scene, closest_points
from reachwise.io.robot_file import load_robot, robot_from_dict, robot_to_dict
from reachwise.kinematics.robot import Robot
from reachwise.server import protocol as P
from reachwise.server.client import SceneClient, ServerInputError, ServerSceneResult
from reachwise.server.service import SceneService
from reachwise.server.state import StateStore

from .conftest import HANG_GUARD, LINKS, MAX_CLOUD_POINTS, box_points, crane_q, start_server
from .described import described

E = P.ErrorCode
CAMERA = "camera"


def _frame(k: int, n: int = 1500) -> NDArray[np.float64]:
    """Camera frame ``k``: a box that moves 5 cm per frame through the crane's reach."""
    return box_points((0.5, 0.4, 1.2), n, seed=100 + k) + np.array([2.0, 0.05 * k - 0.4, 0.6])


def _scene(
    scene: Scene | SceneClient, crane: Robot, clouds: dict[str, NDArray[np.float64]]
) -> None:
    scene.add_robot(crane, crane_q(crane, 0), stamp=0.0)
    for link in LINKS:
        scene.add_object(link, clouds[link], robot=crane.name, link=link)
    scene.add_object(CAMERA, _frame(0))
    for link in LINKS:
        scene.watch(link, CAMERA, math.inf, kind="robot-environment")


def _brute(
    link_points: NDArray[np.float64], pose: NDArray[np.float64], camera: NDArray[np.float64]
) -> float:
    return closest_points(link_points, camera, pose, None, strategy="brute").distance


def _check_on_reported_version(
    r: ServerSceneResult,
    sent: dict[int, NDArray[np.float64]],
    stamps: dict[int, float],
    poses: dict[str, NDArray[np.float64]],
    clouds: dict[str, NDArray[np.float64]],
) -> int:
    """Every pair's answer equals brute force on the camera cloud version it reports;
    returns that version."""
    assert r.valid, r.reason
    v = r.versions[CAMERA]
    assert v in sent, (v, sorted(sent))
    assert r.cloud_stamps[CAMERA] == stamps[v]
    cam = sent[v]
    for p in r.pairs:
        assert p.b == CAMERA and p.versions == (0, v)
        res = p.result
        truth = _brute(clouds[p.a], poses[p.a], cam)
        assert abs(res.distance - truth) <= 1e-12 * max(1.0, truth), (p.a, v)
        # the closest point on the camera side is a point of that very version
        np.testing.assert_allclose(res.point_b, cam[res.index_b], rtol=0, atol=1e-12)
    return v


def test_every_answer_is_brute_force_on_the_cloud_version_it_reports(
    tmp_path: Path, crane: Robot, clouds: dict[str, NDArray[np.float64]]
) -> None:
    proc = start_server(tmp_path / "srv")
    try:
        local = Scene()  # the link poses, for the brute-force truth
        _scene(local, crane, clouds)
        with (
            SceneClient(proc.endpoint, deadline=HANG_GUARD, batch_inputs=True) as ctrl,
            SceneClient(proc.endpoint, setup_deadline=HANG_GUARD) as camera,
        ):
            ctrl.wait_ready(30.0)
            _scene(ctrl, crane, clouds)
            sent = {0: _frame(0)}
            stamps = {0: math.inf}
            seen = []
            for k in range(1, 25):
                frame = _frame(k)
                # float32 and float64 frames alternate; the server's cloud is float64
                wire = frame.astype(np.float32) if k % 2 else frame
                v = camera.replace_cloud(CAMERA, wire, stamp=100.0 + k)
                assert v == k
                sent[v] = wire.astype(np.float64)
                stamps[v] = 100.0 + k
                for j in range(3):  # queries while the worker indexes it
                    q = crane_q(crane, 40 * k + j)
                    ctrl.set_joints(crane.name, q, stamp=float(k))
                    local.set_joints(crane.name, q)
                    r = ctrl.query_all()
                    seen.append(_check_on_reported_version(r, sent, stamps, local.poses(), clouds))
            last = camera.replace_cloud(CAMERA, _frame(30), block=True, stamp=200.0)
            sent[last], stamps[last] = _frame(30), 200.0
            r = ctrl.query_all()
            assert _check_on_reported_version(r, sent, stamps, local.poses(), clouds) == last
            assert ctrl.ticks >= len(seen)  # answered through the binary path
        assert seen == sorted(seen), "the version an answer uses never goes back"
        assert len(set(seen)) > 3, "answers must have run on several streamed versions"
    finally:
        status = proc.stop()
    assert status == 0, (proc.workdir / "server.log").read_text()


def test_block_returns_once_the_version_is_in_use_and_versions_only_grow(
    tmp_path: Path, crane: Robot, clouds: dict[str, NDArray[np.float64]]
) -> None:
    """Two clients stream into one object concurrently: every hand-over gets its own
    version, they only grow; ``block`` returns once its version is in use; a clean
    restart resumes from the newest version with its stamp."""
    workdir = tmp_path / "srv"
    proc = start_server(workdir)
    got: dict[int, list[int]] = {0: [], 1: []}
    try:
        with SceneClient(proc.endpoint, deadline=HANG_GUARD) as c:
            c.wait_ready(30.0)
            _scene(c, crane, clouds)

            def stream(i: int) -> None:
                with SceneClient(proc.endpoint, setup_deadline=HANG_GUARD) as s:
                    for k in range(15):
                        got[i].append(s.replace_cloud(CAMERA, _frame(k, 300), stamp=float(k)))

            workers = [threading.Thread(target=stream, args=(i,)) for i in (0, 1)]
            for w in workers:
                w.start()
            for w in workers:
                w.join(HANG_GUARD)
            for mine in got.values():
                assert mine == sorted(mine) and len(set(mine)) == len(mine) == 15
            assert sorted(got[0] + got[1]) == list(range(1, 31))
            v = c.replace_cloud(CAMERA, _frame(40), block=True, stamp=55.5)
            assert v == 31
            r = c.query_all()
            assert (r.versions[CAMERA], r.cloud_stamps[CAMERA]) == (31, 55.5)
            described = {o.name: o for o in c.describe(clouds=True).objects}
            np.testing.assert_array_equal(described[CAMERA].cloud, _frame(40))
        assert proc.stop() == 0
        proc = start_server(workdir)  # the same state directory
        with SceneClient(proc.endpoint, deadline=HANG_GUARD) as c:
            c.wait_ready(30.0)
            r = c.query_all()
            assert (r.versions[CAMERA], r.cloud_stamps[CAMERA]) == (31, 55.5)
            assert all(r.cloud_stamps[link] == math.inf for link in LINKS)
            assert c.replace_cloud(CAMERA, _frame(41), block=True) == 32
    finally:
        status = proc.stop()
    assert status == 0, (proc.workdir / "server.log").read_text()


def _raw(endpoint: str, frames: list[bytes], timeout_ms: int = 60_000) -> P.DecodedReply:
    ctx = zmq.Context()
    try:
        s = ctx.socket(zmq.REQ)
        s.linger = 0
        s.connect(endpoint)
        s.send_multipart(frames)
        assert s.poll(timeout_ms, zmq.POLLIN), "no reply: the server must always answer"
        raw = s.recv()
        s.close(linger=0)
    finally:
        ctx.term()
    return P.decode_reply(raw, P.ObjectReply)


def _header(body: dict[str, object], op: str = "replace_cloud") -> bytes:
    return msgpack.packb({"v": 1, "id": 4, "op": op, "body": body}, use_bin_type=True)


def test_malformed_frames_get_typed_errors_and_the_server_survives(
    tmp_path: Path, crane: Robot, clouds: dict[str, NDArray[np.float64]]
) -> None:
    proc = start_server(tmp_path / "srv")
    try:
        with SceneClient(proc.endpoint, deadline=HANG_GUARD) as c:
            c.wait_ready(30.0)
            _scene(c, crane, clouds)
            first = c.query_all()
            ep = proc.endpoint
            body = {"name": CAMERA, "points": 4, "dtype": "<f4"}
            cases: list[tuple[list[bytes], P.ErrorCode, str]] = [
                ([_header(body), b"\0" * 47], E.WRONG_SHAPE, "cloud"),
                ([_header({**body, "dtype": "<i4"}), b"\0" * 48], E.WRONG_TYPE, "body.dtype"),
                ([_header({**body, "points": 0}), b""], E.WRONG_SHAPE, "body.points"),
                (
                    [_header({**body, "points": MAX_CLOUD_POINTS + 1}), b"\0" * 12],
                    E.OVERSIZED_CLOUD,
                    "body.points",
                ),
                ([_header(body)], E.BAD_MESSAGE, "frames"),
                ([_header(body), b"\0" * 48, b"\0" * 48], E.BAD_MESSAGE, "frames"),
                ([_header({**body, "name": "nothing"}), b"\0" * 48], E.UNKNOWN_ID, "body.name"),
                ([_header({}, "health"), b"\0"], E.BAD_MESSAGE, "frames"),
                ([b"\x92\x01", b"\0" * 48], E.BAD_MESSAGE, "message"),
                ([b"RWq\x01" + b"\0" * 3], E.BAD_MESSAGE, "message"),  # a truncated tick
            ]
            for frames, code, field in cases:
                err = _raw(ep, frames).error
                assert err is not None and (err.code, err.field) == (code, field), frames[0]
            # a well-formed cloud with bad points: refused by the indexing worker, never
            # swapped in; block reports it as the typed error
            bad = np.zeros((4, 3), dtype=np.float32)
            bad[2, 1] = np.nan
            with pytest.raises(ServerInputError) as info:
                c.replace_cloud(CAMERA, bad, block=True)
            assert (info.value.code, info.value.field) == (E.INVALID, "cloud")
            assert c.replace_cloud(CAMERA, bad) > 0  # without block: a version, unused
            assert c.query_all().versions[CAMERA] == first.versions[CAMERA] == 0
            # a stale layout: a tick under an old key is refused, the client resends it
            c.watch(LINKS[0], LINKS[2], 0.5)
            r = c.query_all()
            assert r.valid and len(r.pairs) == len(first.pairs) + 1
            assert c.query_all().valid and c._channel.stale_ticks == 1
            assert c.health().ready
            errors = c.metrics().errors
        assert E.INTERNAL not in errors
    finally:
        status = proc.stop()
    assert status == 0, (proc.workdir / "server.log").read_text()


# ------------------------------------------------------------------ the tick = the full path


def _service(seed: int) -> tuple[SceneService, dict[str, int], list[str]]:
    """Scene ``seed`` of the corpus: one or two robots, parts on their links, fixed and
    run-time objects, pairs of every kind."""
    rng = np.random.default_rng(seed)
    svc = SceneService(clock=lambda: 1000.0)
    robots: dict[str, int] = {}
    names = ["hiab-xs033", "puma560"][: 1 + seed % 2]
    objects: list[str] = []
    for i, name in enumerate(names):
        robot = load_robot(name)
        model = robot_to_dict(robot)
        model["name"] = f"r{i}"
        renamed = robot_from_dict(model, name)
        svc.handle(
            P.OperationCall.of("add_robot", renamed, rng.normal(scale=0.3, size=robot.n), stamp=1.0)
        )
        robots[f"r{i}"] = robot.n
        for link in robot.link_names[2 : 2 + 2 + seed % 3]:
            obj = f"r{i}_{link}"
            svc.handle(P.AddObject(obj, rng.normal(scale=0.2, size=(200, 3)), None, f"r{i}", link))
            objects.append(obj)
    for j in range(1 + seed % 3):
        pose = np.eye(4)
        pose[:3, 3] = rng.uniform(-2, 2, 3)
        svc.handle(P.AddObject(f"fixed{j}", rng.normal(scale=0.5, size=(800, 3)), pose))
    svc.handle(P.AddObject("probe", rng.normal(scale=0.1, size=(100, 3)), np.eye(4), dynamic=True))
    for r in robots:
        svc.handle(P.OperationCall.of("watch_environment", r, float(rng.uniform(0.5, 3.0))))
        svc.handle(P.OperationCall.of("watch_self", r, 0.4))
    if len(robots) == 2:
        svc.handle(P.OperationCall.of("watch_robots", "r0", "r1", 2.0))
    svc.handle(P.OperationCall.of("watch", "probe", objects[0], math.inf, kind="custom"))
    return svc, robots, objects


@pytest.mark.parametrize("seed", range(6))
def test_the_binary_tick_answers_exactly_as_the_full_protocol(seed: int) -> None:
    """Two identical services, one asked in full (msgpack), the other by binary ticks,
    through queries with joint states and poses and streamed clouds: the same replies,
    and the same results on the client side."""
    full, robots, _ = _service(seed)
    fast, _, _ = _service(seed)
    first, fast_first = full.handle(P.Query(2.0)), fast.handle(P.Query(2.0))
    assert isinstance(first, P.QueryReply) and isinstance(fast_first, P.QueryReply)
    layout, fast_layout = P.Layout.of(first), P.Layout.of(fast_first)
    assert layout is not None and fast_layout is not None and layout.key and fast_layout.key
    assert (layout.pairs, layout.objects, layout.robots) == (
        fast_layout.pairs,
        fast_layout.objects,
        fast_layout.robots,
    )
    rng = np.random.default_rng(100 + seed)
    for k in range(25):
        joints = {r: rng.normal(scale=0.5, size=n) for r, n in robots.items() if rng.random() < 0.8}
        poses = None
        if k % 3 == 0:
            pose = np.eye(4)
            pose[:3, 3] = rng.uniform(-1, 1, 3)
            poses = {"probe": pose}
        if k % 5 == 4:  # a new cloud for a fixed object, on both, waited for
            cloud = rng.normal(scale=0.5, size=(500, 3)).astype(np.float32)
            for svc in (full, fast):
                svc.handle(P.ReplaceCloud("fixed0", cloud, 50.0 + k, block=True))
        stamp = 10.0 + k
        q_full = P.Query(stamp, joints or None, poses, None, layout.name)
        rid, req = P.decode_request(P.encode_request(k, q_full))
        a = P.decode_reply(P.encode_reply(rid, full.handle(req)), P.QueryReply).reply
        q_fast = P.Query(stamp, joints or None, poses, None, fast_layout.name)
        tick = P.encode_tick(k, q_fast, fast_layout)
        assert tick is not None
        payload, _ = fast.tick(tick, P.DEFAULT_LIMITS)
        got, b = P.decode_tick_reply(payload, fast_layout)
        assert got == k and isinstance(a, P.QueryReply)
        assert (a.sequence, a.measured_at, a.pairs) == (b.sequence, b.measured_at, None)
        np.testing.assert_array_equal(a.rows, b.rows)
        assert a.clouds is not None and b.clouds is not None
        np.testing.assert_array_equal(a.clouds, b.clouds)
        ra = ServerSceneResult.of_reply(a, layout, computed_at=1.0)
        rb = ServerSceneResult.of_reply(b, fast_layout, computed_at=1.0)
        assert dict(ra.versions) == dict(rb.versions) and dict(ra.cloud_stamps) == dict(
            rb.cloud_stamps
        )
        for pa, pb in zip(ra.pairs, rb.pairs, strict=True):
            assert (pa.a, pa.b, pa.margin, pa.kind, pa.versions) == (
                pb.a,
                pb.b,
                pb.margin,
                pb.kind,
                pb.versions,
            )
            assert pa.result.no_risk == pb.result.no_risk
            assert (pa.result.index_a, pa.result.index_b) == (pb.result.index_a, pb.result.index_b)
            np.testing.assert_array_equal(pa.result.point_a, pb.result.point_a)
            assert pa.result.distance == pb.result.distance or (
                math.isinf(pa.result.distance) and math.isinf(pb.result.distance)
            )
    assert ra.versions["fixed0"] == 5 and ra.cloud_stamps["fixed0"] == 50.0 + 24


def test_a_tick_is_refused_like_the_full_query(crane: Robot) -> None:
    """Bad content in a tick gets the full protocol's typed error, field included."""
    svc = SceneService()
    svc.handle(P.OperationCall.of("add_robot", crane, np.zeros(crane.n), stamp=1.0))
    svc.handle(P.AddObject("part", box_points((1, 1, 1), 50, 1), None, crane.name, "link_2"))
    svc.handle(P.AddObject("probe", box_points((1, 1, 1), 50, 2), np.eye(4), dynamic=True))
    svc.handle(P.OperationCall.of("watch", "part", "probe", 1.0, kind="custom"))
    layout = P.Layout.of(svc.handle(P.Query(1.0)))  # type: ignore[arg-type]
    assert layout is not None
    bad_pose = np.eye(4)
    bad_pose[3, 3] = 2.0
    for query in (
        P.Query(1.0, {crane.name: np.zeros(2)}, None, None, layout.name),
        P.Query(1.0, None, {"probe": bad_pose}, None, layout.name),
    ):
        with pytest.raises(P.ProtocolError) as full:
            svc.handle(query)
        tick = P.encode_tick(3, query, layout)
        assert tick is not None
        payload, reply = svc.tick(tick, P.DEFAULT_LIMITS)
        err = P.decode_reply(payload, P.QueryReply).error
        assert reply is None and err is not None
        assert (err.code, err.field) == (full.value.code, full.value.field)
    svc.handle(
        P.OperationCall.of("unwatch", "part", "probe")
    )  # the layout changes: the old key is stale
    tick = P.encode_tick(4, P.Query(1.0, None, None, None, layout.name), layout)
    assert tick is not None
    err = P.decode_reply(svc.tick(tick, P.DEFAULT_LIMITS)[0], P.QueryReply).error
    assert err is not None and err.code == E.STALE_LAYOUT


def test_only_indexed_clouds_are_saved_and_a_crash_restores_the_last_saved(
    tmp_path: Path, crane: Robot, clouds: dict[str, NDArray[np.float64]]
) -> None:
    """Streamed clouds are saved lazily: the newest indexed one (never one with bad
    points); a restart without a clean stop comes back with it, version and stamp."""
    svc = SceneService(store=StateStore(tmp_path))
    svc.load()
    svc.handle(P.AddObject(CAMERA, _frame(0)))
    for k in (1, 2):
        svc.handle(P.ReplaceCloud(CAMERA, _frame(k).astype(np.float32), 10.0 + k, block=True))
    svc.flush_clouds(force=True)
    bad = _frame(3)
    bad[5] = np.inf
    assert svc.handle(P.ReplaceCloud(CAMERA, bad, 13.0)).version == 3  # type: ignore[union-attr]
    svc.flush_clouds(force=True, timeout=HANG_GUARD)  # refused by the worker: not saved
    svc.handle(P.ReplaceCloud(CAMERA, _frame(4), 14.0))  # handed over, never saved: a crash
    again = SceneService(store=StateStore(tmp_path))  # the same directory, no clean stop
    again.load()
    assert again.ready
    (cam,) = described(again, clouds=True).objects
    np.testing.assert_array_equal(cam.cloud, _frame(2).astype(np.float32))
    answer = again.handle(P.Query(1.0))
    assert isinstance(answer, P.QueryReply) and answer.clouds is not None
    assert answer.clouds.tolist() == [[2.0, 12.0]]
    svc.close()
    again.close()


def test_a_cloud_handed_over_before_a_clear_is_never_swapped_in_or_saved(
    tmp_path: Path,
) -> None:
    """A ``block`` hand-over parked across a ``clear`` is refused (``unknown_id``) even
    when an object of the same name was added again meanwhile; its cloud is never used
    and never saved, and the new object answers with its own cloud."""
    svc = SceneService(store=StateStore(tmp_path))
    svc.load()
    svc.handle(P.AddObject(CAMERA, _frame(0)))
    svc.handle(P.AddObject("probe", np.array([[2.0, -0.4, 0.0]]), None, dynamic=True))
    wait = svc.hand_over(P.ReplaceCloud(CAMERA, _frame(5), 15.0, block=True))
    cleared = svc.handle(P.OperationCall.of("clear"))
    assert isinstance(cleared, P.OperationResult) and cleared.result is None
    svc.handle(P.AddObject(CAMERA, _frame(1)))
    svc.handle(P.AddObject("probe", np.array([[2.0, -0.4, 0.0]]), None, dynamic=True))
    svc.handle(P.OperationCall.of("watch", "probe", CAMERA, 10.0))
    with pytest.raises(P.ProtocolError) as info:
        while svc.settle(wait) is None:  # the old worker was stopped: returns at once
            pass
    assert info.value.code == P.ErrorCode.UNKNOWN_ID and "cleared" in info.value.message
    svc.flush_clouds(force=True, timeout=HANG_GUARD)
    answer = svc.handle(P.Query(1.0))
    assert isinstance(answer, P.QueryReply) and answer.clouds is not None
    assert answer.clouds.tolist() == [[0.0, math.inf], [0.0, math.inf]]  # both as added
    probe = np.array([2.0, -0.4, 0.0])
    want = float(np.min(np.linalg.norm(_frame(1) - probe, axis=1)))
    assert answer.rows[0, 0] == pytest.approx(want, abs=1e-12)
    again = SceneService(store=StateStore(tmp_path))
    again.load()
    cam = next(o for o in described(again, clouds=True).objects if o.name == CAMERA)
    np.testing.assert_array_equal(cam.cloud, _frame(1))
    svc.close()
    again.close()
