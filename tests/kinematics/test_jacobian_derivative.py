"""The Jacobian's derivatives and the LCI gradient against central finite differences."""

from __future__ import annotations

import numpy as np
import pytest

from reachwise import load_robot
from reachwise.kinematics.conditioning import lci_gradient
from reachwise.kinematics.indices import lci
from reachwise.kinematics.jacobian_derivative import jacobian_derivatives
from reachwise.kinematics.robot import BASE_PARAMS, DH_PARAMS, Robot
from reachwise.kinematics.transforms import pose_from_xyz_rpy, xyz_rpy_from_pose
from tests.conftest import random_chain

H = 1e-6


def every_parameter(robot: Robot) -> list[tuple[str, int, str]]:
    """Every DH parameter of every row (fixed rows included) and every base coordinate."""
    rows = [("joint", j, p) for j in range(len(robot.joints)) for p in DH_PARAMS]
    return rows + [("base", -1, p) for p in BASE_PARAMS]


def moved(robot: Robot, param: tuple[str, int, str], h: float) -> Robot:
    kind, j, p = param
    if kind == "joint":
        dh = np.array(robot.dh)
        dh[j, DH_PARAMS.index(p)] += h
        return robot.with_parameters(dh=dh)
    xyz, rpy = xyz_rpy_from_pose(robot.base)
    v = np.concatenate([xyz, rpy])
    v[BASE_PARAMS.index(p)] += h
    return robot.with_parameters(base=pose_from_xyz_rpy(v[:3], v[3:]))


def fd(robot: Robot, q: np.ndarray, k: int, params: list, f) -> np.ndarray:  # type: ignore[no-untyped-def, type-arg]
    """Central difference of ``f(robot, q)`` along joint ``k`` or parameter ``k - n``."""
    if k < robot.n:
        dq = np.zeros_like(q)
        dq[:, k] = H
        return (f(robot, q + dq) - f(robot, q - dq)) / (2 * H)
    par = params[k - robot.n]
    return (f(moved(robot, par, H), q) - f(moved(robot, par, -H), q)) / (2 * H)


def _jac(robot: Robot, q: np.ndarray) -> np.ndarray:
    return np.asarray(robot.jacobian(q))


@pytest.mark.parametrize("classic", [False, True])
def test_jacobian_derivative_matches_fd_on_random_chains(
    classic: bool, rng: np.random.Generator
) -> None:
    for _ in range(3):
        robot = random_chain(rng, 7, classic=classic)
        params = every_parameter(robot)
        q = rng.uniform(robot.lower, robot.upper, (3, robot.n))
        T, J, _, dJ = jacobian_derivatives(robot, q, params)
        assert np.allclose(J, _jac(robot, q)) and np.allclose(T, robot.fk(q))
        assert dJ.shape == (3, 6, robot.n, robot.n + len(params))
        for k in range(robot.n + len(params)):
            np.testing.assert_allclose(dJ[..., k], fd(robot, q, k, params, _jac), atol=2e-7)


def test_a_wrong_axis_rule_is_caught() -> None:
    """The check above can fail: the plausible slip of treating a row's own ``a`` as not
    moving its joint axis (only the tool point moves) is far from the finite difference."""
    robot = load_robot("sb60")
    params = [("joint", 4, "a")]
    q = np.random.default_rng(0).uniform(robot.lower, robot.upper, (2, robot.n))
    _, J, W, dJ = jacobian_derivatives(robot, q, params)
    i = robot.movable_joints.index(4)
    wrong = dJ[..., -1].copy()
    wrong[:, :3, i] = np.cross(J[:, 3:, i], W[:, :3, -1])  # z_i × v_a: the slip
    wrong[:, 3:, i] = 0.0
    truth = fd(robot, q, robot.n, params, _jac)
    assert np.allclose(dJ[..., -1], truth, atol=2e-7)
    assert not np.allclose(wrong, truth, atol=1e-3)


@pytest.mark.parametrize("name", ["sb60", "stanford", "p2-man5"])
def test_lci_gradient_matches_fd(name: str, rng: np.random.Generator) -> None:
    robot = load_robot(name)
    params = robot.design.free or every_parameter(robot)[:12]
    q = rng.uniform(robot.lower, robot.upper, (4, robot.n))
    value, grad = lci_gradient(robot, q, params)
    np.testing.assert_allclose(value, lci(robot, q), rtol=1e-12)

    def f(r: Robot, qq: np.ndarray) -> np.ndarray:
        return np.asarray(lci(r, qq))

    for k in range(robot.n + len(params)):
        num = fd(robot, q, k, params, f)
        rel = np.abs(grad[:, k] - num) / np.maximum(np.abs(num), 1e-3)
        assert rel.max() <= 1e-6, (k, rel.max())
