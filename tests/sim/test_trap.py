"""The `trap` scenario (issue 9): the reactive controller stalls, the hybrid escapes."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest
import typer
import yaml
from typer.testing import CliRunner

from reachwise.errors import InputError
from reachwise.sim.log import SimulationLog
from reachwise.sim.scenarios import (
    EscapeSpec,
    builtin_scenarios,
    load_scenario,
    scenario_from_dict,
)
from reachwise.sim.simulate import simulate

GOAL = np.array([0.45, -0.50, 0.30])


@pytest.fixture(scope="module")
def reactive() -> SimulationLog:
    return simulate("trap")


@pytest.fixture(scope="module")
def hybrid() -> SimulationLog:
    pytest.importorskip("ompl")
    return simulate("trap", escape=True)


def _kinds(log: SimulationLog) -> list[str]:
    return [e.kind for e in log.events]


def test_trap_is_built_in() -> None:
    assert "trap" in builtin_scenarios()
    assert load_scenario("trap").spec.escape is None  # reactive unless asked


def test_reactive_controller_alone_stalls(reactive: SimulationLog) -> None:
    stalls = [e for e in reactive.events if e.kind == "stalled"]
    assert stalls and "local minimum" in stalls[0].text
    assert not reactive.all_goals_reached
    assert reactive.goals[0].reached_at is None
    # it stays stuck: the tool ends far from the goal, in front of the cup (y > 0)
    tool = reactive.tool["arm"][-1, :3, 3]
    assert np.linalg.norm(tool - GOAL) > 0.5 and tool[1] > 0.1
    assert reactive.state["arm"][-1] == "stalled"
    # it stalls safely: no collision, never within 2 cm
    assert reactive.first_collision is None and reactive.min_distance.min() >= 0.02
    assert "escape" not in reactive.extras
    assert not {"planning", "escaped"} & set(_kinds(reactive))


def test_hybrid_reaches_the_goal_at_least_2_cm_clear(
    reactive: SimulationLog, hybrid: SimulationLog
) -> None:
    assert hybrid.all_goals_reached, hybrid.goals
    g = hybrid.goals[0]
    assert np.linalg.norm(hybrid.tool["arm"][-1, :3, 3] - GOAL) <= 0.005 + 1e-9
    assert np.all(hybrid.min_distance >= 0.02), hybrid.min_distance.min()
    assert hybrid.first_collision is None
    assert all(hybrid.limits_held().values()) and all(hybrid.speeds_held().values())
    # the same stall first, then planning, escape and the goal, in that order
    kinds = _kinds(hybrid)
    order = [kinds.index(k) for k in ("stalled", "planning", "escaped", "reached")]
    assert order == sorted(order)
    stall = next(e for e in reactive.events if e.kind == "stalled")
    assert next(e for e in hybrid.events if e.kind == "stalled").t == stall.t
    assert g.reached_at is not None and g.reached_at > stall.t
    assert "escape_failed" not in kinds


def test_hybrid_reports_planning_time_and_path(hybrid: SimulationLog) -> None:
    ev = next(e for e in hybrid.events if e.kind == "planning")
    assert "RRT-Connect (OMPL)" in ev.text and "waypoints" in ev.text
    plans = hybrid.extras["escape"]["plans"]
    assert len(plans) == 1 and plans[0]["success"]
    p = plans[0]
    assert p["planning_time_s"] > 0.0 and f"{p['planning_time_s']:.3f} s" in ev.text
    assert p["waypoints"] >= 2 and p["joint_path_length"] > 0 and p["tool_path_length"] > 0
    assert p["held_q_indices"] and p["path_duration_s"] > 0
    # the path went around the cup: the tool rose above its roof (z = 0.47 m)
    t0, t1 = ev.t, next(e for e in hybrid.events if e.kind == "escaped").t
    k = (hybrid.t >= t0) & (hybrid.t <= t1)
    assert hybrid.tool["arm"][k, 2, 3].max() > 0.47 + 0.1
    # the summary carries it to JSON
    data = json.loads(json.dumps(hybrid.summary()))
    assert data["extras"]["escape"]["plans"][0]["status"] == "Exact solution"


def test_without_ompl_the_stall_stands_with_a_clear_message(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setitem(sys.modules, "ompl", None)
    log = simulate("trap", escape=True, duration=8.0)
    kinds = _kinds(log)
    assert "stalled" in kinds and "planning" not in kinds
    msg = next(e for e in log.events if e.kind == "escape_failed").text
    assert "reachwise[plan]" in msg and "stall stands" in msg
    assert not log.all_goals_reached
    assert log.extras["escape"]["available"] is False


def test_escape_option_in_scenario_files() -> None:
    data = yaml.safe_load(load_scenario("trap").path("trap.yaml").read_text())
    data["escape"] = "ompl"
    assert scenario_from_dict(data).spec.escape == EscapeSpec()
    data["escape"] = {"planner": "ompl", "time_limit": 2.0, "attempts": 1}
    spec = scenario_from_dict(data).spec.escape
    assert spec is not None and spec.time_limit == 2.0 and spec.attempts == 1
    bad_values = [
        ("rrt", "escape.planner"),
        ({"time_limit": 0}, "escape.time_limit"),
        ({"speed": 1.5}, "escape.speed"),
        ({"tries": 2}, "escape.tries"),
    ]
    for bad, field in bad_values:
        data["escape"] = bad
        with pytest.raises(InputError, match=field.replace(".", r"\.")):
            scenario_from_dict(data, "trap.yaml")


def test_cli_escape_flag() -> None:
    pytest.importorskip("ompl")
    from reachwise.cli.simulate import simulate as cli

    app = typer.Typer()
    app.command()(cli)
    res = CliRunner().invoke(app, ["trap", "--escape", "--json", "--duration", "12"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)  # OMPL's own log stays out of the JSON
    kinds = [e["kind"] for e in data["avoidance"]["events"]]
    assert "stalled" in kinds and "planning" in kinds
    assert data["avoidance"]["extras"]["escape"]["plans"][0]["planning_time_s"] > 0
