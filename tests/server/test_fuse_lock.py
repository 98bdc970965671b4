"""A depth frame fused on the collision server never holds up queries: the memory's
fusing (the expensive part) runs without the service's scene lock, one frame at a time
per memory, and only the swap of the ready cloud takes the lock.

The test looks from another thread while the frame is being fused: the scene lock is
free and another client's query of every watched pair is answered (with the cloud in
use before the frame); after the fuse the new cloud answers. Two frames fused at once
swap in their order whichever hands over first.
"""

from __future__ import annotations

import math
import threading

import numpy as np
import pytest

from reachwise.distance.scene import Scene
from reachwise.distance.scene_memories import add_memory, fuse_depth, watch_memory
from reachwise.distance.scene_memory import MemoryConfig, SceneMemory
from reachwise.distance.scene_ops import OPERATIONS
from reachwise.server import protocol as P
from reachwise.server.client import SceneClient
from reachwise.server.service import SceneService
from reachwise.server.transport import CollisionServer

from ..distance.test_scene_memories import INTRINSICS, LOWER, MARGIN, POSE, PROBE, UPPER, frames
from .conftest import HANG_GUARD
from .lock_probe import from_another_thread

CONFIG = MemoryConfig(voxel=0.03, shadow_depth=0.4)


def _memory_service() -> SceneService:
    svc = SceneService(clock=lambda: 1000.0)
    svc.handle(P.OperationCall.of("add_memory", "memory", LOWER, UPPER, CONFIG))
    svc.handle(P.AddObject("probe", PROBE, np.eye(4)))
    svc.handle(P.OperationCall.of("watch_memory", "probe", "memory", MARGIN))
    return svc


def _distance(reply: P.Reply | None) -> float:
    assert isinstance(reply, P.QueryReply)
    (d,) = reply.rows[:, 0]
    return float(d)


def test_a_frame_is_fused_outside_the_scene_lock(monkeypatch: pytest.MonkeyPatch) -> None:
    svc = _memory_service()
    with_box, _ = frames()
    assert _distance(svc.handle(P.Query(1.0))) == math.inf  # nothing seen yet
    during: list[tuple[bool, P.Reply | None]] = []
    integrate = SceneMemory.integrate

    def observed(memory: SceneMemory, *args: object, **kwargs: object) -> None:
        during.append(from_another_thread(svc))
        integrate(memory, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(SceneMemory, "integrate", observed)
    reply = svc.handle(P.OperationCall.of("fuse_depth", "memory", with_box, POSE, INTRINSICS, 3.0))
    assert isinstance(reply, P.OperationResult)

    assert len(during) == 1
    free, answer = during[0]
    assert free
    assert _distance(answer) == math.inf  # answered with the cloud in use before the frame
    local = Scene()  # the same frame in process: the swap went on after the fuse
    add_memory(local, "memory", LOWER, UPPER, CONFIG)
    local.add_object("probe", PROBE)
    watch_memory(local, "probe", "memory", MARGIN)
    fuse_depth(local, "memory", with_box, POSE, INTRINSICS, 3.0)
    (pair,) = local.query_all().pairs
    assert math.isfinite(pair.result.distance)
    assert _distance(svc.handle(P.Query(4.0))) == pytest.approx(pair.result.distance, abs=1e-12)


def test_the_lock_check_sees_a_held_lock() -> None:
    """The check above would catch a fuse under the lock: with the lock held by the
    fusing thread, the other thread finds it taken."""
    svc = _memory_service()
    with svc.lock:
        free, answer = from_another_thread(svc)
    assert not free and answer is None


def test_frames_fused_at_once_swap_in_their_order() -> None:
    """Two frames fused concurrently: the later frame's cloud stays in even when the
    earlier one hands over last (its hand-over changes nothing)."""
    scene = Scene()
    add_memory(scene, "memory", LOWER, UPPER, CONFIG)
    scene.add_object("probe", PROBE)
    watch_memory(scene, "probe", "memory", MARGIN)
    with_box, without = frames()
    op = OPERATIONS["fuse_depth"]
    assert op.hand_over is not None
    first = op.function(scene, "memory", with_box, POSE, INTRINSICS, 3.0)
    second = op.function(scene, "memory", without, POSE, INTRINSICS, 4.0)
    version = op.hand_over(scene, second)
    assert op.hand_over(scene, first) == version == scene.versions["memory"]
    (pair,) = scene.query_all().pairs
    assert pair.result.distance == math.inf  # the box gone (second frame): freed
    assert scene.query_all().cloud_stamps["memory"] == 4.0


def test_a_server_answers_queries_while_it_fuses_a_frame(monkeypatch: pytest.MonkeyPatch) -> None:
    """Through the wire: while the server fuses a camera client's frame (held in
    ``integrate`` until the controller's query is answered), a second client's query
    is answered; the fuse then completes and its cloud answers. A server that fused on
    the thread that answers queries would let the query run into its deadline."""
    answered = threading.Event()
    entered = threading.Event()
    integrate = SceneMemory.integrate

    def held(memory: SceneMemory, *args: object, **kwargs: object) -> None:
        entered.set()
        answered.wait(HANG_GUARD)
        integrate(memory, *args, **kwargs)  # type: ignore[arg-type]

    with_box, _ = frames()
    with CollisionServer("tcp://127.0.0.1:*").background() as endpoint:
        with (
            SceneClient(endpoint, deadline=HANG_GUARD, setup_deadline=HANG_GUARD) as camera,
            SceneClient(endpoint, deadline=5.0, setup_deadline=HANG_GUARD) as controller,
        ):
            add_memory(camera, "memory", LOWER, UPPER, CONFIG)
            camera.add_object("probe", PROBE)
            watch_memory(camera, "probe", "memory", MARGIN)
            monkeypatch.setattr(SceneMemory, "integrate", held)
            versions: list[int] = []
            fuser = threading.Thread(
                target=lambda: versions.append(
                    fuse_depth(camera, "memory", with_box, POSE, INTRINSICS, 3.0)
                )
            )
            fuser.start()
            assert entered.wait(HANG_GUARD)  # the server is fusing the frame now
            during = controller.query_all()
            answered.set()
            fuser.join(HANG_GUARD)
            assert during.valid, during.reason  # answered while the frame was fused
            assert during.get("probe", "memory").result.distance == math.inf
            assert versions == [1]
            after = controller.query_all()
            assert math.isfinite(after.get("probe", "memory").result.distance)
