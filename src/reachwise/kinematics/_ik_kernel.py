"""Compiled inner loop of the damped-least-squares inverse kinematics (see ``ik.py``),
on typed groups: the ``Chain``, an ``IKTarget``, ``IKBounds`` and ``IKSettings``."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit
from numpy.typing import NDArray

from reachwise.kinematics._jit import RO_F8_1D, Field, group_type
from reachwise.kinematics._kernels import frames, tool_jacobian
from reachwise.kinematics.chain import CHAIN, Chain
from reachwise.kinematics.dls import damped_solve
from reachwise.kinematics.orientation import axis_error_into, rotation_error_into


@njit(cache=True)
def axis_rows(zd, F, Jw, e, J5, r0):  # type: ignore[no-untyped-def]
    """5-D rows from ``r0`` on: the axis error (``orientation.axis_error_into``) and the
    angular Jacobian rows on the two directions normal to the current tool axis z, the
    tool's own x and y axes (rotation about z does not change the axis). Returns φ."""
    ev = np.empty(3)
    phi = axis_error_into(F, zd, ev)
    for b in range(2):
        ux = F[0, b]
        uy = F[1, b]
        uz = F[2, b]
        e[r0 + b] = ux * ev[0] + uy * ev[1] + uz * ev[2]
        for k in range(Jw.shape[1]):
            J5[r0 + b, k] = ux * Jw[3, k] + uy * Jw[4, k] + uz * Jw[5, k]
    return phi


@njit(cache=True)
def dls_step(J, e, w, epsilon, lambda_max, znull, dq):  # type: ignore[no-untyped-def]
    """Weighted damped least squares (P-II Eq. 25–28) with the σ_min damping of
    P-I Eq. 14 and a null-space term (thesis Eq. 3.7), see ``reachwise.kinematics.dls``:

        Φ = J W,   Δq = W Φ̃⁺ e + W (I − Φ⁺ Φ) W z.

    Returns σ_min of Φ.
    """
    r, n = J.shape
    Phi = np.empty((r, n))
    for i in range(r):
        for k in range(n):
            Phi[i, k] = J[i, k] * w[k]
    d = damped_solve(Phi, e, w * znull, epsilon, lambda_max)
    for k in range(n):
        dq[k] = w[k] * (d.step[k] + d.null_motion[k])
    return d.sigma_min


class IKTarget(NamedTuple):
    """What one solve aims at: the tool ``pose`` (4, 4), the task ``rows`` (6 bools:
    x y z rx ry rz, world frame) and ``axis_mode`` (the 5-D tool-axis error instead of
    the rotation-vector rows)."""

    pose: NDArray[np.float64]
    rows: NDArray[np.bool_]
    axis_mode: bool


class IKBounds(NamedTuple):
    """Per joint variable ``(n,)``: the limits ``lower``, ``upper`` (may be infinite)
    and the step cap ``max_step`` of one iteration."""

    lower: NDArray[np.float64]
    upper: NDArray[np.float64]
    max_step: NDArray[np.float64]


class IKSettings(NamedTuple):
    """Tolerances ``tol_position`` (m), ``tol_orientation`` (rad), ``max_iter``; the
    damping schedule ``lambda_max``, ``epsilon`` (``reachwise.kinematics.dls``), faded
    by ``min(1, error/err_ref)``; ``k_null`` the mid-range gain in the null space."""

    tol_position: float
    tol_orientation: float
    max_iter: int
    lambda_max: float
    epsilon: float
    k_null: float
    err_ref: float


class IKAttempt(NamedTuple):
    """Outcome of one attempt: final ``q``, ``iterations``, ``position_error`` (m) and
    ``orientation_error`` (rad) over the constrained rows."""

    q: NDArray[np.float64]
    iterations: int
    position_error: float
    orientation_error: float


TARGET_SPEC = {
    "pose": Field(np.float64, (4, 4)),
    "rows": Field(np.bool_, (6,)),
    "axis_mode": Field(bool),
}
BOUNDS_SPEC = {
    "lower": Field(np.float64, ("n",)),
    "upper": Field(np.float64, ("n",)),
    "max_step": Field(np.float64, ("n",)),
}
SETTINGS_SPEC = {
    "tol_position": Field(float),
    "tol_orientation": Field(float),
    "max_iter": Field(int),
    "lambda_max": Field(float),
    "epsilon": Field(float),
    "k_null": Field(float),
    "err_ref": Field(float),
}


@njit(cache=True)
def _iterate(chain, target, bounds, settings, q0):  # type: ignore[no-untyped-def]
    """The iteration of :func:`ik_loop` (below) on named groups. One compiled
    function on purpose: the iterate, the error, the damped step and its clamping to
    the joint bounds share their work arrays, allocated once per solve, and numba
    would pass them through memory at every helper call inside the loop."""
    kind = chain.kind
    qidx = chain.qidx
    classic = chain.classic
    Td = target.pose
    rows = target.rows
    axis_mode = target.axis_mode
    lo = bounds.lower
    hi = bounds.upper
    max_step = bounds.max_step
    tol_p = settings.tol_position
    tol_o = settings.tol_orientation
    lambda_max = settings.lambda_max
    epsilon = settings.epsilon
    k_null = settings.k_null
    N = kind.shape[0]
    n = q0.shape[0]
    F = np.empty((N + 2, 4, 4))
    Jg = np.empty((6, n))
    e6 = np.empty(6)
    q = q0.copy()
    mid = 0.5 * (lo + hi)
    span = hi - lo
    npos = 0
    for i in range(3):
        if rows[i]:
            npos += 1
    nori = 2 if axis_mode else int(rows[3]) + int(rows[4]) + int(rows[5])
    r = npos + nori
    J = np.empty((r, n))
    e = np.empty(r)
    w = np.ones(n)
    dq = np.empty(n)
    znull = np.zeros(n)
    ep = 0.0
    eo = 0.0
    it = 0
    zd = Td[:3, 2].copy()
    Rd = Td[:3, :3].copy()
    best = 1e300
    stall = 0
    while True:
        frames(kind, qidx, chain.dh, classic, chain.base, chain.tool, q, F)
        tool_jacobian(kind, qidx, classic, F, n, Jg)
        Tt = F[N + 1]
        row = 0
        ep2 = 0.0
        for i in range(3):
            d = Td[i, 3] - Tt[i, 3]
            if rows[i]:
                e[row] = d
                J[row, :] = Jg[i, :]
                ep2 += d * d
                row += 1
        ep = math.sqrt(ep2)
        if axis_mode:
            eo = axis_rows(zd, Tt, Jg, e, J, row)
        else:
            rotation_error_into(Tt, Rd, e6)
            eo2 = 0.0
            for i in range(3):
                if rows[3 + i]:
                    e[row] = e6[i]
                    J[row, :] = Jg[3 + i, :]
                    eo2 += e6[i] * e6[i]
                    row += 1
            eo = math.sqrt(eo2)
        if (ep <= tol_p and eo <= tol_o) or it >= settings.max_iter:
            break
        score = ep + eo
        if score < 0.999 * best:
            best = score
            stall = 0
        else:
            stall += 1
            if stall >= 12:
                break
        it += 1
        # Near the solution the damping fades with the error (Levenberg–Marquardt
        # style) so the last steps converge quadratically even inside the singular
        # region; far from it, λ_max applies as in P-I Eq. 14.
        lam = lambda_max * min(1.0, score / settings.err_ref)
        for k in range(n):
            if math.isfinite(span[k]) and span[k] > 0.0:
                znull[k] = -k_null * (q[k] - mid[k]) / (span[k] * span[k])
            else:
                znull[k] = 0.0
            w[k] = 1.0
        # Dynamic weighting (P-II Eq. 25–28): a joint at a bound that the step drives
        # further out gets weight 0, and the step is solved again without it.
        for _ in range(n + 1):
            dls_step(J, e, w, epsilon, lam, znull, dq)
            changed = False
            for k in range(n):
                if w[k] > 0.0 and (
                    (q[k] <= lo[k] and dq[k] < 0.0) or (q[k] >= hi[k] and dq[k] > 0.0)
                ):
                    w[k] = 0.0
                    changed = True
            if not changed:
                break
        scale = 1.0
        for k in range(n):
            a = abs(dq[k])
            if a * scale > max_step[k]:
                scale = max_step[k] / a
        for k in range(n):
            q[k] = min(max(q[k] + scale * dq[k], lo[k]), hi[k])
    return IKAttempt(q, it, ep, eo)


@njit(
    (
        CHAIN,
        group_type(IKTarget, TARGET_SPEC),
        group_type(IKBounds, BOUNDS_SPEC),
        group_type(IKSettings, SETTINGS_SPEC),
        RO_F8_1D,
    ),
    cache=True,
)
def ik_loop(chain, target, bounds, settings, q0):  # type: ignore[no-untyped-def]
    """Iterate DLS steps from ``q0`` (groups as plain tuples, see ``_jit``); returns an
    :class:`IKAttempt`."""
    return _iterate(Chain(*chain), IKTarget(*target), IKBounds(*bounds), IKSettings(*settings), q0)
