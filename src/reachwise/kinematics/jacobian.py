"""Jacobians: geometric tool and point Jacobians (thesis Eq. 3.1) and the Jacobian of
the tool pose with respect to the DH parameters and the base frame (P-I Eq. 15–19).

All are world-frame, linear rows first, exact (analytic) and batched.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

import reachwise.kinematics._kernels as K
from reachwise.errors import InputError
from reachwise.kinematics.fk import as_q
from reachwise.kinematics.model import KinematicModel


def jacobian(robot: KinematicModel, q: ArrayLike) -> NDArray[np.float64]:
    """Geometric tool Jacobian ``(6, n)`` (or ``(m, 6, n)``), world frame, linear rows first."""
    Q, single = as_q(robot, q)
    c = robot.arrays
    _, J, _ = K.jacobians_batch(c.kind, c.qidx, c.dh, c.classic, c.base, c.tool, Q, False)
    return J[0] if single else J


def jacobians(
    robot: KinematicModel, q: ArrayLike, params: bool = True
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Tool poses, tool Jacobians and DH/base parameter Jacobians in one pass.

    Returns ``T (m, 4, 4)``, ``J (m, 6, n)``, ``P (m, 6, 4N + 6)`` (``P`` empty when
    ``params`` is False). ``q`` is always treated as a batch.
    """
    Q, _ = as_q(robot, q)
    c = robot.arrays
    T, J, P = K.jacobians_batch(c.kind, c.qidx, c.dh, c.classic, c.base, c.tool, Q, params)
    return T, J, P


def param_jacobian(robot: KinematicModel, q: ArrayLike) -> NDArray[np.float64]:
    """``(6, 4N + 6)`` (or batched) Jacobian of the tool pose w.r.t. every DH parameter
    (columns ``a, alpha, d, theta`` per joint, fixed joints included) and the base
    ``x, y, z, roll, pitch, yaw`` (URDF rpy). Linear rows: tool-point velocity; angular
    rows: tool angular velocity, per unit parameter change."""
    Q, single = as_q(robot, q)
    c = robot.arrays
    _, _, P = K.jacobians_batch(c.kind, c.qidx, c.dh, c.classic, c.base, c.tool, Q, True)
    return P[0] if single else P


def point_jacobian(
    robot: KinematicModel, q: ArrayLike, link: int | str, point: ArrayLike, frame: str = "link"
) -> NDArray[np.float64]:
    """``(3, n)`` Jacobian of a point fixed to ``link``.

    ``point`` is in the link frame (``frame="link"``, default) or in world coordinates
    at configuration ``q`` (``frame="world"``), e.g. the closest point returned by a
    distance query. Only joints between the base and the link contribute.
    """
    Q, single = as_q(robot, q)
    if not single:
        raise InputError(robot.name, "q", "point_jacobian takes one configuration (n,)")
    if frame not in ("link", "world"):
        raise InputError(robot.name, "frame", f"'link' or 'world', got {frame!r}")
    p = np.asarray(point, dtype=np.float64)
    if p.shape != (3,) or not np.isfinite(p).all():
        raise InputError(robot.name, "point", f"expected 3 finite numbers, got {p!r}")
    k = robot.link_index(link)
    c = robot.arrays
    F = np.empty((len(robot.joints) + 2, 4, 4))
    K.frames(c.kind, c.qidx, c.dh, c.classic, c.base, c.tool, Q[0], F)
    pw = p if frame == "world" else F[k, :3, :3] @ p + F[k, :3, 3]
    J = np.empty((6, robot.n))
    K.point_jacobian_rows(c.kind, c.qidx, c.classic, F, k, pw[0], pw[1], pw[2], J)
    return J[:3]
