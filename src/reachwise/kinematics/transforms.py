"""Homogeneous transforms: building and checking 4x4 poses (pure numpy/scipy).

``rpy`` follows URDF: fixed axes, ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from reachwise.errors import InputError

Pose = NDArray[np.float64]


def rot_x(a: float) -> Pose:
    """4x4 rotation about x by ``a`` (rad)."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1]])


def rot_y(a: float) -> Pose:
    """4x4 rotation about y by ``a`` (rad)."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s, 0], [0, 1.0, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1]])


def rot_z(a: float) -> Pose:
    """4x4 rotation about z by ``a`` (rad)."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1.0, 0], [0, 0, 0, 1]])


def translation(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> Pose:
    """4x4 translation by (x, y, z) m."""
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def rpy_from_matrix(R: ArrayLike) -> tuple[float, float, float]:
    """URDF roll, pitch, yaw (``R = Rz(yaw) Ry(pitch) Rx(roll)``) of a rotation matrix.

    Accurate to rounding also at and near gimbal lock (pitch = ±π/2): pitch from
    ``atan2``, yaw from the first column, then roll from the remaining pure x-rotation
    ``Ry(pitch)ᵀ Rz(yaw)ᵀ R``, so an inaccurate yaw near the lock is compensated by roll.
    """
    M = np.asarray(R, dtype=float)[:3, :3]
    pitch = math.atan2(-M[2, 0], math.hypot(M[0, 0], M[1, 0]))
    yaw = math.atan2(M[1, 0], M[0, 0])
    X = rot_y(pitch)[:3, :3].T @ rot_z(yaw)[:3, :3].T @ M
    roll = math.atan2(X[2, 1], X[1, 1])
    return roll, pitch, yaw


def matrix_from_rpy(rpy: Sequence[float]) -> Pose:
    """4x4 rotation ``Rz(yaw) Ry(pitch) Rx(roll)`` (URDF fixed-axis convention)."""
    r, p, y = (float(v) for v in rpy)
    return rot_z(y) @ rot_y(p) @ rot_x(r)


def pose_from_xyz_rpy(xyz: ArrayLike = (0, 0, 0), rpy: ArrayLike = (0, 0, 0)) -> Pose:
    """4x4 pose from a translation (m) and URDF roll-pitch-yaw angles (rad)."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", np.asarray(rpy, dtype=float)).as_matrix()
    T[:3, 3] = np.asarray(xyz, dtype=float)
    return T


def xyz_rpy_from_pose(T: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Translation and URDF roll-pitch-yaw of a 4x4 pose (pitch in [-π/2, π/2]),
    exact also at gimbal lock (see ``rpy_from_matrix``)."""
    M = np.asarray(T, dtype=float)
    return M[:3, 3].copy(), np.array(rpy_from_matrix(M), dtype=float)


def check_pose(T: ArrayLike, source: str = "pose", tol: float = 1e-6) -> Pose:
    """Validate a 4x4 rigid transform; return it as float64 or raise naming ``source``."""
    try:
        M = np.asarray(T, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(source, "", f"not numeric: {exc}") from None
    if M.shape != (4, 4):
        raise InputError(source, "", f"expected a 4x4 matrix, got shape {M.shape}")
    if not np.isfinite(M).all():
        raise InputError(source, "", "contains NaN or inf")
    R = M[:3, :3]
    if np.abs(R.T @ R - np.eye(3)).max() > tol or np.linalg.det(R) < 0:
        raise InputError(source, "", "rotation part is not a proper orthonormal matrix")
    if np.abs(M[3] - (0, 0, 0, 1)).max() > tol:
        raise InputError(source, "", "last row must be [0, 0, 0, 1]")
    return M


def check_poses(T: ArrayLike, source: str = "pose", tol: float = 1e-6) -> Pose:
    """Validate one (4, 4) pose or a batch (m, 4, 4); return float64."""
    M = np.asarray(T, dtype=np.float64)
    if M.ndim == 2:
        return check_pose(M, source, tol)
    if M.ndim != 3 or M.shape[1:] != (4, 4):
        raise InputError(source, "", f"expected (4, 4) or (m, 4, 4), got shape {M.shape}")
    for i in range(M.shape[0]):
        check_pose(M[i], f"{source}[{i}]", tol)
    return M
