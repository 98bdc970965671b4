"""Built-in scenarios: the Must-show lines of issue 6, plants and scenario files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import reachwise
from reachwise.errors import InputError, UnknownName
from reachwise.sim.plant import Plant, PlantConfig, hanging_joints
from reachwise.sim.scenarios import builtin_scenarios, load_scenario, scenario_from_dict
from reachwise.sim.simulate import simulate


def _check_avoidance(log) -> None:  # type: ignore[no-untyped-def]
    assert log.all_goals_reached, [g for g in log.goals if g.reached_at is None]
    md = log.min_distance
    assert np.all(md >= 0.02), float(md.min())
    assert log.first_collision is None
    assert all(log.limits_held().values()) and all(log.speeds_held().values())


def _check_baseline(log) -> None:  # type: ignore[no-untyped-def]
    assert log.first_collision is not None
    assert log.min_distance.min() <= 0.0
    assert any(e.kind == "collision" for e in log.events)


@pytest.fixture(scope="module")
def p5() -> tuple:  # type: ignore[type-arg]
    return simulate("p5-crane-obstacle"), simulate("p5-crane-obstacle", avoidance=False)


def test_builtins_listed() -> None:
    assert {"p3-self-collision", "p4-dual-drilling", "p5-crane-obstacle"} <= set(
        builtin_scenarios()
    )


def test_p5_avoidance_reaches_every_goal_safely(p5: tuple) -> None:  # type: ignore[type-arg]
    _check_avoidance(p5[0])


def test_p5_baseline_collides_and_reports_when(p5: tuple) -> None:  # type: ignore[type-arg]
    _check_baseline(p5[1])
    assert 0.0 < p5[1].first_collision < 5.0


def test_p5_grabber_hangs_and_scan_has_its_size(p5: tuple) -> None:  # type: ignore[type-arg]
    log = p5[0]
    crane = reachwise.load_robot("hiab-xs033")
    for k in range(0, log.t.size, 200):
        R = crane.fk_all(log.q["crane"][k])[6, :3, :3]
        np.testing.assert_allclose(R[:, 0], [0, 0, -1], atol=1e-6)


def test_p3_must_show() -> None:
    """P-III §5: the conventional controller drives the feed into the boom on its way to
    the mirrored pose; with avoidance the goal is reached without self-collision, the
    joint trajectories modified in the null space while the tool keeps its straight
    path and its orientation (Fig. 3a)."""
    log = simulate("p3-self-collision")
    _check_avoidance(log)
    p = log.tool["boom"][:, :3, 3]
    u = (p[-1] - p[0]) / np.linalg.norm(p[-1] - p[0])
    d = p - p[0]
    assert np.linalg.norm(d - np.outer(d @ u, u), axis=1).max() < 0.05
    R0 = log.tool["boom"][0, :3, :3]
    cos = (np.einsum("kij,ij->k", log.tool["boom"][:, :3, :3], R0) - 1.0) / 2.0
    assert np.arccos(np.clip(cos, -1.0, 1.0)).max() < 0.02
    base = simulate("p3-self-collision", avoidance=False)
    _check_baseline(base)
    first, pair, reached = base.first_collision, base.first_collision_pair, base.goals[0].reached_at
    assert first is not None and pair is not None and reached is not None
    assert first < reached  # on the way, not at the goal
    assert pair.startswith(("boom/link_8|", "boom/link_7|"))  # the feed or its cradle


def test_p4_must_show() -> None:
    """P-IV (thesis §4.4): four holes, lowest first, each boom taking the next free one;
    the boom moving from hole 1 to hole 3 passes the other's feed while that boom is
    locked drilling hole 2. The baseline drives into the locked boom."""
    log = simulate("p4-dual-drilling")
    _check_avoidance(log)
    assert any(e.kind == "locked" for e in log.events)
    order = sorted(log.goals, key=lambda g: g.reached_at or np.inf)
    assert [(g.name, g.robot) for g in order] == [
        ("hole 1", "A"), ("hole 2", "B"), ("hole 3", "A"), ("hole 4", "B")
    ]  # fmt: skip
    # A's tool first rises above hole 2 while B is still locked there
    k = int(np.argmax(log.tool["A"][:, 2, 3] > 2.0 + 0.05))
    assert log.tool["A"][k, 2, 3] > 2.05 and log.state["B"][k] == "locked"
    base = simulate("p4-dual-drilling", avoidance=False)
    _check_baseline(base)
    first, pair = base.first_collision, base.first_collision_pair
    assert first is not None and pair is not None
    k = int(np.argmin(np.abs(base.t - first)))
    a, b = pair.split("|")
    assert a.split("/")[0] != b.split("/")[0]  # the two booms, not a self-collision
    assert "locked" in (base.state["A"][k], base.state["B"][k])


def test_infeasible_task_deviates_or_stops_without_interpenetrating(tmp_path: Path) -> None:
    """The crane's goal lies inside the scanned box: the grabber stops at the box."""
    data = {
        "name": "infeasible",
        "duration": 8.0,
        "robots": [{
            "name": "crane", "robot": "hiab-xs033",
            "q0": [0.4161, 1.0425, -2.0918, 0.2913, 0.0, 0.0], "links": ["link_6"],
            "controller": {"v_max": 0.25, "mu": 4e-4, "stop_distance": 0.08,
                           "approach_speed": 0.25},
            "goals": [{"xyz": [2.7, 0.0, 1.3], "dims": 3}],
        }],
        "objects": [{"name": "scan", "scanner": "p5-floor-obstacle"}],
        "watch": [{"robot": "crane", "environment": ["scan"], "margin": 0.3}],
    }  # fmt: skip
    log = simulate(scenario_from_dict(data, "test", tmp_path))
    assert not log.all_goals_reached
    assert log.first_collision is None
    assert np.all(log.min_distance >= 0.02)


def test_hydraulic_plant_lags_and_respects_limits() -> None:
    r = reachwise.load_robot("sb60")
    p = Plant(r, np.zeros(r.n), PlantConfig(kind="hydraulic", time_constant=0.1, rate_limit=1.0))
    cmd = np.full(r.n, 10.0)
    p.step(cmd, 0.01)
    assert np.all(p.qdot <= 0.01 * 1.0 + 1e-12)  # rate limited
    for _ in range(2000):
        p.step(cmd, 0.01)
    assert np.all(p.q <= r.upper + 1e-12)
    assert np.all(np.abs(p.qdot) <= r.vmax + 1e-12)


def test_hanging_joints_point_down() -> None:
    crane = reachwise.load_robot("hiab-xs033")
    q = hanging_joints(crane, [0.5, 0.7, -1.1, 0.4, 0.3, 0.2])
    R = crane.fk_all(q)[6, :3, :3]
    np.testing.assert_allclose(R[:, 0], [0, 0, -1], atol=1e-9)
    assert q[4] == pytest.approx(q[1] + q[2], abs=1e-6)


def test_scenario_errors_name_file_and_field(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\nduration: 1\nrobots:\n  - {name: a, robot: sb60, q0: [0], speed: 3}\n")
    with pytest.raises(InputError, match=r"bad.yaml: robots\[0\].speed"):
        load_scenario(bad)
    with pytest.raises(InputError, match=r"missing\.yaml: no such file"):
        load_scenario(tmp_path / "missing.yaml")
    with pytest.raises(UnknownName, match=r"unknown built-in scenario 'p9'; valid: .*p5-crane"):
        load_scenario("p9")
    data = {"name": "x", "duration": 1, "robots": [{"name": "a", "robot": "sb60", "q0": [0]}],
            "watch": [{"self": "b", "margin": 0.3}]}  # fmt: skip
    with pytest.raises(InputError, match="unknown robot 'b'"):
        scenario_from_dict(data, "s.yaml")


def test_log_saves(tmp_path: Path, p5: tuple) -> None:  # type: ignore[type-arg]
    out = p5[0].save(tmp_path / "run")
    assert {"log.npz", "log.csv", "summary.json"} <= {f.name for f in out.iterdir()}
    with np.load(out / "log.npz") as z:
        assert z["crane.q"].shape[0] == p5[0].t.size
