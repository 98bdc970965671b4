"""Tool, point and DH-parameter Jacobians against central finite differences."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from reachwise import load_robot
from reachwise.kinematics.robot import Robot
from reachwise.kinematics.transforms import pose_from_xyz_rpy, xyz_rpy_from_pose
from tests.conftest import random_chain

H = 1e-6


def twist_fd(T_plus: np.ndarray, T_minus: np.ndarray, h: float) -> np.ndarray:
    """Central difference of a pose: [linear velocity; angular velocity]."""
    v = (T_plus[:3, 3] - T_minus[:3, 3]) / (2 * h)
    w = Rotation.from_matrix(T_plus[:3, :3] @ T_minus[:3, :3].T).as_rotvec() / (2 * h)
    return np.concatenate([v, w])


def fd_tool_jacobian(robot: Robot, q: np.ndarray) -> np.ndarray:
    cols = []
    for i in range(robot.n):
        dq = np.zeros(robot.n)
        dq[i] = H
        cols.append(twist_fd(robot.fk(q + dq), robot.fk(q - dq), H))
    return np.stack(cols, axis=1)


ROBOTS = ["panda", "puma560"]


@pytest.mark.parametrize("name", ROBOTS)
def test_tool_jacobian_matches_fd_builtin(name: str, rng: np.random.Generator) -> None:
    robot = load_robot(name)
    for _ in range(20):
        q = rng.uniform(robot.lower, robot.upper)
        np.testing.assert_allclose(robot.jacobian(q), fd_tool_jacobian(robot, q), atol=1e-6)


@pytest.mark.parametrize("classic", [False, True])
def test_tool_jacobian_matches_fd_random_chains(rng: np.random.Generator, classic: bool) -> None:
    for _ in range(30):
        robot = random_chain(rng, int(rng.integers(2, 9)), classic)
        if robot.n == 0:
            continue
        q = rng.uniform(robot.lower, robot.upper)
        J = robot.jacobian(q)
        np.testing.assert_allclose(J, fd_tool_jacobian(robot, q), atol=1e-6)
        # a prismatic column is a unit translation: never zero
        for k in np.flatnonzero(robot.prismatic):
            assert np.linalg.norm(J[:3, k]) == pytest.approx(1.0)
            assert np.allclose(J[3:, k], 0.0)


def test_batched_jacobian_equals_single(rng: np.random.Generator) -> None:
    robot = random_chain(rng, 8)
    Q = rng.uniform(robot.lower, robot.upper, (10, robot.n))
    Jb = robot.jacobian(Q)
    Pb = robot.param_jacobian(Q)
    for i in range(10):
        np.testing.assert_array_equal(Jb[i], robot.jacobian(Q[i]))
        np.testing.assert_array_equal(Pb[i], robot.param_jacobian(Q[i]))


@pytest.mark.parametrize("classic", [False, True])
def test_point_jacobian_matches_fd(rng: np.random.Generator, classic: bool) -> None:
    for _ in range(10):
        robot = random_chain(rng, 7, classic)
        q = rng.uniform(robot.lower, robot.upper)
        for link in range(len(robot.link_names)):
            p_local = rng.uniform(-0.5, 0.5, 3)

            def world(
                qq: np.ndarray, link: int = link, p: np.ndarray = p_local, robot: Robot = robot
            ) -> np.ndarray:
                F = robot.fk_all(qq)[link]
                return F[:3, :3] @ p + F[:3, 3]

            fd = np.stack(
                [(world(q + H * e) - world(q - H * e)) / (2 * H) for e in np.eye(robot.n)],
                axis=1,
            )
            Jp = robot.point_jacobian(q, link, p_local)
            np.testing.assert_allclose(Jp, fd, atol=1e-6)
            # the same point given in world coordinates
            Jw = robot.point_jacobian(q, robot.link_names[link], world(q), frame="world")
            np.testing.assert_allclose(Jw, Jp, atol=1e-12)


def test_point_jacobian_at_tool_equals_tool_jacobian(rng: np.random.Generator) -> None:
    robot = load_robot("panda")
    q = rng.uniform(robot.lower, robot.upper)
    np.testing.assert_allclose(
        robot.point_jacobian(q, "tool", np.zeros(3)), robot.jacobian(q)[:3], atol=1e-14
    )


def fd_param_jacobian(robot: Robot, q: np.ndarray) -> np.ndarray:
    cols = []
    dh = robot.dh
    for j in range(len(robot.joints)):
        for p in range(4):
            d = np.zeros_like(dh)
            d[j, p] = H
            Tp = robot.with_parameters(dh=dh + d).fk(q)
            Tm = robot.with_parameters(dh=dh - d).fk(q)
            cols.append(twist_fd(Tp, Tm, H))
    xyz, rpy = xyz_rpy_from_pose(robot.base)
    x6 = np.concatenate([xyz, rpy])
    for k in range(6):
        e = np.zeros(6)
        e[k] = H
        bp = pose_from_xyz_rpy((x6 + e)[:3], (x6 + e)[3:])
        bm = pose_from_xyz_rpy((x6 - e)[:3], (x6 - e)[3:])
        cols.append(
            twist_fd(robot.with_parameters(base=bp).fk(q), robot.with_parameters(base=bm).fk(q), H)
        )
    return np.stack(cols, axis=1)


@pytest.mark.parametrize("classic", [False, True])
def test_param_jacobian_matches_fd(rng: np.random.Generator, classic: bool) -> None:
    for _ in range(15):
        robot = random_chain(rng, int(rng.integers(1, 9)), classic)
        q = rng.uniform(robot.lower, robot.upper)
        P = robot.param_jacobian(q)
        assert P.shape == (6, 4 * len(robot.joints) + 6)
        np.testing.assert_allclose(P, fd_param_jacobian(robot, q), atol=1e-6)


def test_param_jacobian_theta_column_equals_joint_column(rng: np.random.Generator) -> None:
    """For a revolute joint the theta offset and q enter the same way."""
    robot = load_robot("panda")
    q = rng.uniform(robot.lower, robot.upper)
    P = robot.param_jacobian(q)
    J = robot.jacobian(q)
    for k in range(7):
        np.testing.assert_allclose(P[:, 4 * k + 3], J[:, k], atol=1e-14)
