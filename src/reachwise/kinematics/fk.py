"""Forward kinematics (P-I Eq. 2–6): tool pose and every frame, batched without Python loops."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

import reachwise.kinematics._kernels as K
from reachwise.errors import InputError
from reachwise.kinematics.model import KinematicModel


def as_q(robot: KinematicModel, q: ArrayLike, name: str = "q") -> tuple[NDArray[np.float64], bool]:
    """Validate ``q`` as ``(n,)`` or ``(m, n)``; return a C-contiguous ``(m, n)`` and
    whether the input was a single configuration."""
    try:
        Q = np.asarray(q, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(robot.name, name, f"not numeric: {exc}") from None
    single = Q.ndim == 1
    if single:
        Q = Q[None, :]
    if Q.ndim != 2 or Q.shape[1] != robot.n:
        raise InputError(
            robot.name, name, f"expected shape ({robot.n},) or (m, {robot.n}), got {np.shape(q)}"
        )
    if not np.isfinite(Q).all():
        raise InputError(robot.name, name, "contains NaN or inf")
    return np.ascontiguousarray(Q), single


def fk(robot: KinematicModel, q: ArrayLike) -> NDArray[np.float64]:
    """Tool pose in world: ``(4, 4)`` for ``q`` of shape ``(n,)``, ``(m, 4, 4)`` for ``(m, n)``."""
    Q, single = as_q(robot, q)
    c = robot.arrays
    T = K.fk_batch(c.kind, c.qidx, c.dh, c.classic, c.base, c.tool, Q)
    return T[0] if single else T


def fk_all(robot: KinematicModel, q: ArrayLike) -> NDArray[np.float64]:
    """World pose of every frame in ``robot.link_names`` order: ``(N+2, 4, 4)`` or
    ``(m, N+2, 4, 4)`` — base, link 1 … N, tool."""
    Q, single = as_q(robot, q)
    c = robot.arrays
    F = K.fk_all_batch(c.kind, c.qidx, c.dh, c.classic, c.base, c.tool, Q)
    return F[0] if single else F


def fk_all_into(robot: KinematicModel, q: NDArray[np.float64], out: NDArray[np.float64]) -> None:
    """:func:`fk_all` of one configuration into ``out`` ``(N+2, 4, 4)``, allocating
    nothing: the per-tick path of a 1 kHz loop. ``q`` must be checked already (a
    C-ordered float64 ``(n,)`` of finite values)."""
    c = robot.arrays
    K.frames(c.kind, c.qidx, c.dh, c.classic, c.base, c.tool, q, out)
