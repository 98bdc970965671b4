"""Conditioning indices: singular poses, bounds and hand-computed cases."""

from __future__ import annotations

import numpy as np
import pytest

from reachwise import load_robot
from reachwise.errors import InputError
from reachwise.kinematics.indices import (
    condition_number,
    gci,
    inverse_condition,
    kci,
    lci,
    manipulability,
    scaled_jacobian,
)
from reachwise.kinematics.robot import Joint, Robot


def test_puma_singular_poses(rng: np.random.Generator) -> None:
    robot = load_robot("puma560")
    for _ in range(20):
        q = rng.uniform(robot.lower, robot.upper)
        q[4] = 0.0  # wrist singularity: axes 4 and 6 aligned
        assert lci(robot, q) < 1e-12
    # elbow singularity: the forearm (a3, d4) lies along the upper arm a2, i.e. the
    # arm is stretched: θ3 = π/2 + atan2(a3, d4) in Craig's frames (the other root,
    # −π/2 + atan2(a3, d4), is outside the θ3 range)
    q = np.array([0.2, -0.4, np.pi / 2 + np.arctan2(0.0203, 0.4318), 0.3, 0.5, 0.1])
    assert robot.within_limits(q)
    assert lci(robot, q) < 1e-12


def test_kci_le_gci_le_one(rng: np.random.Generator) -> None:
    robot = load_robot("panda")
    Q = rng.uniform(robot.lower, robot.upper, (100, 7))
    v = lci(robot, Q)
    assert np.all((v >= 0) & (v <= 1))
    assert kci(v) <= gci(v) <= 1.0
    # KCI is the worst case: 1 / max κ of the nominal-length-scaled Jacobians
    T = robot.fk(Q)
    L = np.linalg.norm(T[:, :3, 3] - robot.base[:3, 3], axis=1)
    kappa = condition_number(scaled_jacobian(robot.jacobian(Q), L))
    assert kci(v) == pytest.approx(1 / np.max(kappa), rel=1e-12)


def test_hand_computed_planar_2r() -> None:
    """Planar 2R with equal links l: position Jacobian singular values are known.

    At q2 = π/2 and l1 = l2 = 1 the 2x2 position Jacobian [[-1-... ]] has
    J = [[-s1 - s12, -s12], [c1 + c12, c12]]; at q1 = 0, q2 = π/2:
    J = [[-1, -1], [1, 0]], σ² = (3 ± √5)/2, κ = (3 + √5)/2 / 1 → κ = φ² (golden ratio²).
    """
    robot = Robot("2r", (Joint("revolute"), Joint("revolute", a=1.0), Joint("fixed", a=1.0)))
    q = np.array([0.0, np.pi / 2])
    J = robot.jacobian(q)[:2]
    phi = (1 + np.sqrt(5)) / 2
    assert condition_number(J) == pytest.approx(phi**2, rel=1e-12)
    assert lci(robot, q, rows=[0, 1], scale=False) == pytest.approx(1 / phi**2, rel=1e-12)
    assert manipulability(J) == pytest.approx(1.0)  # |det J| = l1 l2 |sin q2|
    # stretched arm is singular
    assert lci(robot, np.array([0.3, 0.0]), rows=[0, 1]) < 1e-15


def test_nominal_length_scaling_is_eq_36_37() -> None:
    J = np.arange(12.0).reshape(6, 2) + 1
    S = np.diag([1, 1, 1, 2.5, 2.5, 2.5])
    np.testing.assert_allclose(scaled_jacobian(J, 2.5), S @ J)
    # scaling the whole matrix does not change κ
    assert inverse_condition(S @ J) == pytest.approx(inverse_condition(S @ J / 2.5))


def test_bad_index_input() -> None:
    with pytest.raises(InputError):
        gci([])
    with pytest.raises(InputError):
        kci([0.5, np.nan])
