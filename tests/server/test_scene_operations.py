"""A scene query written once: registered in this test with ``scene_operation`` and
nothing else, it answers in process and through a real collision server on 127.0.0.1
alike; its wire messages come from its type hints, checked strictly."""

from __future__ import annotations

import inspect
import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Literal

import numpy as np
import pytest
from numpy.typing import NDArray

from reachwise.distance.pairs import PairKind, WatchedPair
from reachwise.distance.scene import Scene
from reachwise.distance.scene_ops import OPERATIONS, scene_change, scene_operation
from reachwise.errors import InputError
from reachwise.kinematics.robot import Robot
from reachwise.server import protocol as P
from reachwise.server.client import SceneClient
from reachwise.server.client.errors import ServerInputError
from reachwise.server.transport import CollisionServer

from .conftest import HANG_GUARD, LINKS, build_scene, crane_q


@dataclass(frozen=True)
class Closest:
    """The closest watched pair of one kind, its distance and its closest points."""

    a: str
    b: str
    distance: float
    points: NDArray[np.float64]
    within: tuple[str, ...]


@scene_operation
def closest_of_kind(
    scene: Scene, kind: PairKind, within: float = math.inf, order: Literal["a", "b"] = "a"
) -> Closest | None:
    """The toy query: the closest answered pair of ``kind``, with the names of the
    objects (side ``order``) of every pair of that kind closer than ``within``."""
    res = scene.query_all()
    rows = [p for p in res.pairs if p.kind == kind]
    if not rows:
        return None
    best = min(rows, key=lambda p: p.result.distance)
    near = tuple(sorted(p.a if order == "a" else p.b for p in rows if p.result.distance < within))
    r = best.result
    return Closest(best.a, best.b, r.distance, np.vstack([r.point_a, r.point_b]), near)


@scene_change
def watch_against(
    scene: Scene, target: str, margin: float, kind: PairKind = "custom"
) -> tuple[WatchedPair, ...]:
    """The toy change: every other object watched against ``target``, in name order."""
    others = sorted(n for n in scene.objects if n != target)
    return tuple(scene.watch(n, target, margin, kind=kind) for n in others)


@pytest.fixture(scope="module")
def served() -> Iterator[str]:
    with CollisionServer("tcp://127.0.0.1:*").background() as endpoint:
        yield endpoint


def test_a_query_written_once_answers_in_process_and_through_the_server(
    served: str, crane: Robot, clouds: dict[str, NDArray[np.float64]]
) -> None:
    local = Scene()
    build_scene(local, crane, clouds)
    with SceneClient(served, deadline=HANG_GUARD, setup_deadline=HANG_GUARD) as client:
        client.clear()
        build_scene(client, crane, clouds)
        for k in (0, 40, 300):
            q = crane_q(crane, k)
            local.set_joints(crane.name, q)
            client.set_joints(crane.name, q)
            for kind in ("self", "robot-environment"):
                here = closest_of_kind(local, kind, within=1.0, order="b")
                there = closest_of_kind(client, kind, within=1.0, order="b")
                assert here is not None and there is not None
                assert (there.a, there.b, there.within) == (here.a, here.b, here.within)
                assert there.distance == pytest.approx(here.distance, abs=1e-12)
                np.testing.assert_allclose(there.points, here.points, rtol=0, atol=1e-12)
                assert isinstance(there.within, tuple)
            assert (
                closest_of_kind(client, "robot-robot")
                is None
                is closest_of_kind(local, "robot-robot")
            )


def test_a_change_written_once_changes_both_scenes_alike(
    served: str, crane: Robot, clouds: dict[str, NDArray[np.float64]]
) -> None:
    local = Scene()
    build_scene(local, crane, clouds)
    with SceneClient(served, deadline=HANG_GUARD, setup_deadline=HANG_GUARD, mirror=True) as client:
        client.clear()
        build_scene(client, crane, clouds)
        client.query_all()  # the client holds the layout from before the change
        here = watch_against(local, "environment", 0.9, kind="robot-environment")
        there = watch_against(client, "environment", 0.9, kind="robot-environment")
        assert there == here and len(here) == len(LINKS)
        assert client.pairs == local.pairs  # the mirror made the same change
        served_pairs = client.describe().pairs
        assert [(p.a, p.b, p.margin, p.kind) for p in served_pairs] == [
            (p.a, p.b, p.margin, p.kind) for p in local.pairs
        ]
        q = crane_q(crane, 120)
        local.set_joints(crane.name, q)
        client.set_joints(crane.name, q)
        res, ref = client.query_all(), local.query_all()
        assert res.valid, res.reason  # the server's pair list is the mirror's
        for p in ref.pairs:
            assert res.get(p.a, p.b).result.distance == pytest.approx(p.result.distance, abs=1e-12)
        client.unwatch("link_1", "environment")
        local.unwatch("link_1", "environment")
        assert client.pairs == local.pairs and client.query_all().valid


def test_the_clients_pair_rules_are_the_scenes() -> None:
    for name in ("watch", "unwatch", "watch_self", "watch_environment", "watch_robots"):
        assert inspect.signature(getattr(SceneClient, name)) == inspect.signature(
            getattr(Scene, name)
        )
        assert OPERATIONS[name].mutates


def test_wrong_arguments_are_typed_errors(served: str, crane: Robot) -> None:
    with SceneClient(served, deadline=HANG_GUARD, setup_deadline=HANG_GUARD) as client:
        with pytest.raises(ServerInputError) as info:
            closest_of_kind(client, "no-such-kind")  # type: ignore[arg-type]
        assert info.value.code == P.ErrorCode.INVALID and info.value.field.endswith("kind")
        with pytest.raises(ServerInputError) as info:
            closest_of_kind(client, "self", within="far")  # type: ignore[arg-type]
        assert info.value.code == P.ErrorCode.WRONG_TYPE
        with pytest.raises(InputError, match="unknown argument"):
            closest_of_kind(client, "self", nearest=1.0)  # type: ignore[call-arg]
        with pytest.raises(InputError, match="missing"):
            closest_of_kind(client)  # type: ignore[call-arg]


def _body(operation: object, arguments: object) -> bytes:
    import msgpack

    env = {"v": 1, "id": 3, "op": "call", "body": {"operation": operation, "arguments": arguments}}
    return msgpack.packb(env, use_bin_type=True)


@pytest.mark.parametrize(
    ("operation", "arguments", "code"),
    [
        ("no_such_operation", {}, P.ErrorCode.UNKNOWN_OP),
        ("closest_of_kind", {}, P.ErrorCode.MISSING_FIELD),
        ("closest_of_kind", {"kind": "self", "bogus": 1}, P.ErrorCode.UNKNOWN_FIELD),
        ("closest_of_kind", {"kind": "self", "within": float("nan")}, P.ErrorCode.NON_FINITE),
        ("closest_of_kind", {"kind": ["self"]}, P.ErrorCode.INVALID),
        ("closest_of_kind", {"kind": "self", "within": True}, P.ErrorCode.WRONG_TYPE),
        ("closest_of_kind", [], P.ErrorCode.WRONG_TYPE),
        (["closest_of_kind"], {}, P.ErrorCode.WRONG_TYPE),
    ],
)
def test_calls_are_checked_against_the_type_hints(
    operation: object, arguments: object, code: P.ErrorCode
) -> None:
    with pytest.raises(P.ProtocolError) as info:
        P.decode_request(_body(operation, arguments))
    assert info.value.code == code


def test_a_call_round_trips(crane: Robot) -> None:
    call = P.OperationCall("closest_of_kind", {"kind": "self", "within": 0.5})
    rid, back = P.decode_request(P.encode_request(9, call))
    assert rid == 9 and isinstance(back, P.OperationCall)
    assert back.operation == call.operation and back.arguments == call.arguments


def test_results_round_trip_and_are_checked() -> None:
    value = Closest("x", "y", 0.25, np.arange(6.0).reshape(2, 3), ("p", "q"))
    hint = OPERATIONS["closest_of_kind"].result
    back = P.decode_value(P.encode_value(value, hint), hint, "result")
    assert isinstance(back, Closest) and back.within == ("p", "q")
    np.testing.assert_array_equal(back.points, value.points)
    assert P.decode_value(P.encode_value(None, hint), hint, "result") is None
    broken = P.encode_value(value, hint)
    broken["distance"] = "near"
    with pytest.raises(P.ProtocolError) as info:
        P.decode_value(broken, hint, "result")
    assert info.value.field == "result.distance"
    del broken["distance"]
    with pytest.raises(P.ProtocolError) as info:
        P.decode_value(broken, hint, "result")
    assert info.value.code == P.ErrorCode.MISSING_FIELD


def test_registering_a_name_twice_is_refused() -> None:
    def closest_of_kind(scene: Scene) -> int:
        return 0

    with pytest.raises(ValueError, match="registered already"):
        scene_operation(closest_of_kind)
