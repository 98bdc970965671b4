"""A real collision server on 127.0.0.1 fed thousands of hostile messages built from the
real message formats (a seeded generator): deep nesting, huge sizes and counts, wrong
types, NaN and inf, unknown and missing fields, wrong frame counts, damaged bytes and
damaged binary ticks. Every message gets a reply (a typed error or an answer), the
server stays alive, answers a valid query equal to the in-process scene afterwards, and
its memory stays bounded."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from typing import Any

import msgpack
import numpy as np
import pytest
import zmq
from numpy.typing import NDArray

from reachwise.distance.scene import Scene
from reachwise.kinematics.robot import Robot
from reachwise.server import protocol as P
from reachwise.server.client import SceneClient
from reachwise.server.transport import CollisionServer

from .conftest import HANG_GUARD, build_scene, crane_q

LIMITS = P.Limits(max_message_bytes=1 << 20, max_cloud_points=20_000)
MESSAGES = 4000
#: Resident-memory growth allowed over the fuzzing (bytes): the messages are capped
#: at 1 MiB, so a leak of even a few bytes per message would show well above noise.
RSS_GROWTH = 64 * 2**20

Rng = np.random.Generator


def _rss() -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    raise AssertionError("no VmRSS in /proc/self/status")


def _deep(depth: int, leaf: object, rng: Rng) -> object:
    """``leaf`` inside ``depth`` levels of one-entry lists or maps (built without
    recursion; msgpack packs it iteratively up to its own limit of 512 levels)."""
    out = leaf
    for _ in range(depth):
        out = [out] if rng.random() < 0.5 else {"k": out}
    return out


def _deep_bytes(depth: int) -> bytes:
    """msgpack bytes of ``depth`` nested one-element arrays around 1 (any depth)."""
    return b"\x91" * depth + b"\x01"


def _hostile_value(rng: Rng) -> object:
    """A value of the wrong kind, size or finiteness for any field."""
    k = int(rng.integers(0, 16))
    if k == 0:
        return _deep(int(rng.integers(20, 300)), "x", rng)
    if k == 1:
        return "n" * int(rng.integers(201, 200_000))
    if k == 2:
        return [P.FLOAT, [(2**62), 3], b"\0" * 24]
    if k == 3:
        return [P.FLOAT, [int(rng.integers(1, 5)), 3], b"\0" * int(rng.integers(0, 64))]
    if k == 4:
        return float("nan")
    if k == 5:
        return float(rng.choice([math.inf, -math.inf]))
    if k == 6:
        return [P.FLOAT, [2], np.array([np.nan, 1.0]).tobytes()]
    if k == 7:
        return list(range(int(rng.integers(1000, 60_000))))
    if k == 8:
        return {f"k{i}": i for i in range(int(rng.integers(100, 5000)))}
    if k == 9:
        return int(rng.integers(-(2**62), 2**62)) * int(rng.choice([1, 2**1]))
    if k == 10:
        return rng.bytes(int(rng.integers(0, 4096)))
    if k == 11:
        return bool(rng.random() < 0.5)
    if k == 12:
        return None
    if k == 13:
        return [_deep(int(rng.integers(1, 40)), 1.5, rng), [2**63 - 1, -1], b"x"]
    if k == 14:
        return [[P.FLOAT], [[3]], [b"\0" * 24]]
    return "\x00\x1b[2J" + "é" * int(rng.integers(0, 50))


def _mutate_body(body: dict[str, Any], rng: Rng) -> dict[str, Any]:
    out = dict(body)
    for _ in range(int(rng.integers(1, 4))):
        action = int(rng.integers(0, 4))
        keys = list(out)
        if action == 0 and keys:  # a field's value replaced
            out[keys[int(rng.integers(0, len(keys)))]] = _hostile_value(rng)
        elif action == 1 and keys:  # a required or optional field dropped
            del out[keys[int(rng.integers(0, len(keys)))]]
        elif action == 2:  # an unknown field
            out[str(rng.choice(["bogus", "x" * 300, "", "é"]))] = _hostile_value(rng)
        else:  # a field nested deeper
            if keys:
                key = keys[int(rng.integers(0, len(keys)))]
                out[key] = _deep(int(rng.integers(1, 60)), out[key], rng)
    return out


class Fuzzer:
    """Builds hostile multipart messages from real requests (``templates``) and, once
    it knows the server's layout, from real binary ticks."""

    def __init__(self, templates: list[P.Request], rng: Rng) -> None:
        self.templates = templates
        self.rng = rng
        self.tick: bytes | None = None

    def _envelope(self, req: P.Request) -> dict[str, Any]:
        return {"v": 1, "id": int(self.rng.integers(0, 2**40)), "op": req.OP, "body": req.body()}

    def message(self) -> list[bytes]:
        rng = self.rng
        req = self.templates[int(rng.integers(0, len(self.templates)))]
        env = self._envelope(req)
        data = [bytes(b) for b in req.data()]
        kind = int(rng.integers(0, 10))
        if kind <= 3:  # the body's fields
            env["body"] = _mutate_body(env["body"], rng)
        elif kind == 4:  # the envelope's fields: op, v, id, body
            key = str(rng.choice(["op", "v", "id", "body", "extra"]))
            env[key] = _hostile_value(rng)
        elif kind == 5:  # nesting deeper than msgpack's packer goes, spliced by hand
            depth = int(rng.integers(900, 1100)) if rng.random() < 0.7 else 100_000
            key = str(rng.choice(["op", "body", "dtype"]))
            if key == "dtype":
                env["body"] = {**env["body"], "dtype": "@@"}
                raw = msgpack.packb(env, use_bin_type=True)
                return [raw.replace(msgpack.packb("@@"), _deep_bytes(depth), 1), *data]
            env[key] = "@@"
            raw = msgpack.packb(env, use_bin_type=True)
            return [raw.replace(msgpack.packb("@@"), _deep_bytes(depth), 1), *data]
        elif kind == 6:  # wrong frame counts
            n = int(rng.integers(0, 4))
            frames = [msgpack.packb(env, use_bin_type=True), *data]
            extra = [rng.bytes(int(rng.integers(0, 64))) for _ in range(n)]
            return frames[: int(rng.integers(0, len(frames) + 1))] + extra
        elif kind == 7:  # damaged bytes
            raw = bytearray(msgpack.packb(env, use_bin_type=True))
            for _ in range(int(rng.integers(1, 6))):
                if not raw:
                    break
                i = int(rng.integers(0, len(raw)))
                if rng.random() < 0.5:
                    raw[i] ^= int(rng.integers(1, 256))
                else:
                    del raw[i:]
                    raw += rng.bytes(int(rng.integers(0, 16)))
            return [bytes(raw), *data]
        elif kind == 8:  # a damaged binary tick, or random bytes
            if self.tick is None or rng.random() < 0.2:
                return [rng.bytes(int(rng.integers(0, 512)))]
            tick = bytearray(self.tick)
            for _ in range(int(rng.integers(1, 4))):
                i = int(rng.integers(4, len(tick)))
                tick[i] = int(rng.integers(0, 256))
            if rng.random() < 0.3:
                tick = tick[: int(rng.integers(4, len(tick)))]
            return [bytes(tick)]
        else:  # a data frame that does not match its header
            if data:
                data = [rng.bytes(int(rng.integers(0, 2048)))]
            env["body"] = _mutate_body(env["body"], rng) if rng.random() < 0.5 else env["body"]
        return [msgpack.packb(env, use_bin_type=True), *data]


def _templates(robot: Robot) -> list[P.Request]:
    """Every kind of request, named after the fuzzed scene's robot and objects (so a
    mutation can reach the scene's checks). ``clear`` is left out: it would only
    empty the scene the final comparison needs."""
    cloud = np.random.default_rng(0).uniform(-0.1, 0.1, (50, 3))
    pose = np.eye(4)
    name = robot.name
    return [
        P.Hello("fuzz", (1,)),
        P.Health(),
        P.Metrics(),
        P.OperationCall.of("add_robot", robot, np.zeros(robot.n), stamp=1.0),
        P.AddObject("fuzz_part", cloud, pose, name, "link_2"),
        P.AddObject("fuzz_probe", cloud, None, None, None, True),
        P.ReplaceCloud("environment", cloud, 2.0),
        P.ReplaceCloud("environment", cloud.astype(np.float32), 2.5, True),
        P.SetJoints(name, crane_q(robot, 5), 3.0),
        P.SetPose("fuzz_probe", pose),
        P.OperationCall.of("watch", "link_2", "environment", 1.0, kind="custom"),
        P.OperationCall.of("watch_self", name, 0.2, (("link_2", "link_6"),)),
        P.OperationCall.of("watch_environment", name, 0.5, ("environment",)),
        P.OperationCall.of("watch_robots", name, name, 0.3),
        P.OperationCall.of("unwatch", "fuzz_part", "environment"),
        P.Query(),
        P.Query(1.0, {name: crane_q(robot, 7)}, None, (("link_6", "environment"),)),
        P.OperationCall.of("describe", clouds=True),
        P.OperationCall("object_poses", {}),
    ]


@pytest.fixture
def fuzzed_server() -> Iterator[str]:
    server = CollisionServer("tcp://127.0.0.1:*", limits=LIMITS)
    with server.background() as endpoint:
        yield endpoint


def _reply_is_typed(frames: list[bytes]) -> None:
    """One reply frame: a binary tick reply, or a msgpack reply that is an answer or
    an error with a known code."""
    assert len(frames) == 2 and frames[0] == b"", f"{len(frames)} reply frames"
    raw = frames[1]
    if P.is_tick_reply(raw):
        return
    obj = msgpack.unpackb(raw, raw=False, strict_map_key=False)
    assert obj["ok"] in (True, False)
    if obj["ok"] is False:
        P.ErrorCode(obj["error"]["code"])
        assert len(obj["error"]["message"]) <= P.fields.MAX_ERROR_LENGTH


def _exchange(sock: zmq.Socket[bytes], frames: list[bytes]) -> list[bytes]:
    sock.send_multipart([b"", *frames])
    assert sock.poll(int(HANG_GUARD * 1000)), "no reply: the server stopped answering"
    return sock.recv_multipart()


def _answers(scene: Any) -> tuple[list[tuple[str, str]], NDArray[np.float64]]:
    """The answered pairs and their distances, points and directions."""
    res = scene.query_all()
    return [(p.a, p.b) for p in res.pairs], np.asarray(res.rows)[:, :10]


def test_server_survives_thousands_of_hostile_messages(
    fuzzed_server: str, crane: Robot, clouds: dict[str, NDArray[np.float64]]
) -> None:
    rng = np.random.default_rng(2026)
    fuzzer = Fuzzer(_templates(crane), rng)
    ctx = zmq.Context.instance()
    sock = ctx.socket(zmq.DEALER)
    sock.linger = 0
    sock.connect(fuzzed_server)
    try:
        with SceneClient(fuzzed_server, deadline=HANG_GUARD, setup_deadline=HANG_GUARD) as client:
            build_scene(client, crane, clouds)
            first = _exchange(sock, [P.encode_request(1, P.Query())])
            decoded = P.decode_reply(first[1], P.QueryReply, LIMITS)
            assert isinstance(decoded.reply, P.QueryReply)
            layout = P.Layout.of(decoded.reply)
            assert layout is not None
            fuzzer.tick = P.encode_tick_inputs(
                2, layout, 1.0, {crane.name: crane_q(crane, 3)}, None
            )
            warm = 300
            before = 0
            for k in range(MESSAGES):
                if k == warm:
                    before = _rss()
                _reply_is_typed(_exchange(sock, fuzzer.message()))
                if k % 500 == 499:  # valid queries keep being answered in between
                    assert len(client.query_all().rows) > 0
            grown = _rss() - before
            # afterwards: the same scene in process and on the fuzzed server
            client.clear()
            build_scene(client, crane, clouds)
            local = Scene()
            build_scene(local, crane, clouds)
            for k in (10, 250):
                q = crane_q(crane, k)
                client.set_joints(crane.name, q)
                local.set_joints(crane.name, q)
                (remote_pairs, remote), (local_pairs, here) = _answers(client), _answers(local)
                assert remote_pairs == local_pairs and len(local_pairs) > 0
                np.testing.assert_allclose(remote, here, rtol=0, atol=1e-12)
            assert client.health().ready
    finally:
        sock.close(linger=0)
    assert grown < RSS_GROWTH, f"resident memory grew by {grown / 2**20:.1f} MiB"


_SAFE_CASES: list[tuple[str, Callable[[], object]]] = [
    ("deep list", lambda: _deep(5000, 1, np.random.default_rng(0))),
    ("long string", lambda: "y" * 1_000_000),
    ("long bytes", lambda: b"\0" * 1_000_000),
    ("big int", lambda: 10**5000),
]


@pytest.mark.parametrize(("label", "make"), _SAFE_CASES, ids=[c[0] for c in _SAFE_CASES])
def test_safe_repr_is_bounded(label: str, make: Callable[[], object]) -> None:
    text = P.safe_repr(make())
    assert len(text) <= 80


def test_depth_check_refuses_deep_and_keeps_shallow() -> None:
    rng = np.random.default_rng(1)
    P.check_depth(_deep(P.MAX_DEPTH, 1, rng))
    with pytest.raises(P.ProtocolError) as info:
        P.check_depth(_deep(P.MAX_DEPTH + 1, 1, rng))
    assert info.value.code == P.ErrorCode.BAD_MESSAGE


@pytest.mark.parametrize("depth", [500, 999, 1020])
@pytest.mark.parametrize("where", ["op", "body", "dtype"])
def test_deep_nesting_is_a_typed_error(depth: int, where: str) -> None:
    env: dict[str, Any] = {"v": 1, "id": 7, "op": "replace_cloud", "body": {}}
    if where == "dtype":
        env["body"] = {"name": "e", "points": 1, "dtype": "@@"}
    else:
        env[where] = "@@"
    raw = msgpack.packb(env).replace(msgpack.packb("@@"), _deep_bytes(depth), 1)
    with pytest.raises(P.ProtocolError) as info:
        P.decode_frames([raw, b"\0" * 24], LIMITS)
    assert info.value.code == P.ErrorCode.BAD_MESSAGE
    assert len(str(info.value)) < 500
