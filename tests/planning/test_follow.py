"""Timing a joint path, and following it with the task-space controller."""

from __future__ import annotations

import numpy as np
import pytest

from reachwise.control.controller import Controller, ControllerConfig
from reachwise.errors import InputError
from reachwise.io.robot_file import load_robot
from reachwise.planning import TimedPath, time_path
from reachwise.planning.follow import PathFollower

PATH = np.array(
    [
        [0.8307, 0.5112, 0.0084, -1.6943, -0.0051, 2.2055, 0.841],
        [0.40, 0.20, 0.0084, -1.40, 0.30, 1.60, 0.90],
        [-0.50, 0.30, 0.0084, -1.80, 0.60, 2.00, 0.40],
    ]
)


def _speeds(tp: TimedPath, fk, n: int = 4000) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # type: ignore[no-untyped-def]
    """Finite-difference joint, tool linear and tool angular speeds along ``tp``."""
    t = np.linspace(0.0, tp.duration, n)
    q = np.array([tp.at(s) for s in t])
    T = fk(q)
    dt = t[1] - t[0]
    qd = np.abs(np.diff(q, axis=0)) / dt
    v = np.linalg.norm(np.diff(T[:, :3, 3], axis=0), axis=1) / dt
    R = np.einsum("kji,kjl->kil", T[:-1, :3, :3], T[1:, :3, :3])
    w = np.arccos(np.clip((np.trace(R, axis1=1, axis2=2) - 1) / 2, -1, 1)) / dt
    return qd, v, w


def test_time_path_keeps_joint_and_tool_speeds() -> None:
    robot = load_robot("panda")
    tp = time_path(
        PATH, robot.vmax, speed=0.5, fk=robot.fk, tool_speed=0.1, tool_rate=0.4, samples=64
    )
    np.testing.assert_array_equal(tp.q, PATH)
    assert tp.t[0] == 0.0 and np.all(np.diff(tp.t) > 0)
    np.testing.assert_allclose(tp.at(0.0), PATH[0])
    np.testing.assert_allclose(tp.at(tp.duration + 1.0), PATH[-1])
    np.testing.assert_allclose(tp.at(tp.t[1]), PATH[1], atol=1e-12)
    qd, v, w = _speeds(tp, robot.fk)
    assert np.all(qd <= 0.5 * robot.vmax + 1e-9)
    # the tool bounds are enforced on 64 samples per segment: finer differences may
    # exceed them by the curvature between samples, a few per mille here
    assert v.max() <= 0.1 * 1.01 and w.max() <= 0.4 * 1.01
    # and one of the bounds is active on every segment (not slower than needed)
    for i in range(len(PATH) - 1):
        seg = (np.linspace(0, tp.duration, 4000)[:-1] >= tp.t[i]) & (
            np.linspace(0, tp.duration, 4000)[:-1] < tp.t[i + 1]
        )
        ratios = [qd[seg].max(axis=0).max() / (0.5 * robot.vmax.min()), v[seg].max() / 0.1]
        assert max(max(ratios), w[seg].max() / 0.4) > 0.95


def test_time_path_joint_limits_only_and_velocity() -> None:
    vmax = np.full(7, 2.0)
    tp = time_path(PATH, vmax, speed=1.0)
    seg = np.diff(PATH, axis=0)
    np.testing.assert_allclose(np.diff(tp.t), np.abs(seg).max(axis=1) / 2.0)
    np.testing.assert_allclose(tp.velocity(0.5 * tp.t[1]), seg[0] / tp.t[1])
    np.testing.assert_array_equal(tp.velocity(tp.duration + 1.0), np.zeros(7))
    # repeated waypoints are dropped, a single one is a zero-length path
    tp2 = time_path(np.repeat(PATH, 2, axis=0), vmax, speed=1.0)
    np.testing.assert_allclose(tp2.t, tp.t)
    one = time_path(PATH[:1], vmax)
    assert one.duration == 0.0


@pytest.mark.parametrize(
    ("kw", "field"),
    [({"speed": 0.0}, "speed"), ({"tool_speed": -1.0}, "tool_speed"), ({"samples": 0}, "samples")],
)
def test_time_path_rejects_bad_options(kw: dict, field: str) -> None:  # type: ignore[type-arg]
    with pytest.raises(InputError, match=field):
        time_path(PATH, np.ones(7), **kw)


def test_time_path_needs_a_finite_bound() -> None:
    with pytest.raises(InputError, match="no finite speed bound"):
        time_path(PATH, np.full(7, np.inf))


def _follow(hold: tuple[int, ...]) -> tuple[np.ndarray, PathFollower, float]:
    """Run the controller (no obstacles) on a kinematic plant along PATH (joint 3 fixed
    in it) with the joints ``hold`` locked; returns the largest deviation of each joint
    from the reference, the follower and how late it finished (s)."""
    robot = load_robot("panda")
    cfg = ControllerConfig(avoidance=False, v_max=0.25, w_max=1.0, kv=1.0, kw=1.0)
    ctl = Controller(robot, cfg, locked_joints=hold)
    tp = time_path(PATH, robot.vmax, speed=0.5, fk=robot.fk, tool_speed=0.125, tool_rate=0.5)
    f = PathFollower(robot, tp, lead=1.0 / cfg.kv, turn_lead=2.0 / cfg.kw, stall_time=2.0)
    q = PATH[0].copy()
    dt = 0.01
    dev = np.zeros(robot.n)
    t = 0.0
    while not f.done(q) and not f.stuck and t < tp.duration + 20.0:
        goal = f.goal(q, dt)
        cmd, st = ctl.step(q, goal, None, t)
        assert st.state in ("moving", "reached")
        q = q + dt * cmd
        dev = np.maximum(dev, np.abs(q - tp.at(f.s)))
        t += dt
    return dev, f, t - tp.duration


def test_follower_tracks_the_joint_path_with_the_surplus_joint_locked() -> None:
    dev, f, late = _follow(hold=(2,))
    assert f.done(f.path.q[-1]) and not f.stuck
    assert f.finished and late < 3.0  # at most the controller's settling behind the path
    assert dev[2] < 1e-12  # the locked joint never moves
    # tool errors up to the hold distances (5 cm, 0.25 rad), mostly at the corners
    assert dev.max() < 0.2, dev


def test_follower_with_a_free_redundant_joint_drifts_in_the_null_space() -> None:
    # why the planner holds surplus joints: the same poses, other joint values
    dev, _, _ = _follow(hold=())
    assert dev[[0, 2]].max() > 0.3, dev  # joints 1 and 3 trade places (elbow swivel)


def test_follower_validates_its_input() -> None:
    robot = load_robot("panda")
    tp = time_path(PATH, robot.vmax)
    with pytest.raises(InputError, match="dims"):
        PathFollower(robot, tp, lead=1.0, dims=4)
    with pytest.raises(InputError, match="lead"):
        PathFollower(robot, tp, lead=-1.0)
    with pytest.raises(InputError, match="path"):
        PathFollower(robot, TimedPath(tp.t, tp.q[:, :6]), lead=1.0)
