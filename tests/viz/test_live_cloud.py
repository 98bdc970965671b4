"""The viewer shows a depth camera's live cloud: the frame in the scene at each shown
tick, in playback of a log and in a live run (server side, no browser)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

import reachwise
from reachwise.sim.scenarios import load_scenario, scenario_from_dict
from reachwise.sim.world import build_world
from reachwise.viz.viewer import Viewer

HALF = np.array([0.2, 0.2, 0.85])  # the walker's half sizes


@pytest.fixture(scope="module")
def scenario() -> Any:
    """A box person walks past a Panda; a small noiseless camera watches."""
    data = {
        "name": "camera-view",
        "dt": 0.01,
        "duration": 0.6,
        "robots": [
            {
                "name": "arm",
                "robot": "panda",
                "q0": [-0.7435, 0.0963, 0.0846, -2.0309, -0.0096, 2.1269, -0.6543],
                "links": ["link_7"],
                "link_clouds": {"link_7": {"mesh": "meshes/panda-hand.obj", "points": 100}},
                "goals": [{"xyz": [0.45, -0.2, 0.45], "dims": 3}],
            }
        ],
        "objects": [
            {
                "name": "walker",
                "box": [0.4, 0.4, 1.7],
                "scene": False,
                "pose": {"xyz": [1.2, -1.0, 0.85]},
                "motion": {"velocity": [0.0, 1.0, 0.0]},
            }
        ],
        "sensors": [
            {
                "kind": "depth",
                "name": "cam",
                "pose": {"xyz": [3.0, -0.3, 1.2]},
                "look_at": [1.0, -0.5, 0.6],
                "width": 48,
                "height": 36,
                "latency": 0.02,
            }
        ],
        "watch": [{"robot": "arm", "environment": ["cam"], "margin": 0.1}],
    }
    return scenario_from_dict(data, "camera-view.yaml", load_scenario("trap").folder)


def assert_shows_frame(viewer: Viewer, sc: Any, tick: int) -> None:
    """The cloud on screen is the frame in the scene at ``tick``: every point on the
    walker's box where it stood at that frame's capture, and a frame's worth of them."""
    sensor = build_world(sc).sensors[0]
    k = sensor.frame_in_use(tick)
    assert k > 0
    t = sensor.capture_tick(k) * sc.spec.dt
    centre = np.array([1.2, -1.0 + t, 0.85])
    pts = np.asarray(viewer.nodes["/env/cam"].points, dtype=float)
    local = np.abs(pts - centre)
    assert len(pts) > 50
    np.testing.assert_allclose(np.max(local - HALF, axis=1), 0.0, atol=2e-5)  # float32


def test_playback_shows_the_frame_in_use_at_each_tick(viewer: Viewer, scenario: Any) -> None:
    from reachwise.viz.playback import Playback

    log = reachwise.simulate(scenario)
    pb = Playback(viewer, log, build_world(scenario))
    shown = []
    for k in (40, 12, log.t.size - 1):
        pb.slider.value = float(log.t[k])
        assert pb.index == k
        assert_shows_frame(viewer, scenario, k)
        shown.append(np.array(viewer.nodes["/env/cam"].points))
        walker = np.asarray(viewer.nodes["/env/walker"].position)
        np.testing.assert_allclose(walker, log.object_poses["walker"][k][:3, 3], atol=1e-6)
    assert not np.array_equal(shown[0], shown[1])  # the walker moved between the frames


def test_a_live_run_shows_the_newest_frame(viewer: Viewer, scenario: Any) -> None:
    from reachwise.viz.live import LiveRun

    run = LiveRun(viewer, scenario, speed=0.0, fps=1e6)
    log = run.run()
    assert log is not None and run.error is None
    assert_shows_frame(viewer, scenario, log.t.size - 1)
