"""Moving and deforming obstacles (issue 9): trajectory math against analytic cases,
the scenario schema, the per-tick hook, the velocity-aware controller terms and the
built-in ``moving-obstacle`` scenario's Must-show."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

import reachwise
from reachwise.control import Controller, ControllerConfig, Goal
from reachwise.control.avoidance import AvoidancePoints, SceneConverter
from reachwise.distance.scene import Scene
from reachwise.errors import InputError
from reachwise.geometry.cloud import PointCloud
from reachwise.sim.log import load_log
from reachwise.sim.motion import ConstantVelocity, WaypointTrajectory, point_velocity
from reachwise.sim.scenarios import load_scenario, scenario_from_dict
from reachwise.sim.simulate import simulate
from reachwise.sim.world import build_world

# --------------------------------------------------------------------------- math


@st.composite
def waypoints(draw, loop: bool = False):  # type: ignore[no-untyped-def]
    k = draw(st.integers(2 if loop else 1, 5))
    gaps = draw(st.lists(st.floats(0.1, 5.0), min_size=k, max_size=k))
    t = np.cumsum(gaps) - gaps[0] + draw(st.floats(0.0, 3.0))
    seed = draw(st.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    p = rng.uniform(-5, 5, (k, 3))
    q = Rotation.random(k, random_state=seed).as_quat()
    if loop:
        p[-1] = p[0]
        q[-1] = q[0]
    return t, p, q


@given(waypoints())
@settings(max_examples=60, deadline=None)
def test_waypoint_poses_are_met_and_rotations_stay_rotations(wp) -> None:  # type: ignore[no-untyped-def]
    t, p, q = wp
    tr = WaypointTrajectory(t, p, q)
    for i in range(t.size):
        T = tr.pose(t[i])
        np.testing.assert_allclose(T[:3, 3], p[i], atol=1e-9)
        R_true = Rotation.from_quat(q[i]).as_matrix()
        np.testing.assert_allclose(T[:3, :3], R_true, atol=1e-9)
    for s in np.linspace(t[0] - 1.0, t[-1] + 1.0, 17):
        R = tr.pose(s)[:3, :3]
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-12)
    # outside the waypoint times the object stands at the first / last waypoint
    np.testing.assert_allclose(tr.pose(t[0] - 2.0), tr.pose(t[0]), atol=1e-12)
    np.testing.assert_allclose(tr.pose(t[-1] + 2.0), tr.pose(t[-1]), atol=1e-12)


@given(waypoints())
@settings(max_examples=40, deadline=None)
def test_positions_linear_and_twist_is_the_derivative(wp) -> None:  # type: ignore[no-untyped-def]
    t, p, q = wp
    tr = WaypointTrajectory(t, p, q)
    h = 1e-6
    for i in range(t.size - 1):
        mid = 0.5 * (t[i] + t[i + 1])
        np.testing.assert_allclose(tr.pose(mid)[:3, 3], 0.5 * (p[i] + p[i + 1]), atol=1e-9)
        for frac in (0.25, 0.6):
            s = t[i] + frac * (t[i + 1] - t[i])
            v, w = tr.twist(s)
            Tp, Tm = tr.pose(s + h), tr.pose(s - h)
            np.testing.assert_allclose(v, (Tp[:3, 3] - Tm[:3, 3]) / (2 * h), atol=1e-5)
            w_fd = Rotation.from_matrix(Tp[:3, :3] @ Tm[:3, :3].T).as_rotvec() / (2 * h)
            np.testing.assert_allclose(w, w_fd, atol=1e-5)


@given(waypoints(loop=True), st.floats(0.0, 30.0))
@settings(max_examples=30, deadline=None)
def test_a_loop_repeats_with_its_period(wp, s: float) -> None:  # type: ignore[no-untyped-def]
    t, p, q = wp
    tr = WaypointTrajectory(t, p, q, loop=True)
    np.testing.assert_allclose(tr.pose(t[0] + s + tr.period), tr.pose(t[0] + s), atol=1e-8)


def test_constant_velocity_is_the_analytic_motion() -> None:
    P0 = np.eye(4)
    P0[:3, 3] = [1.0, 2.0, 0.5]
    P0[:3, :3] = Rotation.from_euler("z", 30, degrees=True).as_matrix()
    v = np.array([0.3, -0.4, 0.0])
    w = np.array([0.0, 0.0, 0.5])
    tr = ConstantVelocity(P0, v, w, start=1.0, stop=5.0)
    for t in (0.0, 1.0, 2.5, 5.0, 9.0):
        tau = min(max(t, 1.0), 5.0) - 1.0
        T = tr.pose(t)
        np.testing.assert_allclose(T[:3, 3], P0[:3, 3] + v * tau, atol=1e-12)
        R = Rotation.from_euler("z", 30 + math.degrees(0.5 * tau), degrees=True).as_matrix()
        np.testing.assert_allclose(T[:3, :3], R, atol=1e-12)
    np.testing.assert_allclose(tr.twist(3.0)[0], v)
    np.testing.assert_allclose(tr.twist(0.5)[0], 0.0)
    np.testing.assert_allclose(tr.twist(5.0)[1], 0.0)
    assert tr.max_speed == pytest.approx(0.5)


def test_point_velocity_matches_a_moved_point() -> None:
    tr = ConstantVelocity(np.eye(4), [0.2, 0.0, 0.1], [0.3, -0.2, 0.4])
    x_local = np.array([0.5, -0.3, 1.2])
    h = 1e-6

    def world(t: float) -> np.ndarray:
        T = tr.pose(t)
        return np.asarray(T[:3, :3] @ x_local + T[:3, 3])

    s = 2.0
    T = tr.pose(s)
    v = point_velocity(tr.twist(s), T[:3, 3], world(s))
    np.testing.assert_allclose(v, (world(s + h) - world(s - h)) / (2 * h), atol=1e-6)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"times": [0.0, 0.0], "positions": np.zeros((2, 3)), "quats": [[0, 0, 0, 1]] * 2},
         "waypoints"),
        ({"times": [0.0, 1.0], "positions": [[0, 0, 0], [1, 0, 0]], "quats": [[0, 0, 0, 1]] * 2,
          "loop": True}, "loop"),
        ({"times": [0.0], "positions": [[0, 0, 0]], "quats": [[0, 0, 0, 0]]}, "waypoints"),
    ],
)  # fmt: skip
def test_bad_trajectories_are_named(kwargs: dict, field: str) -> None:  # type: ignore[type-arg]
    with pytest.raises(InputError, match=field):
        WaypointTrajectory(**kwargs)


# --------------------------------------------------------------------------- schema


def _scenario(objects: list, tmp_path: Path, **extra) -> dict:  # type: ignore[type-arg]
    data = {
        "name": "moving-test",
        "duration": 1.0,
        "robots": [{
            "name": "crane", "robot": "hiab-xs033", "q0": [0.0, 1.1539, -1.67, 0.3526, 0.0, 0.0],
            "links": ["link_6"], "controller": {"v_max": 0.01},
            "goals": [{"xyz": [3.0, 2.0, 2.2], "dims": 3}],
        }],
        "objects": objects,
        "watch": [{"robot": "crane", "environment": [o["name"] for o in objects], "margin": 0.3}],
    }  # fmt: skip
    data.update(extra)
    return data


@pytest.mark.parametrize(
    ("obj", "where"),
    [
        ({"name": "p", "box": [0.5, 0.5, 1.8], "motion": {"velocity": [1, 0, 0],
          "waypoints": [{"t": 0, "xyz": [0, 0, 0]}]}}, "motion"),
        ({"name": "p", "box": [0.5, 0.5, 1.8], "motion": {"velocity": [1, 0, 0], "loop": True}},
         "motion"),
        ({"name": "p", "box": [0.5, 0.5, 1.8], "pose": {"xyz": [1, 0, 0]},
          "motion": {"waypoints": [{"t": 0, "xyz": [0, 0, 0]}]}}, "objects[0]"),
        ({"name": "p", "box": [0.5, 0.5, 1.8], "rescan": {"every": 1.0}}, "objects[0]"),
        ({"name": "p", "scanner": "p5-floor-obstacle", "motion": {"velocity": [1, 0, 0]}},
         "objects[0]"),
        ({"name": "p", "box": [0.5, 0.5, 1.8], "clouds": [{"t": 2, "box": [1, 1, 1]},
          {"t": 1, "box": [1, 1, 1]}]}, "objects[0]"),
        ({"name": "p", "box": [0.5, 0.0, 1.8]}, "objects[0]"),
        ({"name": "p", "box": [0.5, 0.5, 1.8], "motion": {"waypoints": [
          {"t": 1, "xyz": [0, 0, 0]}, {"t": 1, "xyz": [1, 0, 0]}]}}, "motion"),
    ],
)  # fmt: skip
def test_scenario_errors_name_the_field(obj: dict, where: str, tmp_path: Path) -> None:  # type: ignore[type-arg]
    with pytest.raises(InputError, match=where.replace("[", r"\[").replace("]", r"\]")):
        scenario_from_dict(_scenario([obj], tmp_path), "test.yaml", tmp_path)


# --------------------------------------------------------------------------- hook


def test_poses_follow_the_trajectory_and_the_log_round_trips(tmp_path: Path) -> None:
    wp = [{"t": 0.0, "xyz": [3.6, -2.0, 0.9]}, {"t": 1.0, "xyz": [3.6, -1.5, 0.9],
          "rpy_deg": [0, 0, 45]}]  # fmt: skip
    obj = {"name": "person", "box": [0.5, 0.5, 1.8], "points": 500, "motion": {"waypoints": wp}}
    sc = scenario_from_dict(_scenario([obj], tmp_path), "test", tmp_path)
    log = simulate(sc, avoidance=False, duration=0.5)
    tr = sc.spec.objects[0].motion.trajectory(np.eye(4))  # type: ignore[union-attr]
    poses = log.object_poses["person"]
    assert poses.shape == (log.t.size, 4, 4)
    for k in range(0, log.t.size, 7):
        np.testing.assert_allclose(poses[k], tr.pose(log.t[k]), atol=1e-12)
    out = log.save(tmp_path / "run")
    with np.load(out / "log.npz") as z:
        np.testing.assert_array_equal(z["object.person.pose"], poses)
    np.testing.assert_array_equal(load_log(out, sc).object_poses["person"], poses)
    # the logged distance is the true distance to the moved cloud
    world = build_world(sc, avoidance=False)
    k = log.t.size - 1
    world.scene.set_joints("crane", log.q["crane"][k])
    own = world.scene.poses()["crane/link_6"]
    a = world.scene.objects["crane/link_6"].cloud.points @ own[:3, :3].T + own[:3, 3]
    b = world.scene.objects["person"].cloud.points @ poses[k][:3, :3].T + poses[k][:3, 3]
    d = cKDTree(b).query(a)[0].min()
    assert log.distance[k, 0] == pytest.approx(d, abs=1e-9) or (
        d > 0.6 and np.isinf(log.distance[k, 0])
    )


def test_static_world_controller_sees_the_start_pose_but_the_log_the_truth(tmp_path: Path) -> None:
    """A person stands in the grabber's way at t = 0 and walks off at once: the live
    controller goes straight through the freed space; the static-world controller
    still avoids the person where it stood, while its log (the truth) shows nobody
    near."""
    obj = {"name": "person", "box": [0.5, 0.5, 1.8], "points": 1500,
           "motion": {"waypoints": [{"t": 0.0, "xyz": [3.0, 1.0, 0.9]},
                                    {"t": 0.5, "xyz": [6.0, 1.0, 0.9]}]}}  # fmt: skip
    data = _scenario([obj], tmp_path, duration=8.0)
    r = data["robots"][0]
    r["controller"] = {"v_max": 0.4, "mu": 4e-4, "stop_distance": 0.08, "approach_speed": 0.25}
    r["goals"] = [{"xyz": [3.0, 2.0, 2.2], "dims": 3}]
    sc = scenario_from_dict(data, "test", tmp_path)
    live = simulate(sc)
    static = simulate(sc, static_world=True)
    assert static.extras["static_world"] is True and live.extras["static_world"] is False

    # live: straight on (x stays 3.0) to the goal; static world: held back by a ghost
    assert np.abs(live.tool["crane"][:, 0, 3] - 3.0).max() < 0.02
    assert live.tool["crane"][-1, 1, 3] > 1.9
    assert static.tool["crane"][-1, 1, 3] < 1.5
    # the logged distances are the true ones: the person left, nothing within range
    late = static.t > 1.0
    assert np.all(np.isinf(static.distance[late]))


def test_scheduled_clouds_replace_the_cloud_at_their_times(tmp_path: Path) -> None:
    far = np.column_stack([np.full(50, 4.5), np.linspace(-1, 1, 50), np.full(50, 1.8)])
    near = far - [0.6, 0.0, 0.0]
    np.save(tmp_path / "far.npy", far)
    np.save(tmp_path / "near.npy", near)
    obj = {"name": "heap", "file": "far.npy", "clouds": [{"t": 0.3, "file": "near.npy"}]}
    sc = scenario_from_dict(_scenario([obj], tmp_path, monitor=2.0), "test", tmp_path)
    log = simulate(sc, avoidance=False, duration=0.6)
    world = build_world(sc, avoidance=False)
    for k in (0, 29, 30, 59):
        world.scene.set_joints("crane", log.q["crane"][k])
        P = world.scene.poses()["crane/link_6"]
        a = world.scene.objects["crane/link_6"].cloud.points @ P[:3, :3].T + P[:3, 3]
        cloud = far if log.t[k] < 0.3 - 1e-9 else near
        assert log.distance[k, 0] == pytest.approx(cKDTree(cloud).query(a)[0].min(), abs=1e-9)


def test_rescan_runs_the_scanner_again_with_a_new_seed(tmp_path: Path) -> None:
    """With range noise every re-scan gives a different cloud: the logged distance to
    the scan changes exactly at the re-scan times and nowhere else."""
    obj = {"name": "scan", "scanner": "p5-floor-obstacle", "noise": 0.01, "rescan": {"every": 0.2}}
    data = _scenario([obj], tmp_path, duration=0.45, monitor=3.0)
    data["robots"][0].update(q0=[0.4161, 1.0425, -2.0918, 0.2913, 0.0, 0.0], controller={})
    data["robots"][0]["goals"] = [{"xyz": [2.15, 0.95, 1.3], "dims": 3, "work": 5.0}]
    sc = scenario_from_dict(data, "test", tmp_path)
    log = simulate(sc, avoidance=False)
    assert log.t[-1] == pytest.approx(0.45)
    d = log.distance[:, 0]
    changed = np.flatnonzero(np.abs(np.diff(d)) > 1e-12) + 1
    np.testing.assert_allclose(log.t[changed], [0.2, 0.4], atol=1e-9)


# --------------------------------------------------------------------------- controller


def _tool_point_case(obstacle_velocity: np.ndarray, **cfg: float) -> np.ndarray:
    """Panda holding its pose (goal = current pose); one tool point 0.12 m from an
    obstacle below it (collision line +z). Returns the tool point's velocity."""
    robot = reachwise.load_robot("panda")
    q = np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.7])
    T = robot.fk(q)
    tool = robot.link_names.index("tool")
    config = ControllerConfig(v_max=2.0, v_rep_max=1.0, mu=2e-4, **cfg)  # type: ignore[arg-type]
    ctrl = Controller(robot, config)
    pts = AvoidancePoints(
        1, 0.0, 0.0, np.array([tool]), T[:3, 3][None], np.array([-1]), np.full((1, 3), np.nan),
        np.array([[0.0, 0.0, 1.0]]), np.array([0.12]), np.array([0.3]), np.array([True]),
        obstacle_velocity=np.asarray(obstacle_velocity, float)[None],
    )  # fmt: skip
    qdot, st = ctrl.step(q, Goal(T, 6), pts, 0.0)
    assert st.active_points == 1  # at its goal: the command is the avoidance alone
    return np.asarray(robot.jacobian(q)[:3] @ qdot)


def test_velocity_aware_repulsion_adds_the_approach_speed() -> None:
    """Khatib alone: μ(1/ρ − 1/ρ_O)/ρ² along the collision line (Eq. 3.17); an obstacle
    approaching at u along that line adds u (the point backs away with it)."""
    khatib = 2e-4 * (1 / 0.12 - 1 / 0.3) / 0.12**2
    v_static = _tool_point_case(np.zeros(3))
    np.testing.assert_allclose(v_static, [0.0, 0.0, khatib], atol=1e-6)
    v_moving = _tool_point_case(np.array([0.0, 0.0, 0.4]))
    np.testing.assert_allclose(v_moving, [0.0, 0.0, khatib + 0.4], atol=1e-6)
    # receding or sideways: nothing added
    np.testing.assert_allclose(_tool_point_case(np.array([0.0, 0.0, -0.4])), v_static, atol=1e-9)
    np.testing.assert_allclose(_tool_point_case(np.array([0.4, 0.0, 0.0])), v_static, atol=1e-9)
    # the static law on request
    off = _tool_point_case(np.array([0.0, 0.0, 0.4]), velocity_aware=False)  # type: ignore[arg-type]
    np.testing.assert_allclose(off, v_static, atol=1e-9)


def test_reaction_time_brings_an_approaching_obstacle_in_early() -> None:
    """0.4 m away (beyond the 0.3 m margin) the static law does nothing; an obstacle
    approaching at 0.5 m/s with a 0.4 s reaction time counts as 0.2 m away."""
    robot = reachwise.load_robot("panda")
    q = np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.7])
    T = robot.fk(q)
    tool = robot.link_names.index("tool")

    def rate(reaction: float) -> float:
        ctrl = Controller(robot, ControllerConfig(v_max=2.0, mu=2e-4, reaction_time=reaction))
        pts = AvoidancePoints(
            1, 0.0, 0.0, np.array([tool]), T[:3, 3][None], np.array([-1]),
            np.full((1, 3), np.nan), np.array([[0.0, 0.0, 1.0]]), np.array([0.4]),
            np.array([0.3]), np.array([True]), obstacle_velocity=np.array([[0.0, 0.0, 0.5]]),
        )  # fmt: skip
        qdot, _ = ctrl.step(q, Goal(T, 6), pts, 0.0)
        return float((robot.jacobian(q)[:3] @ qdot)[2])

    assert rate(0.0) == pytest.approx(0.0, abs=1e-12)
    khatib = 2e-4 * (1 / 0.2 - 1 / 0.3) / 0.2**2
    assert rate(0.4) == pytest.approx(khatib + 0.5, abs=1e-6)


def test_converter_gives_the_moving_objects_point_velocity() -> None:
    robot = reachwise.load_robot("panda")
    scene = Scene()
    q = np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.7])
    scene.add_robot(robot, q)
    scene.add_object("hand", PointCloud(np.zeros((1, 3))), robot="panda", link="tool")
    tip = robot.fk(q)[:3, 3]
    box = PointCloud(np.array([[0.0, 0.0, 0.0], [0.3, 0.0, 0.0]]))
    pose = np.eye(4)
    pose[:3, 3] = tip - [0.0, 0.0, 0.2]
    scene.add_object("box", box, pose, dynamic=True)
    scene.watch("hand", "box", 0.6)
    conv = SceneConverter(scene, robot, margins={("hand", "box"): 0.3})
    v, w = np.array([0.1, 0.0, 0.2]), np.array([0.0, 0.0, 1.0])
    origin = pose[:3, 3] + [0.0, 0.5, 0.0]
    pts = conv(scene.query_all(), stamp=0.0, twists={"box": (v, w, origin)})
    assert len(pts) == 1
    pb = pose[:3, 3]  # the box point nearest the hand
    np.testing.assert_allclose(pts.obstacle_velocity[0], v + np.cross(w, pb - origin))  # type: ignore[index]
    # static objects: zero; a moving pair just beyond rho_O is kept (reaction time)
    assert np.all(conv(scene.query_all(), stamp=0.0).obstacle_velocity == 0.0)
    scene.set_pose("box", pose @ _shift(0.15))
    assert len(conv(scene.query_all(), stamp=0.0)) == 0
    assert len(conv(scene.query_all(), stamp=0.0, twists={"box": (v, w, origin)})) == 1


def _shift(dz: float) -> np.ndarray:
    T = np.eye(4)
    T[2, 3] = -dz
    return T


# --------------------------------------------------------------------------- Must-show


@pytest.fixture(scope="module")
def moving() -> tuple:  # type: ignore[type-arg]
    return simulate("moving-obstacle"), simulate("moving-obstacle", static_world=True)


def test_person_moves_at_up_to_half_a_metre_per_second(moving: tuple) -> None:  # type: ignore[type-arg]
    log = moving[0]
    poses = log.object_poses["person"]
    # corners of the larger of its two shapes (the 1.0 x 0.6 x 1.8 m cart) at every tick
    half = np.array([0.5, 0.3, 0.9])
    corners = np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)]) * half
    speeds = [
        np.linalg.norm(np.diff(poses[:, :3, :3] @ c + poses[:, :3, 3], axis=0), axis=1) / log.dt
        for c in corners
    ]
    top = max(float(s.max()) for s in speeds)
    assert 0.45 <= top <= 0.5 + 1e-9
    spec = load_scenario("moving-obstacle").spec.objects[0]
    assert spec.motion is not None
    assert spec.motion.trajectory(np.eye(4)).max_speed == pytest.approx(0.5)


def test_moving_obstacle_live_avoidance_keeps_clear(moving: tuple) -> None:  # type: ignore[type-arg]
    log = moving[0]
    assert log.all_goals_reached
    assert log.first_collision is None
    assert np.all(log.min_distance >= 0.02), float(log.min_distance.min())
    assert all(log.limits_held().values()) and all(log.speeds_held().values())


def test_static_world_baseline_collides_and_reports_when(moving: tuple) -> None:  # type: ignore[type-arg]
    log = moving[1]
    assert log.first_collision is not None and 0.0 < log.first_collision < 5.0
    assert log.min_distance.min() <= 0.0
    assert any(e.kind == "collision" and "person" in e.text for e in log.events)


def test_live_updates_alone_are_not_enough() -> None:
    """The same run with the static law (velocity_aware off) collides: seeing the
    person's current pose every tick does not suffice at 0.5 m/s."""
    sc = load_scenario("moving-obstacle")
    data = sc.spec.model_dump(by_alias=True, exclude_unset=True)
    data["robots"][0]["controller"]["velocity_aware"] = False
    log = simulate(scenario_from_dict(data, sc.source, sc.folder), duration=5.0)
    assert log.first_collision is not None


def test_moving_obstacle_figure(moving: tuple, tmp_path: Path) -> None:  # type: ignore[type-arg]
    from reachwise.report.sim_plots import moving_obstacle_figure

    fig = moving_obstacle_figure(*moving)
    top, dist = fig.axes
    labels = [t.get_text() for t in top.get_legend().get_texts()]
    assert dist.get_ylabel() == "minimum distance (m)"
    assert "person (centre)" in labels and "crane tool (static world)" in labels
    fig.savefig(tmp_path / "moving.png")
    assert (tmp_path / "moving.png").stat().st_size > 10_000
