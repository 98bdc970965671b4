"""``load_log`` reads back what ``SimulationLog.save`` wrote (round trip)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from reachwise.errors import InputError
from reachwise.sim.log import SimulationLog, load_log
from reachwise.sim.scenarios import load_scenario, scenario_from_dict
from reachwise.sim.simulate import simulate


def _same(a: SimulationLog, b: SimulationLog) -> None:
    assert (a.scenario, a.avoidance, a.dt) == (b.scenario, b.avoidance, b.dt)
    assert a.robots == b.robots and a.pairs == b.pairs
    np.testing.assert_array_equal(a.t, b.t)
    for f in ("distance", "signed", "margins"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f))
    for f in ("q", "qdot", "command", "tool", "state", "goal_index", "lower", "upper", "vmax"):
        da, db = getattr(a, f), getattr(b, f)
        assert da.keys() == db.keys(), f
        for r in da:
            np.testing.assert_array_equal(da[r], db[r], err_msg=f"{f}[{r}]")
    assert a.events == b.events
    assert a.goals == b.goals
    assert a.first_collision == b.first_collision
    assert a.first_collision_pair == b.first_collision_pair
    assert a.summary() == b.summary()


def test_builtin_scenario_log_round_trips(tmp_path: Path) -> None:
    log = simulate("p5-crane-obstacle", avoidance=False, duration=1.5)
    back = load_log(log.save(tmp_path / "run"))
    _same(log, back)
    assert "limits" not in back.extras  # limits came from the built-in scenario


def test_file_scenario_log_needs_the_scenario_for_limits(tmp_path: Path) -> None:
    data = {
        "name": "two-boxes",
        "duration": 0.3,
        "robots": [{"name": "arm", "robot": "puma560", "q0": [0, -0.5, 0.5, 0, 0.3, 0],
                    "goals": [{"q": [0.4, -0.4, 0.6, 0, 0.2, 0]}]}],
        "objects": [{"name": "box", "box": [0.3, 0.3, 0.3], "pose": {"xyz": [0.6, 0, 0.3]}}],
        "watch": [{"robot": "arm", "environment": ["box"], "margin": 0.1}],
    }  # fmt: skip
    sc = scenario_from_dict(data, "two-boxes.yaml", tmp_path)
    log = simulate(sc, duration=0.3)
    folder = log.save(tmp_path / "run")
    _same(log, load_log(folder, sc))
    # without the scenario the arrays still round-trip; the limits are unknown (±inf)
    blind = load_log(folder)
    np.testing.assert_array_equal(blind.q["arm"], log.q["arm"])
    assert np.all(np.isinf(blind.upper["arm"])) and "limits" in blind.extras


def test_missing_or_broken_files_name_the_file(tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"log\.npz"):
        load_log(tmp_path)
    log = simulate(load_scenario("p3-self-collision"), duration=0.05)
    folder = log.save(tmp_path / "run")
    (folder / "summary.json").write_text(json.dumps({"scenario": "x"}))
    with pytest.raises(InputError, match=r"summary\.json.*avoidance"):
        load_log(folder)
    (folder / "summary.json").write_text("{not json")
    with pytest.raises(InputError, match=r"summary\.json"):
        load_log(folder)
