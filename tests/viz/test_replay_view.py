"""A replayed recording in the viewer: scrubbing to a frame puts the robot at the joint
positions that frame queried, shows the cloud whose stamp the frame reports and the
closest-point lines of the replay's answers; and the clouds kept for display are the
handed-over ones, thinned. With a scene memory, each frame shows the memory's occupied,
shadow and free voxels as the memory held them after the depth frame it used."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from reachwise.errors import InputError
from reachwise.io.ros.replay import ReplaySpec, replay_recording
from reachwise.viz.memory_voxels import memory_node
from reachwise.viz.replay_view import ROBOT, ReplayClouds, ReplayMemory, ReplayPlayback
from reachwise.viz.scene_data import voxel_centres
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
    """``reachwise replay … --view`` (here with a scene memory) writes its files,
    prints the viewer's URL, serves the page, and Ctrl-C ends it cleanly with the port
    freed."""
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
            "--clouds", "/points", "--clouds", "/depth/image", "--memory", "0.05",
            "--memory-box=-1,-1.5,-1,2,1.5,2", "--points", "100", "--out", str(tmp_path / "out"),
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


def test_a_replayed_scene_memory_is_shown_by_its_voxels(viewer: Viewer, cell: Path) -> None:
    """The memory's voxels shown at a frame are those the memory held after the depth
    frame that frame's answers used (their counts those it reported), whichever way the
    playback seeks (copies every 3 frames: the grid is rebuilt from its changes)."""
    from reachwise.distance.scene_memory import STATES, MemoryConfig, SceneMemory

    robot = _cell.panda()
    link_clouds = _cell.link_clouds(robot)
    spec = ReplaySpec(
        joints="/joint_states",
        clouds=("/points", "/depth/image"),
        memory=MemoryConfig(voxel=0.05),
        memory_box=((-1.0, -1.5, -1.0), (2.0, 1.5, 2.0)),
    )
    kept, tape = ReplayClouds(max_points=50), ReplayMemory(every=3)
    truth: dict[float, tuple[np.ndarray, tuple[int, ...]]] = {}

    def on_memory(stamp: float, memory: SceneMemory) -> None:
        truth[stamp] = (memory.state.copy(), tuple(memory.counts()))
        tape(stamp, memory)

    res = replay_recording(
        cell, robot, spec, link_clouds=link_clouds, on_cloud=kept, on_memory=on_memory
    )
    assert len(truth) == res.clouds["/depth/image"] == 10
    pb = ReplayPlayback(viewer, res, robot, link_clouds, kept, memory=tape)
    column = res.pairs.index("link_3|memory")
    frames = np.flatnonzero(~np.isnan(res.cloud_stamp[:, column]))
    assert len({float(res.cloud_stamp[k, column]) for k in frames}) == 10
    codes = dict(zip(("unknown", "free", "occupied", "shadow"), range(4), strict=True))
    for k in (frames[-1], frames[0], frames[len(frames) // 2], frames[-1], frames[5]):
        pb.slider.value = float(res.t[k])
        assert pb.index == k
        state, counts = truth[float(res.cloud_stamp[k, column])]
        for name in ("occupied", "shadow", "free"):
            shown = np.asarray(viewer.nodes[memory_node("memory", name)].points)
            n = counts[codes[name]]
            assert len(shown) == n if n else not viewer.nodes[memory_node("memory", name)].visible
            if n:
                want = voxel_centres(state, (-1.0, -1.5, -1.0), 0.05, STATES[name], n)
                np.testing.assert_allclose(shown, want, atol=1e-6)
    last = truth[float(res.cloud_stamp[frames[-1], column])][1]
    assert last[codes["occupied"]] > 0 and last[codes["free"]] > 0  # something to see
    assert pb.cloud_node("memory") not in viewer.nodes  # not also as a plain cloud
    pb.stop()


def test_replay_memory_rebuilds_every_grid_in_any_order() -> None:
    """:class:`ReplayMemory` gives, for each stamp, the grid the memory held after that
    frame, read in any order (random grids, copies every 4 frames)."""
    from reachwise.distance.scene_memory import SceneMemory

    rng = np.random.default_rng(3)
    memory = SceneMemory((0.0, 0.0, 0.0), (0.3, 0.2, 0.1))
    tape = ReplayMemory(every=4)
    grids = []
    for k in range(13):
        flip = np.asarray(rng.random(memory.state.shape) < 0.2)
        memory.state[flip] = rng.integers(0, 4, int(np.count_nonzero(flip))).astype(np.uint8)
        grids.append(memory.state.copy())
        tape(0.1 * k, memory)
    for k in [12, 0, 5, 6, 7, 3, 11, 8, 8, 1, 12]:
        np.testing.assert_array_equal(tape.state_at(0.1 * k), grids[k])
    assert tape.state_at(5.0) is None
    with pytest.raises(InputError, match="every"):
        ReplayMemory(every=0)
