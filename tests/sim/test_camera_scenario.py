"""Issue 17's must-show for live sensing: a person walks into a Panda's workspace and only
a depth camera sees them (``panda-person-camera``). Judged on the person's true mesh."""

from __future__ import annotations

import numpy as np
import pytest

from reachwise.control.safety import protective_separation
from reachwise.sim.log import SimulationLog
from reachwise.sim.scenarios import load_scenario
from reachwise.sim.simulate import simulate
from reachwise.sim.world import build_world

NAME = "panda-person-camera"


@pytest.fixture(scope="module")
def baseline() -> SimulationLog:
    return simulate(NAME, avoidance=False, duration=5.0)


@pytest.fixture(scope="module")
def avoiding() -> SimulationLog:
    return simulate(NAME)


def test_only_the_camera_sees_the_person() -> None:
    sc = load_scenario(NAME)
    person = next(o for o in sc.spec.objects if o.name == "person")
    assert not person.scene
    assert person.motion is not None
    assert person.motion.trajectory(np.eye(4)).max_speed == pytest.approx(0.5)
    world = build_world(sc)
    assert "person" not in world.scene.objects
    assert {p.b for p in world.scene.pairs} == {"camera"}
    assert world.truth == tuple((f"arm/{k}", "person") for k in ("link_3", "link_5", "link_7"))
    cam = world.sensors[0]
    assert (cam.spec.width, cam.spec.height, cam.spec.rate) == (160, 120, 30.0)


def test_baseline_runs_into_the_person_and_says_when_and_with_what(
    baseline: SimulationLog,
) -> None:
    log = baseline
    assert log.first_collision is not None and 2.0 < log.first_collision < 5.0
    assert log.first_collision_pair == "arm/link_7|person"
    k = int(np.flatnonzero(log.t == log.first_collision)[0])
    j = log.true_pairs.index("arm/link_7|person")
    assert log.true_distance[k, j] <= 0.0 < log.min_true_distance[:k].min()
    assert log.min_true_distance.min() < -0.02  # not a graze: the hand goes into them
    hits = [e for e in log.events if e.kind == "collision"]
    assert hits and hits[0].t == log.first_collision and "person" in hits[0].text


def test_with_the_camera_the_arm_keeps_clear_of_the_true_mesh(avoiding: SimulationLog) -> None:
    log = avoiding
    assert log.first_collision is None
    near = np.isfinite(log.min_true_distance)  # measured whenever the person is near
    assert near.sum() > 500
    assert log.min_true_distance.min() >= 0.02, float(log.min_true_distance.min())
    assert all(log.limits_held().values()) and all(log.speeds_held().values())


def test_the_arm_resumes_its_work_after_the_person_leaves(avoiding: SimulationLog) -> None:
    log = avoiding
    assert log.all_goals_reached
    first_b = log.goals[0]
    assert first_b.name == "B" and first_b.reached_at is not None
    assert first_b.reached_at > 8.0  # blocked while the person stood at B (3.5-8 s)
    assert any(e.kind == "stalled" and 3.5 < e.t < 8.0 for e in log.events)
    assert [g.name for g in log.goals] == ["B", "A", "B again", "A again"]


def test_the_margin_covers_the_cameras_lag_resolution_and_noise() -> None:
    world = build_world(NAME)
    cam = world.sensors[0]
    spec = world.scenario.spec
    ctrl = spec.robots[0].controller
    assert ctrl.v_max is not None
    person = next(m for m in world.movers if m.spec.name == "person")
    assert person.trajectory is not None
    depth = 2.0  # the farthest working depth from the camera
    resolution = cam.camera.pixel_spacing(depth) + 3.0 * cam.spec.noise * depth**2
    needed = protective_separation(
        robot_speed=ctrl.v_max,
        reaction_time=cam.max_age() + spec.dt,
        obstacle_speed=person.trajectory.max_speed,
        cloud_resolution=resolution,
    )
    assert needed == pytest.approx(0.108, abs=1e-3)
    assert world.margins.min() >= needed + 0.02
    fk = world.robots["arm"].fk_all(np.asarray(spec.robots[0].q0))
    camera = cam.pose({"arm": fk})[:3, 3]
    goals = [g.pose(world.robots["arm"].fk)[:3, 3] for g in spec.robots[0].goals]
    assert max(np.linalg.norm(camera - g) for g in goals) < depth
