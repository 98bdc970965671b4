"""The stale-data rule covers the clouds: a watched cloud older than its allowed age
stops the robot like stale joint states, a fresh one lets it resume; and the
converter's compiled path over answer rows gives the points of its loop over pairs."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

import reachwise
from reachwise.control import Controller, ControllerConfig, Goal, SafetyConfig, SceneConverter
from reachwise.distance import Scene
from reachwise.distance.scene import SceneResult

DT = 1e-3


@pytest.fixture(scope="module")
def panda() -> reachwise.Robot:
    return reachwise.load_robot("panda")


Q0 = np.array([0.0, -0.5, 0.0, -2.0, 0.0, 1.6, 0.8])


def _scene(robot: reachwise.Robot, rng: np.random.Generator, clock: bool = False) -> Scene:
    scene = Scene(clock=(lambda: 0.0) if clock else None)
    scene.add_robot(robot, Q0, stamp=0.0)
    for link in ("link_3", "link_5", "link_7", "tool"):
        scene.add_object(link, rng.normal(scale=0.05, size=(100, 3)), robot="panda", link=link)
    scene.add_object("map", rng.normal(scale=0.2, size=(300, 3)) + np.array([0.0, 0.0, -1.0]))
    scene.add_object("camera", rng.normal(scale=0.2, size=(300, 3)) + np.array([2.0, 2.0, 0.0]))
    scene.watch_environment("panda", 0.1)
    return scene


def _tick(
    scene: Scene, conv: SceneConverter, c: Controller, goal: Goal, k: int
) -> tuple[np.ndarray, object]:
    t = k * DT
    scene.set_joints("panda", Q0, stamp=t)
    pts = conv(scene.query_all(), stamp=t)
    return c.step(Q0, goal, pts, t)


def test_a_cloud_older_than_its_age_stops_the_robot_and_a_fresh_one_resumes(
    panda: reachwise.Robot, rng: np.random.Generator
) -> None:
    scene = _scene(panda, rng)
    scene.replace_cloud("camera", rng.normal(size=(400, 3)) + np.array([2.0, 2.0, 0.0]),
                        block=True, stamp=0.0)  # fmt: skip
    safety = SafetyConfig(dt=DT, max_age_ticks=2, stop_ticks=4, max_cloud_age=0.05)
    c = Controller(panda, ControllerConfig(safety=safety))
    free = Controller(panda, ControllerConfig(safety=SafetyConfig(dt=DT)))  # inf: no bound
    conv = SceneConverter(scene, panda)
    goal = Goal(panda.fk(Q0 + 0.2))
    for k in range(51):  # the camera cloud is 0 … 50 ms old: moving
        qd, st = _tick(scene, conv, c, goal, k)
        assert st.state == "moving", (k, st.reason)  # type: ignore[attr-defined]
    cmds = []
    for k in range(51, 58):  # older than 50 ms: a protective stop within 4 ticks
        qd, st = _tick(scene, conv, c, goal, k)
        assert st.state == "protective_stop"  # type: ignore[attr-defined]
        assert "stale cloud 'camera'" in st.reason  # type: ignore[attr-defined]
        cmds.append(float(np.abs(qd).max()))
    assert cmds[0] > 0.0 and all(a >= b for a, b in itertools.pairwise(cmds))
    assert cmds[3] == 0.0 and cmds[-1] == 0.0
    # without a bound the same old cloud never stops the robot
    _, st_free = _tick(scene, conv, free, goal, 57)
    assert st_free.state == "moving"  # type: ignore[attr-defined]
    # a fresh frame: control resumes at the next tick
    scene.replace_cloud("camera", rng.normal(size=(400, 3)) + np.array([2.0, 2.0, 0.0]),
                        block=True, stamp=58 * DT)  # fmt: skip
    qd, st = _tick(scene, conv, c, goal, 58)
    assert st.state == "moving" and np.abs(qd).max() > 0  # type: ignore[attr-defined]
    scene.close()


def test_clouds_that_do_not_age_never_stop_and_an_unknown_stamp_does(
    panda: reachwise.Robot, rng: np.random.Generator
) -> None:
    scene = _scene(panda, rng)  # every cloud added without a stamp: +inf, no age
    safety = SafetyConfig(dt=DT, stop_ticks=2, max_cloud_age=0.01)
    c = Controller(panda, ControllerConfig(safety=safety))
    conv = SceneConverter(scene, panda)
    goal = Goal(panda.fk(Q0 + 0.2))
    _, st = _tick(scene, conv, c, goal, 10_000)
    assert st.state == "moving"  # type: ignore[attr-defined]
    scene.replace_cloud("camera", rng.normal(size=(50, 3)) + 3.0, block=True)  # no clock: NaN
    _, st = _tick(scene, conv, c, goal, 10_001)
    assert st.state == "protective_stop"  # type: ignore[attr-defined]
    assert "'camera' without a valid timestamp" in st.reason  # type: ignore[attr-defined]
    with pytest.raises(ValueError, match="max_cloud_age"):
        SafetyConfig(max_cloud_age=0.0)
    scene.close()


def test_the_rows_path_gives_the_points_of_the_pair_loop(
    panda: reachwise.Robot, rng: np.random.Generator
) -> None:
    scene = Scene()
    scene.add_robot(panda, Q0, stamp=0.0)
    for link in panda.link_names[1:]:
        scene.add_object(link, rng.normal(scale=0.08, size=(150, 3)), robot="panda", link=link)
    scene.add_object("box", rng.uniform(-0.6, 0.6, size=(800, 3)) + np.array([0.3, 0.0, 0.4]))
    scene.add_object("scan", rng.normal(scale=0.3, size=(500, 3)))
    scene.replace_cloud("scan", rng.normal(scale=0.3, size=(500, 3)), block=True, stamp=0.5)
    scene.watch_environment("panda", 0.3)
    scene.watch_self("panda", 0.2)
    scene.watch("box", "scan", 10.0)  # a pair without the robot: never a point
    conv = SceneConverter(
        scene, panda, tool_links=("link_7", "tool"), margins={("link_3", "box"): 0.1}
    )
    seen = 0
    for _ in range(20):
        scene.set_joints(
            "panda", panda.lower + rng.uniform(0, 1, panda.n) * (panda.upper - panda.lower)
        )
        res = scene.query_all()
        fast = conv(res, stamp=1.0)
        plain = SceneResult(
            res.sequence, tuple(res.pairs), versions=res.versions, cloud_stamps=res.cloud_stamps
        )
        slow = conv(plain, stamp=1.0)
        assert fast.pairs == slow.pairs and len(fast) == len(slow)
        for f in ("a_link", "a_point", "b_link", "b_point", "normal", "distance", "margin",
                  "task_space", "obstacle_velocity"):  # fmt: skip
            np.testing.assert_array_equal(getattr(fast, f), getattr(slow, f), err_msg=f)
        assert (fast.cloud_stamp, fast.cloud) == (slow.cloud_stamp, slow.cloud) == (0.5, "scan")
        seen += len(fast)
        assert fast.stamp == slow.stamp == 1.0
    assert seen > 20  # self pairs, environment pairs, tool parts: the rules were exercised
    scene.close()
