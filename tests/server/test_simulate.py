"""``reachwise simulate --server``: the same simulation on a collision server process
as in process (identical logs), twice on one server (each run owns its scene), and
through the command line."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import typer
from typer.testing import CliRunner

from reachwise.api import simulate
from reachwise.benchmarks.server import ServerProcess
from reachwise.cli.simulate import simulate as simulate_cli
from reachwise.io.robot_file import load_robot
from reachwise.server.client import SceneClient, ServerOptions, owned_scene
from reachwise.sim.log import SimulationLog

from .conftest import HANG_GUARD

SCENARIO = "p5-crane-obstacle"
DURATION = 2.5  # s: the grabber comes within its margin of the scan before this


def _assert_identical(remote: SimulationLog, local: SimulationLog) -> None:
    assert remote.pairs == local.pairs and remote.t.size == local.t.size
    for r in local.robots:
        np.testing.assert_array_equal(remote.q[r], local.q[r])
        np.testing.assert_array_equal(remote.command[r], local.command[r])
        np.testing.assert_array_equal(remote.state[r], local.state[r])
    np.testing.assert_array_equal(remote.distance, local.distance)
    np.testing.assert_array_equal(remote.signed, local.signed)
    assert remote.events == local.events


def test_simulation_on_a_server_equals_the_one_in_process(server: ServerProcess) -> None:
    local = simulate(SCENARIO, duration=DURATION)
    # the avoidance is active in this window: the comparison covers the repulsion
    assert np.nanmin(local.distance) < local.margins.max()
    assert not any(e.kind == "protective_stop" for e in local.events)
    link = ServerOptions(server.endpoint, deadline=HANG_GUARD)
    first = simulate(SCENARIO, duration=DURATION, server=link)
    _assert_identical(first, local)
    # a second run clears the server's scene and registers its own again
    second = simulate(SCENARIO, duration=DURATION, server=link)
    _assert_identical(second, local)
    with SceneClient(server.endpoint, setup_deadline=HANG_GUARD) as c:
        d = c.describe()
    assert [f"{p.a}|{p.b}" for p in d.pairs] == list(local.pairs)
    assert sorted(d.robots) == ["crane"]


def test_simulate_command_takes_server(server: ServerProcess, tmp_path: Path) -> None:
    app = typer.Typer()
    app.command()(simulate_cli)
    args = [SCENARIO, "--duration", "0.5", "--no-figures", "--json"]
    res = CliRunner().invoke(
        app, [*args, "--server", server.endpoint, "--server-deadline", str(HANG_GUARD)]
    )
    assert res.exit_code == 0, res.output
    remote = json.loads(res.stdout)["avoidance"]
    local = json.loads(CliRunner().invoke(app, args).stdout)["avoidance"]
    assert remote["ticks"] == local["ticks"] == 51
    assert remote["min_distance_by_pair"] == local["min_distance_by_pair"]
    assert not any(e["kind"] == "protective_stop" for e in remote["events"])


def test_owner_reports_a_server_whose_pairs_differ_as_missing_data(
    server: ServerProcess,
) -> None:
    crane = load_robot("hiab-xs033")
    box = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.1, 0.0]])
    owner = owned_scene(ServerOptions(server.endpoint, deadline=HANG_GUARD))
    try:
        owner.add_robot(crane, np.zeros(crane.n))
        owner.add_object("grabber", box, robot=crane.name, link="link_6")
        owner.add_object("rock", box + 3.0)
        owner.add_object("post", box - 3.0)
        owner.watch_environment(crane.name, 0.5)
        first = owner.query_all()
        assert first.valid and [p.b for p in first.pairs] == ["rock", "post"]
        # the owner's local copy answers without the server
        assert set(owner.objects) == {"grabber", "rock", "post"}
        assert [o.name for o in owner.robot_objects(crane.name)] == ["grabber"]
        np.testing.assert_array_equal(owner.poses()["rock"][:3, 3], [0.0, 0.0, 0.0])
        with SceneClient(server.endpoint, setup_deadline=HANG_GUARD) as other:
            other.unwatch("grabber", "post")  # behind the owner's back
        lost = owner.query_all()
        assert not lost.valid and "differ" in lost.reason
        assert [p.b for p in lost.pairs] == ["rock", "post"]  # the owner's layout, NaN
        assert all(math.isnan(p.result.distance) for p in lost.pairs)
        owner.unwatch("grabber", "post")  # the owner agrees again
        assert owner.query_all().valid
        owner.clear()  # the server's scene and its saved state are empty again
        assert owner.objects == {} and owner.pairs == ()
        with SceneClient(server.endpoint, setup_deadline=HANG_GUARD) as other:
            d = other.describe()
            h = other.health()
        assert (d.robots, d.objects, d.pairs) == ({}, (), ())
        assert (h.robots, h.objects, h.pairs) == (0, 0, 0)
    finally:
        owner.close()
