"""Kill the server with SIGKILL during a simulation: the robot stops safely; restart it
on the same state directory: the scene is restored and the simulation reaches its goal.

The simulation here is a stand-in for ``reachwise.simulate`` (issue 6, in progress): a
kinematic plant driven to a goal at bounded joint speed, 100 Hz, that makes a
protective stop (zero velocity) on missing distance data — an invalid result or a
non-finite distance. :func:`run_simulation` is the one place to change when the real
simulation lands.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from reachwise.benchmarks.server import ServerProcess
from reachwise.kinematics.robot import Robot
from reachwise.server import protocol as P
from reachwise.server.client import SceneClient, SceneLike

from .conftest import build_scene, crane_q, start_server

DT = 0.01  # s, P-V's 10 ms control cycle
SPEED = 0.4  # rad/s (m/s for the telescope), per joint
KILL_AT = 40  # tick
RESTART_AT = 60  # tick: the restart begins (it takes a while: the loop goes on)
MAX_TICKS = 3000


@dataclass(frozen=True)
class Tick:
    k: int
    q: NDArray[np.float64]
    status: str  # "moving", "reached" or "protective stop"
    reason: str
    sequence: int


def stand_in_simulation(
    scene: SceneLike,
    robot: Robot,
    start: NDArray[np.float64],
    goal: NDArray[np.float64],
    on_tick: Callable[[int], None],
) -> list[Tick]:
    """Drive ``robot`` from ``start`` to ``goal``; stop on missing distance data."""
    q = start.copy()
    log: list[Tick] = []
    next_tick = time.monotonic()
    for k in range(MAX_TICKS):
        on_tick(k)
        scene.set_joints(robot.name, q)
        r = scene.query_all()
        valid = bool(getattr(r, "valid", True))
        finite = all(p.result.no_risk or math.isfinite(p.result.distance) for p in r.pairs)
        if valid and finite:
            step = np.clip(goal - q, -SPEED * DT, SPEED * DT)
            status = "reached" if np.max(np.abs(goal - q)) < 1e-9 else "moving"
            q = q + step
            reason = ""
        else:
            status, reason = "protective stop", getattr(r, "reason", "") or "non-finite distance"
        log.append(Tick(k, q.copy(), status, reason, r.sequence))
        if status == "reached":
            break
        next_tick += DT
        time.sleep(max(0.0, next_tick - time.monotonic()))
    return log


def run_simulation(scene: SceneLike, robot: Robot, on_tick: Callable[[int], None]) -> list[Tick]:
    """The simulation this test drives (stand-in until ``reachwise.simulate`` lands)."""
    start, goal = crane_q(robot, 0), crane_q(robot, 150)
    return stand_in_simulation(scene, robot, start, goal, on_tick)


def _describe(endpoint: str) -> P.DescribeReply:
    with SceneClient(endpoint, setup_deadline=10.0) as c:
        return c.describe(clouds=True)


def test_sigkill_stops_the_robot_and_a_restart_restores_the_scene(
    tmp_path: Path, crane: Robot, clouds: dict[str, NDArray[np.float64]]
) -> None:
    workdir = tmp_path / "srv"
    first = start_server(workdir)
    endpoint = first.endpoint
    procs: list[ServerProcess] = [first]
    restarter: list[threading.Thread] = []
    try:
        with SceneClient(endpoint) as setup:
            setup.wait_ready(30.0)
            build_scene(setup, crane, clouds)
            probe = np.eye(4)
            probe[:3, 3] = [3.0, 0.0, 1.2]
            setup.add_object("probe", clouds["link_6"], probe, dynamic=True)
            setup.watch("probe", "link_6", 2.0, "robot-obstacle")
            sequence_before = setup.health().sequence
        before = _describe(endpoint)

        def chaos(k: int) -> None:
            if k == KILL_AT:
                first.kill()  # SIGKILL: no goodbye, no flush
            if k == RESTART_AT:
                # the same address and state directory, started while the loop goes on
                def restart() -> None:
                    procs.append(start_server(workdir, bind=endpoint))

                t = threading.Thread(target=restart)
                t.start()
                restarter.append(t)

        with SceneClient(endpoint, deadline=0.05, batch_inputs=True) as client:
            log = run_simulation(client, crane, chaos)
            reconnects = client.reconnects
        for t in restarter:
            t.join()

        # before the kill: moving on valid data
        assert all(t.status == "moving" for t in log[:KILL_AT])
        # the kill: a protective stop at the very next tick, holding still
        stopped = [t for t in log if t.status == "protective stop"]
        assert log[KILL_AT].status == "protective stop"
        assert stopped and all(t.reason for t in stopped)
        first_stop = stopped[0].k
        resumed = next(t.k for t in log[KILL_AT:] if t.status != "protective stop")
        assert resumed > RESTART_AT
        held = np.array([t.q for t in log[first_stop:resumed]])
        assert np.array_equal(held, np.broadcast_to(log[first_stop - 1].q, held.shape))
        assert all(t.status == "protective stop" for t in log[first_stop:resumed])
        assert reconnects > 0  # Lazy Pirate: fresh sockets after the lost replies
        # after the restart: on to the goal
        assert log[-1].status == "reached"
        assert np.allclose(log[-1].q, crane_q(crane, 150), atol=1e-12)
        assert all(t.status != "protective stop" for t in log[resumed:])
        # the restarted server has the same scene and never repeats a sequence number
        after = _describe(endpoint)
        assert after.robots == before.robots and after.pairs == before.pairs
        assert [(o.name, o.source, o.robot, o.link) for o in after.objects] == [
            (o.name, o.source, o.robot, o.link) for o in before.objects
        ]
        for a, b in zip(after.objects, before.objects, strict=True):
            assert a.cloud is not None and b.cloud is not None
            np.testing.assert_array_equal(a.cloud, b.cloud)
            np.testing.assert_array_equal(a.pose, b.pose)
        assert min(t.sequence for t in log[resumed:]) > max(
            sequence_before, *(t.sequence for t in log[:KILL_AT])
        )
    finally:
        for t in restarter:
            t.join()
        statuses = [p.stop() for p in procs]
    assert statuses[0] == -9  # the one we killed
    assert statuses[1:] == [0], (workdir / "server.log").read_text()
