"""Inverse kinematics: success rate on reachable targets, honesty, masks and limits."""

from __future__ import annotations

import numpy as np
import pytest

from reachwise import load_robot
from reachwise.errors import InputError
from reachwise.kinematics.orientation import angle_between, axis_error
from reachwise.kinematics.transforms import pose_from_xyz_rpy


def test_panda_1000_random_reachable_targets() -> None:
    robot = load_robot("panda")
    rng = np.random.default_rng(2017)
    Q = rng.uniform(robot.lower, robot.upper, (1000, robot.n))
    targets = robot.fk(Q)
    solved = 0
    for T in targets:
        res = robot.ik(T, rng=rng)
        # independent check of what the solver claims
        Tq = robot.fk(res.q)
        ep = np.linalg.norm(Tq[:3, 3] - T[:3, 3])
        eo = angle_between(Tq[:3, :3], T[:3, :3])
        inside = bool(robot.within_limits(res.q))
        honest = ep <= 1e-6 and eo <= 1e-6 and inside
        assert res.success == honest, (res, ep, eo)
        assert res.position_error == pytest.approx(ep, abs=1e-12)
        solved += honest
    assert solved >= 997


def test_position_only_and_axis_masks(rng: np.random.Generator) -> None:
    robot = load_robot("puma560")
    for _ in range(30):
        q = rng.uniform(robot.lower, robot.upper)
        T = robot.fk(q)
        # 3-D: any orientation, position exact
        target = T.copy()
        target[:3, :3] = pose_from_xyz_rpy(rpy=rng.uniform(-3, 3, 3))[:3, :3]
        r3 = robot.ik(target, mask=3, rng=rng)
        assert r3.success
        assert np.linalg.norm(robot.fk(r3.q)[:3, 3] - T[:3, 3]) <= 1e-6
        # 5-D: tool z axis matched, roll about it free
        roll = pose_from_xyz_rpy(rpy=(0, 0, rng.uniform(-3, 3)))
        r5 = robot.ik(T @ roll, mask=5, rng=rng)
        assert r5.success
        T5 = robot.fk(r5.q)
        assert np.linalg.norm(axis_error(T5[:3, :3], T[:3, 2])) <= 1e-6
        assert np.linalg.norm(T5[:3, 3] - T[:3, 3]) <= 1e-6


def test_row_mask_selects_directions(rng: np.random.Generator) -> None:
    robot = load_robot("panda")
    q = rng.uniform(robot.lower, robot.upper)
    T = robot.fk(q)
    target = T.copy()
    target[2, 3] += 5.0  # z unreachable change, but z is not constrained
    res = robot.ik(target, mask=np.array([1, 1, 0, 1, 1, 1], dtype=bool), rng=rng)
    assert res.success
    got = robot.fk(res.q)
    np.testing.assert_allclose(got[:2, 3], T[:2, 3], atol=1e-6)


def test_unreachable_target_is_not_success() -> None:
    robot = load_robot("panda")
    T = pose_from_xyz_rpy((3.0, 0.0, 0.5))
    res = robot.ik(T, rng=0, restarts=3)
    assert not res.success
    assert res.position_error > 1.0
    assert robot.within_limits(res.q)


def test_start_outside_limits_is_projected_inside(rng: np.random.Generator) -> None:
    robot = load_robot("panda")
    q = rng.uniform(robot.lower, robot.upper)
    q0 = robot.upper + 0.5
    res = robot.ik(robot.fk(q), q0=q0, rng=rng)
    assert res.success and robot.within_limits(res.q)


def test_seeded_results_are_reproducible() -> None:
    robot = load_robot("panda")
    T = robot.fk(np.array([0.5, 0.3, -0.2, -1.5, 0.2, 1.8, 0.4]))
    a = robot.ik(T, rng=5)
    b = robot.ik(T, rng=5)
    np.testing.assert_array_equal(a.q, b.q)


@pytest.mark.parametrize("mask", [4, 0, np.zeros(6, dtype=bool), [1, 2]])
def test_bad_mask(mask: object) -> None:
    robot = load_robot("panda")
    with pytest.raises(InputError, match="mask"):
        robot.ik(np.eye(4), mask=mask)


def test_bad_target() -> None:
    robot = load_robot("panda")
    with pytest.raises(InputError, match="ik target"):
        robot.ik(np.full((4, 4), np.nan))


def test_options_group_and_keywords_are_one_setting() -> None:
    """IKOptions is the typed group of solve_ik's settings; each field is also a keyword
    (the documented call), and a keyword overrides the group."""
    from reachwise.kinematics.ik import IKOptions, solve_ik

    robot = load_robot("puma560")
    T = robot.fk(np.full(robot.n, 0.3))
    loose = IKOptions(tol_position=1e-3, tol_orientation=1e-3, max_iter=1, restarts=0)
    by_group = solve_ik(robot, T, options=loose)
    by_keywords = solve_ik(
        robot, T, tol_position=1e-3, tol_orientation=1e-3, max_iter=1, restarts=0
    )
    np.testing.assert_array_equal(by_group.q, by_keywords.q)
    assert (by_group.iterations, by_group.attempts) == (by_keywords.iterations, 1)
    assert by_group.iterations == 1 and not by_group.success  # one step from mid-range
    longer = solve_ik(robot, T, options=loose, max_iter=50)  # the keyword wins
    assert longer.success and longer.iterations > 1
    with pytest.raises(TypeError, match="tol_postion"):
        solve_ik(robot, T, tol_postion=1e-3)
