"""Kill the server with SIGKILL during a simulation: the robot stops safely; restart it
on the same state directory: the scene is restored and the simulation reaches its goal.

The simulation is the real one (:func:`reachwise.sim.simulate.simulate` with
``server=``): the crane of P-V, its controller with the safety layer, a kinematic plant
and a scenario of our own. It runs in simulated time; the kill and the restart are real
and happen from its ``on_tick`` hook, so they land on known ticks: the server is killed
right after the answer of tick :data:`KILL_AT`, and a restart on the same address and
state directory begins on a thread while the simulation goes on.

No pass/fail decision rests on how fast a reply comes. While the server is known to be
up, a tick's reply deadline is a generous hang guard (:data:`LIVE_DEADLINE`), so a
slow reply on a loaded machine is still data. From the kill until the first valid
answer after it, no reply can come from the dead server, and the deadline is short
(:data:`DOWN_DEADLINE`): each such tick is missing data whatever the machine's load,
and its deadline of real time paces the outage while the restart runs.
"""

from __future__ import annotations

import math
import threading
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray

from reachwise.api import simulate
from reachwise.benchmarks.server import ServerProcess
from reachwise.distance.scene import SceneResult
from reachwise.distance.scene_queries import SceneDescription
from reachwise.io.robot_file import robot_to_dict
from reachwise.server import protocol as P
from reachwise.server.client import SceneClient, ServerOptions
from reachwise.sim.scenarios import scenario_from_dict

from .conftest import start_server

KILL_AT = 60  # tick: the server dies right after answering it
STOP_TICKS = 4  # the controller's protective-stop ramp (ticks)
LIVE_DEADLINE = 60.0  # s, per tick while the server is up: only a hang guard
DOWN_DEADLINE = 0.2  # s, per tick while it is known to be down: paces the outage
TICK_REQUESTS = (P.Query, P.SetJoints, P.SetPose)
RESTART_AT = KILL_AT + STOP_TICKS + 3  # tick: the restart begins (the outage outlasts the stop)


def _scenario(folder: Path, environment: NDArray[np.float64]) -> dict[str, object]:
    """The crane's tool goes 1.2 m sideways past a rock (3-D goal, ~6 s at 0.25 m/s)."""
    np.save(folder / "rock.npy", environment)
    return {
        "name": "server-kill",
        "dt": 0.01,
        "duration": 30.0,
        "robots": [{
            "name": "crane", "robot": "hiab-xs033",
            "q0": [0.4161, 1.0425, -2.0918, 0.2913, 0.0, 0.0],
            "links": ["link_3", "link_6"], "points": 300,
            "controller": {"v_max": 0.25, "stop_ticks": STOP_TICKS,
                           "position_tolerance": 0.01},
            "plant": {"kind": "kinematic"},
            "goals": [{"name": "goal", "xyz": [2.15, -0.25, 1.3], "dims": 3}],
        }],
        "objects": [{"name": "rock", "file": "rock.npy", "pose": {"xyz": [3.3, 0.0, 0.0]}}],
        "watch": [{"robot": "crane", "environment": ["rock"], "margin": 0.3}],
    }  # fmt: skip


def _describe(endpoint: str) -> SceneDescription:
    with SceneClient(endpoint, setup_deadline=20.0) as c:
        c.wait_ready(30.0)
        return c.describe(clouds=True)


def test_sigkill_stops_the_robot_and_a_restart_restores_the_scene(
    tmp_path: Path, clouds: dict[str, NDArray[np.float64]], monkeypatch: pytest.MonkeyPatch
) -> None:
    sc = scenario_from_dict(_scenario(tmp_path, clouds["environment"]), "test", tmp_path)
    workdir = tmp_path / "srv"
    first = start_server(workdir)
    endpoint = first.endpoint
    procs: list[ServerProcess] = [first]
    restarter: list[threading.Thread] = []
    answers: list[tuple[float, int, bool, str]] = []  # t, sequence, valid, reason
    before: list[SceneDescription] = []
    down = threading.Event()  # set from the kill until the first valid answer after it
    real_call, real_query_all = SceneClient.call, SceneClient.query_all

    def call(self: SceneClient, request: P.Request, deadline: float | None = None) -> P.Reply:
        if isinstance(request, TICK_REQUESTS):
            deadline = DOWN_DEADLINE if down.is_set() else LIVE_DEADLINE
        return real_call(self, request, deadline)

    def query_all(
        self: SceneClient,
        *,
        pairs: list[tuple[str, str]] | None = None,
        deadline: float | None = None,
    ) -> SceneResult:
        # the binary tick does not go through call(): its deadline is set here
        deadline = DOWN_DEADLINE if down.is_set() else LIVE_DEADLINE
        return real_query_all(self, pairs=pairs, deadline=deadline)

    monkeypatch.setattr(SceneClient, "call", call)
    monkeypatch.setattr(SceneClient, "query_all", query_all)

    def chaos(t: float, q: dict[str, NDArray[np.float64]], res: SceneResult) -> None:
        answers.append((t, res.sequence, res.valid, res.reason))
        if res.valid and down.is_set():
            down.clear()  # the restarted server answers: back to the hang guard
        if len(answers) - 1 == KILL_AT:
            before.append(_describe(endpoint))  # the scene the simulation registered
            first.kill()  # SIGKILL: no goodbye, no flush
            down.set()
        if len(answers) - 1 == RESTART_AT:  # the robot has stopped: bring the server back

            def restart() -> None:  # the same address and state directory
                procs.append(start_server(workdir, bind=endpoint))

            thread = threading.Thread(target=restart)
            thread.start()
            restarter.append(thread)

    try:
        log = simulate(sc, server=ServerOptions(endpoint, deadline=LIVE_DEADLINE), on_tick=chaos)
        for thread in restarter:
            thread.join()
        after = _describe(endpoint)
    finally:
        for thread in restarter:
            thread.join()
        statuses = [p.stop() for p in procs]
    assert statuses[0] == -9  # the one we killed
    assert statuses[1:] == [0], (workdir / "server.log").read_text()

    state = log.state["crane"]
    cmd = log.command["crane"]
    q = log.q["crane"]
    # before the kill: valid answers, moving
    assert all(valid for _, _, valid, _ in answers[: KILL_AT + 1])
    assert set(state[: KILL_AT + 1]) == {"moving"}
    assert np.abs(cmd[KILL_AT]).max() > 0.01
    # the kill: missing data at the very next tick, a protective stop with its reason
    stop = KILL_AT + 1
    assert not answers[stop][2] and "no reply" in answers[stop][3]
    resumed = next(k for k in range(stop, len(answers)) if answers[k][2])
    assert resumed > stop + STOP_TICKS  # the outage outlasts the stop ramp
    assert set(state[stop:resumed]) == {"protective_stop"}
    stops = [e for e in log.events if e.kind == "protective_stop"]
    assert len(stops) == 1 and math.isclose(stops[0].t, log.t[stop])
    assert "missing distance data" in stops[0].text and "no reply" in stops[0].text
    # zero commanded velocity within the configured ticks: a linear ramp down, then 0
    speed = np.abs(cmd).max(axis=1)
    ramp = speed[stop - 1 : stop + STOP_TICKS]
    assert np.all(np.diff(ramp) < 0)
    for j in range(1, STOP_TICKS):
        np.testing.assert_allclose(
            cmd[stop - 1 + j], cmd[stop - 1] * (STOP_TICKS - j) / STOP_TICKS, atol=1e-15
        )
    assert np.all(cmd[stop - 1 + STOP_TICKS : resumed] == 0.0)
    # and the robot stands still from then on (kinematic plant)
    still = q[stop + STOP_TICKS : resumed + 1]
    assert np.array_equal(still, np.broadcast_to(still[0], still.shape))
    # after the restart: the same scene, fresh sequence numbers, on to the goal
    b = before[0]
    assert {k: robot_to_dict(r) for k, r in after.robots.items()} == {
        k: robot_to_dict(r) for k, r in b.robots.items()
    }
    assert after.pairs == b.pairs
    assert [(o.name, o.source, o.robot, o.link) for o in after.objects] == [
        (o.name, o.source, o.robot, o.link) for o in b.objects
    ]
    for x, y in zip(after.objects, b.objects, strict=True):
        assert x.cloud is not None and y.cloud is not None
        np.testing.assert_array_equal(x.cloud, y.cloud)
        np.testing.assert_array_equal(x.pose, y.pose)
    seq_before = [s for _, s, _, _ in answers[: KILL_AT + 1]]
    seq_after = [s for _, s, valid, _ in answers[resumed:] if valid]
    assert all(valid for _, _, valid, _ in answers[resumed:])
    assert min(seq_after) > max(seq_before)
    assert np.all(np.diff(seq_after) > 0)
    assert "protective_stop" not in set(state[resumed:])
    assert log.all_goals_reached, log.goals
    assert log.goals[0].reached_at is not None and log.goals[0].reached_at > log.t[resumed]
    assert log.first_collision is None
