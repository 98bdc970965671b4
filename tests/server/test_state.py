"""Durability: atomic state files, restore into an equal scene, not-ready until restored."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray

from reachwise.distance import Scene
from reachwise.io.robot_file import robot_to_dict
from reachwise.kinematics.robot import Robot
from reachwise.server import protocol as P
from reachwise.server.service import SceneService
from reachwise.server.state import StateError, StateStore, atomic_write

from .conftest import LINKS, crane_q
from .described import described


def _service(root: Path | None) -> SceneService:
    return SceneService(store=None if root is None else StateStore(root))


def _populate(svc: SceneService, crane: Robot, clouds: dict[str, NDArray[np.float64]]) -> None:
    svc.handle(P.OperationCall.of("add_robot", crane, crane_q(crane, 0), stamp=5.0))
    for link in LINKS:
        svc.handle(P.AddObject(link, clouds[link], None, crane.name, link))
    env = np.eye(4)
    env[0, 3] = 3.4
    svc.handle(P.AddObject("environment", clouds["environment"], env))
    probe = np.eye(4)
    probe[:3, 3] = [2.0, 0.5, 1.0]
    svc.handle(P.AddObject("probe", clouds["link_6"], probe, dynamic=True))
    svc.handle(P.OperationCall.of("watch_environment", crane.name, 1.5))
    svc.handle(P.OperationCall.of("watch_self", crane.name, 0.5))
    svc.handle(P.OperationCall.of("watch", "probe", "environment", math.inf, kind="custom"))
    svc.handle(P.OperationCall.of("watch", "probe", "link_3", 0.8, kind="robot-environment"))


def _query(svc: SceneService) -> P.QueryReply:
    rep = svc.handle(P.Query(stamp=100.0))
    assert isinstance(rep, P.QueryReply)
    return rep


def test_atomic_write_leaves_no_temporary_files(tmp_path: Path) -> None:
    target = tmp_path / "f.json"
    atomic_write(target, b"one")
    atomic_write(target, b"two")
    assert target.read_bytes() == b"two"
    assert [p.name for p in tmp_path.iterdir()] == ["f.json"]


def test_restore_gives_the_same_scene_and_answers(
    tmp_path: Path, crane: Robot, clouds: dict[str, NDArray[np.float64]]
) -> None:
    svc = _service(tmp_path)
    svc.load()
    _populate(svc, crane, clouds)
    moved = np.eye(4)
    moved[:3, 3] = [2.2, 0.4, 0.9]
    svc.handle(P.SetPose("probe", moved, 6.0))
    svc.handle(P.SetJoints(crane.name, crane_q(crane, 40), 7.0))
    scan = clouds["environment"][::2]
    hand_over = svc.handle(P.ReplaceCloud("environment", scan, 6.5, block=True))
    assert isinstance(hand_over, P.ObjectReply) and hand_over.version == 1
    svc.flush_live(force=True)
    svc.flush_clouds(force=True)
    before = described(svc, clouds=True)
    answer = _query(svc)
    last_sequence = svc.sequence.last

    again = _service(tmp_path)
    assert not again.ready and again.state == "loading"
    again.load()
    assert again.ready
    after = described(again, clouds=True)
    assert {k: robot_to_dict(r) for k, r in after.robots.items()} == {
        k: robot_to_dict(r) for k, r in before.robots.items()
    }
    assert after.pairs == before.pairs
    assert [o.name for o in after.objects] == [o.name for o in before.objects]
    for a, b in zip(after.objects, before.objects, strict=True):
        assert (a.source, a.robot, a.link, a.points) == (b.source, b.robot, b.link, b.points)
        np.testing.assert_array_equal(a.pose, b.pose)
        assert a.cloud is not None and b.cloud is not None
        np.testing.assert_array_equal(a.cloud, b.cloud)
    np.testing.assert_array_equal(after.joints[crane.name], crane_q(crane, 40))
    re = _query(again)
    np.testing.assert_array_equal(re.rows, answer.rows)
    assert re.measured_at == 6.0  # the oldest restored input (the probe's pose)
    # the handed-over scan comes back with its version and stamp; the rest do not age
    assert re.objects == answer.objects and re.objects is not None
    assert re.clouds is not None and answer.clouds is not None
    np.testing.assert_array_equal(re.clouds, answer.clouds)
    table = dict(zip(re.objects, re.clouds.tolist(), strict=True))
    assert table["environment"] == [1.0, 6.5]
    assert all(v == [0.0, math.inf] for k, v in table.items() if k != "environment")
    assert again.handle(P.ReplaceCloud("environment", scan)).version == 2  # goes on
    assert re.sequence > last_sequence  # sequence numbers never repeat across restarts
    # exactly the referenced clouds are left: the replaced scan's file is gone
    files = {p.name for p in (tmp_path / "clouds").iterdir()}
    manifest = json.loads((tmp_path / "scene.json").read_text())
    assert files == {o["cloud"] for o in manifest["objects"]}


def test_in_process_scene_matches_restored_service(
    tmp_path: Path, crane: Robot, clouds: dict[str, NDArray[np.float64]]
) -> None:
    svc = _service(tmp_path)
    svc.load()
    _populate(svc, crane, clouds)
    restored = _service(tmp_path)
    restored.load()
    scene = Scene()
    scene.add_robot(crane, crane_q(crane, 0))
    for link in LINKS:
        scene.add_object(link, clouds[link], robot=crane.name, link=link)
    env = np.eye(4)
    env[0, 3] = 3.4
    scene.add_object("environment", clouds["environment"], env)
    probe = np.eye(4)
    probe[:3, 3] = [2.0, 0.5, 1.0]
    scene.add_object("probe", clouds["link_6"], probe, dynamic=True)
    scene.watch_environment(crane.name, 1.5)
    scene.watch_self(crane.name, 0.5)
    scene.watch("probe", "environment", math.inf, kind="custom")
    scene.watch("probe", "link_3", 0.8, kind="robot-environment")
    for k in range(0, 200, 20):
        q = crane_q(crane, k)
        scene.set_joints(crane.name, q)
        rep = restored.handle(P.Query(stamp=1.0, joints={crane.name: q}))
        assert isinstance(rep, P.QueryReply)
        ref = scene.query_all()
        assert rep.pairs is not None
        assert [(p.a, p.b, p.margin, p.kind) for p in rep.pairs] == [
            (p.a, p.b, p.margin, p.kind) for p in ref.pairs
        ]
        for row, p in zip(rep.rows, ref.pairs, strict=True):
            r = p.result
            assert bool(row[12]) == r.no_risk
            if not r.no_risk:
                assert row[0] == r.distance
                assert (int(row[10]), int(row[11])) == (r.index_a, r.index_b)
                np.testing.assert_array_equal(row[1:10], np.r_[r.point_a, r.point_b, r.direction])


def test_not_ready_until_restored_then_failed_on_a_bad_state(tmp_path: Path) -> None:
    svc = _service(tmp_path)
    health = svc.handle(P.Health())
    assert isinstance(health, P.HealthReply) and not health.ready and health.state == "loading"
    with pytest.raises(P.ProtocolError) as info:
        svc.handle(P.Query())
    assert info.value.code == P.ErrorCode.NOT_READY
    (tmp_path / "scene.json").write_text('{"version": 1, "strategy": "default", "robots": 3}')
    svc.load()
    health = svc.handle(P.Health())
    assert isinstance(health, P.HealthReply)
    assert health.state == "failed" and not health.ready and "scene.json" in health.reason
    with pytest.raises(P.ProtocolError) as info:
        described(svc)
    assert info.value.code == P.ErrorCode.NOT_READY and "failed" in info.value.message


def test_state_errors_name_the_file_and_field(tmp_path: Path) -> None:
    store = StateStore(tmp_path)
    (tmp_path / "scene.json").write_text("{not json")
    with pytest.raises(StateError, match=r"scene\.json.*unreadable"):
        store.read()
    (tmp_path / "scene.json").write_text(
        json.dumps(
            {
                "version": 1,
                "strategy": "default",
                "objects": [
                    {
                        "name": "x",
                        "cloud": "0" * 32 + ".npy",
                        "points": 3,
                        "source": "fixed",
                        "pose": np.eye(4).tolist(),
                    }
                ],
            }
        )
    )
    with pytest.raises(StateError, match="object 'x'"):
        store.read()
    np.save(tmp_path / "clouds" / ("0" * 32 + ".npy"), np.zeros((2, 3)))
    with pytest.raises(StateError, match=r"expected float64 or float32 \(3, 3\)"):
        store.read()
    (tmp_path / "sequence.json").write_text('{"version": 1, "reserved": -5}')
    with pytest.raises(StateError, match="reserved"):
        store.read_reserved()


def test_handed_over_clouds_saved_without_a_time_restore_as_unknown(tmp_path: Path) -> None:
    """A state file written before stamps were kept holds handed-over clouds
    (``version`` > 0) without a stamp; with ``"unknown"`` too, a cloud's time is not
    known. Each restores (the server becomes ready) with its version and a NaN stamp,
    stale under ``max_cloud_age``, not as a cloud that never ages; a timed one keeps its
    time, the next hand-over's version goes on, and the state saved again says
    ``"unknown"``, so a second restart gives the same."""
    store = StateStore(tmp_path)
    objects = {  # name: (version, saved stamp; absent: no "stamp" field)
        "probe": (0, None),
        "scan": (3, None),  # the older form
        "unknown": (2, "unknown"),
        "timed": (1, 6.5),
        "added_at": (0, 2.0),
        "unknown_added": (0, "unknown"),
    }
    rows = []
    for k, (name, (version, stamp)) in enumerate(objects.items()):
        pose = np.eye(4)
        pose[0, 3] = float(k)
        row = {"name": name, "cloud": store.write_cloud(np.zeros((1, 3))), "points": 1,
               "source": "fixed", "pose": pose.tolist(), "version": version}  # fmt: skip
        rows.append(row if stamp is None else {**row, "stamp": stamp})
    pairs = [{"a": "probe", "b": n, "margin": 10.0, "kind": "custom"} for n in list(objects)[1:]]
    manifest = {"version": 1, "strategy": "default", "objects": rows, "pairs": pairs}
    (tmp_path / "scene.json").write_text(json.dumps(manifest))
    want = {
        "probe": [0.0, math.inf],
        "scan": [3.0, math.nan],
        "unknown": [2.0, math.nan],
        "timed": [1.0, 6.5],
        "added_at": [0.0, 2.0],
        "unknown_added": [0.0, math.nan],
    }

    def restored() -> SceneService:
        svc = _service(tmp_path)
        svc.load()
        assert svc.ready, svc.reason
        rep = _query(svc)
        assert rep.objects is not None and rep.clouds is not None
        table = dict(zip(rep.objects, rep.clouds.tolist(), strict=True))
        np.testing.assert_array_equal([table[n] for n in want], list(want.values()))
        return svc

    svc = restored()
    svc.handle(P.OperationCall.of("watch", "scan", "timed", 1.0, kind="custom"))  # saves
    saved = {o["name"]: o for o in json.loads((tmp_path / "scene.json").read_text())["objects"]}
    assert {n: (o["version"], o.get("stamp")) for n, o in saved.items()} == {
        **objects,
        "scan": (3, "unknown"),
    }
    svc = restored()
    rep = svc.handle(P.ReplaceCloud("scan", np.ones((2, 3)), 7.0, block=True))
    assert isinstance(rep, P.ObjectReply) and rep.version == 4  # the version goes on
    after = _query(svc)
    assert after.objects is not None and after.clouds is not None
    assert after.clouds.tolist()[after.objects.index("scan")] == [4.0, 7.0]


def test_a_crash_between_cloud_and_manifest_leaves_no_trace(
    tmp_path: Path, crane: Robot, clouds: dict[str, NDArray[np.float64]]
) -> None:
    svc = _service(tmp_path)
    svc.load()
    _populate(svc, crane, clouds)
    orphan = StateStore(tmp_path).write_cloud(np.ones((4, 3)))  # written, never referenced
    (tmp_path / ".scene.json.dead.tmp").write_bytes(b"half")
    again = _service(tmp_path)
    again.load()
    assert again.ready
    assert not (tmp_path / "clouds" / orphan).exists()
    assert not (tmp_path / ".scene.json.dead.tmp").exists()
