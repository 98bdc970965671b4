"""The server's per-tick path (:meth:`SceneService.tick`): what it keeps between ticks
(the layout, the cloud table and its bytes) follows every change of the scene, its
answers are the in-process scene's, and a bad or failing tick is a typed error that
names its request."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.typing import NDArray

from reachwise.distance import Scene
from reachwise.kinematics.robot import Robot
from reachwise.server import protocol as P
from reachwise.server.counters import Metrics
from reachwise.server.service import SceneService

from .conftest import LINKS, box_points, crane_q
from .described import described

E = P.ErrorCode


def _both(crane: Robot, clouds: dict[str, NDArray[np.float64]]) -> tuple[SceneService, Scene]:
    """The crane scene on a service and, as the reference, in process."""
    svc = SceneService(clock=lambda: 1000.0)
    local = Scene()
    svc.handle(P.OperationCall.of("add_robot", crane, crane_q(crane, 0), stamp=1.0))
    local.add_robot(crane, crane_q(crane, 0), stamp=1.0)
    for link in LINKS:
        svc.handle(P.AddObject(link, clouds[link], None, crane.name, link))
        local.add_object(link, clouds[link], robot=crane.name, link=link)
    env = np.eye(4)
    env[0, 3] = 1.6
    svc.handle(P.AddObject("environment", clouds["environment"], env))
    local.add_object("environment", clouds["environment"], env)
    svc.handle(P.OperationCall.of("watch_environment", crane.name, 1.5))
    local.watch_environment(crane.name, 1.5)
    return svc, local


def _layout(svc: SceneService) -> P.Layout:
    """The layout a full query sends now."""
    layout = P.Layout.of(svc.handle(P.Query(2.0)))  # type: ignore[arg-type]
    assert layout is not None and layout.key
    return layout


def _tick(
    svc: SceneService, layout: P.Layout, rid: int, q: NDArray[np.float64], robot: str
) -> P.QueryReply:
    raw = P.encode_tick(rid, P.Query(5.0, {robot: q}, None, None, layout.name), layout)
    assert raw is not None
    payload, compute = svc.tick(raw, P.DEFAULT_LIMITS)
    got, reply = P.decode_tick_reply(payload, layout)
    assert got == rid and compute == reply.compute_time and compute > 0.0
    return reply


def _assert_as_in_process(reply: P.QueryReply, layout: P.Layout, local: Scene) -> None:
    """Rows, pair order and cloud table equal to the in-process scene's answer."""
    ref = local.query_all()
    assert layout.pairs == tuple(P.PairInfo(p.a, p.b, p.margin, p.kind) for p in local.pairs)
    np.testing.assert_array_equal(reply.rows, ref.rows)
    assert reply.clouds is not None
    versions = {n: int(v) for n, (v, _) in zip(layout.objects, reply.clouds, strict=True)}
    stamps = {n: float(s) for n, (_, s) in zip(layout.objects, reply.clouds, strict=True)}
    assert versions == dict(ref.versions) and stamps == dict(ref.cloud_stamps)


def test_what_the_tick_path_keeps_follows_every_change(
    crane: Robot, clouds: dict[str, NDArray[np.float64]]
) -> None:
    """Ticks between a cloud swap, a new pair, a new object and a removed pair: each
    answer equals the in-process scene's after the same changes (the kept cloud table
    and layout are replaced, never reused stale), and a tick under a replaced layout is
    refused."""
    svc, local = _both(crane, clouds)
    layout = _layout(svc)
    rid = 0

    def step(k: int) -> P.QueryReply:
        nonlocal rid
        rid += 1
        q = crane_q(crane, k)
        reply = _tick(svc, layout, rid, q, crane.name)
        local.set_joints(crane.name, q, stamp=5.0)
        _assert_as_in_process(reply, layout, local)
        return reply

    for k in range(0, 200, 40):
        step(k)
    # a new cloud: the same layout, a new cloud table
    moved = clouds["environment"] + np.array([0.0, 0.0, 0.3])
    svc.handle(P.ReplaceCloud("environment", moved, 42.0, block=True))
    local.replace_cloud("environment", moved, block=True, stamp=42.0)
    before = layout
    reply = step(200)
    assert layout is before and reply.clouds is not None
    assert tuple(reply.clouds[layout.objects.index("environment")]) == (1.0, 42.0)
    changes: list[tuple[P.Request, str]] = [
        (P.OperationCall.of("watch", LINKS[0], LINKS[2], 0.8, kind="custom"), "watch"),
        (P.AddObject("probe", box_points((0.3, 0.3, 0.3), 80, 9), np.eye(4), dynamic=True), "add"),
        (P.OperationCall.of("watch", "probe", LINKS[1], math.inf, kind="custom"), "probe"),
        (P.OperationCall.of("unwatch", LINKS[0], LINKS[2]), "unwatch"),
    ]
    for request, what in changes:
        svc.handle(request)
        if what == "watch":
            local.watch(LINKS[0], LINKS[2], 0.8, kind="custom")
        elif what == "add":
            local.add_object("probe", box_points((0.3, 0.3, 0.3), 80, 9), np.eye(4), dynamic=True)
        elif what == "probe":
            local.watch("probe", LINKS[1], math.inf, kind="custom")
        else:
            local.unwatch(LINKS[0], LINKS[2])
        stale = P.encode_tick(99, P.Query(5.0, None, None, None, layout.name), layout)
        assert stale is not None
        err = P.decode_reply(svc.tick(stale, P.DEFAULT_LIMITS)[0], P.QueryReply).error
        assert err is not None and err.code == E.STALE_LAYOUT, what
        layout = _layout(svc)
        for k in range(240, 320, 40):
            step(k)


def test_a_bad_tick_is_refused_with_its_request_id(
    crane: Robot, clouds: dict[str, NDArray[np.float64]]
) -> None:
    """A joint state of the wrong length in a tick: the full protocol's typed error
    (code and field), answered to the request that sent it; nothing is applied."""
    svc, _ = _both(crane, clouds)
    layout = _layout(svc)
    bad = P.Query(5.0, {crane.name: np.zeros(2)}, None, None, layout.name)
    raw = P.encode_tick(77, bad, layout)
    assert raw is not None
    payload, compute = svc.tick(raw, P.DEFAULT_LIMITS)
    decoded = P.decode_reply(payload, P.QueryReply)
    assert compute is None and decoded.request_id == 77 and decoded.error is not None
    assert (decoded.error.code, decoded.error.field) == (E.WRONG_SHAPE, f"body.joints.{crane.name}")
    assert "6 joint variables" in decoded.error.message
    np.testing.assert_array_equal(described(svc).joints[crane.name], crane_q(crane, 0))


def test_a_tick_that_fails_inside_is_an_internal_error_and_the_next_is_answered(
    crane: Robot, clouds: dict[str, NDArray[np.float64]], monkeypatch: pytest.MonkeyPatch
) -> None:
    svc, _ = _both(crane, clouds)
    layout = _layout(svc)
    real = svc.scene.query_all

    def broken() -> object:
        raise RuntimeError("the kernel fell over")

    monkeypatch.setattr(svc.scene, "query_all", broken)
    raw = P.encode_tick(5, P.Query(5.0, None, None, None, layout.name), layout)
    assert raw is not None
    decoded = P.decode_reply(svc.tick(raw, P.DEFAULT_LIMITS)[0], P.QueryReply)
    assert decoded.request_id == 5 and decoded.error is not None
    assert decoded.error.code == E.INTERNAL and "the kernel fell over" in decoded.error.message
    monkeypatch.setattr(svc.scene, "query_all", real)
    _tick(svc, layout, 6, crane_q(crane, 10), crane.name)
    errors = svc.metrics.snapshot(1.0, 0).errors
    assert errors == {E.INTERNAL.value: 1}


def test_ticks_count_as_queries_in_the_metrics() -> None:
    m = Metrics()
    assert "query" not in m.snapshot(1.0, 0).requests
    m.tick()
    m.tick()
    assert m.snapshot(1.0, 0).requests == {"query": 2}
    m.request("query")
    m.request("health")
    assert m.snapshot(1.0, 0).requests == {"query": 3, "health": 1}


def test_the_clients_tick_path_refuses_bad_inputs_and_goes_on(
    crane: Robot, clouds: dict[str, NDArray[np.float64]]
) -> None:
    """A batched client that holds the layout (its queries go as ticks): a joint state
    of the wrong length gets the full protocol's typed error from the tick, one of a
    robot the layout does not hold goes in full and gets its typed error; the inputs
    are dropped, and the next answers equal the in-process scene's."""
    from reachwise.server.client import SceneClient, ServerInputError
    from reachwise.server.transport import CollisionServer

    server = CollisionServer("tcp://127.0.0.1:*")
    local = Scene()
    with server.background() as endpoint:
        with SceneClient(endpoint, deadline=60.0, batch_inputs=True) as c:
            for scene in (c, local):
                scene.add_robot(crane, crane_q(crane, 0), stamp=1.0)
                for link in LINKS:
                    scene.add_object(link, clouds[link], robot=crane.name, link=link)
                scene.add_object("environment", clouds["environment"])
                scene.watch_environment(crane.name, 1.5)
            assert c.query_all().valid and c.ticks == 0  # the first one in full
            cases = [
                (crane.name, np.zeros(2), E.WRONG_SHAPE, f"body.joints.{crane.name}"),
                ("ghost", np.zeros(6), E.UNKNOWN_ID, "body.joints.ghost"),
            ]
            for k, (robot, q, code, field) in enumerate(cases):
                c.set_joints(robot, q, stamp=2.0)
                with pytest.raises(ServerInputError) as info:
                    c.query_all()
                assert (info.value.code, info.value.field) == (code, field)
                q_ok = crane_q(crane, 50 * (k + 1))
                c.set_joints(crane.name, q_ok, stamp=3.0)
                local.set_joints(crane.name, q_ok, stamp=3.0)
                ticks = c.ticks
                r = c.query_all()
                assert r.valid and c.ticks == ticks + 1 and r.measured_at == 3.0
                np.testing.assert_array_equal(r.rows, local.query_all().rows)
