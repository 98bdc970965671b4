"""Homogeneous transforms: building and checking 4x4 poses (pure numpy/scipy).

``rpy`` follows URDF: fixed axes, ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from reachwise.errors import InputError

Pose = NDArray[np.float64]


def pose_from_xyz_rpy(xyz: ArrayLike = (0, 0, 0), rpy: ArrayLike = (0, 0, 0)) -> Pose:
    """4x4 pose from a translation (m) and URDF roll-pitch-yaw angles (rad)."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", np.asarray(rpy, dtype=float)).as_matrix()
    T[:3, 3] = np.asarray(xyz, dtype=float)
    return T


def xyz_rpy_from_pose(T: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Translation and URDF roll-pitch-yaw of a 4x4 pose (pitch in [-π/2, π/2])."""
    M = np.asarray(T, dtype=float)
    rpy = Rotation.from_matrix(M[:3, :3]).as_euler("xyz")
    return M[:3, 3].copy(), np.asarray(rpy, dtype=float)


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
