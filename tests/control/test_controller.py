"""Controller: null-space property, infeasible task, safety stops, joint limits."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

import reachwise
from reachwise.control import AvoidancePoints, Controller, ControllerConfig, Goal, SafetyConfig
from reachwise.control.limits import limit_scale, velocity_bounds
from reachwise.control.potential import approach_bound, repulsive_potential, repulsive_speed
from reachwise.control.safety import protective_separation
from reachwise.kinematics.orientation import quaternion_error


@pytest.fixture(scope="module")
def sb60() -> reachwise.Robot:
    return reachwise.load_robot("sb60")


Q_MID = np.array([0.1, 0.3, 0.8, 0.3, 0.1, 0.4, 0.5, 0.8])


def _points(
    robot: reachwise.Robot,
    q: np.ndarray,
    link: str,
    local: np.ndarray,
    n: np.ndarray,
    d: float,
    margin: float,
    seq: int = 1,
    stamp: float = 0.0,
) -> AvoidancePoints:
    F = robot.fk_all(q)[robot.link_index(link)]
    p = F[:3, :3] @ local + F[:3, 3]
    return AvoidancePoints(
        seq, stamp, stamp, np.array([robot.link_index(link)]), p[None], np.array([-1]),
        np.full((1, 3), np.nan), (n / np.linalg.norm(n))[None], np.array([d]),
        np.array([margin]), np.array([False]),
    )  # fmt: skip


def _task_velocity(robot: reachwise.Robot, q: np.ndarray, goal: Goal, cfg: ControllerConfig):
    T = robot.fk(q)
    v = cfg.kv * (goal.pose[:3, 3] - T[:3, 3])
    if np.linalg.norm(v) > cfg.v_max:
        v *= cfg.v_max / np.linalg.norm(v)
    w = cfg.kw * quaternion_error(T[:3, :3], goal.pose[:3, :3])
    if np.linalg.norm(w) > cfg.w_max:
        w *= cfg.w_max / np.linalg.norm(w)
    return np.concatenate([v, w])


def test_reported_orientation_error_is_the_rotation_angle(sb60: reachwise.Robot) -> None:
    """The tick measures Eq. 3.9's error: a goal turned by φ about any axis reads φ."""
    from scipy.spatial.transform import Rotation

    c = Controller(sb60, ControllerConfig(avoidance=False))
    T = sb60.fk(Q_MID)
    for k, phi in enumerate((0.0, 0.3, 1.2, np.pi - 1e-3)):
        u = Rotation.random(random_state=k).as_rotvec()
        G = T.copy()
        G[:3, :3] = Rotation.from_rotvec(phi * u / np.linalg.norm(u)).as_matrix() @ T[:3, :3]
        _, st = c.step(Q_MID, Goal(G), None, float(k))
        assert st.orientation_error == pytest.approx(phi, abs=1e-9)
        assert st.position_error == pytest.approx(0.0, abs=1e-12)


def test_null_space_property_with_avoidance_active(sb60: reachwise.Robot) -> None:
    """‖J q̇ − ẋ‖ ≤ 1e-6 while an avoidance point acts (Eq. 3.18), away from singularities."""
    cfg = ControllerConfig(kv=0.5, kw=0.5, mu=2e-3, safety=SafetyConfig(dt=0.01))
    goal = Goal(sb60.fk(Q_MID + np.array([0.05, 0.04, 0.1, -0.05, 0.05, 0.1, -0.05, 0.1])))
    c = Controller(sb60, cfg)
    pts = _points(
        sb60, Q_MID, "link_3", np.array([0.0, 0.15, -1.0]), np.array([0, 0, 1.0]), 0.1, 0.3
    )
    qd, st = c.step(Q_MID, goal, pts, 0.0)
    assert st.active_points == 1 and st.task_scale == 1.0 and st.limit_scale == 1.0
    assert st.sigma_min > cfg.epsilon  # away from singularities
    xd = _task_velocity(sb60, Q_MID, goal, cfg)
    J = sb60.jacobian(Q_MID)
    assert np.linalg.norm(J @ qd - xd) <= 1e-6
    # the avoidance changed the joint velocities (it is really active) ...
    c2 = Controller(sb60, cfg)
    qd0, _ = c2.step(Q_MID, goal, AvoidancePoints.empty(1, 0.0), 0.0)
    assert np.linalg.norm(qd - qd0) > 1e-3
    # ... and moves the avoidance point away from the obstacle
    Jo = sb60.point_jacobian(Q_MID, "link_3", pts.a_point[0], frame="world")
    assert pts.normal[0] @ Jo @ qd > pts.normal[0] @ Jo @ qd0


def test_three_d_goal_uses_position_rows_only(sb60: reachwise.Robot) -> None:
    cfg = ControllerConfig(kv=0.5)
    T = sb60.fk(Q_MID)
    goal = Goal.at(T[:3, 3] + [0.1, -0.05, 0.05])
    qd, st = Controller(sb60, cfg).step(Q_MID, goal, AvoidancePoints.empty(1, 0.0), 0.0)
    assert st.orientation_error == 0.0
    np.testing.assert_allclose(sb60.jacobian(Q_MID)[:3] @ qd, 0.5 * np.array([0.1, -0.05, 0.05]),
                               atol=1e-9)  # fmt: skip


def test_passive_joints_never_commanded() -> None:
    crane = reachwise.load_robot("hiab-xs033")
    q = np.array([0.3, 1.0, -2.0, 0.3, -1.0, 0.0])
    goal = Goal.at(crane.fk(q)[:3, 3] + [0.2, 0.1, -0.1])
    qd, _ = Controller(crane).step(q, goal, AvoidancePoints.empty(1, 0.0), 0.0)
    assert np.all(qd[~np.asarray(crane.actuated)] == 0.0)
    assert np.linalg.norm(qd) > 0


def test_stale_missing_nan_data_stop_within_set_ticks(sb60: reachwise.Robot) -> None:
    dt = 0.01
    cfg = ControllerConfig(safety=SafetyConfig(dt=dt, max_age_ticks=2, stop_ticks=4))
    goal = Goal(sb60.fk(Q_MID + 0.2))
    for fault in ("missing", "stale", "nan", "repeat"):
        c = Controller(sb60, cfg)
        qd, st = c.step(Q_MID, goal, AvoidancePoints.empty(1, 0.0), 0.0)
        assert st.state == "moving" and np.abs(qd).max() > 0
        cmds = []
        for k in range(1, 7):
            t = k * dt
            if fault == "missing":
                data = None
            elif fault == "stale":
                data = AvoidancePoints.empty(1 + k, t - 3 * dt)  # 3 ticks old
            elif fault == "repeat":
                data = AvoidancePoints.empty(1, t)  # the same sequence again
            else:
                data = _points(sb60, Q_MID, "link_3", np.zeros(3), np.array([0, 0, 1.0]),
                               np.nan, 0.3, seq=1 + k, stamp=t)  # fmt: skip
            qd, st = c.step(Q_MID, goal, data, t)
            assert st.state == "protective_stop" and st.reason
            cmds.append(np.abs(qd).max())
        assert all(a >= b for a, b in itertools.pairwise(cmds))
        assert cmds[3] == 0.0 and cmds[-1] == 0.0  # zero at the 4th faulty tick
        # good data again: control resumes
        qd, st = c.step(Q_MID, goal, AvoidancePoints.empty(100, 7 * dt), 7 * dt)
        assert st.state == "moving"


def test_start_outside_limit_moves_only_inward(sb60: reachwise.Robot) -> None:
    q = Q_MID.copy()
    q[1] = sb60.lower[1] - 0.1  # boom lift below its lower limit
    q[7] = sb60.upper[7] + 0.05  # feed extension above its upper limit
    goal = Goal(sb60.fk(Q_MID - 0.1))
    c = Controller(sb60)
    dt = 0.01
    prev = q.copy()
    for k in range(300):
        qd, _ = c.step(q, goal, AvoidancePoints.empty(k + 1, k * dt), k * dt)
        assert qd[1] >= 0.0 and qd[7] <= 0.0
        assert np.all(np.abs(qd) <= sb60.vmax + 1e-12)
        q = q + qd * dt
        assert q[1] >= prev[1] - 1e-15 and q[7] <= prev[7] + 1e-15
        prev = q.copy()
    assert q[1] > sb60.lower[1] - 0.1 + 0.01  # it did move back


def test_limits_scale_whole_vector(sb60: reachwise.Robot, rng: np.random.Generator) -> None:
    """Commands keep the joint limits and speeds, from anywhere inside the limits."""
    c = Controller(sb60, ControllerConfig(kv=5.0, kw=5.0, v_max=3.0, w_max=3.0))
    dt = 0.01
    for _ in range(15):
        q = rng.uniform(sb60.lower, sb60.upper)
        goal = Goal(sb60.fk(rng.uniform(sb60.lower, sb60.upper)))
        c.reset()
        for k in range(50):
            qd, _st = c.step(q, goal, AvoidancePoints.empty(k + 1, k * dt), k * dt)
            assert np.all(np.abs(qd) <= sb60.vmax + 1e-12)
            lo, hi = velocity_bounds(q, sb60.lower, sb60.upper, sb60.vmax, c.config.k_limit)
            assert np.all(qd >= lo - 1e-12) and np.all(qd <= hi + 1e-12)
            q = q + qd * dt
            assert np.all(q >= sb60.lower - 1e-12) and np.all(q <= sb60.upper + 1e-12)


def test_limit_helpers() -> None:
    lo, hi = velocity_bounds([0.0, 0.95, -2.0], [-1, -1, -1], [1, 1, 1], [0.5, 0.5, 0.5], 2.0)
    np.testing.assert_allclose(hi, [0.5, 0.1, 0.5])
    np.testing.assert_allclose(lo, [-0.5, -0.5, 0.0])
    assert limit_scale([1.0, 0.05, 0.0], lo, hi) == pytest.approx(0.5)
    assert limit_scale([0.0, 0.0, -1.0], lo, hi) == 0.0


def test_khatib_speed_is_negative_gradient() -> None:
    mu, r0 = 1e-3, 0.3
    rho = np.linspace(0.02, 0.29, 20)
    h = 1e-7
    grad = (repulsive_potential(rho + h, r0, mu) - repulsive_potential(rho - h, r0, mu)) / (2 * h)
    np.testing.assert_allclose(repulsive_speed(rho, r0, mu), -grad, rtol=1e-5)
    assert repulsive_speed(np.inf, r0, mu) == 0.0 and repulsive_potential(0.5, r0, mu) == 0.0
    b = approach_bound([0.04, 0.17, 0.3, 0.5], 0.3, 0.04, 0.26)
    np.testing.assert_allclose(b[:3], [0.0, -0.13, -0.26])
    assert b[3] == -np.inf


def test_protective_separation() -> None:
    m = protective_separation(0.5, 0.03, deceleration=2.0, cloud_resolution=0.04,
                              calibration_error=0.01)  # fmt: skip
    assert m == pytest.approx(0.5 * 0.03 + 0.25 / 4 + 0.04 + 0.01)
    assert protective_separation(0.0, 0.1) == 0.0
    with pytest.raises(ValueError, match="robot_speed"):
        protective_separation(-1.0, 0.1)
