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

__all__ = ["joint_velocity_interval", "limit_scale", "scale_into", "velocity_bounds"]


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
def scale_into(v, lo, hi, top):  # type: ignore[no-untyped-def]
    """The factor ``α ≤ top`` (``top ≥ 0``) that brings one joint's velocity into
    ``[lo, hi]`` when ``v`` is its velocity already scaled by ``top``: ``top · hi / v``
    above the interval, ``top · lo / v`` below it (0 if the sign is wrong), ``top``
    inside."""
    if v > hi:
        return top * hi / v if v > 0.0 else 0.0
    if v < lo:
        return top * lo / v if v < 0.0 else 0.0
    return top


@njit(cache=True)
def _limit_scale(qdot, lo, hi):  # type: ignore[no-untyped-def]
    alpha = 1.0
    for k in range(qdot.shape[0]):
        alpha = min(alpha, scale_into(qdot[k], lo[k], hi[k], 1.0))
    return max(alpha, 0.0)


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
    """Largest ``α ∈ [0, 1]`` with ``lo ≤ α q̇ ≤ hi`` for every joint (``lo ≤ 0 ≤ hi``;
    :func:`scale_into` per joint, as the controller's tick)."""
    arrays = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (qdot, lo, hi)))
    v, lo_a, hi_a = (np.ascontiguousarray(a).ravel() for a in arrays)
    return float(_limit_scale(v, lo_a, hi_a))
