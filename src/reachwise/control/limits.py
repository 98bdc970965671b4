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
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["limit_scale", "velocity_bounds"]


def velocity_bounds(
    q: ArrayLike, lower: ArrayLike, upper: ArrayLike, vmax: ArrayLike, k: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Allowed joint-velocity interval ``(lo, hi)`` at ``q`` (see the module docstring).

    A joint below ``lower`` gets ``[0, v_max]``, above ``upper`` ``[−v_max, 0]``.
    """
    qq = np.asarray(q, dtype=float)
    lo_q = np.asarray(lower, dtype=float)
    hi_q = np.asarray(upper, dtype=float)
    v = np.asarray(vmax, dtype=float)
    with np.errstate(invalid="ignore"):
        hi = np.minimum(v, np.maximum(k * (hi_q - qq), 0.0))
        lo = np.maximum(-v, np.minimum(k * (lo_q - qq), 0.0))
    below = qq < lo_q
    above = qq > hi_q
    lo = np.where(below, 0.0, np.where(above, -v, lo))
    hi = np.where(below, v, np.where(above, 0.0, hi))
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
