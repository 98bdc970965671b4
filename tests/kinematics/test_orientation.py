"""Orientation errors: Eq. 3.9 against its closed form, rotation vectors against scipy."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from reachwise.kinematics.orientation import (
    angle_between,
    axis_error,
    quaternion_error,
    rotation_error,
    skew,
)

angles = st.floats(-np.pi, np.pi)
unit = st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1)).filter(
    lambda v: np.linalg.norm(v) > 0.1
)


@settings(max_examples=200, deadline=None)
@given(rv=unit, phi=st.floats(0.0, np.pi - 1e-3), r0=unit, phi0=angles)
def test_quaternion_error_is_half_angle_axis(rv, phi, r0, phi0) -> None:  # type: ignore[no-untyped-def]
    u = np.array(rv) / np.linalg.norm(rv)
    R = Rotation.from_rotvec(np.array(r0) / np.linalg.norm(r0) * phi0).as_matrix()
    Rd = Rotation.from_rotvec(u * phi).as_matrix() @ R  # R_d = Rot(u, φ) R, world frame
    e = quaternion_error(R, Rd)
    np.testing.assert_allclose(e, np.sin(phi / 2) * u, atol=1e-9)
    np.testing.assert_allclose(rotation_error(R, Rd), phi * u, atol=1e-8)
    assert abs(angle_between(R, Rd) - phi) < 1e-8  # R_d is R turned by φ


def _rx(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])


def _rz(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def test_angle_between_analytic_rotation_pairs() -> None:
    """Pairs whose angle is known by construction, written out without scipy."""
    eye = np.eye(3)
    flip_x = np.diag([1.0, -1.0, -1.0])  # half turn about x
    cases = [
        (eye, eye, 0.0),
        (eye, _rx(np.pi / 2), np.pi / 2),
        (_rz(0.3), _rz(-0.4), 0.7),  # same axis: the angles subtract
        (_rz(3.0), _rz(-3.0), 2 * np.pi - 6.0),  # and wrap the short way round
        (eye, flip_x, np.pi),
        (_rx(0.2), _rx(0.2) @ _rz(1e-7), 1e-7),  # tiny angles keep their precision
        (_rz(1.0) @ _rx(0.5), _rx(0.5), 1.0),  # a world-frame turn of 1 rad about z
    ]
    for R, Rd, angle in cases:
        got = angle_between(R, Rd)
        assert abs(got - angle) < 1e-12 * max(1.0, angle) + 1e-15, (angle, got)
        assert abs(angle_between(Rd, R) - angle) < 1e-12 * max(1.0, angle) + 1e-15
    batch = angle_between(np.stack([eye, eye]), np.stack([_rx(0.25), _rz(-1.5)]))
    np.testing.assert_allclose(batch, [0.25, 1.5], rtol=1e-13)


def test_eq_3_9_written_out() -> None:
    rng = np.random.default_rng(1)
    for _ in range(50):
        q = Rotation.random(random_state=rng)
        qd = Rotation.random(random_state=rng)
        x, y, z, w = q.as_quat()
        xd, yd, zd, wd = qd.as_quat()
        if w * wd + x * xd + y * yd + z * zd < 0:
            xd, yd, zd, wd = -xd, -yd, -zd, -wd
        eps, epsd = np.array([x, y, z]), np.array([xd, yd, zd])
        expect = w * epsd - wd * eps - skew(epsd) @ eps
        np.testing.assert_allclose(
            quaternion_error(q.as_matrix(), qd.as_matrix()), expect, atol=1e-12
        )


def test_zero_error_and_batch() -> None:
    R = Rotation.random(5, random_state=3).as_matrix()
    assert np.allclose(quaternion_error(R, R), 0.0)
    assert np.allclose(rotation_error(R, R), 0.0)
    assert quaternion_error(R, R).shape == (5, 3)


def test_axis_error_ignores_roll_about_tool_axis() -> None:
    R = Rotation.from_euler("xyz", [0.3, -0.2, 0.1]).as_matrix()
    roll = Rotation.from_rotvec(R[:, 2] * 1.3).as_matrix() @ R
    assert np.allclose(axis_error(roll, R[:, 2]), 0.0, atol=1e-12)
    e = axis_error(R, [0, 0, 1])
    assert np.isclose(np.linalg.norm(e), np.arccos(R[2, 2]))
    assert abs(np.dot(e, R[:, 2])) < 1e-12  # no component about the tool axis
    # antiparallel: a half turn about an axis normal to z
    flip = axis_error(np.eye(3), [0, 0, -1])
    assert np.isclose(np.linalg.norm(flip), np.pi) and abs(flip[2]) < 1e-12
