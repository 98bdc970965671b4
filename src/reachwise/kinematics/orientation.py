"""Orientation errors: the unit-quaternion error of thesis Eq. 3.9, the rotation-vector
error used by the solvers, and the 5-D error of an axis-symmetric tool (P-II §5).

Quaternions are exposed in scipy's ``(x, y, z, w)`` order.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation


def skew(v: ArrayLike) -> NDArray[np.float64]:
    """The skew-symmetric matrix ``S(v)`` with ``S(v) w = v × w``."""
    x, y, z = np.asarray(v, dtype=float)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def quaternion_error(R: ArrayLike, R_d: ArrayLike) -> NDArray[np.float64]:
    """Orientation error ``e_O = η ε_d − η_d ε − S(ε_d) ε`` (thesis Eq. 3.9).

    ``σ = {η, ε}`` and ``σ_d = {η_d, ε_d}`` are the unit quaternions of the current
    rotation ``R`` and the goal ``R_d`` (world frame). ``e_O`` is the vector part of
    ``σ_d * σ⁻¹``, i.e. ``sin(φ/2) u`` for the rotation ``(u, φ)`` taking ``R`` to
    ``R_d``; ``σ_d`` is sign-aligned with ``σ`` so the shorter rotation is taken.
    Batched over leading axes.
    """
    q = Rotation.from_matrix(np.asarray(R, dtype=float)).as_quat()
    qd = Rotation.from_matrix(np.asarray(R_d, dtype=float)).as_quat()
    q, qd = np.broadcast_arrays(q, qd)
    flip = np.sum(q * qd, axis=-1) < 0
    qd = np.where(flip[..., None], -qd, qd)
    eta, eps = q[..., 3:4], q[..., :3]
    eta_d, eps_d = qd[..., 3:4], qd[..., :3]
    return np.asarray(eta * eps_d - eta_d * eps - np.cross(eps_d, eps))


def rotation_error(R: ArrayLike, R_d: ArrayLike) -> NDArray[np.float64]:
    """Rotation vector ``φ u`` of ``R_d Rᵀ`` (world frame), ``φ ∈ [0, π]``; batched.

    Same direction as Eq. 3.9's ``e_O`` (``|e_O| = sin(φ/2)``), but linear in the angle,
    which gives the inverse-kinematics iteration its quadratic convergence.
    """
    Rm = np.asarray(R, dtype=float)
    Rd = np.asarray(R_d, dtype=float)
    E = Rd @ np.swapaxes(Rm, -1, -2)
    return np.asarray(Rotation.from_matrix(E).as_rotvec())


def axis_error(R: ArrayLike, axis_d: ArrayLike) -> NDArray[np.float64]:
    """5-D orientation error of an axis-symmetric tool (drill feed, P-II §5).

    Only the direction of the tool z axis ``z = R[:, 2]`` matters: the error is the
    rotation vector ``φ u`` of the shortest rotation taking ``z`` onto ``axis_d``
    (``u ∥ z × axis_d``), with no component about the tool axis. Batched.
    """
    z = np.asarray(R, dtype=float)[..., :, 2]
    zd = np.asarray(axis_d, dtype=float)
    zd = zd / np.linalg.norm(zd, axis=-1, keepdims=True)
    c = np.cross(z, zd)
    s = np.linalg.norm(c, axis=-1, keepdims=True)
    cosang = np.sum(z * zd, axis=-1, keepdims=True)
    ang = np.arctan2(s, cosang)
    with np.errstate(invalid="ignore", divide="ignore"):
        u = np.where(s > 1e-15, c / np.where(s > 0, s, 1.0), 0.0)
    # Antiparallel axes: any axis perpendicular to z is a shortest rotation.
    anti = (s[..., 0] <= 1e-15) & (cosang[..., 0] < 0)
    if np.any(anti):
        perp = np.asarray(R, dtype=float)[..., :, 0]
        u = np.where(anti[..., None], perp, u)
    return np.asarray(u * ang)


def angle_between(R: ArrayLike, R_d: ArrayLike) -> NDArray[np.float64] | float:
    """Rotation angle (rad) between two orientations, batched."""
    e = np.linalg.norm(rotation_error(R, R_d), axis=-1)
    return float(e) if np.ndim(e) == 0 else e
