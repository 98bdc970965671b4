"""Kinematic performance indices (P-I Eq. 34–37, P-II Eq. 38–39).

Condition number ``κ = σ_max / σ_min`` of the Jacobian (P-I Eq. 34); the local
conditioning index ``LCI = 1/κ`` (Eq. 35). Because position rows (m) and orientation
rows (rad) differ in units, the Jacobian is scaled with the nominal length ``L`` of
Lee et al. (2001): the distance from the base frame origin to the tool centre point at
that configuration (P-I Eq. 36–37, ``J̃ = S J`` with ``S = diag(I, L·I)``: the three
angular rows are multiplied by ``L``). Multiplying the angular rows by ``L`` or dividing
the linear rows by ``L`` gives the same κ, since κ is invariant to a common scale.

Over a task (``m`` postures): ``GCI = mean LCI`` (P-II Eq. 38) and
``KCI = min LCI = 1 / max κ`` (P-II Eq. 39). The thesis writes ``KCI = 1/κ_min`` but
describes it as "the worst performance of the manipulator in the task space", 0 when
any posture is singular: that is the *largest* condition number, so reachwise uses
``1 / max κ``, which also guarantees ``KCI ≤ GCI ≤ 1``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.errors import InputError

if TYPE_CHECKING:
    from reachwise.kinematics.robot import Robot


def scaled_jacobian(J: ArrayLike, length: ArrayLike) -> NDArray[np.float64]:
    """``S J`` with ``S = diag(I₃, L I₃)`` (P-I Eq. 36–37); ``J`` (6, n) or (m, 6, n)."""
    Jm = np.array(J, dtype=np.float64)
    L = np.asarray(length, dtype=np.float64)
    Jm[..., 3:, :] *= L[..., None, None] if L.ndim else L
    return Jm


def inverse_condition(J: ArrayLike) -> NDArray[np.float64] | float:
    """``1/κ = σ_min / σ_max`` of each matrix (0 for a singular or zero matrix)."""
    s = np.linalg.svd(np.asarray(J, dtype=np.float64), compute_uv=False)
    smax = s[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(smax > 0, s[..., -1] / np.where(smax > 0, smax, 1.0), 0.0)
    return float(r) if r.ndim == 0 else r


def condition_number(J: ArrayLike) -> NDArray[np.float64] | float:
    """``κ = σ_max / σ_min`` (P-I Eq. 34); ``inf`` at a singularity."""
    inv = np.asarray(inverse_condition(J))
    with np.errstate(divide="ignore"):
        k = np.where(inv > 0, 1.0 / np.where(inv > 0, inv, 1.0), np.inf)
    return float(k) if k.ndim == 0 else k


def nominal_length(robot: Robot, T: ArrayLike) -> NDArray[np.float64]:
    """Distance from the base frame origin to the tool centre point (Lee et al. 2001)."""
    p = np.asarray(T, dtype=np.float64)[..., :3, 3]
    return np.asarray(np.linalg.norm(p - robot.base[:3, 3], axis=-1))


def lci(
    robot: Robot, q: ArrayLike, rows: ArrayLike | None = None, scale: bool = True
) -> NDArray[np.float64] | float:
    """Local conditioning index ``1/κ(S J)`` at ``q`` (``(n,)`` → float, ``(m, n)`` → (m,)).

    ``rows`` selects task rows of ``J`` (e.g. ``[0, 1, 2]`` for a 3-D task); with
    ``scale`` the angular rows are multiplied by the nominal length (Eq. 36–37).
    """
    from reachwise.kinematics.jacobian import jacobians

    Q = np.asarray(q, dtype=np.float64)
    single = Q.ndim == 1
    T, J, _ = jacobians(robot, Q, params=False)
    if scale:
        J = scaled_jacobian(J, nominal_length(robot, T))
    if rows is not None:
        idx = np.asarray(rows)
        if idx.dtype == np.bool_:
            idx = np.flatnonzero(idx)
        if idx.size == 0 or idx.min() < 0 or idx.max() > 5:
            raise InputError("lci", "rows", "row indices must lie in 0..5")
        J = J[:, idx, :]
    out = np.asarray(inverse_condition(J))
    return float(out[0]) if single else out


def gci(lcis: ArrayLike) -> float:
    """Global conditioning index: mean LCI over the task points (P-II Eq. 38)."""
    v = _check_lcis(lcis)
    return float(v.mean())


def kci(lcis: ArrayLike) -> float:
    """Kinematic conditioning index: worst LCI over the task, ``1/max κ`` (P-II Eq. 39)."""
    v = _check_lcis(lcis)
    return float(v.min())


def manipulability(J: ArrayLike) -> NDArray[np.float64] | float:
    """Yoshikawa's measure ``sqrt(det(J Jᵀ))`` = product of singular values."""
    s = np.linalg.svd(np.asarray(J, dtype=np.float64), compute_uv=False)
    w = np.prod(s, axis=-1)
    return float(w) if np.ndim(w) == 0 else np.asarray(w)


def _check_lcis(lcis: ArrayLike) -> NDArray[np.float64]:
    v = np.asarray(lcis, dtype=np.float64).ravel()
    if v.size == 0:
        raise InputError("indices", "lci", "no task postures given")
    if not np.isfinite(v).all() or (v < 0).any() or (v > 1 + 1e-12).any():
        raise InputError("indices", "lci", "LCI values must be finite and in [0, 1]")
    return v
