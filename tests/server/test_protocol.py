"""The wire protocol: round trips, strict validation with typed errors, decoder fuzzing."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import msgpack
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from reachwise.distance.pairs import WatchedPair
from reachwise.distance.scene_queries import ObjectInfo, SceneDescription
from reachwise.io.robot_file import robot_to_dict
from reachwise.kinematics.robot import Robot
from reachwise.server import protocol as P
from reachwise.server.protocol import codec

E = P.ErrorCode
LIMITS = P.Limits(max_message_bytes=64 * 1024, max_cloud_points=100)


def _pose() -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = [1.0, -2.0, 0.5]
    return T


def sample_requests(crane: Robot) -> list[P.Request]:
    cloud = np.arange(30, dtype=float).reshape(10, 3)
    return [
        P.Hello("test", (1,)),
        P.Health(),
        P.Metrics(),
        P.OperationCall.of("add_robot", crane, np.zeros(crane.n), stamp=12.5),
        P.OperationCall.of("add_robot", crane),
        P.AddObject("part", cloud, _pose(), "hiab-xs033", "link_2"),
        P.AddObject("probe", cloud, None, None, None, True),
        P.AddObject("scan", cloud, None, stamp=2.5),
        P.AddObject("seen", cloud, None, stamp=math.nan),  # unknown: travels as nil
        P.ReplaceCloud("environment", cloud),
        P.ReplaceCloud("camera", cloud.astype(np.float32), 2.5, True),
        P.SetJoints("hiab-xs033", np.linspace(0, 1, crane.n), 3.0),
        P.SetPose("probe", _pose()),
        P.OperationCall.of("watch", "a", "b", math.inf, kind="custom"),
        P.OperationCall.of("watch_self", "hiab-xs033", 0.2, (("link_1", "link_3"),)),
        P.OperationCall.of("watch_environment", "hiab-xs033", 0.5, ("environment",)),
        P.OperationCall.of("watch_environment", "hiab-xs033", 0.5),
        P.OperationCall.of("watch_robots", "r1", "r2", 0.3),
        P.OperationCall.of("unwatch", "a", "b"),
        P.OperationCall.of("clear"),
        P.Query(),
        P.Query(1.0, {"hiab-xs033": np.zeros(crane.n)}, {"probe": _pose()}, (("a", "b"),), "x-1"),
        P.OperationCall.of("describe", clouds=True),
        P.OperationCall("object_poses", {}),
    ]


def _equal(a: object, b: object) -> bool:
    if isinstance(a, Robot):  # a robot travels as its model: compared as one
        return isinstance(b, Robot) and robot_to_dict(a) == robot_to_dict(b)
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return bool(np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_equal(a[k], b[k]) for k in a)
    if isinstance(a, tuple | list) and isinstance(b, tuple | list):
        return len(a) == len(b) and all(_equal(x, y) for x, y in zip(a, b, strict=True))
    if hasattr(a, "__dataclass_fields__"):
        return type(a) is type(b) and all(
            _equal(getattr(a, f), getattr(b, f)) for f in a.__dataclass_fields__
        )
    return a == b


def test_every_request_round_trips(crane: Robot) -> None:
    reqs = sample_requests(crane)
    assert {type(r).OP for r in reqs} == set(P.REQUESTS)
    for k, req in enumerate(reqs):
        frames = [bytes(f) for f in P.encode_frames(k, req)]
        assert len(frames) == 1 + type(req).DATA_FRAMES
        rid, back = P.decode_frames(frames)
        assert rid == k
        assert _equal(back, req), req.OP


def test_replies_round_trip(crane: Robot) -> None:
    rows = np.zeros((2, P.ROW_COLUMNS))
    rows[0] = [0.1, 1, 2, 3, 4, 5, 6, 0, 0, 1, 7, 9, 0]
    rows[1, :10] = [math.inf] + [math.nan] * 9
    rows[1, 10:] = [-1, -1, 1]
    pairs = (P.PairInfo("a", "b", 0.5, "custom"), P.PairInfo("c", "d", math.inf, "self"))
    description = SceneDescription(
        "default",
        {"hiab-xs033": crane},
        {"hiab-xs033": np.zeros(crane.n)},
        (
            ObjectInfo("part", 10, "link", np.eye(4), "hiab-xs033", "link_2"),
            ObjectInfo("env", 2, "fixed", _pose(), cloud=np.ones((2, 3))),
        ),
        (WatchedPair("a", "b", 0.5, "custom"), WatchedPair("c", "d", math.inf, "self")),
    )
    replies: list[tuple[str, P.Reply]] = [
        ("hello", P.HelloReply("reachwise", "0.1.0", 1, "abc", True)),
        ("health", P.HealthReply(True, "ready", "", 7, "abc", 1.5, 1, 2, 3)),
        (
            "metrics",
            P.MetricsReply(
                2.0, 9, {"query": 3}, {"unknown_id": 1}, (1.0, 2.0), (0, 1, 2), (3, 0, 0)
            ),
        ),
        ("add_object", P.ObjectReply("part", 10)),
        ("set_joints", P.Ack()),
        ("query", P.QueryReply(3, 1.25, 1e-4, "abc-2", pairs, rows)),
        ("query", P.QueryReply(4, 1.25, 1e-4, "abc-2", None, rows)),
        ("call", P.OperationResult(P.encode_value(description, SceneDescription))),
        ("call", P.OperationResult({"part": P.encode_array(_pose())})),
    ]
    for op, rep in replies:
        back = P.decode_reply(P.encode_reply(11, rep), P.REPLIES[op])
        assert back.request_id == 11 and back.error is None
        assert _equal(back.reply, rep), op
    wire = P.encode_value(description, SceneDescription)
    back_description = P.decode_value(wire, SceneDescription, "result")
    assert robot_to_dict(back_description.robots["hiab-xs033"]) == robot_to_dict(crane)
    no_robots = dataclasses.replace(description, robots={})
    assert _equal(dataclasses.replace(back_description, robots={}), no_robots)
    q = P.decode_reply(P.encode_reply(1, replies[6][1]), P.QueryReply).reply
    assert isinstance(q, P.QueryReply)
    assert q.index.tolist() == [[7, 9], [-1, -1]] and q.no_risk.tolist() == [False, True]
    err = P.decode_reply(
        P.encode_error(None, P.ErrorReply(E.UNKNOWN_ID, "body.robot", "no robot")), P.Ack
    )
    assert err.request_id is None and err.error == P.ErrorReply(
        E.UNKNOWN_ID, "body.robot", "no robot"
    )


def _raw(op: str, body: Any, v: int = 1, rid: Any = 1) -> bytes:
    return msgpack.packb({"v": v, "id": rid, "op": op, "body": body}, use_bin_type=True)


#: The smallest valid robot model.
_ONE_JOINT = {"name": "r", "joints": [{"type": "revolute"}]}


def _call(operation: str, arguments: Any) -> bytes:
    return _raw("call", {"operation": operation, "arguments": arguments})


def _arr(a: np.ndarray, dtype: str = "<f8") -> list[Any]:
    return P.encode_array(a, dtype)


def _code(raw: bytes, limits: P.Limits = LIMITS) -> tuple[P.ErrorCode, str]:
    with pytest.raises(P.ProtocolError) as info:
        P.decode_request(raw, limits)
    return info.value.code, info.value.field


@pytest.mark.parametrize(
    ("raw", "code", "field"),
    [
        (b"", E.BAD_MESSAGE, "message"),
        (b"\xc1", E.BAD_MESSAGE, "message"),  # never used in msgpack
        (msgpack.packb([1, 2, 3]), E.BAD_MESSAGE, "message"),
        (msgpack.packb({"v": 1, "id": 1, "op": "health"}), E.MISSING_FIELD, "body"),
        (msgpack.packb({"v": 1, "op": "health", "body": {}}), E.BAD_MESSAGE, "id"),
        (msgpack.packb({"v": 1, "id": -3, "op": "health", "body": {}}), E.BAD_MESSAGE, "id"),
        (_raw("health", {}, v=2), E.UNSUPPORTED_VERSION, "v"),
        (_raw("health", {}, v="1"), E.BAD_MESSAGE, "v"),
        (_raw("launch", {}), E.UNKNOWN_OP, "op"),
        (_raw("health", {"x": 1}), E.UNKNOWN_FIELD, "body.x"),
        (_raw("health", []), E.WRONG_TYPE, "body"),
        (
            msgpack.packb({"v": 1, "id": 1, "op": "health", "body": {}, "extra": 0}),
            E.UNKNOWN_FIELD,
            "extra",
        ),
        (_raw("set_joints", {"robot": "r"}), E.MISSING_FIELD, "body.q"),
        (_raw("set_joints", {"robot": 5, "q": _arr(np.zeros(3))}), E.WRONG_TYPE, "body.robot"),
        (_raw("set_joints", {"robot": "", "q": _arr(np.zeros(3))}), E.WRONG_TYPE, "body.robot"),
        (_raw("set_joints", {"robot": "r", "q": [0.0, 1.0]}), E.WRONG_TYPE, "body.q"),
        (_raw("set_joints", {"robot": "r", "q": _arr(np.zeros((3, 1)))}), E.WRONG_SHAPE, "body.q"),
        (_raw("set_joints", {"robot": "r", "q": _arr(np.zeros(3), "<i8")}), E.WRONG_TYPE, "body.q"),
        (
            _raw("set_joints", {"robot": "r", "q": ["<f8", [4], b"\x00" * 24]}),
            E.WRONG_SHAPE,
            "body.q",
        ),
        (_raw("set_joints", {"robot": "r", "q": ["<f8", [-1], b""]}), E.WRONG_SHAPE, "body.q"),
        (_raw("set_joints", {"robot": "r", "q": ["<f8", [3], "text"]}), E.WRONG_TYPE, "body.q"),
        (
            _raw("set_joints", {"robot": "r", "q": _arr(np.array([0.0, np.nan]))}),
            E.NON_FINITE,
            "body.q",
        ),
        (
            _raw("set_joints", {"robot": "r", "q": _arr(np.zeros(2)), "stamp": math.inf}),
            E.NON_FINITE,
            "body.stamp",
        ),
        (
            _raw("set_joints", {"robot": "r", "q": _arr(np.zeros(2)), "stamp": True}),
            E.WRONG_TYPE,
            "body.stamp",
        ),
        (_raw("set_pose", {"name": "p", "pose": _arr(np.eye(3))}), E.WRONG_SHAPE, "body.pose"),
        (
            _raw("add_object", {"name": "p", "cloud": _arr(np.zeros((101, 3)))}),
            E.OVERSIZED_CLOUD,
            "body.cloud",
        ),
        (
            _raw("add_object", {"name": "p", "cloud": _arr(np.zeros((0, 3)))}),
            E.WRONG_SHAPE,
            "body.cloud",
        ),
        (
            _raw("add_object", {"name": "p", "cloud": _arr(np.full((2, 3), np.inf))}),
            E.NON_FINITE,
            "body.cloud",
        ),
        (
            _raw("add_object", {"name": "p", "cloud": _arr(np.zeros((4, 2)))}),
            E.WRONG_SHAPE,
            "body.cloud",
        ),
        (
            _raw("add_object", {"name": "p", "cloud": _arr(np.zeros((4, 3))), "dynamic": 1}),
            E.WRONG_TYPE,
            "body.dynamic",
        ),
        (
            _call("watch", {"a": "x", "b": "y", "margin": "near", "kind": "custom"}),
            E.WRONG_TYPE,
            "body.arguments.margin",
        ),
        (
            _call("watch", {"a": "x", "b": "y", "margin": 0.1, "kind": "robot-obstacle"}),
            E.INVALID,
            "body.arguments.kind",
        ),
        (
            _call("watch", {"a": "x", "b": "y", "margin": 0.1, "side": "a"}),
            E.UNKNOWN_FIELD,
            "body.arguments.side",
        ),
        (_call("watch", {"a": "x", "margin": 0.1}), E.MISSING_FIELD, "body.arguments.b"),
        (
            _call("watch_self", {"robot": "r", "margin": 0.1, "exclude": [["a"]]}),
            E.WRONG_SHAPE,
            "body.arguments.exclude[0]",
        ),
        (
            _call("watch_environment", {"robot": "r", "margin": 0.1, "objects": [1]}),
            E.WRONG_TYPE,
            "body.arguments.objects[0]",
        ),
        (_raw("query", {"pairs": [["a", 3]]}), E.WRONG_TYPE, "body.pairs[0][1]"),
        (_raw("query", {"joints": {"r": _arr(np.array([np.nan]))}}), E.NON_FINITE, "body.joints.r"),
        (_raw("query", {"poses": {"p": _arr(np.zeros((4, 4, 1)))}}), E.WRONG_SHAPE, "body.poses.p"),
        (_call("add_robot", {"robot": {"name": "r", "x": {1: 2}}}), E.BAD_MESSAGE, "message"),
        (
            _call("add_robot", {"robot": {"name": "r", "joints": [{}] * 65}}),
            E.WRONG_SHAPE,
            "body.arguments.robot.joints",
        ),
        (
            _call("add_robot", {"robot": {"name": "r", "blob": b"\x00"}}),
            E.WRONG_TYPE,
            "body.arguments.robot.blob",
        ),
        (_call("describe", {"clouds": "yes"}), E.WRONG_TYPE, "body.arguments.clouds"),
        # the checks the messages' type hints make: names, finite stamps and joint
        # values, pose shapes, unknown and missing fields, list entries
        (
            _raw("add_object", {"name": "a\x00b", "cloud": _arr(np.zeros((2, 3)))}),
            E.WRONG_TYPE,
            "body.name",
        ),
        (
            _raw(
                "add_object",
                {"name": "p", "cloud": _arr(np.zeros((2, 3))), "pose": _arr(np.eye(3))},
            ),
            E.WRONG_SHAPE,
            "body.pose",
        ),
        (_raw("add_object", {"cloud": _arr(np.zeros((2, 3)))}), E.MISSING_FIELD, "body.name"),
        (
            _call("add_robot", {"robot": _ONE_JOINT, "q": _arr(np.array([np.nan]))}),
            E.NON_FINITE,
            "body.arguments.q",
        ),
        (
            _call("add_robot", {"robot": _ONE_JOINT, "colour": 1}),
            E.UNKNOWN_FIELD,
            "body.arguments.colour",
        ),
        (_raw("hello", {"client": "t", "versions": [1, "2"]}), E.WRONG_TYPE, "body.versions[1]"),
    ],
)
def test_bad_requests_are_typed_errors(raw: bytes, code: P.ErrorCode, field: str) -> None:
    assert _code(raw) == (code, field)


def test_size_cap_is_checked_before_decoding() -> None:
    big = _raw("add_object", {"name": "p", "cloud": _arr(np.zeros((5000, 3)))})
    assert len(big) > LIMITS.max_message_bytes
    assert _code(big) == (E.TOO_LARGE, "message")
    # garbage of that size is refused by its size, never handed to msgpack
    assert _code(b"\xc1" * (LIMITS.max_message_bytes + 1)) == (E.TOO_LARGE, "message")


def test_request_id_is_echoed_in_errors() -> None:
    with pytest.raises(P.ProtocolError) as info:
        P.decode_request(_raw("set_joints", {"robot": "r"}, rid=42), LIMITS)
    assert info.value.request_id == 42


def test_extension_types_and_deep_nesting_are_refused() -> None:
    ext = msgpack.packb({"v": 1, "id": 1, "op": "health", "body": msgpack.ExtType(5, b"abc")})
    assert _code(ext)[0] == E.BAD_MESSAGE
    stamp = msgpack.packb({"v": 1, "id": 1, "op": "health", "body": msgpack.Timestamp(1, 0)})
    assert _code(stamp)[0] == E.BAD_MESSAGE
    # 100 000 nested one-element arrays as the body, written by hand (msgpack's own
    # packer refuses that depth): the decoder must refuse it, not overflow its stack
    head = b"\x84" + b"".join(msgpack.packb(x) for x in ("v", 1, "id", 1, "op", "health", "body"))
    nested = head + b"\x91" * 100_000 + b"\x01"
    code, _ = _code(nested, P.Limits(max_message_bytes=1 << 20))
    assert code in (E.BAD_MESSAGE, E.WRONG_TYPE)


# ------------------------------------------------------------------ fuzzing the decoder

_FUZZ = settings(
    max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow], database=None
)
_leaf = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(min_value=-(2**63), max_value=2**64 - 1),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=20),
    st.binary(max_size=64),
)
_values = st.recursive(
    _leaf,
    lambda inner: st.one_of(
        st.lists(inner, max_size=5), st.dictionaries(st.text(max_size=8), inner, max_size=5)
    ),
    max_leaves=30,
)
_keys = st.sampled_from(
    [
        "v",
        "id",
        "op",
        "body",
        "robot",
        "q",
        "name",
        "cloud",
        "pose",
        "pairs",
        "joints",
        "stamp",
        "margin",
        "a",
        "b",
        "kind",
        "clouds",
        "x",
    ]
)


def _decodes_or_typed_error(raw: bytes) -> None:
    try:
        rid, req = P.decode_request(raw, LIMITS)
    except P.ProtocolError as exc:
        assert isinstance(exc.code, P.ErrorCode) and isinstance(exc.field, str) and exc.message
    else:
        assert isinstance(req, P.Request) and isinstance(rid, int)


@_FUZZ
@given(st.binary(max_size=512))
def test_fuzz_random_bytes(raw: bytes) -> None:
    _decodes_or_typed_error(raw)


@_FUZZ
@given(
    op=st.one_of(st.sampled_from(sorted(P.REQUESTS)), st.text(max_size=10)),
    body=st.dictionaries(_keys, _values, max_size=6),
    v=st.one_of(st.just(1), _leaf),
    rid=st.one_of(st.integers(min_value=0, max_value=2**40), _leaf),
)
def test_fuzz_structured_messages(op: str, body: dict[str, Any], v: Any, rid: Any) -> None:
    _decodes_or_typed_error(
        msgpack.packb({"v": v, "id": rid, "op": op, "body": body}, use_bin_type=True)
    )


@_FUZZ
@given(data=st.data())
def test_fuzz_mutated_valid_requests(crane: Robot, data: st.DataObject) -> None:
    reqs = [r for r in sample_requests(crane) if not type(r).DATA_FRAMES]
    raw = bytearray(P.encode_request(1, data.draw(st.sampled_from(reqs))))
    for _ in range(data.draw(st.integers(1, 4))):
        i = data.draw(st.integers(0, len(raw) - 1))
        action = data.draw(st.sampled_from(["flip", "cut", "insert"]))
        if action == "flip":
            raw[i] ^= data.draw(st.integers(1, 255))
        elif action == "cut":
            del raw[i:]
            if not raw:
                raw.append(0)
        else:
            raw[i:i] = data.draw(st.binary(min_size=1, max_size=8))
    _decodes_or_typed_error(bytes(raw))


def _float_vector(n: int, values: list[float]) -> list[Any]:
    return [P.FLOAT, [n], np.asarray(values, dtype="<f8").tobytes()]


_stamps = st.one_of(
    st.none(), st.floats(), st.integers(-(2**40), 2**40), st.booleans(), st.text(max_size=3)
)
_names = st.one_of(
    st.sampled_from(["crane", "hiab-xs033", "", "a\nb", "x" * 201]), st.integers(0, 3)
)
_vectors = st.one_of(
    st.lists(st.floats(), min_size=0, max_size=7).map(lambda v: _float_vector(len(v), v)),
    st.lists(st.floats(), min_size=1, max_size=7).map(lambda v: _float_vector(len(v) + 1, v)),
    st.just(["<f4", [2], b"\0" * 8]),
    st.just([P.FLOAT, [2, 1], b"\0" * 16]),
    st.just([P.FLOAT, [True], b"\0" * 8]),
    _leaf,
)


def _full_parse(cls: type[P.Request], body: Any) -> P.Request | None:
    try:
        r = P.Reader(body)
        out = cls.parse(r, P.DEFAULT_LIMITS)
        r.done()
    except P.ProtocolError:
        return None
    return out


@settings(max_examples=300, deadline=None)
@given(
    stamp=_stamps,
    layout=st.one_of(st.none(), st.text(max_size=4), st.just("l" * 201), st.integers(-5, 5)),
    joints=st.one_of(st.none(), st.dictionaries(_names, _vectors, max_size=3), _leaf),
    extra=st.sampled_from([{}, {"poses": None}, {"pairs": [["a", "b"]]}, {"bogus": 1}]),
    drop=st.sets(st.sampled_from(["stamp", "layout", "joints"])),
)
def test_fast_query_parser_agrees_with_the_full_one(
    stamp: Any, layout: Any, joints: Any, extra: dict[str, Any], drop: set[str]
) -> None:
    """The hot-path parser accepts only what the full parser accepts, and builds the
    same request; everything else falls through to the full parser's typed errors."""
    body = {"stamp": stamp, "layout": layout, "joints": joints, **extra}
    for k in drop:
        body.pop(k)
    fast = codec._fast_query(body)
    full = _full_parse(P.Query, body)
    if fast is not None:
        assert full is not None and _equal(fast, full), (fast, full)
    # and the whole decoder gives the full parser's answer either way
    raw = msgpack.packb({"v": 1, "id": 3, "op": "query", "body": body}, use_bin_type=True)
    try:
        _, dec = P.decode_request(raw)
    except P.ProtocolError:
        assert full is None
    else:
        assert full is not None and _equal(dec, full)


@settings(max_examples=200, deadline=None)
@given(robot=_names, q=_vectors, stamp=_stamps, extra=st.sampled_from([{}, {"x": 1}]))
def test_fast_set_joints_parser_agrees_with_the_full_one(
    robot: Any, q: Any, stamp: Any, extra: dict[str, Any]
) -> None:
    body = {"robot": robot, "q": q, "stamp": stamp, **extra}
    fast = codec._fast_set_joints(body)
    full = _full_parse(P.SetJoints, body)
    if fast is not None:
        assert full is not None and _equal(fast, full)


# ------------------------------------------------------------------ hot-path corpus
#
# The fast parsers may decline a message (the full parser then decides), so the
# agreement tests above pass for a parser that always declines. The hot path exists
# for the per-tick messages as clients send them: every one of these must be taken by
# the fast parser and give exactly the full parser's request.

_hot_names = st.text(
    alphabet="abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789-_/.",
    min_size=1,
    max_size=40,
)
_finite = st.floats(allow_nan=False, allow_infinity=False, width=64)
_joint_vectors = st.lists(_finite, min_size=1, max_size=12).map(np.array)
_hot_stamps = st.one_of(st.none(), _finite)


def _wire_body(request: P.Request) -> Any:
    """The body as the server sees it: encoded by the client's encoder, unpacked."""
    return msgpack.unpackb(P.encode_request(7, request), raw=False)["body"]


@settings(max_examples=200, deadline=None)
@given(
    stamp=_hot_stamps,
    joints=st.one_of(
        st.none(), st.dictionaries(_hot_names, _joint_vectors, min_size=1, max_size=3)
    ),
    layout=st.one_of(st.none(), _hot_names),
)
def test_fast_query_parser_takes_every_valid_tick_query(
    stamp: float | None, joints: dict[str, Any] | None, layout: str | None
) -> None:
    req = P.Query(stamp, joints, None, None, layout)
    body = _wire_body(req)
    fast = codec._fast_query(body)
    assert fast is not None, body
    full = _full_parse(P.Query, body)
    assert full is not None and _equal(fast, full) and _equal(fast, req)
    _, dec = P.decode_request(P.encode_request(7, req))
    assert _equal(dec, req)


@settings(max_examples=200, deadline=None)
@given(robot=_hot_names, q=_joint_vectors, stamp=_hot_stamps)
def test_fast_set_joints_parser_takes_every_valid_joint_state(
    robot: str, q: np.ndarray, stamp: float | None
) -> None:
    req = P.SetJoints(robot, q, stamp)
    body = _wire_body(req)
    fast = codec._fast_set_joints(body)
    assert fast is not None, body
    full = _full_parse(P.SetJoints, body)
    assert full is not None and _equal(fast, full) and _equal(fast, req)


@settings(max_examples=200, deadline=None)
@given(
    seq=st.integers(0, 2**40),
    measured=_finite,
    compute=st.floats(0.0, 10.0),
    layout=_hot_names,
    rows=st.lists(
        st.tuples(
            st.lists(_finite, min_size=10, max_size=10),
            st.integers(-1, 10_000),
            st.integers(-1, 10_000),
            st.booleans(),
        ),
        max_size=5,
    ),
)
def test_fast_query_reply_parser_takes_every_valid_reply(
    seq: int, measured: float, compute: float, layout: str, rows: list[Any]
) -> None:
    arr = np.array([[*r, float(ia), float(ib), float(flag)] for r, ia, ib, flag in rows])
    rep = P.QueryReply(seq, measured, compute, layout, None, arr.reshape(len(rows), 13))
    body = msgpack.unpackb(P.encode_reply(7, rep), raw=False)["body"]
    fast = codec._fast_query_reply(body)
    assert fast is not None, body
    r = P.Reader(body)
    full = P.QueryReply.parse(r)
    r.done()
    assert _equal(fast, full) and _equal(fast, rep)


def _index_row(r: list[float]) -> list[float]:
    """Mostly valid index and flag columns (sometimes not: NaN, inf stay as drawn)."""
    ia = float(round(r[10] % 5)) if math.isfinite(r[10]) else r[10]
    flag = float(r[12] > 0) if math.isfinite(r[12]) else r[12]
    return [*r[:10], ia, -1.0, flag]


@settings(max_examples=200, deadline=None)
@given(
    seq=st.one_of(st.integers(-2, 2**40), st.floats(), st.booleans()),
    measured=st.one_of(st.floats(), st.integers(-5, 5)),
    compute=st.one_of(st.floats(), st.integers(-5, 5)),
    rows=st.lists(st.lists(st.floats(), min_size=13, max_size=13).map(_index_row), max_size=4),
    cols=st.sampled_from([13, 12]),
    pairs=st.sampled_from([None, "omit", []]),
)
def test_fast_query_reply_parser_agrees_with_the_full_one(
    seq: Any, measured: Any, compute: Any, rows: list[list[float]], cols: int, pairs: Any
) -> None:
    arr = np.asarray(rows, dtype="<f8").reshape(len(rows), 13)[:, :cols]
    body: dict[str, Any] = {
        "sequence": seq, "measured_at": measured, "compute_time": compute, "layout": "x-1",
        "rows": [P.FLOAT, [len(rows), cols], arr.tobytes()], "pairs": pairs,
    }  # fmt: skip
    if pairs == "omit":
        del body["pairs"]
    fast = codec._fast_query_reply(body)
    try:
        r = P.Reader(body)
        full: P.QueryReply | None = P.QueryReply.parse(r)
        r.done()
    except P.ProtocolError:
        full = None
    if fast is not None:
        assert full is not None and _equal(fast, full)
