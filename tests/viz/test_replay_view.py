"""A replayed recording in the viewer: scrubbing to a frame puts the robot at the joint
positions that frame queried, shows the cloud whose stamp the frame reports and the
closest-point lines of the replay's answers; and the clouds kept for display are the
handed-over ones, thinned."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from reachwise.errors import InputError
from reachwise.io.ros.replay import ReplaySpec, replay_recording
from reachwise.viz.replay_view import ROBOT, ReplayClouds, ReplayPlayback
from reachwise.viz.viewer import Viewer
from tests._real_arms import arm_path, needs_erd
from tests.io.ros import _cell
from tests.viz.test_viewer import assert_robot_at, our_threads


@pytest.fixture(scope="module")
def cell(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _cell.write_cell(tmp_path_factory.mktemp("cell") / "cell.mcap")


def test_replay_playback_shows_each_frames_answers(viewer: Viewer, cell: Path) -> None:
    robot = _cell.panda()
    link_clouds = _cell.link_clouds(robot)
    spec = ReplaySpec(joints="/joint_states", clouds=("/points", "/depth/image"), margin=0.3)
    kept = ReplayClouds(max_points=50)
    res = replay_recording(cell, robot, spec, link_clouds=link_clouds, on_cloud=kept)
    # each handed-over cloud kept once, thinned to at most 50 points
    assert {o: len(c) for o, c in kept.clouds.items()} == res.clouds
    assert all(len(p) <= 50 for c in kept.clouds.values() for p in c.values())
    for k, t in enumerate(res.t):  # the frames' joint positions are the recorded ones
        np.testing.assert_allclose(res.q[k], _cell.joint_path(t), atol=1e-12)
    pb = ReplayPlayback(viewer, res, robot, link_clouds, kept)
    assert viewer.active is pb and viewer.mode == "playback"
    depth = res.pairs.index("link_3|/depth/image")
    for k in (res.t.size - 1, 30, 0):
        pb.slider.value = float(res.t[k])
        assert pb.index == k
        assert_robot_at(viewer, ROBOT, res.q[k])
        lines = np.asarray(viewer.nodes["/distance/lines"].points)
        ok = np.isfinite(res.distance[k])
        if not ok.any():  # before the first cloud: no line to show
            assert not viewer.nodes["/distance/lines"].visible
            continue
        expected = np.stack([res.point_a[k][ok], res.point_b[k][ok]], axis=1)
        np.testing.assert_allclose(lines, expected, atol=1e-6)
        red = (np.asarray(viewer.nodes["/distance/lines"].colors)[:, 0, 1] < 100).tolist()  # G
        assert red == (res.distance[k][ok] <= 0.3).tolist()
        shown = np.asarray(viewer.nodes[pb.cloud_node("/depth/image")].points)
        np.testing.assert_array_equal(shown, kept.at("/depth/image", res.cloud_stamp[k, depth]))
    # the kept depth cloud holds every k-th of the frame's points
    last = kept.at("/depth/image", res.cloud_stamp[-1, depth])
    stamp = float(res.cloud_stamp[-1, depth])
    full = _cell.depth_world_points(round((stamp - 0.05) / 0.1), stamp)
    step = int(np.ceil(len(full) / 50))
    assert last is not None and len(last) == len(full[::step])
    from scipy.spatial.distance import cdist

    assert cdist(last, full).min(axis=1).max() < 1e-6  # each one a point of the frame
    pb.stop()
    assert "reachwise-playback" not in our_threads()


def test_a_replay_without_frames_or_of_another_robot_is_refused(viewer: Viewer, cell: Path) -> None:
    robot = _cell.panda()
    spec = ReplaySpec(joints="/joint_states", clouds=("/points",))
    res = replay_recording(cell, robot, spec, link_clouds=_cell.link_clouds(robot))
    import dataclasses

    import reachwise

    with pytest.raises(InputError, match="not"):
        ReplayPlayback(viewer, res, reachwise.load_robot("puma560"), {}, ReplayClouds())
    empty = dataclasses.replace(res, t=res.t[:0], q=res.q[:0])
    with pytest.raises(InputError, match="no frames"):
        ReplayPlayback(viewer, empty, robot, {}, ReplayClouds())
    with pytest.raises(InputError, match="max_points"):
        ReplayClouds(max_points=0)


@needs_erd
def test_reachwise_replay_view_serves_until_ctrl_c(tmp_path: Path) -> None:
    """``reachwise replay … --view`` writes its files, prints the viewer's URL, serves
    the page, and Ctrl-C ends it cleanly with the port freed."""
    import os
    import signal
    import subprocess
    import sys
    import time
    import urllib.request

    from tests.cli.test_replay import UR5
    from tests.conftest import sigint_default
    from tests.viz.test_viewer import port_open

    bag = _cell.write_cell(tmp_path / "cell.mcap", seconds=0.3, joints=UR5)
    args = ["replay", str(bag), "--robot", str(arm_path("ur5")), "--tip", "tool0",
            "--clouds", "/points", "--points", "100", "--out", str(tmp_path / "out"),
            "--view", "--port", "0"]  # fmt: skip
    env = dict(os.environ, PYTHONUNBUFFERED="1", COLUMNS="200")
    proc = subprocess.Popen(
        [sys.executable, "-c", "from reachwise.cli import main; main()", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=env,
        preexec_fn=sigint_default,
    )
    try:
        assert proc.stdout is not None
        seen: list[str] = []
        end = time.monotonic() + 120
        while not any("viewer at" in x for x in seen) and time.monotonic() < end:
            line = proc.stdout.readline()
            if not line and proc.poll() is not None:
                break
            seen.append(line)
        text = "".join(seen)
        assert "viewer at" in text, text
        assert (tmp_path / "out" / "distances.csv").exists()
        url = next(w for x in seen if "viewer at" in x for w in x.split() if "http" in w)
        port = int(url.rstrip(":").rsplit(":", 1)[1])
        with urllib.request.urlopen(url, timeout=10) as r:
            assert r.status == 200 and b"<html" in r.read().lower()
        time.sleep(0.5)
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=30) == 0
        assert not port_open(port)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)
