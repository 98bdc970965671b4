"""The synthesis problem: layout, residual and its Jacobian against finite differences."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from reachwise import load_robot
from reachwise.errors import InputError
from reachwise.kinematics.robot import DesignSpace, Robot
from reachwise.synthesis.problem import SynthesisProblem
from reachwise.tasks.task import Task
from tests.synthesis.conftest import recovery_task, sb60

H = 1e-6


def test_layout_counts() -> None:
    robot = sb60()
    task, _, _ = recovery_task(robot, np.random.default_rng(0), 87)
    prob = SynthesisProblem(robot, task, locked={6: 0.0})
    assert prob.p == robot.design.size == 10
    assert prob.n_free_joints == robot.n - 1
    assert prob.size == 10 + 87 * 7  # several hundred unknowns …
    assert prob.residual_rows == 87 * 6 < prob.size  # … fewer residuals than unknowns
    z = prob.pack(prob.design_vector(), np.zeros((87, robot.n)))
    d, Q = prob.split(z)
    assert np.allclose(Q[:, 6], 0.0) and d.shape == (10,)


@pytest.mark.parametrize("dims", [3, 5, 6])
def test_residual_jacobian_matches_fd_at_solution(dims: int) -> None:
    """At the exact solution the residual's derivative is −Φ in every row, the
    orientation rows included (the rotation-vector map has unit derivative at 0)."""
    robot = sb60()
    rng = np.random.default_rng(dims)
    task, design, Q = recovery_task(robot, rng, 4, dims)
    prob = SynthesisProblem(robot, task)
    z = prob.pack(design, Q)
    ev = prob.evaluate(z)
    assert np.abs(ev.e).max() < 1e-9
    Phi = prob.dense_jacobian(ev)
    fd = np.empty_like(Phi)
    for i in range(prob.size):
        dz = np.zeros(prob.size)
        dz[i] = H
        rp = prob.dense_residual(prob.evaluate(z + dz))
        rm = prob.dense_residual(prob.evaluate(z - dz))
        fd[:, i] = -(rp - rm) / (2 * H)
    np.testing.assert_allclose(Phi, fd, atol=1e-6)


def test_jacobian_matches_pose_fd_away_from_solution() -> None:
    """Away from the solution the rows are the tool-point velocity and angular
    velocity per unit change of each variable (geometric Jacobian)."""
    robot = sb60()
    rng = np.random.default_rng(9)
    task, design, Q = recovery_task(robot, rng, 3, 6)
    prob = SynthesisProblem(robot, task)
    z = prob.pack(design, Q) + rng.normal(0, 0.05, prob.size)
    ev = prob.evaluate(z)
    Phi = prob.dense_jacobian(ev)
    for i in range(prob.size):
        dz = np.zeros(prob.size)
        dz[i] = H
        Tp, Tm = prob.evaluate(z + dz).T, prob.evaluate(z - dz).T
        v = (Tp[:, :3, 3] - Tm[:, :3, 3]) / (2 * H)
        w = Rotation.from_matrix(Tp[:, :3, :3] @ np.swapaxes(Tm[:, :3, :3], 1, 2)).as_rotvec()
        col = np.concatenate([v, w / (2 * H)], axis=1).ravel()
        np.testing.assert_allclose(Phi[:, i], col, atol=1e-6)


def test_bad_problems() -> None:
    robot = load_robot("panda")
    task = Task.from_arrays("t", np.ones((2, 3)), dims=3)
    with pytest.raises(InputError, match="no free design parameter"):
        SynthesisProblem(robot, task)
    with pytest.raises(InputError, match="lower bound"):
        DesignSpace(joints={0: {"a": (1.0, -1.0)}})
    tpl = Robot("x", robot.joints, design=DesignSpace(joints={0: {"d": (0.0, 1.0)}}))
    with pytest.raises(InputError, match="locked"):
        SynthesisProblem(tpl, task, locked={0: 99.0})
