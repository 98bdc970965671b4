"""Result metadata shared by the in-process scene and the server client: sequence,
measurement and computation time stamps, validity; the controller treats both alike."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from numpy.typing import NDArray

from reachwise.benchmarks.server import ServerProcess
from reachwise.control.avoidance import SceneConverter
from reachwise.control.controller import Controller, ControllerConfig, Goal
from reachwise.control.safety import SafetyConfig
from reachwise.distance.scene import Scene, SceneResult
from reachwise.errors import InputError
from reachwise.kinematics.robot import Robot
from reachwise.server.client import SceneClient, ServerSceneResult

from .conftest import HANG_GUARD, crane_q


class Clock:
    def __init__(self, t: float = 0.0) -> None:
        self.t = t
        self.reads = 0

    def __call__(self) -> float:
        self.reads += 1
        return self.t


def _crane_scene(
    scene: Scene | SceneClient, crane: Robot, clouds: dict[str, NDArray[np.float64]]
) -> None:
    scene.add_robot(crane)
    scene.add_object("grabber", clouds["link_6"], robot=crane.name, link="link_6")
    env = np.eye(4)
    env[0, 3] = 3.4
    scene.add_object("environment", clouds["environment"], env)
    scene.add_object("probe", clouds["link_2"], np.eye(4), dynamic=True)
    scene.add_object("post", clouds["link_3"], env)


def test_in_process_stamps_are_the_oldest_input_the_answer_depends_on(
    crane: Robot, clouds: dict[str, NDArray[np.float64]]
) -> None:
    scene = Scene()
    _crane_scene(scene, crane, clouds)
    scene.watch("grabber", "environment", 1.0)
    scene.set_joints(crane.name, crane_q(crane, 0), stamp=2.0)
    scene.set_pose("probe", np.eye(4), stamp=1.0)
    r = scene.query_all()
    # the probe is not in any watched pair: its older stamp does not count
    assert (r.sequence, r.measured_at, r.valid, r.reason) == (1, 2.0, True, "")
    assert math.isnan(r.computed_at)  # no clock: unknown
    scene.watch("probe", "environment", 1.0)
    assert scene.query_all().measured_at == 1.0
    scene.set_pose("probe", np.eye(4), stamp=3.5)
    r2 = scene.query_all()
    assert (r2.sequence, r2.measured_at) == (3, 2.0)
    scene.set_joints(crane.name, crane_q(crane, 1))  # no stamp, no clock: unknown age
    assert math.isnan(scene.query_all().measured_at)
    # fixed objects alone depend on no input
    only_fixed = Scene()
    only_fixed.add_object("a", clouds["link_2"])
    only_fixed.add_object("b", clouds["link_3"], np.diag([1.0, 1.0, 1.0, 1.0]))
    only_fixed.watch("a", "b", 1.0)
    assert math.isnan(only_fixed.query_all().measured_at)
    for bad in (math.nan, math.inf, "1", True):
        with pytest.raises(InputError, match="stamp"):
            scene.set_joints(crane.name, crane_q(crane, 0), stamp=bad)  # type: ignore[arg-type]


def test_in_process_clock_stamps_unstamped_inputs_query_and_answer(
    crane: Robot, clouds: dict[str, NDArray[np.float64]]
) -> None:
    clock = Clock(5.0)
    scene = Scene(clock=clock)
    _crane_scene(scene, crane, clouds)
    scene.watch("grabber", "environment", 1.0)
    scene.watch("post", "environment", 1.0)
    scene.set_joints(crane.name, crane_q(crane, 0))  # stamped 5.0 by the clock
    clock.t = 7.0
    r = scene.query_all()
    assert (r.measured_at, r.computed_at) == (5.0, 7.0)
    scene.set_joints(crane.name, crane_q(crane, 0), stamp=9.0)  # newer than the query
    r = scene.query_all()
    assert (r.measured_at, r.computed_at) == (7.0, 7.0)  # the query's own time


def test_server_results_carry_the_same_fields(
    server: ServerProcess, crane: Robot, clouds: dict[str, NDArray[np.float64]]
) -> None:
    names = {f.name for f in dataclasses.fields(SceneResult)}
    assert names <= {f.name for f in dataclasses.fields(ServerSceneResult)}
    assert {"sequence", "measured_at", "computed_at", "valid", "reason"} <= names
    clock = Clock(100.0)
    with SceneClient(server.endpoint, deadline=HANG_GUARD, clock=clock, mirror=True) as c:
        c.wait_ready(30.0)
        c.clear()
        _crane_scene(c, crane, clouds)
        c.watch("grabber", "environment", 1.0)
        c.set_joints(crane.name, crane_q(crane, 0), stamp=98.5)
        clock.t = 101.0
        r1 = c.query_all()
        r2 = c.query_all()
        c.clear()
    assert isinstance(r1, SceneResult) and r1.valid
    assert (r1.measured_at, r1.computed_at) == (98.5, 101.0)
    assert r2.sequence > r1.sequence and r1.compute_time >= 0.0


def _controller(crane: Robot) -> Controller:
    return Controller(crane, ControllerConfig(safety=SafetyConfig(dt=0.01, stop_ticks=3)))


def test_controller_treats_in_process_and_server_results_alike(
    crane: Robot, clouds: dict[str, NDArray[np.float64]]
) -> None:
    scene = Scene()
    _crane_scene(scene, crane, clouds)
    scene.watch("grabber", "environment", 1.0)
    q = crane_q(crane, 0)
    scene.set_joints(crane.name, q, stamp=0.0)
    conv = SceneConverter(scene, crane)
    goal = Goal.at(crane.fk(q)[:3, 3] + [0.0, 0.2, 0.0])
    good = scene.query_all()
    for cls in (SceneResult, ServerSceneResult):
        ctrl = _controller(crane)
        ok = cls(1, good.pairs, measured_at=0.0, computed_at=0.0)
        cmd0, st = ctrl.step(q, goal, conv(ok), 0.0)
        assert st.state == "moving"
        # missing data: a protective stop naming the reason (ramp: 2/3 of the command)
        missing = cls(1, good.pairs, valid=False, reason="no reply within 10 ms")
        cmd, st = ctrl.step(q, goal, conv(missing, stamp=0.01), 0.01)
        np.testing.assert_allclose(cmd, cmd0 * 2 / 3)
        assert st.state == "protective_stop"
        assert st.reason == "missing distance data: no reply within 10 ms"
        # a result older than its use: the converter keeps the older stamp, so stale
        old = cls(2, good.pairs, measured_at=0.0, computed_at=0.05)
        _, st = ctrl.step(q, goal, conv(old, stamp=0.05), 0.05)
        assert st.state == "protective_stop" and "stale" in st.reason
        # fresh again: control resumes
        fresh = cls(3, good.pairs, measured_at=0.06, computed_at=0.06)
        _, st = ctrl.step(q, goal, conv(fresh), 0.06)
        assert st.state == "moving"
        # a stamp that is unknown (NaN) is refused, too
        unknown = cls(4, good.pairs)
        _, st = ctrl.step(q, goal, conv(unknown), 0.07)
        assert st.state == "protective_stop" and "timestamp" in st.reason
