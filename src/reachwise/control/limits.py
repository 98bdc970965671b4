"""Joint position and velocity limits as bounds on the commanded joint velocity.

The controller never exceeds an actuator's limits, and it never clips one joint: it
scales the whole joint-velocity vector, so the motion keeps its direction (thesis
Eq. 3.12–3.13 do the same for the task velocity).

For a joint inside its range ``[q_lo, q_hi]`` the allowed velocity is

    max(−v_max, k (q_lo − q)) ≤ q̇ ≤ min(v_max, k (q_hi − q)),

a position "velocity damper": the joint may approach a limit only at a speed that
falls to zero at the limit, so with a kinematic plant and ``k ≤ 1/Δt`` it never
crosses it; with a first-order hydraulic lag of time constant ``τ`` choose
``k ≤ 1/(4τ)`` (critically damped approach, no overshoot). A joint found outside its
range (started there, or pushed by an external force) may only move back inward.

The interval is written once, in the compiled :func:`joint_velocity_interval` that the
controller's tick calls; :func:`velocity_bounds` applies it to arrays.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

__all__ = ["joint_velocity_interval", "limit_scale", "velocity_bounds"]


@njit(cache=True)
def joint_velocity_interval(q, lower, upper, vmax, k):  # type: ignore[no-untyped-def]
    """Allowed velocity interval ``(lo, hi)`` of one joint at position ``q``: inside
    ``[lower, upper]`` ``max(−v_max, k (q_lo − q)) ≤ q̇ ≤ min(v_max, k (q_hi − q))``
    (the position velocity damper, gain ``k`` in 1/s); below ``lower`` ``[0, v_max]``,
    above ``upper`` ``[−v_max, 0]`` (only back inward)."""
    if q < lower:
        return 0.0, vmax
    if q > upper:
        return -vmax, 0.0
    return max(-vmax, min(k * (lower - q), 0.0)), min(vmax, max(k * (upper - q), 0.0))


@njit(cache=True)
def _velocity_bounds(q, lower, upper, vmax, k, lo, hi):  # type: ignore[no-untyped-def]
    for i in range(q.shape[0]):
        lo[i], hi[i] = joint_velocity_interval(q[i], lower[i], upper[i], vmax[i], k)


def velocity_bounds(
    q: ArrayLike, lower: ArrayLike, upper: ArrayLike, vmax: ArrayLike, k: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Allowed joint-velocity interval ``(lo, hi)`` at ``q`` (see the module docstring).

    A joint below ``lower`` gets ``[0, v_max]``, above ``upper`` ``[−v_max, 0]``.
    """
    arrays = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (q, lower, upper, vmax)))
    qq, lo_q, hi_q, v = (np.ascontiguousarray(a).ravel() for a in arrays)
    lo = np.empty(arrays[0].shape)
    hi = np.empty(arrays[0].shape)
    _velocity_bounds(qq, lo_q, hi_q, v, float(k), lo.reshape(-1), hi.reshape(-1))
    return lo, hi


def limit_scale(qdot: ArrayLike, lo: ArrayLike, hi: ArrayLike) -> float:
    """Largest ``α ∈ [0, 1]`` with ``lo ≤ α q̇ ≤ hi`` for every joint (``lo ≤ 0 ≤ hi``)."""
    v = np.asarray(qdot, dtype=float)
    lo_a = np.asarray(lo, dtype=float)
    hi_a = np.asarray(hi, dtype=float)
    alpha = 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        up = np.where(v > hi_a, hi_a / v, 1.0)
        dn = np.where(v < lo_a, lo_a / v, 1.0)
    if v.size:
        alpha = float(min(alpha, np.min(up), np.min(dn)))
    return max(alpha, 0.0)
