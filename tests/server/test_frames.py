"""Raw frames on the wire: streamed clouds (header + data frame, no copy), the binary
tick each way, their typed errors, and fuzzing of both decoders."""

from __future__ import annotations

import math
import struct
from typing import Any

import msgpack
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from reachwise.server import protocol as P
from reachwise.server.protocol import tick as T

E = P.ErrorCode
LIMITS = P.Limits(max_message_bytes=64 * 1024, max_cloud_points=1000)
_FUZZ = settings(
    max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow], database=None
)

PAIRS = (
    P.PairInfo("grabber", "rock", 0.5, "robot-environment"),
    P.PairInfo("boom", "probe", math.inf, "custom"),
    P.PairInfo("boom", "grabber", 0.2, "self"),
)
LAYOUT = P.Layout((7 << 32) | 3, PAIRS, ("boom", "grabber", "rock", "probe"), ("crane", "arm"))


def _header(body: dict[str, Any], op: str = "replace_cloud", rid: int = 5) -> bytes:
    return msgpack.packb({"v": 1, "id": rid, "op": op, "body": body}, use_bin_type=True)


def _cloud_body(n: int, dtype: str = "<f4", **extra: Any) -> dict[str, Any]:
    return {"name": "camera", "points": n, "dtype": dtype, **extra}


# ------------------------------------------------------------------ streamed clouds


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_a_cloud_travels_without_a_copy_either_way(dtype: type) -> None:
    cloud = np.random.default_rng(1).normal(size=(200, 3)).astype(dtype)
    frames = P.encode_frames(9, P.ReplaceCloud("camera", cloud, 3.25, block=True))
    assert len(frames) == 2
    header = msgpack.unpackb(frames[0])["body"]
    assert header == {
        "name": "camera",
        "points": 200,
        "dtype": np.dtype(dtype).str,
        "stamp": 3.25,
        "block": True,
    }
    assert np.shares_memory(np.frombuffer(frames[1], dtype=dtype), cloud)  # sent as it is
    rid, req = P.decode_frames(frames, LIMITS)
    assert rid == 9 and isinstance(req, P.ReplaceCloud)
    assert np.shares_memory(req.cloud, cloud)  # viewed where it was received
    assert req.cloud.dtype == dtype and (req.stamp, req.block) == (3.25, True)
    np.testing.assert_array_equal(req.cloud, cloud)


def test_other_arrays_are_sent_as_float64_copies() -> None:
    strided = np.arange(60, dtype=np.float64).reshape(10, 6)[:, :3]
    req = P.ReplaceCloud("c", strided)
    assert req.cloud.flags.c_contiguous and req.cloud.dtype == np.float64
    np.testing.assert_array_equal(req.cloud, strided)
    for other in (strided.astype(">f8"), strided.astype(np.float16), strided.tolist()):
        sent = P.ReplaceCloud("c", other).cloud  # type: ignore[arg-type]
        assert sent.dtype.str == "<f8"
        np.testing.assert_array_equal(sent, strided)


@pytest.mark.parametrize(
    ("frames", "code", "field"),
    [
        ([_header(_cloud_body(10)), b"\0" * 119], E.WRONG_SHAPE, "cloud"),
        ([_header(_cloud_body(10, "<f8")), b"\0" * 120], E.WRONG_SHAPE, "cloud"),
        ([_header(_cloud_body(10, "<f2")), b"\0" * 60], E.WRONG_TYPE, "body.dtype"),
        ([_header(_cloud_body(10, ">f4")), b"\0" * 120], E.WRONG_TYPE, "body.dtype"),
        ([_header(_cloud_body(0)), b""], E.WRONG_SHAPE, "body.points"),
        ([_header(_cloud_body(-1)), b""], E.WRONG_TYPE, "body.points"),
        ([_header(_cloud_body(1001)), b"\0" * 12012], E.OVERSIZED_CLOUD, "body.points"),
        ([_header(_cloud_body(True)), b"\0" * 12], E.WRONG_TYPE, "body.points"),  # type: ignore[arg-type]
        ([_header(_cloud_body(1, stamp=math.nan)), b"\0" * 12], E.NON_FINITE, "body.stamp"),
        ([_header(_cloud_body(1, block=1)), b"\0" * 12], E.WRONG_TYPE, "body.block"),
        ([_header(_cloud_body(1, cloud=[1])), b"\0" * 12], E.UNKNOWN_FIELD, "body.cloud"),
        ([_header({"points": 1, "dtype": "<f4"}), b"\0" * 12], E.MISSING_FIELD, "body.name"),
        ([_header(_cloud_body(1))], E.BAD_MESSAGE, "frames"),  # no data frame
        ([_header(_cloud_body(1)), b"\0" * 12, b"\0" * 12], E.BAD_MESSAGE, "frames"),
        ([_header({}, "health"), b"\0" * 12], E.BAD_MESSAGE, "frames"),  # health takes none
        ([b"\xc1", b"\0" * 12], E.BAD_MESSAGE, "message"),
        ([_header(_cloud_body(1)), b"\0" * (LIMITS.max_message_bytes + 1)], E.TOO_LARGE, "message"),
        ([], E.BAD_MESSAGE, "frames"),
    ],
)
def test_malformed_cloud_messages_are_typed_errors(
    frames: list[bytes], code: P.ErrorCode, field: str
) -> None:
    with pytest.raises(P.ProtocolError) as info:
        P.decode_frames(frames, LIMITS)
    assert (info.value.code, info.value.field) == (code, field)


def test_encode_request_refuses_what_needs_data_frames() -> None:
    """A request with data frames is not one frame: the single-frame decoder says so."""
    frames = P.encode_frames(1, P.ReplaceCloud("c", np.zeros((2, 3))))
    with pytest.raises(P.ProtocolError) as info:
        P.decode_request(frames[0], LIMITS)
    assert (info.value.code, info.value.field, info.value.request_id) == (
        E.BAD_MESSAGE,
        "frames",
        1,
    )


_DTYPES = st.sampled_from(["<f4", "<f8", "<f2", ">f4", "<i8", "f8", "", 3, None])


@_FUZZ
@given(
    body=st.fixed_dictionaries(
        {},
        optional={
            "name": st.one_of(st.text(max_size=5), st.integers(-(2**63), 2**63 - 1)),
            "points": st.one_of(st.integers(-3, 1200), st.floats(), st.booleans()),
            "dtype": _DTYPES,
            "stamp": st.one_of(st.floats(), st.integers(-(2**40), 2**40), st.text(max_size=2)),
            "block": st.one_of(st.booleans(), st.integers(0, 2)),
            "extra": st.integers(0, 9),
        },
    ),
    data=st.lists(st.binary(max_size=200), max_size=3),
)
def test_fuzz_cloud_messages(body: dict[str, Any], data: list[bytes]) -> None:
    frames = [_header(body), *data]
    try:
        _, req = P.decode_frames(frames, LIMITS)
    except P.ProtocolError as exc:
        assert isinstance(exc.code, P.ErrorCode) and exc.message
        return
    # accepted: exactly one data frame holding the points the header announces
    assert isinstance(req, P.ReplaceCloud) and len(data) == 1
    assert req.cloud.shape == (body["points"], 3) and req.cloud.dtype.str == body["dtype"]
    assert req.cloud.nbytes == len(data[0])


# ------------------------------------------------------------------ ticks


def _query(joints: dict[str, np.ndarray] | None, poses: dict[str, np.ndarray] | None) -> P.Query:
    return P.Query(12.5, joints, poses, None, LAYOUT.name)


def _full(query: P.Query) -> P.Query:
    """The same query through the full protocol (msgpack, field by field)."""
    return P.decode_request(P.encode_request(3, query))[1]  # type: ignore[return-value]


def _same_query(a: P.Query, b: P.Query) -> None:
    assert (a.stamp, a.pairs, a.layout) == (b.stamp, b.pairs, b.layout)
    for x, y in ((a.joints, b.joints), (a.poses, b.poses)):
        assert (x is None) == (y is None)
        if x is not None and y is not None:
            assert list(x) == list(y)
            for k in x:
                np.testing.assert_array_equal(x[k], y[k])


_finite = st.floats(allow_nan=False, allow_infinity=False, width=64)


@settings(max_examples=200, deadline=None)
@given(
    robots=st.lists(st.sampled_from(LAYOUT.robots), unique=True, max_size=2),
    dofs=st.lists(st.integers(0, 9), min_size=2, max_size=2),
    objects=st.lists(st.sampled_from(LAYOUT.objects), unique=True, max_size=3),
    seed=st.integers(0, 1000),
    stamp=st.one_of(st.none(), _finite),
)
def test_a_tick_stands_for_the_full_query(
    robots: list[str], dofs: list[int], objects: list[str], seed: int, stamp: float | None
) -> None:
    rng = np.random.default_rng(seed)
    joints = {r: rng.normal(size=d) for r, d in zip(robots, dofs, strict=False)} or None
    poses = {o: rng.normal(size=(4, 4)) for o in objects} or None
    query = P.Query(stamp, joints, poses, None, LAYOUT.name)
    raw = P.encode_tick(11, query, LAYOUT)
    assert raw is not None and P.is_tick(raw)
    rid, back = P.decode_tick(raw, LAYOUT, P.DEFAULT_LIMITS)
    assert rid == 11
    _same_query(back, query)
    _same_query(back, _full(query))


def test_what_a_tick_cannot_carry_goes_in_full() -> None:
    q = np.zeros(3)
    assert P.encode_tick(1, P.Query(1.0, {"nobody": q}, None, None, LAYOUT.name), LAYOUT) is None
    assert (
        P.encode_tick(1, P.Query(1.0, None, {"ghost": np.eye(4)}, None, LAYOUT.name), LAYOUT)
        is None
    )
    assert (
        P.encode_tick(1, P.Query(1.0, None, None, (("boom", "rock"),), LAYOUT.name), LAYOUT) is None
    )
    assert P.encode_tick(1, P.Query(1.0, None, None, None, "123"), LAYOUT) is None
    assert (
        P.encode_tick(1, P.Query(1.0, {"crane": np.zeros((2, 2))}, None, None, LAYOUT.name), LAYOUT)
        is None
    )
    one_off = P.Layout(0, PAIRS, LAYOUT.objects, LAYOUT.robots)
    assert P.encode_tick(1, P.Query(1.0, None, None, None, ""), one_off) is None


def _tick(
    rid: int, key: int, stamp: float, entries: list[tuple[int, int]], values: list[float], nj: int
) -> bytes:
    head = struct.pack("<4sIQQdII", T.TICK_MAGIC, 0, rid, key, stamp, nj, len(entries) - nj)
    ent = np.array(entries, dtype="<i4").reshape(-1).tobytes()
    return head + ent + np.array(values, dtype="<f8").tobytes()


K = LAYOUT.key


@pytest.mark.parametrize(
    ("raw", "code", "field"),
    [
        (b"RWq\x01" + b"\0" * 10, E.BAD_MESSAGE, "message"),
        (_tick(1, K, 1.0, [], [], 0)[:-1], E.BAD_MESSAGE, "message"),
        (_tick(1, K + 1, 1.0, [], [], 0), E.STALE_LAYOUT, "layout"),
        (_tick(1, 0, 1.0, [], [], 0), E.STALE_LAYOUT, "layout"),
        (_tick(2**63, K, 1.0, [], [], 0), E.BAD_MESSAGE, "id"),
        (_tick(1, K, math.inf, [], [], 0), E.NON_FINITE, "body.stamp"),
        (_tick(1, K, 1.0, [], [1.0], 0), E.WRONG_SHAPE, "values"),
        (_tick(1, K, 1.0, [(0, 2)], [1.0], 1), E.WRONG_SHAPE, "values"),
        (_tick(1, K, 1.0, [(0, -1)], [], 1), E.WRONG_SHAPE, "values"),
        (_tick(1, K, 1.0, [(2, 1)], [1.0], 1), E.WRONG_SHAPE, "entries[0]"),
        (_tick(1, K, 1.0, [(-1, 1)], [1.0], 1), E.WRONG_SHAPE, "entries[0]"),
        (_tick(1, K, 1.0, [(0, 2)], [1.0, math.nan], 1), E.NON_FINITE, "body.joints.crane"),
        (_tick(1, K, 1.0, [(0, 1), (0, 1)], [1.0, 2.0], 2), E.BAD_MESSAGE, "entries[1]"),
        (_tick(1, K, 1.0, [(3, 9)], [0.0] * 9, 0), E.WRONG_SHAPE, "body.poses.probe"),
        (_tick(1, K, 1.0, [(3, 16)], [math.inf] + [0.0] * 15, 0), E.NON_FINITE, "body.poses.probe"),
        (_tick(1, K, 1.0, [(0, 1)] * 3, [1.0] * 3, 3), E.WRONG_SHAPE, "entries"),
        (struct.pack("<4sIQQdII", T.TICK_MAGIC, 0, 1, K, 1.0, 1, 0), E.WRONG_SHAPE, "entries"),
    ],
)
def test_malformed_ticks_are_typed_errors(raw: bytes, code: P.ErrorCode, field: str) -> None:
    with pytest.raises(P.ProtocolError) as info:
        P.decode_tick(raw, LAYOUT, P.DEFAULT_LIMITS)
    assert (info.value.code, info.value.field) == (code, field)


def test_tick_flags_and_size_cap() -> None:
    raw = bytearray(_tick(4, K, 1.0, [], [], 0))
    raw[4] = 1
    with pytest.raises(P.ProtocolError) as info:
        P.decode_tick(bytes(raw), LAYOUT, P.DEFAULT_LIMITS)
    assert (info.value.code, info.value.request_id) == (E.BAD_MESSAGE, 4)
    big = _tick(1, K, 1.0, [(0, 9000)], [0.0] * 9000, 1)
    with pytest.raises(P.ProtocolError) as info:
        P.decode_tick(big, LAYOUT, LIMITS)
    assert info.value.code == E.TOO_LARGE


def _reply(seed: int) -> P.QueryReply:
    rng = np.random.default_rng(seed)
    rows = rng.normal(size=(len(PAIRS), P.ROW_COLUMNS))
    rows[:, 10:12] = rng.integers(-1, 50, size=(len(PAIRS), 2))
    rows[:, 12] = rng.integers(0, 2, size=len(PAIRS))
    clouds = np.column_stack(
        [rng.integers(0, 9, len(LAYOUT.objects)), rng.normal(size=len(LAYOUT.objects))]
    )
    clouds[0, 1] = math.inf
    return P.QueryReply(17, 2.5, 1e-4, LAYOUT.name, None, rows, clouds=clouds)


def test_a_tick_reply_round_trips_and_equals_the_full_reply() -> None:
    rep = _reply(3)
    raw = P.encode_tick_reply(8, rep, LAYOUT)
    assert P.is_tick_reply(raw) and not P.is_tick(raw)
    rid, back = P.decode_tick_reply(raw, LAYOUT)
    full = P.decode_reply(P.encode_reply(8, rep), P.QueryReply).reply
    assert rid == 8 and isinstance(full, P.QueryReply)
    for r in (back, full):
        assert (r.sequence, r.measured_at, r.compute_time, r.layout, r.pairs) == (
            17,
            2.5,
            1e-4,
            LAYOUT.name,
            None,
        )
        np.testing.assert_array_equal(r.rows, rep.rows)
        assert r.clouds is not None
        np.testing.assert_array_equal(r.clouds, rep.clouds)


@pytest.mark.parametrize(
    "mutate",
    [
        lambda b: b[:-8],  # a row short
        lambda b: b[:4] + b"\1" + b[5:],  # flags
        lambda b: b[:24] + struct.pack("<Q", K + 1) + b[32:],  # another layout
        lambda b: b[:48] + struct.pack("<I", 2) + b[52:],  # pair count
        lambda b: b[:32] + struct.pack("<d", math.nan) + b[40:],  # measured_at
        lambda b: b[:40] + struct.pack("<d", -1.0) + b[48:],  # compute_time
        lambda b: b"RWx\x01" + b[4:],
    ],
)
def test_malformed_tick_replies_are_typed_errors(mutate: Any) -> None:
    raw = mutate(P.encode_tick_reply(8, _reply(1), LAYOUT))
    with pytest.raises(P.ProtocolError):
        P.decode_tick_reply(raw, LAYOUT)


def _valid_ticks() -> list[bytes]:
    rng = np.random.default_rng(4)
    out = []
    for joints, poses in (
        (None, None),
        ({"crane": rng.normal(size=6)}, None),
        ({"arm": rng.normal(size=7), "crane": rng.normal(size=6)}, {"probe": np.eye(4)}),
    ):
        raw = P.encode_tick(5, _query(joints, poses), LAYOUT)
        assert raw is not None
        out.append(raw)
    return out


def _typed_or_query(raw: bytes) -> None:
    try:
        rid, q = P.decode_tick(raw, LAYOUT, LIMITS)
    except P.ProtocolError as exc:
        assert isinstance(exc.code, P.ErrorCode) and isinstance(exc.field, str) and exc.message
    else:
        assert isinstance(q, P.Query) and 0 <= rid < 2**63
        for v in (q.joints or {}).values():
            assert np.isfinite(v).all()


@_FUZZ
@given(st.binary(max_size=300))
def test_fuzz_random_ticks(raw: bytes) -> None:
    _typed_or_query(T.TICK_MAGIC + raw)


@_FUZZ
@given(data=st.data())
def test_fuzz_mutated_ticks_and_replies(data: st.DataObject) -> None:
    reply = P.encode_tick_reply(5, _reply(data.draw(st.integers(0, 50))), LAYOUT)
    raw = bytearray(data.draw(st.sampled_from([*_valid_ticks(), reply])))
    for _ in range(data.draw(st.integers(1, 4))):
        i = data.draw(st.integers(0, len(raw) - 1))
        action = data.draw(st.sampled_from(["flip", "cut", "insert"]))
        if action == "flip":
            raw[i] ^= data.draw(st.integers(1, 255))
        elif action == "cut":
            del raw[max(i, 1) :]
        else:
            raw[i:i] = data.draw(st.binary(min_size=1, max_size=16))
    _typed_or_query(bytes(raw))
    try:
        P.decode_tick_reply(bytes(raw), LAYOUT)
    except P.ProtocolError as exc:
        assert isinstance(exc.code, P.ErrorCode) and exc.message


def test_layout_keys_and_names() -> None:
    assert P.layout_key(LAYOUT.name) == LAYOUT.key
    for name in ("", "x-1", "00", "-5", "٣", str(2**64), "1" * 21):
        assert P.layout_key(name) == 0
    assert P.layout_key(str(2**64 - 1)) == 2**64 - 1
    np.testing.assert_array_equal(LAYOUT.pair_objects, [[1, 2], [0, 3], [0, 1]])
