"""``reachwise simulate --bag``: the Panda, a person walking and a depth camera
(panda-person-camera, shortened) written as a recording and replayed: every pair's
per-frame distance equals the live run's wherever the replay used the same cloud (the
scene's input, recorded exactly: ``/camera/points``), and within float32 depth
rounding from the depth images."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

import reachwise
import reachwise.cli as cli
from reachwise.distance.scene import OnLink
from reachwise.io.ros.bag import Recording
from reachwise.sim.log import load_log
from reachwise.sim.world import build_world


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    tmp = tmp_path_factory.mktemp("sim")
    bag, out = tmp / "run.mcap", tmp / "out"
    argv = ["reachwise", "simulate", "panda-person-camera", "--duration", "4", "--bag",
            str(bag), "--out", str(out), "--no-figures"]  # fmt: skip
    mp = pytest.MonkeyPatch()
    mp.setattr(sys, "argv", argv)
    try:
        cli.main()
    except SystemExit as exc:
        assert exc.code in (0, None)
    finally:
        mp.undo()
    return bag, out


def _replay(bag: Path, topic: str) -> tuple[reachwise.Robot, object, object]:
    world = build_world("panda-person-camera")
    clouds = {
        o.source.link: o.cloud for o in world.scene.objects.values() if isinstance(o.source, OnLink)
    }
    robot = world.agents[0].robot
    res = reachwise.replay(bag, robot, clouds=topic, link_clouds=clouds, margin=0.25)
    return world, res, clouds


def _live_stamps(world: object, out: Path) -> tuple[object, np.ndarray]:
    log = load_log(out / "avoidance")
    s = world.sensors[0]  # type: ignore[attr-defined]
    return log, np.array([s.capture_tick(int(k)) * s.dt for k in log.frames["camera"]])


def test_the_bag_holds_the_run(run: tuple[Path, Path]) -> None:
    bag, out = run
    log = load_log(out / "avoidance")
    with Recording(bag) as rec:
        assert rec.topics["/joint_states"] == "sensor_msgs/msg/JointState"
        assert rec.topics["/camera/depth/image_rect_raw"] == "sensor_msgs/msg/Image"
        assert rec.topics["/camera/depth/camera_info"] == "sensor_msgs/msg/CameraInfo"
        assert rec.topics["/tf_static"] == "tf2_msgs/msg/TFMessage"
        js = [m for m in rec.messages(["/joint_states"])]
    assert len(js) == log.t.size
    np.testing.assert_array_equal(np.array([m.msg.position for m in js]), log.q["arm"])


def test_replay_equals_the_live_run(run: tuple[Path, Path]) -> None:
    bag, out = run
    world, res, _ = _replay(bag, "/camera/points")
    log, live_stamp = _live_stamps(world, out)
    assert res.pairs == ("link_3|/camera/points", "link_5|/camera/points", "link_7|/camera/points")
    assert log.pairs == ("arm/link_3|camera", "arm/link_5|camera", "arm/link_7|camera")
    np.testing.assert_allclose(res.t, log.t, rtol=0, atol=1e-12)
    same = np.abs(res.cloud_stamp - live_stamp[:, None]) < 1e-12  # the same cloud
    compared = same & np.isfinite(log.distance)  # the live run reports within its margin
    assert compared.sum() > 200
    assert np.abs(res.distance[compared] - log.distance[compared]).max() <= 1e-9


def test_reachwise_replay_with_the_scenario_equals_the_live_run(
    run: tuple[Path, Path], tmp_path: Path
) -> None:
    """The command line: ``reachwise replay run.mcap --scenario panda-person-camera``
    (robot and link clouds from the scenario); distances.csv against the live log."""
    import csv

    bag, out = run
    argv = ["reachwise", "replay", str(bag), "--scenario", "panda-person-camera",
            "--clouds", "/camera/points", "--margin", "0.25", "--out", str(tmp_path)]  # fmt: skip
    mp = pytest.MonkeyPatch()
    mp.setattr(sys, "argv", argv)
    try:
        cli.main()
    except SystemExit as exc:
        assert exc.code in (0, None)
    finally:
        mp.undo()
    world = build_world("panda-person-camera")
    log, live_stamp = _live_stamps(world, out)
    column = {f"{p.split('|')[0].split('/')[1]}|/camera/points": j for j, p in enumerate(log.pairs)}
    compared = 0
    for row in csv.DictReader((tmp_path / "distances.csv").open()):
        k = int(np.argmin(np.abs(log.t - float(row["time"]))))
        live = log.distance[k, column[row["pair"]]]
        if abs(float(row["cloud_stamp"]) - live_stamp[k]) < 1e-12 and np.isfinite(live):
            assert abs(float(row["distance"]) - live) <= 1e-9
            compared += 1
    assert compared > 200


def test_replay_from_the_depth_images(run: tuple[Path, Path]) -> None:
    bag, out = run
    world, res, _ = _replay(bag, "/camera/depth/image_rect_raw")
    log, live_stamp = _live_stamps(world, out)
    same = np.abs(res.cloud_stamp - live_stamp[:, None]) < 1e-12
    compared = same & np.isfinite(log.distance)
    assert compared.sum() > 200
    # 32FC1 depth: float32 rounding of depths up to a few metres, about 1e-7 m
    assert np.abs(res.distance[compared] - log.distance[compared]).max() <= 1e-6


def test_reachwise_simulate_bag_writes_what_the_command_writes(
    run: tuple[Path, Path], tmp_path: Path
) -> None:
    """``reachwise.simulate(..., bag=)`` (the same scenario and duration): the same
    run, and a recording with the same messages at the same times as ``simulate --bag``
    wrote, topic by topic (joint positions, depth pixels, clouds, TF)."""
    from reachwise.errors import InputError

    bag, out = run
    api_bag = tmp_path / "api.mcap"
    log = reachwise.simulate("panda-person-camera", duration=4.0, bag=api_bag)
    np.testing.assert_array_equal(log.q["arm"], load_log(out / "avoidance").q["arm"])

    def content(path: Path) -> dict[str, list[tuple[float, bytes]]]:
        with Recording(path) as rec:
            topics = sorted(rec.topics)
            got: dict[str, list[tuple[float, bytes]]] = {t: [] for t in topics}
            for m in rec.messages(topics):
                msg = m.msg
                if hasattr(msg, "position"):
                    data = np.asarray(msg.position).tobytes()
                elif hasattr(msg, "data"):
                    data = bytes(np.asarray(msg.data))
                elif hasattr(msg, "transforms"):
                    data = repr([(x.child_frame_id, x.transform) for x in msg.transforms]).encode()
                else:
                    data = repr(msg).encode()
                got[m.topic].append((m.t, data))
        return got

    ours, theirs = content(api_bag), content(bag)
    assert sorted(ours) == sorted(theirs)
    for topic in theirs:
        assert ours[topic] == theirs[topic], topic
    assert len(ours["/joint_states"]) == log.t.size
    with pytest.raises(InputError, match="exists already"):
        reachwise.simulate("panda-person-camera", duration=0.1, bag=api_bag)
    with pytest.raises(InputError, match="not both"):
        reachwise.simulate(
            "panda-person-camera", duration=0.1, bag=tmp_path / "b.mcap", recorder=object()
        )  # type: ignore[arg-type]
