"""Replaying a recording: each frame's distances against brute force on the same
inputs (the link clouds placed by forward kinematics, the clouds moved along TF), the
files it writes, and a typed error naming topic and time for each kind of bad
recording."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial.distance import cdist

from reachwise.errors import InputError
from reachwise.io.ros.bag import Recording
from reachwise.io.ros.recording_error import RecordingError
from reachwise.io.ros.replay import ReplaySpec, replay_recording
from reachwise.report.replay import write_replay_outputs
from tests.io.ros import _cell


def _brute(robot: Any, clouds: dict, q: np.ndarray, link: str, world_pts: np.ndarray) -> float:
    frames = robot.fk_all(q)
    T = frames[robot.link_names.index(link)]
    pts = clouds[link].points @ T[:3, :3].T + T[:3, 3]
    return float(cdist(pts, world_pts).min())


@pytest.fixture(scope="module")
def cell(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _cell.write_cell(tmp_path_factory.mktemp("cell") / "cell.mcap")


def test_each_frame_equals_brute_force(cell: Path) -> None:
    robot = _cell.panda()
    clouds = _cell.link_clouds(robot)
    spec = ReplaySpec(joints="/joint_states", clouds=("/points", "/depth/image"))
    res = replay_recording(cell, robot, spec, link_clouds=clouds)
    assert res.pairs == tuple(f"{l}|{c}" for c in ("/points", "/depth/image") for l in clouds)
    assert res.t.size == 101
    assert res.swapped == res.clouds  # blocking: every cloud was used
    assert res.clouds == {"/points": 10, "/depth/image": 10}
    checked = 0
    for f, t in enumerate(res.t):
        q = _cell.joint_path(t)
        for p, name in enumerate(res.pairs):
            link, topic = name.split("|")
            stamp = res.cloud_stamp[f, p]
            if np.isnan(stamp):  # no cloud yet: before the first one at 0.05 s
                assert t < 0.05 and np.isnan(res.distance[f, p])
                continue
            if topic == "/points":
                k = round((stamp + 0.005 - 0.05) / 0.1)
                pts = _cell.obstacle(k) @ _cell.T_WORLD_CAM[:3, :3].T + _cell.T_WORLD_CAM[:3, 3]
            else:
                k = round((stamp - 0.05) / 0.1)
                pts = _cell.depth_world_points(k, stamp)
            assert res.distance[f, p] == pytest.approx(
                _brute(robot, clouds, q, link, pts), abs=1e-9
            )
            checked += 1
    assert checked > 500


def test_non_blocking_frames_say_which_cloud_they_used(cell: Path) -> None:
    """Paced at the recording's speed, non-blocking hand-overs are swapped in; every
    frame's distance is the brute-force one on the cloud whose stamp it reports."""
    robot = _cell.panda()
    clouds = _cell.link_clouds(robot)
    spec = ReplaySpec(joints="/joint_states", clouds=("/points",), block=False, rate=1.0)
    res = replay_recording(cell, robot, spec, link_clouds=clouds)
    assert res.swapped["/points"] >= 1
    for f in np.flatnonzero(~np.isnan(res.cloud_stamp[:, 0])):
        k = round((res.cloud_stamp[f, 0] + 0.005 - 0.05) / 0.1)
        pts = _cell.obstacle(k) @ _cell.T_WORLD_CAM[:3, :3].T + _cell.T_WORLD_CAM[:3, 3]
        q = _cell.joint_path(res.t[f])
        assert res.distance[f, 0] == pytest.approx(
            _brute(robot, clouds, q, "link_3", pts), abs=1e-9
        )


def test_outputs(cell: Path, tmp_path: Path) -> None:
    robot = _cell.panda()
    spec = ReplaySpec(joints="/joint_states", clouds=("/points",), margin=0.5, every=0.05)
    assert spec.block  # the default: each frame uses the newest cloud received
    res = replay_recording(cell, robot, spec, link_clouds=_cell.link_clouds(robot))
    assert np.all(np.diff(res.t) >= 0.05 - 1e-12)
    summary = write_replay_outputs(res, tmp_path, {"joints": "/joint_states"})
    rows = list(csv.DictReader((tmp_path / "distances.csv").open()))
    assert len(rows) == int((~np.isnan(res.distance)).sum())
    near = list(csv.DictReader((tmp_path / "near.csv").open()))
    assert len(near) == int(res.near.sum()) and all(float(r["distance"]) < 0.5 for r in near)
    assert json.loads((tmp_path / "summary.json").read_text()) == summary
    assert summary["min_distance"] == pytest.approx(np.nanmin(res.distance))
    assert "<img" in (tmp_path / "report.html").read_text()
    with Recording(tmp_path / "results.mcap") as rec:
        got = [m for m in rec.messages(["/reachwise/distances"])]
        assert len(got) == res.t.size
        np.testing.assert_array_equal(got[-1].msg.data, res.distance[-1])
        assert set(rec.topics) >= {"/reachwise/min_distance", "/reachwise/closest_points"}


def _bad(tmp_path: Path, hook: Any) -> Path:
    return _cell.write_cell(tmp_path / "bad.mcap", hook, seconds=0.3)


def _replay(bag: Path, clouds: tuple[str, ...] = ("/points", "/depth/image")) -> Any:
    robot = _cell.panda()
    spec = ReplaySpec(joints="/joint_states", clouds=clouds, block=True)
    return replay_recording(bag, robot, spec, link_clouds=_cell.link_clouds(robot))


def test_wrong_point_step_names_topic_and_time(tmp_path: Path) -> None:
    def hook(topic: str, msg: Any, t: float) -> Any:
        if topic == "/points" and t > 0.1:
            msg.point_step = 16
        return msg

    with pytest.raises(RecordingError, match=r"bad\.mcap: topic /points: point_step.*t = 0\.145"):
        _replay(_bad(tmp_path, hook))


def test_fields_without_xyz(tmp_path: Path) -> None:
    def hook(topic: str, msg: Any, t: float) -> Any:
        if topic == "/points":
            msg.fields[2].name = "w"
        return msg

    with pytest.raises(RecordingError, match=r"topic /points: fields: no z.*t = 0\.045"):
        _replay(_bad(tmp_path, hook))


def test_unknown_encoding(tmp_path: Path) -> None:
    def hook(topic: str, msg: Any, t: float) -> Any:
        if topic == "/depth/image":
            msg.encoding = "bgr8"
        return msg

    with pytest.raises(RecordingError, match=r"/depth/image: encoding.*bgr8.*t = 0\.05"):
        _replay(_bad(tmp_path, hook))


def test_joint_state_without_the_robots_joints(tmp_path: Path) -> None:
    def hook(topic: str, msg: Any, t: float) -> Any:
        if topic == "/joint_states" and t > 0.2:
            msg.name = [n.replace("panda_joint4", "elbow") for n in msg.name]
        return msg

    with pytest.raises(
        RecordingError, match=r"/joint_states: name: lacks.*panda_joint4.*t = 0\.21"
    ):
        _replay(_bad(tmp_path, hook))


def test_frame_with_no_tf_path(tmp_path: Path) -> None:
    def hook(topic: str, msg: Any, t: float) -> Any:
        if topic == "/points":
            msg.header.frame_id = "lidar"
        return msg

    with pytest.raises(
        RecordingError, match=r"/points: header.frame_id.*'world' and 'lidar'.*t = 0\.045"
    ):
        _replay(_bad(tmp_path, hook))


def test_truncated_and_not_a_bag(tmp_path: Path, cell: Path) -> None:
    (storage,) = cell.glob("*.mcap")
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(storage.read_bytes()[:40_000])
    with pytest.raises(InputError, match=r"cut\.mcap"):
        _replay(cut)
    junk = tmp_path / "junk.bag"
    junk.write_bytes(b"#ROSBAG V2.0\n" + b"\0" * 100)
    with pytest.raises(InputError, match=r"junk\.bag"):
        _replay(junk)


def test_a_missing_topic_lists_the_topics(cell: Path) -> None:
    with pytest.raises(InputError, match="/points"):
        _replay(cell, ("/camera/points",))


def test_a_ros1_copy_replays_the_same(cell: Path, tmp_path: Path) -> None:
    """The cell converted to ROS 1 by rosbags replays to the same arrays (ties in
    receive time, which ROS 1 stores in another order, taken clouds first)."""
    from rosbags.convert.converter import convert
    from rosbags.typesys import Stores, get_typestore

    ros1 = tmp_path / "cell.bag"
    store = get_typestore(Stores.ROS1_NOETIC)
    convert([cell], ros1, "sqlite3", 8, None, "file", None, store, [], [], [], [])
    robot = _cell.panda()
    clouds = _cell.link_clouds(robot)
    spec = ReplaySpec(joints="/joint_states", clouds=("/points", "/depth/image"))
    a = replay_recording(cell, robot, spec, link_clouds=clouds)
    b = replay_recording(ros1, robot, spec, link_clouds=clouds)
    np.testing.assert_array_equal(a.t, b.t)
    np.testing.assert_array_equal(a.cloud_stamp, b.cloud_stamp)
    np.testing.assert_array_equal(a.distance, b.distance)
    assert b.ros1 and not a.ros1
    # the results go back into a ROS 1 bag, and read back to the replay's arrays
    summary = write_replay_outputs(b, tmp_path / "out", {})
    assert summary["results_bag"] == str(tmp_path / "out" / "results.bag")
    assert not (tmp_path / "out" / "results.mcap").exists()
    with Recording(tmp_path / "out" / "results.bag") as rec:
        assert rec.ros1
        topics = ["/reachwise/distances", "/reachwise/min_distance", "/reachwise/closest_points"]
        got = {t: [m for m in rec.messages([t])] for t in topics}
        (pairs,) = [m.msg.data for m in rec.messages(["/reachwise/pairs"])]
    assert json.loads(pairs) == list(b.pairs)
    assert [m.t for m in got["/reachwise/distances"]] == pytest.approx(b.t.tolist(), abs=1e-9)
    dist = np.array([m.msg.data for m in got["/reachwise/distances"]])
    np.testing.assert_array_equal(dist, b.distance)
    mins = np.array([m.msg.data for m in got["/reachwise/min_distance"]])
    np.testing.assert_array_equal(mins, b.min_distance)
    last = got["/reachwise/closest_points"][-1].msg.markers[0]
    line = np.array([[p.x, p.y, p.z] for p in last.points]).reshape(-1, 2, 3)
    np.testing.assert_array_equal(line[:, 0], b.point_a[-1])
    np.testing.assert_array_equal(line[:, 1], b.point_b[-1])


def test_depth_frames_fused_into_a_scene_memory(cell: Path) -> None:
    """With a scene memory the depth topic feeds one object ``memory`` (voxel centres):
    its distance less the memory's inflation never exceeds the brute-force distance to
    the frame's observed points."""
    from reachwise.distance.scene_memory import MemoryConfig

    robot = _cell.panda()
    clouds = _cell.link_clouds(robot)
    config = MemoryConfig(voxel=0.05)
    spec = ReplaySpec(
        joints="/joint_states",
        clouds=("/points", "/depth/image"),
        memory=config,
        memory_box=((-1.0, -1.5, -1.0), (2.0, 1.5, 2.0)),
    )
    res = replay_recording(cell, robot, spec, link_clouds=clouds)
    assert res.pairs[-3:] == tuple(f"{link}|memory" for link in clouds)
    assert res.clouds == {"/points": 10, "/depth/image": 10}
    inflation = 0.5 * np.sqrt(3.0) * config.voxel
    checked = 0
    for f in np.flatnonzero(~np.isnan(res.cloud_stamp[:, -1])):
        stamp = res.cloud_stamp[f, -1]
        k = round((stamp - 0.05) / 0.1)
        pts = _cell.depth_world_points(k, stamp)
        q = _cell.joint_path(res.t[f])
        for p, link in enumerate(clouds, start=3):
            bound = _brute(robot, clouds, q, link, pts)
            assert res.distance[f, p] - inflation <= bound + 1e-9
            checked += 1
    assert checked > 200
    with pytest.raises(InputError, match="memory_box"):
        ReplaySpec(joints="/j", clouds=("/c",), memory=config)


def _millimetres(topic: str, msg: Any, t: float) -> Any:
    """The cell's 32FC1 depth images as 16UC1 millimetres (0: no return)."""
    if topic == "/depth/image":
        z = msg.data.view("<f4").reshape(msg.height, msg.width)
        mm = np.where(np.isfinite(z), np.round(np.nan_to_num(z) * 1000.0), 0.0).astype("<u2")
        msg.encoding, msg.step = "16UC1", msg.width * 2
        msg.data = mm.view(np.uint8).reshape(-1).copy()
    return msg


@pytest.mark.parametrize("encoding", ["32FC1", "16UC1"])
def test_recorded_depth_is_fused_from_its_own_pixels_as_from_float64_metres(
    tmp_path: Path, encoding: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A recorded 32FC1 and 16UC1 depth topic fused into a scene memory from the
    images' own pixels gives the replay (every distance, point and stamp) that the same
    images converted to float64 metres first give."""
    from reachwise.distance.scene_memory import MemoryConfig
    from reachwise.io.ros import cloud_topic
    from reachwise.io.ros.depth_image import depth_image_metres

    hook = _millimetres if encoding == "16UC1" else None
    bag = _cell.write_cell(tmp_path / "depth.mcap", hook, seconds=0.5)
    robot = _cell.panda()
    spec = ReplaySpec(
        joints="/joint_states",
        clouds=("/depth/image",),
        memory=MemoryConfig(voxel=0.05),
        memory_box=((-1.0, -1.5, -1.0), (2.0, 1.5, 2.0)),
        block=True,
    )
    clouds = _cell.link_clouds(robot)
    own = replay_recording(bag, robot, spec, link_clouds=clouds)
    monkeypatch.setattr(
        cloud_topic,
        "depth_image_pixels",
        lambda msg, *, topic: (depth_image_metres(msg, topic=topic), 1.0),
    )
    metres = replay_recording(bag, robot, spec, link_clouds=clouds)
    assert own.clouds == metres.clouds == {"/depth/image": 5}
    assert np.isfinite(own.distance).sum() > 100  # the memory held obstacles
    for field in ("distance", "cloud_stamp", "point_a", "point_b"):
        np.testing.assert_array_equal(getattr(own, field), getattr(metres, field))
