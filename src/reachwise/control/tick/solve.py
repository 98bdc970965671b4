"""The joint velocity of a tick: the damped pseudo-inverse of the weighted Jacobian
(thesis Eq. 3.5–3.6 with the damping of P-I Eq. 14, ``reachwise.kinematics.dls``), the
avoidance points' motions projected into its null space (Eq. 3.18), and the dynamic
weighting of joints moving toward a near limit (P-II Eq. 25–28)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from reachwise.control.tick.task import task_velocity
from reachwise.kinematics.dls import damped_pinv


class JointSolution(NamedTuple):
    """``M`` (n, r): the damped pseudo-inverse of the final weighted Jacobian;
    ``unull`` (n,): the avoidance motion in its null space; ``qd`` (n,): the joint
    velocity for the full task (task scale 1); ``sigma_min`` and ``damping`` λ."""

    M: np.ndarray
    unull: np.ndarray
    qd: np.ndarray
    sigma_min: float
    damping: float


@njit(cache=True)
def _null_space_motion(P, w, rows, pts, recalled, gains, unull):  # type: ignore[no-untyped-def]
    """``unull = (I − P) Σ_i J̃_Oi⁺ ẋ_Oi`` (the sum of Eq. 3.18) with the projector
    ``P = J⁺J`` of the weighted Jacobian: every body point that acts (not a tool
    part, not recalled) moves at its repulsive speed along its collision line, plus a
    moving obstacle's feed-forward, through the damped pseudo-inverse of its weighted
    point Jacobian."""
    n = w.shape[0]
    normal = rows.normal
    task_space = rows.task_space
    active = pts.active
    JO = pts.JO
    vrep = pts.vrep
    ff = pts.ff
    zsum = np.zeros(n)
    for i in range(rows.distance.shape[0]):
        if not active[i] or task_space[i] or recalled[i]:
            continue
        PhiO = np.empty((3, n))
        for j in range(3):
            for k in range(n):
                PhiO[j, k] = JO[i, j, k] * w[k]
        MO = damped_pinv(PhiO, gains.epsilon, gains.lambda_max, False).inverse
        for k in range(n):
            acc = 0.0
            for j in range(3):
                acc += MO[k, j] * (vrep[i] * normal[i, j] + ff[i, j])
            zsum[k] += acc
    for k in range(n):
        acc = 0.0
        for j in range(n):
            acc += P[k, j] * zsum[j]
        unull[k] = zsum[k] - acc


@njit(cache=True)
def solve_joints(J, joints, task, limits, rows, pts, recalled, gains, avoid):  # type: ignore[no-untyped-def]
    """``q̇ = W (J̃⁺ (ẋ − ẋ_rec) + Σ_i (I − J⁺J) J̃_Oi⁺ ẋ_Oi) + q̇_rec`` (Eq. 3.18) for
    the weighted Jacobian ``J W``, solved once more if a joint moving toward a limit
    within its ``zone`` gets a weight below 1 (P-II Eq. 25–28; ``joints.w`` is
    updated). Every body point that acts (not a tool part, not recalled) pushes through
    the null space. ``joints``: a :class:`~reachwise.control.tick.joints.JointMotion`,
    ``task``: a :class:`~reachwise.control.tick.task.TaskParts`.
    """
    q, w, rec, xrec = joints.q, joints.w, joints.rec, joints.xrec
    r, n = J.shape
    upper = limits.upper
    lower = limits.lower
    zone = limits.zone
    xd = np.empty(r)
    xs = np.empty(r)
    qd1 = np.empty(n)
    u = np.empty(n)
    unull = np.zeros(n)
    M = np.empty((n, r))
    smin = 0.0
    lam = 0.0
    for npass in range(2):
        Phi = np.empty((r, n))
        for j in range(r):
            for k in range(n):
                Phi[j, k] = J[j, k] * w[k]
        M, P, smin, lam = damped_pinv(Phi, gains.epsilon, gains.lambda_max, True)
        # ---- secondary goal: Eq. 3.18, every body point through the null space
        unull[:] = 0.0
        if avoid:
            _null_space_motion(P, w, rows, pts, recalled, gains, unull)
        task_velocity(1.0, task, gains, xd)
        for j in range(r):
            xs[j] = xd[j] - xrec[j]
        for k in range(n):
            acc = 0.0
            for j in range(r):
                acc += M[k, j] * xs[j]
            u[k] = acc + unull[k]
            qd1[k] = w[k] * u[k] + rec[k]
        if npass == 1:
            break
        # dynamic weighting (P-II Eq. 25–28): a joint moving toward a near limit gets
        # a weight that falls to 0 at the limit; solve once more with those weights
        changed = False
        for k in range(n):
            if w[k] == 0.0:
                continue
            if qd1[k] > 0.0:
                room = upper[k] - q[k]
            elif qd1[k] < 0.0:
                room = q[k] - lower[k]
            else:
                continue
            if room < zone[k]:
                w[k] = max(room / zone[k], 0.0)
                changed = True
        if not changed:
            break
    return JointSolution(M, unull, qd1, smin, lam)
