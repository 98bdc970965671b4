"""The one implementation of each orientation error (used by the IK and controller kernels
and by the synthesis problem) against independent truth: analytic rotation pairs and
scipy's ``Rotation``."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from reachwise.errors import InputError
from reachwise.kinematics.orientation import (
    angle_between,
    axis_error,
    quaternion_error,
    rotation_error,
)


def _rot(axis: list[float], phi: float) -> np.ndarray:
    u = np.asarray(axis, dtype=float)
    return Rotation.from_rotvec(phi * u / np.linalg.norm(u)).as_matrix()


# angles across every branch of Shepperd's method and the half turn itself
ANGLES = [0.0, 1e-9, 1e-4, 0.5, 2.0, 3.0, np.pi - 1e-6, np.pi - 1e-9, np.pi]
AXES = [[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 2, 3], [-2, 0.5, 1], [0.3, -1, -0.2]]


@pytest.mark.parametrize("phi", ANGLES)
@pytest.mark.parametrize("axis", AXES)
def test_analytic_pairs(axis: list[float], phi: float) -> None:
    """``R_d = Rot(u, φ) R``: rotation vector ``φ u``, Eq. 3.9 error ``sin(φ/2) u``."""
    u = np.asarray(axis, float) / np.linalg.norm(axis)
    R = _rot([0.2, -0.4, 0.9], 0.7)
    Rd = _rot(axis, phi) @ R
    rv = rotation_error(R, Rd)
    if phi < np.pi:
        np.testing.assert_allclose(rv, phi * u, atol=1e-9)
    else:  # a half turn: ±u are both the answer
        assert min(np.abs(rv - np.pi * u).max(), np.abs(rv + np.pi * u).max()) < 1e-9
    eo = quaternion_error(R, Rd)
    assert np.linalg.norm(eo) == pytest.approx(np.sin(phi / 2), abs=1e-12)
    if phi < np.pi:
        np.testing.assert_allclose(eo, np.sin(phi / 2) * u, atol=1e-12)
    assert angle_between(R, Rd) == pytest.approx(phi, abs=1e-9)


def test_rotation_vector_matches_scipy_on_random_pairs() -> None:
    rng = np.random.default_rng(11)
    R = Rotation.random(500, random_state=rng).as_matrix()
    Rd = Rotation.random(500, random_state=rng).as_matrix()
    expect = Rotation.from_matrix(Rd @ np.swapaxes(R, 1, 2)).as_rotvec()
    np.testing.assert_allclose(rotation_error(R, Rd), expect, atol=1e-12)
    # and close to a half turn, where the axis is hardest to recover
    u = rng.standard_normal((200, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    phi = np.pi - 10.0 ** rng.uniform(-12, -3, 200)
    Rd2 = Rotation.from_rotvec(phi[:, None] * u).as_matrix() @ R[:200]
    np.testing.assert_allclose(rotation_error(R[:200], Rd2), phi[:, None] * u, atol=1e-9)


def test_quaternion_error_matches_scipy_quaternions() -> None:
    """``e_O`` is the vector part of ``q_d q⁻¹`` taken with a non-negative scalar part."""
    rng = np.random.default_rng(12)
    q = Rotation.random(300, random_state=rng)
    qd = Rotation.random(300, random_state=rng)
    rel = (qd * q.inv()).as_quat()
    rel *= np.where(rel[:, 3:] < 0, -1.0, 1.0)
    e = quaternion_error(q.as_matrix(), qd.as_matrix())
    np.testing.assert_allclose(e, rel[:, :3], atol=1e-12)


def test_broadcast_and_shapes() -> None:
    R = Rotation.random(4, random_state=5).as_matrix()
    one = R[0]
    assert rotation_error(R, one).shape == (4, 3)
    assert quaternion_error(one, R).shape == (4, 3)
    assert rotation_error(one, one).shape == (3,)
    np.testing.assert_allclose(rotation_error(R, one)[2], rotation_error(R[2], one), atol=0)
    assert axis_error(R.reshape(2, 2, 3, 3), [0, 0, 1]).shape == (2, 2, 3)


@pytest.mark.parametrize("phi", [0.0, 1e-8, 0.4, 1.5, 3.0, np.pi - 1e-7])
def test_axis_error_analytic(phi: float) -> None:
    """Tilting the tool axis by φ about an axis normal to it gives ``φ u``; a roll about
    the tool axis changes nothing."""
    R = _rot([0.3, 0.1, -0.5], 1.1)
    z, x = R[:, 2], R[:, 0]
    target = _rot(x, phi) @ z  # z turned by φ about the tool's x axis
    for roll in (0.0, 0.8, -2.5):
        Rr = _rot(z, roll) @ R
        np.testing.assert_allclose(axis_error(Rr, 3.0 * target), phi * x, atol=1e-9)


def test_axis_error_antiparallel_is_a_half_turn_about_tool_x() -> None:
    R = _rot([1, 1, 0], 0.6)
    e = axis_error(R, -R[:, 2])
    np.testing.assert_allclose(e, np.pi * R[:, 0], atol=1e-12)


def test_bad_shapes_name_the_field() -> None:
    with pytest.raises(InputError, match="R_d"):
        rotation_error(np.eye(3), np.eye(4))
    with pytest.raises(InputError, match="axis_d"):
        axis_error(np.eye(3), [0.0, 0.0, 0.0])
    with pytest.raises(InputError, match="R"):
        quaternion_error(np.ones(3), np.eye(3))
