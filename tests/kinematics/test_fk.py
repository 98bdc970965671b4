"""Forward kinematics against hand-built DH products and analytic cases."""

from __future__ import annotations

import numpy as np
import pytest

from reachwise import load_robot
from reachwise.errors import InputError
from reachwise.kinematics.robot import Joint, Robot
from reachwise.kinematics.transforms import rot_x as rx
from reachwise.kinematics.transforms import rot_z as rz
from reachwise.kinematics.transforms import translation as tr
from tests.conftest import random_chain


def naive_frames(robot: Robot, q: np.ndarray) -> list[np.ndarray]:
    """Product of elementary matrices, joint by joint, as written in the DH tables."""
    out = [robot.base.copy()]
    k = 0
    for j in robot.joints:
        theta, d = j.theta, j.d
        if j.type == "revolute":
            theta += q[k]
        if j.type == "prismatic":
            d += q[k]
        k += j.type != "fixed"
        if robot.convention == "modified":
            A = rx(j.alpha) @ tr(x=j.a) @ rz(theta) @ tr(z=d)
        else:
            A = rz(theta) @ tr(z=d) @ tr(x=j.a) @ rx(j.alpha)
        out.append(out[-1] @ A)
    out.append(out[-1] @ robot.tool)
    return out


@pytest.mark.parametrize("classic", [False, True])
def test_fk_all_equals_elementary_product(rng: np.random.Generator, classic: bool) -> None:
    for _ in range(20):
        robot = random_chain(rng, int(rng.integers(1, 9)), classic)
        q = rng.uniform(robot.lower, robot.upper)
        F = robot.fk_all(q)
        ref = np.stack(naive_frames(robot, q))
        np.testing.assert_allclose(F, ref, atol=1e-12)
        np.testing.assert_allclose(robot.fk(q), ref[-1], atol=1e-12)


def test_batch_equals_single(rng: np.random.Generator) -> None:
    robot = random_chain(rng, 8)
    Q = rng.uniform(robot.lower, robot.upper, (50, robot.n))
    T = robot.fk(Q)
    F = robot.fk_all(Q)
    assert T.shape == (50, 4, 4) and F.shape == (50, 10, 4, 4)
    for i in (0, 17, 49):
        np.testing.assert_array_equal(T[i], robot.fk(Q[i]))
        np.testing.assert_array_equal(F[i], robot.fk_all(Q[i]))


def test_planar_2r_analytic() -> None:
    l1, l2 = 0.7, 0.4
    robot = Robot(
        "2r",
        (Joint("revolute"), Joint("revolute", a=l1), Joint("fixed", a=l2)),
    )
    for q1, q2 in [(0.0, 0.0), (0.3, -1.1), (np.pi / 2, np.pi / 2)]:
        p = robot.fk([q1, q2])[:3, 3]
        expect = [l1 * np.cos(q1) + l2 * np.cos(q1 + q2), l1 * np.sin(q1) + l2 * np.sin(q1 + q2), 0]
        np.testing.assert_allclose(p, expect, atol=1e-14)


def test_panda_home_flange() -> None:
    # Published: at q = 0 the Panda flange sits at (0.088, 0, 0.926) m, z pointing down.
    T = load_robot("panda").fk(np.zeros(7))
    np.testing.assert_allclose(T[:3, 3], [0.088, 0.0, 0.926], atol=1e-12)
    np.testing.assert_allclose(T[:3, 2], [0.0, 0.0, -1.0], atol=1e-12)


def test_classic_equals_converted_modified(rng: np.random.Generator) -> None:
    """A classic table rewritten exactly in modified form (a, alpha shifted one row,
    the last a/alpha into the tool) gives the same tool pose."""
    classic = random_chain(rng, 6, classic=True)
    rows = classic.joints
    mod = []
    for i, j in enumerate(rows):
        prev = rows[i - 1] if i else None
        mod.append(
            Joint(
                j.type,
                a=prev.a if prev else 0.0,
                alpha=prev.alpha if prev else 0.0,
                d=j.d,
                theta=j.theta,
                limits=j.limits,
            )
        )
    last = rows[-1]
    tool = tr(x=last.a) @ rx(last.alpha) @ classic.tool
    modified = Robot("m", tuple(mod), "modified", base=classic.base, tool=tool)
    Q = rng.uniform(classic.lower, classic.upper, (30, classic.n))
    np.testing.assert_allclose(classic.fk(Q), modified.fk(Q), atol=1e-12)


@pytest.mark.parametrize("bad", [np.zeros(6), np.zeros((2, 8)), [np.nan] * 7, "abc"])
def test_bad_q_is_a_clear_error(bad: object) -> None:
    with pytest.raises(InputError, match="q"):
        load_robot("panda").fk(bad)  # type: ignore[arg-type]
