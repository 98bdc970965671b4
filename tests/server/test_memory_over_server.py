"""A scene memory on the collision server: a client adds it, sends depth frames of a
known box and reads the watched pair's distance; the answer is the in-process scene's for
the same frames (the same operations, written once), within the memory's inflation of
the box's observed points; a frame with the box gone frees it; the object's cloud
carries the newest frame's time; bad frames are typed errors naming the field."""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from reachwise.benchmarks.server import ServerProcess
from reachwise.control.safety import SafetyConfig, check_data
from reachwise.distance.scene import Scene
from reachwise.distance.scene_memories import (
    add_memory,
    fuse_depth,
    memories_of,
    memory_inflation,
    memory_setups,
    watch_memory,
)
from reachwise.distance.scene_memory import MemoryConfig
from reachwise.server import protocol as P
from reachwise.server.client import SceneClient
from reachwise.server.client.errors import ServerInputError
from reachwise.server.service import SceneService
from reachwise.server.state import StateStore

from ..distance.test_scene_memories import (
    AWAY,
    CAMERA,
    IN_FRONT,
    INTRINSICS,
    LOWER,
    MARGIN,
    POSE,
    PROBE,
    UPPER,
    frames,
    slider_frame,
    slider_scene,
    wall_distances,
)
from .conftest import HANG_GUARD, start_server
from .described import described

CONFIG = MemoryConfig(voxel=0.03, shadow_depth=0.4)


@pytest.fixture
def client(server: ServerProcess) -> Iterator[SceneClient]:
    with SceneClient(server.endpoint, deadline=HANG_GUARD, setup_deadline=HANG_GUARD) as c:
        c.clear()
        yield c


def _build(scene: Scene | SceneClient) -> float:
    inflation = add_memory(scene, "memory", LOWER, UPPER, CONFIG)
    scene.add_object("probe", PROBE)
    watch_memory(scene, "probe", "memory", MARGIN)
    return inflation


def test_frames_fused_on_the_server_answer_as_in_process(client: SceneClient) -> None:
    local = Scene()
    inflation = _build(local)
    assert _build(client) == inflation == memory_inflation(client, "memory")
    assert [(p.a, p.b, p.margin) for p in client.describe().pairs] == [
        (p.a, p.b, p.margin) for p in local.pairs
    ]
    with_box, without = frames()
    observed = CAMERA.points(with_box, POSE)
    seen = observed[np.all((observed >= LOWER) & (observed <= UPPER), axis=1)]
    d_observed = float(np.linalg.norm(seen - PROBE, axis=1).min())

    assert fuse_depth(client, "memory", with_box, POSE, INTRINSICS, 3.0) == 1
    fuse_depth(local, "memory", with_box, POSE, INTRINSICS, 3.0)
    res, ref = client.query_all(), local.query_all()
    assert res.valid, res.reason
    d = res.get("probe", "memory").result.distance
    assert d == pytest.approx(ref.get("probe", "memory").result.distance, abs=1e-12)
    assert abs(d - d_observed) <= inflation + 1e-9
    assert res.cloud_stamps["memory"] == 3.0  # the newest frame's time: it ages

    assert fuse_depth(client, "memory", without, POSE, INTRINSICS, 3.5) == 2
    res = client.query_all()
    assert res.get("probe", "memory").result.distance > d + 1.0  # freed
    assert res.cloud_stamps["memory"] == 3.5
    local.close()


def test_the_robot_never_enters_the_servers_map(client: SceneClient) -> None:
    """The wall seen with the robot away, then the robot's cube in front of it, at the
    joint state the server last got: the cube's distance to the memory stays its
    distance to the wall (brute force), the probe in the space the cube hides keeps
    its distance to the wall, and both equal the in-process scene's."""
    local = Scene()
    for scene in (client, local):
        slider_scene(scene)
        fuse_depth(scene, "memory", slider_frame(AWAY), POSE, INTRINSICS, 1.0)
        scene.set_joints("slider", IN_FRONT)
        fuse_depth(scene, "memory", slider_frame(IN_FRONT), POSE, INTRINSICS, 1.1)  # type: ignore[arg-type]
    res, ref = client.query_all(), local.query_all()
    assert res.valid, res.reason
    inflation = memory_inflation(client, "memory")
    for probe, truth in zip(("cube", "hidden"), wall_distances(), strict=True):
        d = res.get(probe, "memory").result.distance
        assert d == pytest.approx(ref.get(probe, "memory").result.distance, abs=1e-12)
        assert abs(d - truth) <= inflation + 1e-9, probe
    local.close()


def test_a_mirroring_client_fuses_its_frames_into_its_copy_too(server: ServerProcess) -> None:
    """A client with ``mirror=True`` that fuses frames has the server's memory on its
    copy: the local cloud of the memory object gives the server's distance (1e-12) by
    brute force, frame after frame, the robot left out as on the server."""
    with SceneClient(
        server.endpoint, deadline=HANG_GUARD, setup_deadline=HANG_GUARD, mirror=True
    ) as client:
        client.clear()
        slider_scene(client)
        steps = [(AWAY, AWAY, 1.0), (IN_FRONT, IN_FRONT, 1.1), (IN_FRONT, AWAY, 1.2)]
        for q, seen, t in steps:
            client.set_joints("slider", q)
            fuse_depth(client, "memory", slider_frame(seen), POSE, INTRINSICS, t)
            res = client.query_all()
            assert res.valid, res.reason
            local = client.objects["memory"].cloud.points  # the mirror's, no round trip
            for probe in ("cube", "hidden"):
                obj = client.objects[probe]
                pts = obj.cloud.points @ client.poses()[probe][:3, :3].T
                pts = pts + client.poses()[probe][:3, 3]
                brute = float(np.min(np.linalg.norm(pts[:, None] - local[None], axis=2)))
                d = res.get(probe, "memory").result.distance
                assert brute == pytest.approx(d, abs=1e-12), (probe, t)
            assert res.cloud_stamps["memory"] == t


def test_bad_frames_through_the_server_are_typed_errors_naming_the_field(
    client: SceneClient,
) -> None:
    _build(client)
    with_box, _ = frames()
    bad_pose = POSE.copy()
    bad_pose[1, 1] = np.nan
    cases = [
        ((with_box[0], POSE, INTRINSICS, 1.0), "depth"),  # one row, not an image
        ((with_box, bad_pose, INTRINSICS, 1.0), "pose"),
        ((with_box, POSE, (0.0, 60.0, 31.5, 23.5, 0.2, 6.0), 1.0), "intrinsics"),
        ((with_box, POSE, INTRINSICS, math.nan), "t"),
    ]
    for args, field in cases:
        with pytest.raises(ServerInputError) as info:
            fuse_depth(client, "memory", *args)  # type: ignore[arg-type]
        assert info.value.field.endswith(field), (field, info.value)
    with pytest.raises(ServerInputError) as info:
        fuse_depth(client, "memroy", with_box, POSE, INTRINSICS, 1.0)
    assert info.value.code == P.ErrorCode.UNKNOWN_ID and "'memory'" in str(info.value)
    for taken in ("memory", "probe"):  # a memory's name, an object's: EXISTS
        with pytest.raises(ServerInputError) as info:
            add_memory(client, taken, LOWER, UPPER, CONFIG)
        assert info.value.code == P.ErrorCode.EXISTS and info.value.field == "name"
    with pytest.raises(ServerInputError) as info:
        client.add_object("memory", PROBE)
    assert info.value.code == P.ErrorCode.EXISTS and info.value.field.endswith("name")
    res = client.query_all()  # nothing of the bad frames was fused
    assert res.valid and res.get("probe", "memory").result.distance == math.inf


def test_a_state_directory_keeps_the_memory_watched_and_unknown(tmp_path: Path) -> None:
    """Restarted from its state directory, the server has the memory with its box and
    configuration, watched as before (same margin), every voxel unknown: the pair
    sees nothing (unknown is never an obstacle of the query, nor free: a frame of the
    box brings it back as before the restart)."""
    svc = SceneService(store=StateStore(tmp_path))
    svc.load()
    svc.handle(P.AddObject("probe", PROBE, None))
    calls: list[tuple[object, ...]] = [
        ("add_memory", "memory", LOWER, UPPER, CONFIG),
        ("watch_memory", "probe", "memory", MARGIN),
        ("fuse_depth", "memory", frames()[0], POSE, INTRINSICS, 3.0),
    ]
    for name, *args in calls:
        assert isinstance(svc.handle(P.OperationCall.of(str(name), *args)), P.OperationResult)
    rows = svc.handle(P.Query(stamp=4.0))
    assert isinstance(rows, P.QueryReply) and rows.rows[0, 0] < MARGIN  # answered
    before = described(svc)
    first = memories_of(svc.scene)["memory"]

    again = SceneService(store=StateStore(tmp_path))
    again.load()
    assert again.ready, again.reason
    after = described(again)
    assert sorted(o.name for o in after.objects) == ["memory", "probe"]
    assert after.pairs == before.pairs  # watched as before, margin + inflation
    (setup,) = memory_setups(again.scene)
    assert setup.config == CONFIG
    assert np.array_equal(setup.lower, LOWER) and np.array_equal(setup.upper, UPPER)
    memory = memories_of(again.scene)["memory"]
    assert memory.shape == first.shape and np.array_equal(memory.origin, first.origin)
    counts = memory.counts()
    assert counts.unknown == memory.state.size  # the map restarts unknown
    rows = again.handle(P.Query(stamp=5.0))
    assert isinstance(rows, P.QueryReply) and rows.rows[0, 0] > MARGIN  # nothing seen
    fused = again.handle(
        P.OperationCall.of("fuse_depth", "memory", frames()[0], POSE, INTRINSICS, 6.0)
    )
    assert isinstance(fused, P.OperationResult)
    rows = again.handle(P.Query(stamp=6.0))
    ref = svc.handle(P.Query(stamp=6.0))
    assert isinstance(rows, P.QueryReply) and isinstance(ref, P.QueryReply)
    assert rows.rows[0, 0] == pytest.approx(ref.rows[0, 0], abs=1e-12)


def _fresh(res: object, now: float) -> bool:
    """Whether a controller with ``max_cloud_age`` 0.5 s takes the memory's cloud of
    the answer ``res`` at ``now`` (s): the rule of ``control.safety.check_data``."""
    stamp = res.cloud_stamps["memory"]  # type: ignore[attr-defined]
    safety = SafetyConfig(dt=0.01, max_cloud_age=0.5)
    return check_data(1, now, None, now, safety, cloud_stamp=stamp, cloud="memory").ok


def test_a_restarted_servers_memory_is_stale_until_its_first_frame(tmp_path: Path) -> None:
    """A real server with a state directory: the memory is stale under
    ``max_cloud_age`` until its first frame, fresh after it; restarted, the server's
    memory has seen nothing (its map is not kept), so its age is unknown again — stale
    however soon the restart came — until the next frame, after which it is fresh."""
    state = ("--state", str(tmp_path / "state"))
    with_box = frames()[0]
    first = start_server(tmp_path / "first", extra=state)
    try:
        with SceneClient(first.endpoint, deadline=HANG_GUARD, setup_deadline=HANG_GUARD) as c:
            _build(c)
            res = c.query_all()
            assert res.valid and math.isnan(res.cloud_stamps["memory"])
            assert not _fresh(res, 0.0)  # nothing seen yet
            fuse_depth(c, "memory", with_box, POSE, INTRINSICS, 3.0)
            res = c.query_all()
            assert res.cloud_stamps["memory"] == 3.0 and _fresh(res, 3.1)
            assert not _fresh(res, 3.6)  # the checker catches an old frame
    finally:
        assert first.stop() == 0, (first.workdir / "server.log").read_text()
    again = start_server(tmp_path / "again", extra=state)
    try:
        with SceneClient(again.endpoint, deadline=HANG_GUARD, setup_deadline=HANG_GUARD) as c:
            assert [p.b for p in c.describe().pairs] == ["memory"]  # restored
            res = c.query_all()
            assert res.valid and math.isnan(res.cloud_stamps["memory"])
            assert not _fresh(res, 3.1)  # the last frame's time would pass: unknown does not
            fuse_depth(c, "memory", with_box, POSE, INTRINSICS, 8.0)
            res = c.query_all()
            assert res.cloud_stamps["memory"] == 8.0 and _fresh(res, 8.1)
    finally:
        assert again.stop() == 0, (again.workdir / "server.log").read_text()
