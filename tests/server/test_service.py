"""A real server process on loopback: same answers as in process, typed errors for bad
input, malformed frames and fuzzed bytes, eight concurrent clients."""

from __future__ import annotations

import math
import threading
from pathlib import Path

import msgpack
import numpy as np
import pytest
import zmq
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from reachwise.benchmarks.server import ServerProcess
from reachwise.distance import Scene, closest_points
from reachwise.errors import InputError
from reachwise.io.robot_file import robot_from_dict, robot_to_dict
from reachwise.kinematics.robot import Robot
from reachwise.server import protocol as P
from reachwise.server.client import SceneClient, SceneLike, ServerInputError, ServerSceneResult
from reachwise.server.transport import CollisionServer

from .conftest import (
    HANG_GUARD,
    MAX_CLOUD_POINTS,
    MAX_MESSAGE_MB,
    build_scene,
    crane_q,
    start_server,
)

E = P.ErrorCode


@pytest.fixture(scope="module")
def loaded(
    server: ServerProcess, crane: Robot, clouds: dict[str, NDArray[np.float64]]
) -> ServerProcess:
    """The module's server with the crane scene registered."""
    with SceneClient(server.endpoint) as c:
        c.wait_ready(30.0)
        build_scene(c, crane, clouds)
    return server


def _raw_request(endpoint: str, frames: list[bytes], timeout_ms: int = 5000) -> list[bytes]:
    """Send raw frames on a DEALER socket (any framing) and return the reply frames."""
    ctx = zmq.Context()
    try:
        s = ctx.socket(zmq.DEALER)
        s.linger = 0
        s.connect(endpoint)
        s.send_multipart(frames)
        assert s.poll(timeout_ms, zmq.POLLIN), "no reply: the server must always answer"
        out = s.recv_multipart()
        s.close(linger=0)
        return out
    finally:
        ctx.term()


def _error_of(frames: list[bytes]) -> P.ErrorReply:
    dec = P.decode_reply(frames[-1], P.Ack)
    assert dec.error is not None, dec
    return dec.error


def _assert_serving(endpoint: str) -> None:
    with SceneClient(endpoint, deadline=HANG_GUARD) as c:
        assert c.health().ready
        assert c.query_all().valid


def _assert_same(remote: ServerSceneResult, local: object) -> None:
    from reachwise.distance.scene import SceneResult

    assert isinstance(local, SceneResult) and remote.valid, remote.reason
    assert len(remote.pairs) == len(local.pairs)
    for pa, pb in zip(remote.pairs, local.pairs, strict=True):
        assert (pa.a, pa.b, pa.margin, pa.kind) == (pb.a, pb.b, pb.margin, pb.kind)
        ra, rb = pa.result, pb.result
        assert ra.no_risk == rb.no_risk
        if not ra.no_risk:
            assert ra.distance == rb.distance
            assert (ra.index_a, ra.index_b) == (rb.index_a, rb.index_b)
            np.testing.assert_array_equal(ra.point_a, rb.point_a)
            np.testing.assert_array_equal(ra.point_b, rb.point_b)
            np.testing.assert_array_equal(ra.direction, rb.direction)


def test_same_answers_as_the_in_process_scene(
    loaded: ServerProcess, crane: Robot, clouds: dict[str, NDArray[np.float64]]
) -> None:
    local = Scene()
    build_scene(local, crane, clouds)
    with SceneClient(loaded.endpoint, deadline=HANG_GUARD) as remote:
        start = remote.metrics()  # the module's server: other tests' requests came before
    for batch in (False, True):
        with SceneClient(loaded.endpoint, deadline=HANG_GUARD, batch_inputs=batch) as remote:
            hello = remote.hello()
            assert hello.protocol == P.PROTOCOL_VERSION and hello.ready
            last = 0
            within = 0
            for k in range(0, 600, 5):
                q = crane_q(crane, k)
                before = remote.clock()
                remote.set_joints(crane.name, q)
                local.set_joints(crane.name, q)
                r = remote.query_all()
                _assert_same(r, local.query_all())
                assert r.sequence > last
                last = r.sequence
                assert before <= r.measured_at <= r.computed_at
                # the server's computation lies within this client's round trip
                assert 0.0 < r.compute_time <= r.computed_at - before
                within += len(r.at_risk())
            assert within > 0, "the path must bring pairs within their margins"
    # the scene interface: contents as the in-process scene has them
    with SceneClient(loaded.endpoint, deadline=HANG_GUARD) as remote:
        assert isinstance(remote, SceneLike) and isinstance(local, SceneLike)
        assert remote.pairs == local.pairs
        assert remote.strategy == local.strategy
        assert list(remote.robots) == [crane.name]
        objs, ref = remote.objects, local.objects
        assert list(objs) == list(ref)
        for name, obj in objs.items():
            np.testing.assert_array_equal(obj.cloud.points, ref[name].cloud.points)
            assert type(obj.source) is type(ref[name].source)
        assert [o.name for o in remote.robot_objects(crane.name)] == [
            o.name for o in local.robot_objects(crane.name)
        ]
        poses, ref_poses = remote.poses(), local.poses()
        assert poses.keys() == ref_poses.keys()
        for name, pose in poses.items():
            np.testing.assert_array_equal(pose, ref_poses[name])
        chosen = [("link_6", "environment")]
        sub = remote.query_all(pairs=chosen)
        assert [(p.a, p.b) for p in sub.pairs] == chosen
        m = remote.metrics()
    # this test's 241 queries, each one computed (and timed) once
    queries = m.requests["query"] - start.requests.get("query", 0)
    assert queries == 2 * 120 + 1
    assert sum(m.query_compute) - sum(start.query_compute) == queries


def test_bad_input_gets_typed_errors_and_the_server_keeps_serving(
    loaded: ServerProcess, crane: Robot
) -> None:
    renamed = robot_from_dict(dict(robot_to_dict(crane), name="crane-2"), "crane-2")
    with SceneClient(loaded.endpoint, deadline=HANG_GUARD) as c:
        cases: list[tuple[P.Request, P.ErrorCode, str]] = [
            (P.SetJoints("crane-x", np.zeros(6)), E.UNKNOWN_ID, "body.robot"),
            (P.SetJoints(crane.name, np.zeros(3)), E.WRONG_SHAPE, "body.q"),
            (P.SetPose("nothing", np.eye(4)), E.UNKNOWN_ID, "body.name"),
            (P.SetPose("environment", np.eye(4)), E.INVALID, "body.name"),
            (P.Query(pairs=(("link_2", "link_3"),)), E.UNKNOWN_PAIR, "body.pairs[0]"),
            (P.Query(joints={crane.name: np.zeros(2)}), E.WRONG_SHAPE, f"body.joints.{crane.name}"),
            (P.ReplaceCloud("nothing", np.ones((3, 3))), E.UNKNOWN_ID, "body.name"),
            (
                P.AddObject("big", np.zeros((MAX_CLOUD_POINTS + 1, 3))),
                E.OVERSIZED_CLOUD,
                "body.cloud",
            ),
            (P.AddObject("environment", np.ones((3, 3))), E.EXISTS, "body.name"),
            (
                P.AddObject("p", np.ones((3, 3)), None, crane.name, "link_99"),
                E.UNKNOWN_ID,
                "body.link",
            ),
            (P.AddObject("p", np.ones((3, 3)), np.diag([1.0, 1, 2, 1])), E.INVALID, "body.pose"),
            (P.AddObject("p", np.ones((3, 3)), stamp=-math.inf), E.INVALID, "body.stamp"),
            (P.OperationCall.of("watch", "link_2", "nothing", 0.1), E.UNKNOWN_ID, "object"),
            (
                P.OperationCall.of("watch", "link_2", "link_2", 0.1),
                E.INVALID,
                "pair ('link_2', 'link_2')",
            ),
            (P.OperationCall.of("watch", "link_2", "environment", -1.0), E.INVALID, "margin"),
            (
                P.OperationCall.of("watch", "link_2", "environment", math.nan),
                E.NON_FINITE,
                "body.arguments.margin",
            ),
            (P.OperationCall.of("watch_self", "nobody", 0.1), E.UNKNOWN_ID, "robot"),
            (
                P.OperationCall.of("watch_robots", crane.name, crane.name, 1.0),
                E.INVALID,
                "watch_robots",
            ),
            (P.OperationCall.of("add_robot", crane), E.EXISTS, "robot"),
            (P.OperationCall.of("add_robot", renamed, np.zeros(2)), E.INVALID, "q"),
            (
                P.OperationCall.of("add_robot", renamed, np.zeros(crane.n), stamp=math.inf),
                E.INVALID,
                "stamp",
            ),
        ]
        for req, code, field in cases:
            with pytest.raises(ServerInputError) as info:
                c.call(req, HANG_GUARD)
            assert (info.value.code, info.value.field) == (code, field), req.OP
            assert isinstance(info.value, InputError)
        assert "crane-2" not in c.robots  # a refused robot is not registered at all
        with pytest.raises(InputError, match="reachwise Robot"):  # a model is no Robot
            c.add_robot({"name": "r", "joints": []})  # type: ignore[arg-type]
        # robot models the client would refuse itself, sent raw
        for model, code, field in [
            ({"name": "r", "joints": []}, E.INVALID, "body.arguments.robot.joints"),
            (
                {"name": "r", "joints": [{"type": "revolute", "a": "long"}]},
                E.INVALID,
                "body.arguments.robot.joints[0].a",
            ),
            (dict(robot_to_dict(crane), name="a\x00b"), E.WRONG_TYPE, "body.arguments.robot.name"),
        ]:
            raw = msgpack.packb(
                {
                    "v": 1,
                    "id": 8,
                    "op": "call",
                    "body": {"operation": "add_robot", "arguments": {"robot": model}},
                },
                use_bin_type=True,
            )
            err = _error_of(_raw_request(loaded.endpoint, [b"", raw]))
            assert (err.code, err.field) == (code, field)
        # non-finite values the client would refuse itself, sent raw
        bad = P.encode_array(np.array([0.0, np.nan, 0, 0, 0, 0]))
        raw = msgpack.packb(
            {"v": 1, "id": 9, "op": "set_joints", "body": {"robot": crane.name, "q": bad}},
            use_bin_type=True,
        )
        err = _error_of(_raw_request(loaded.endpoint, [b"", raw]))
        assert (err.code, err.field) == (E.NON_FINITE, "body.q")
        # the client checks what it can before sending, with the in-process scene's errors
        with pytest.raises(InputError, match="NaN or inf"):
            c.set_joints(crane.name, [0.0, math.nan])
    _assert_serving(loaded.endpoint)


def test_malformed_messages_only_get_typed_errors(loaded: ServerProcess) -> None:
    ep = loaded.endpoint
    valid = P.encode_request(1, P.Health())
    cap = int(MAX_MESSAGE_MB * 2**20)
    cases: list[tuple[list[bytes], P.ErrorCode]] = [
        ([b"", b"\x00\x01garbage"], E.BAD_MESSAGE),
        ([b"", b""], E.BAD_MESSAGE),  # an empty body frame
        ([b""], E.BAD_MESSAGE),  # a delimiter and nothing else
        ([b"", valid, valid], E.BAD_MESSAGE),  # two body frames
        ([b"", msgpack.packb("just a string")], E.BAD_MESSAGE),
        (
            [b"", msgpack.packb({"v": 7, "id": 1, "op": "health", "body": {}})],
            E.UNSUPPORTED_VERSION,
        ),
        ([b"", msgpack.packb({"v": 1, "id": 1, "op": "reboot", "body": {}})], E.UNKNOWN_OP),
        ([b"", b"\xc1" * (cap + 10)], E.TOO_LARGE),  # refused by size before decoding
        ([b"\x00\x01garbage"], E.BAD_MESSAGE),  # a DEALER peer without a delimiter
    ]
    for frames, code in cases:
        assert _error_of(_raw_request(ep, frames)).code == code, frames[:2]
    ok = P.decode_reply(_raw_request(ep, [valid])[-1], P.HealthReply)  # DEALER framing works
    assert ok.reply is not None
    _assert_serving(ep)


@settings(
    max_examples=120,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
@given(st.lists(st.binary(max_size=300), min_size=1, max_size=3))
def test_fuzzed_frames_at_a_live_server(loaded: ServerProcess, frames: list[bytes]) -> None:
    reply = _raw_request(loaded.endpoint, [b"", *frames])
    dec = P.decode_reply(reply[-1], P.REPLIES["health"])  # any reply must be well-formed
    assert dec.error is not None or dec.reply is not None


def test_the_server_survives_the_fuzzing(loaded: ServerProcess) -> None:
    """Seeded garbage of its own (whatever ran before): every frame gets a typed error,
    the server counts each one and none as internal, and it still serves."""
    ep = loaded.endpoint
    with SceneClient(ep) as c:
        before = c.metrics().errors
    rng = np.random.default_rng(21)
    codes = []
    for _ in range(40):
        frame = rng.bytes(int(rng.integers(1, 300)))
        err = P.decode_reply(_raw_request(ep, [b"", frame])[-1], P.Ack).error
        assert err is not None, frame
        codes.append(err.code)
    _assert_serving(ep)
    with SceneClient(ep) as c:
        after = c.metrics().errors
    assert E.INTERNAL not in codes and E.INTERNAL not in after
    sent = {code: codes.count(code) for code in set(codes)}
    assert sent.get(E.BAD_MESSAGE, 0) > 0, sent
    assert {k: after.get(k, 0) - before.get(k, 0) for k in sent} == sent


CLIENTS = 8
QUERIES = 1000


def test_eight_clients_in_parallel(tmp_path: Path, clouds: dict[str, NDArray[np.float64]]) -> None:
    """8 clients x 1000 queries: each moves its own probe with the query (atomically) and
    must get the distance of its own probe at its own pose back, in sequence order."""
    env = clouds["environment"]
    probe = clouds["link_6"][:60]
    poses = []
    for i in range(CLIENTS):
        row = []
        for j in range(5):
            T = np.eye(4)
            T[:3, 3] = [0.4 * i - 1.4, 0.1 * j - 0.2, 0.6 + 0.15 * j + 0.01 * i]
            row.append(T)
        poses.append(row)
    expected = [[closest_points(probe, env, P_, None).distance for P_ in row] for row in poses]
    assert all(len(set(row)) == 5 for row in expected), "poses must be told apart by distance"
    proc = start_server(tmp_path / "srv")
    failures: list[str] = []
    try:
        with SceneClient(proc.endpoint) as setup:
            setup.wait_ready(30.0)
            setup.add_object("environment", env)
            for i in range(CLIENTS):
                setup.add_object(f"probe_{i}", probe, poses[i][0], dynamic=True)
                setup.watch(f"probe_{i}", "environment", math.inf)

        def client(i: int) -> None:
            with SceneClient(proc.endpoint, deadline=HANG_GUARD, batch_inputs=True) as c:
                last = 0
                for k in range(QUERIES):
                    j = k % 5
                    c.set_pose(f"probe_{i}", poses[i][j])
                    r = c.query_all()
                    if not r.valid:
                        failures.append(f"client {i} query {k}: lost ({r.reason})")
                        return
                    mine = r.get(f"probe_{i}", "environment").result.distance
                    if mine != expected[i][j] or r.sequence <= last:
                        failures.append(f"client {i} query {k}: mismatched reply")
                        return
                    last = r.sequence
                if c.reconnects:
                    failures.append(f"client {i}: {c.reconnects} reconnects")

        workers = [threading.Thread(target=client, args=(i,)) for i in range(CLIENTS)]
        for w in workers:
            w.start()
        for w in workers:
            w.join()
        with SceneClient(proc.endpoint) as c:
            assert c.metrics().requests["query"] == CLIENTS * QUERIES
    finally:
        status = proc.stop()
    assert not failures, failures[:5]
    assert status == 0, (proc.workdir / "server.log").read_text()


def test_an_in_process_server_frees_its_port_and_threads() -> None:
    threads_before = threading.active_count()
    srv = CollisionServer("tcp://127.0.0.1:*")
    with srv.background() as endpoint, SceneClient(endpoint) as c:
        assert c.health().ready
    assert threading.active_count() == threads_before
    again = CollisionServer(endpoint)  # the very same port binds again at once
    again.start()
    again.close()


def test_missing_data_is_reported_not_raised(tmp_path: Path, crane: Robot) -> None:
    """Nobody listens: per-tick calls report missing data, setup calls raise."""
    from reachwise.server.client import MISSING, ServerUnavailable

    ep = f"ipc://{tmp_path / 'nobody.sock'}"
    with SceneClient(ep, deadline=0.02, setup_deadline=0.05) as c:
        c.set_joints(crane.name, np.zeros(crane.n))  # no exception: remembered
        r = c.query_all()
        assert not r.valid and "no reply" in r.reason and r.sequence == 0
        with pytest.raises(ServerUnavailable):
            c.add_robot(crane)
        assert c.reconnects >= 2  # Lazy Pirate: a fresh socket after each lost reply
    assert math.isnan(MISSING.distance) and not MISSING.no_risk


def test_a_slow_registration_does_not_block_queries(
    crane: Robot, clouds: dict[str, NDArray[np.float64]]
) -> None:
    """While the writer thread is held inside a registration, queries and health are
    still answered; the registration completes when released."""
    srv = CollisionServer("tcp://127.0.0.1:*")
    gate = threading.Event()
    inside = threading.Event()
    original = srv.service._handlers[P.AddObject]

    def held(req: P.AddObject) -> P.Reply:
        inside.set()
        gate.wait(30.0)
        return original(req)

    srv.service._handlers[P.AddObject] = held
    with srv.background() as endpoint:
        # 5 s, well under the 30 s the writer is held: a query blocked behind it would
        # miss its deadline (a hang guard longer than the hold could not tell)
        with SceneClient(endpoint, deadline=5.0) as a, SceneClient(endpoint, deadline=5.0) as b:
            gate.set()
            build_scene(a, crane, clouds)
            gate.clear()
            inside.clear()
            done: list[object] = []
            slow = threading.Thread(
                target=lambda: done.append(a.add_object("late", clouds["link_2"], None))
            )
            slow.start()
            assert inside.wait(10.0)
            for k in range(20):  # the writer is held: these are answered regardless
                b.set_joints(crane.name, crane_q(crane, k))
                assert b.query_all().valid
            assert b.health().ready and not done
            gate.set()
            slow.join()
            assert done and "late" in {o.name for o in b.describe().objects}
