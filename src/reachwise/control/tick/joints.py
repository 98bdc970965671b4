"""Joint limits in a tick: which joints take part, which recover into their range
(P-II Eq. 25–28), and the one factor that scales the whole command within every
joint's bounds (see ``reachwise.control.limits`` for the same rules in numpy)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from reachwise.control.limits import joint_velocity_interval, scale_into


class JointMotion(NamedTuple):
    """The joints of a tick: positions ``q`` (n,, rad or m), weights ``w`` (n,, 1 for a
    usable joint inside its range, lowered near a limit), the recovery velocities
    ``rec`` (n,) of joints outside their range, and the task velocity they cause,
    ``xrec`` (r,)."""

    q: np.ndarray
    w: np.ndarray
    rec: np.ndarray
    xrec: np.ndarray


@njit(cache=True)
def joint_weights(q, limits, k_limit):  # type: ignore[no-untyped-def]
    """Weights ``w`` (1 for a usable joint inside its range, else 0) and the recovery
    velocities ``rec`` of usable joints outside their range (inward, at most ``vmax``)."""
    n = q.shape[0]
    lower = limits.lower
    upper = limits.upper
    vmax = limits.vmax
    usable = limits.usable
    rec = np.zeros(n)
    w = np.zeros(n)
    for k in range(n):
        if not usable[k]:
            continue
        if q[k] < lower[k]:
            rec[k] = min(k_limit * (lower[k] - q[k]), vmax[k])
        elif q[k] > upper[k]:
            rec[k] = -min(k_limit * (q[k] - upper[k]), vmax[k])
        else:
            w[k] = 1.0
    return w, rec


@njit(cache=True)
def limit_scale(qd, guard, q, limits, k_limit):  # type: ignore[no-untyped-def]
    """The factor ``α ≤ guard`` that brings ``guard · qd`` within every joint's speed
    bound and position-limit damper
    (:func:`~reachwise.control.limits.joint_velocity_interval`; a joint outside its
    range may only move inward)."""
    lower = limits.lower
    upper = limits.upper
    vmax = limits.vmax
    alpha = guard
    for k in range(qd.shape[0]):
        v = qd[k] * guard
        lo, hi = joint_velocity_interval(q[k], lower[k], upper[k], vmax[k], k_limit)
        alpha = min(alpha, scale_into(v, lo, hi, guard))
    return max(alpha, 0.0)
