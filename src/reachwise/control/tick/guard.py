"""The approach guard of a tick (``controller``, items 5–6; our addition beyond the
thesis): every active pair's distance rate must stay above the velocity damper
``−ξ (ρ − ρ_s)/(ρ_O − ρ_s)`` (plus a moving obstacle's approach speed). Tool parts
deflect the goal velocity; then the goal part of the task is scaled by the largest
``s ∈ [0, 1]`` that keeps every pair within its bound, and if even ``s = 0`` does not,
the whole motion is slowed down; where that would stop it (a pair that may not close
at all, closed by the repulsion that pushes another pair out), the closing part is
projected out instead (:func:`push_out`), so pairs that start inside their margins
are pushed out rather than frozen. The bounds are
:func:`~reachwise.control.potential.damper_bound` and
:func:`~reachwise.control.potential.moving_damper_bound`."""

from __future__ import annotations

import numpy as np
from numba import njit

from reachwise.control.potential import damper_bound, moving_damper_bound
from reachwise.control.tick.joints import limit_scale
from reachwise.control.tick.task import task_velocity


@njit(cache=True)
def deflect_for_tool_parts(pG, pR, rows, pts, settings):  # type: ignore[no-untyped-def]
    """Remove from the goal velocity ``pG`` (in place) the part that would close a tool
    part's gap faster than the velocity damper allows, and keep the part along the
    obstacle: the tool slides around it instead of stopping."""
    rho_stop = settings.stop_distance
    xi = settings.approach_speed
    normal = rows.normal
    rho0 = rows.margin
    task_space = rows.task_space
    active = pts.active
    deff = pts.deff
    approach = pts.approach
    m = rows.distance.shape[0]
    for _ in range(3):
        for i in range(m):
            if not (active[i] and task_space[i]):
                continue
            rate = 0.0
            for j in range(3):
                rate += normal[i, j] * (pG[j] + pR[j])
            lo = damper_bound(deff[i], rho0[i], rho_stop, xi)
            if approach[i] > 0.0:
                lo = moving_damper_bound(deff[i], rho0[i], rho_stop, xi, approach[i])
            if rate < lo:
                for j in range(3):
                    pG[j] += (lo - rate) * normal[i, j]


@njit(cache=True)
def _pair_rates(rows, pts, settings, n):  # type: ignore[no-untyped-def]
    """Per active row: ``g`` (m, n) with ``g_i q̇ = n_iᵀ J_Oi q̇`` the rate of its
    distance, and its lowest allowed rates: ``lo_rate`` (the moving damper against an
    approaching obstacle, else the static one) and ``lo_static`` (the static damper)."""
    rho_stop = settings.stop_distance
    xi = settings.approach_speed
    normal = rows.normal
    rho0 = rows.margin
    active = pts.active
    approach = pts.approach
    deff = pts.deff
    JO = pts.JO
    m = rows.distance.shape[0]
    g = np.zeros((m, n))
    lo_rate = np.zeros(m)
    lo_static = np.zeros(m)
    for i in range(m):
        if not active[i]:
            continue
        for k in range(n):
            acc = 0.0
            for j in range(3):
                acc += normal[i, j] * JO[i, j, k]
            g[i, k] = acc
        lo_static[i] = damper_bound(deff[i], rho0[i], rho_stop, xi)
        lo_rate[i] = lo_static[i]
        if approach[i] > 0.0:
            lo_rate[i] = moving_damper_bound(deff[i], rho0[i], rho_stop, xi, approach[i])
    return g, lo_rate, lo_static


@njit(cache=True)
def _scaled_joint_velocity(s, sol, joints, task, gains, xd, qd):  # type: ignore[no-untyped-def]
    """``q̇(s) = W (J̃⁺ (ẋ(s) − ẋ_rec) + u_null) + q̇_rec`` into ``qd``: the joint
    velocity of ``sol`` for the task scaled by ``s`` (``xd`` is scratch)."""
    M = sol.M
    unull = sol.unull
    w, rec, xrec = joints.w, joints.rec, joints.xrec
    n, r = M.shape
    task_velocity(s, task, gains, xd)
    for k in range(n):
        acc = 0.0
        for j in range(r):
            acc += M[k, j] * (xd[j] - xrec[j])
        qd[k] = w[k] * (acc + unull[k]) + rec[k]


@njit(cache=True)
def _feasible(qs, g, lo_rate, pts, q, limits, gains, moving):  # type: ignore[no-untyped-def]
    """Whether the joint velocity ``qs`` keeps every active row's distance rate above
    its bound; a moving obstacle's row is checked on the command actually sent, after
    the joint-speed scaling (scaling slows a retreat down as well)."""
    active = pts.active
    approach = pts.approach
    a_s = limit_scale(qs, 1.0, q, limits, gains.k_limit) if moving else 1.0
    for i in range(g.shape[0]):
        if not active[i]:
            continue
        rate = 0.0
        for k in range(g.shape[1]):
            rate += g[i, k] * qs[k]
        if rate < lo_rate[i] - 1e-12:
            return False
        if approach[i] > 0.0 and a_s * rate < lo_rate[i] - 1e-12:
            return False
    return True


@njit(cache=True)
def guard_scales(sol, joints, task, limits, rows, pts, gains, settings):  # type: ignore[no-untyped-def]
    """The task scale ``s`` (bisection on feasibility), the guard scale (≤ 1: the whole
    motion slowed down when even ``s = 0`` closes a pair in too fast) and the joint
    velocity for ``s``, from the joint solution ``sol``, the
    :class:`~reachwise.control.tick.joints.JointMotion` ``joints`` and the
    :class:`~reachwise.control.tick.task.TaskParts` ``task``. Returns
    ``(s, guard, q̇)``."""
    n, r = sol.M.shape
    active = pts.active
    g, lo_rate, lo_static = _pair_rates(rows, pts, settings, n)
    moving = False
    for i in range(active.shape[0]):
        if active[i] and pts.approach[i] > 0.0:
            moving = True
    xd = np.empty(r)
    qs = np.empty(n)
    # feasibility of a task scale: every active pair's rate above its bound
    s = 1.0
    lo_s = 0.0
    hi_s = 1.0
    for it in range(16):
        trial = 1.0 if it == 0 else (0.0 if it == 1 else 0.5 * (lo_s + hi_s))
        _scaled_joint_velocity(trial, sol, joints, task, gains, xd, qs)
        ok = _feasible(qs, g, lo_rate, pts, joints.q, limits, gains, moving)
        if it == 0:
            if ok:
                s = 1.0
                break
        elif it == 1:
            if not ok:
                s = 0.0
                break
            lo_s = 0.0
        else:
            if ok:
                lo_s = trial
            else:
                hi_s = trial
        s = lo_s
    qd1 = np.empty(n)
    _scaled_joint_velocity(s, sol, joints, task, gains, xd, qd1)
    # still closing in too fast with no task left: slow the whole motion down. Only
    # the robot's own approach can be slowed (the static damper); a robot too slow
    # to outrun an approaching obstacle keeps retreating as fast as it can
    guard = 1.0
    for i in range(active.shape[0]):
        if not active[i]:
            continue
        rate = 0.0
        for k in range(n):
            rate += g[i, k] * qd1[k]
        if rate < lo_static[i]:
            f = lo_static[i] / rate if rate < 0.0 else 0.0
            guard = min(guard, max(f, 0.0))
    if guard == 0.0 and push_out(qd1, g, lo_static, active):
        guard = 1.0
    return s, guard, qd1


@njit(cache=True)
def push_out(qd, g, lo, active):  # type: ignore[no-untyped-def]
    """Instead of freezing, remove from the joint velocity ``qd`` (in place) what closes
    a pair that may not close at all: a pair inside its margin and the stop distance
    (static damper bound 0) whose rate ``g_i q̇`` is below its bound ``lo_i``, while
    the repulsion of another pair inside its margin (Eq. 3.17) pushes that one out.
    Cyclic projections onto the half-spaces ``g_i q̇ ≥ lo_i`` of the active rows
    (each adds motion along ``g_iᵀ``: it only opens the pair it corrects); returns
    True when ``qd`` then keeps every bound, else restores ``qd`` and returns False
    (the guard then stops the motion)."""
    n = qd.shape[0]
    keep = qd.copy()
    for _ in range(50):
        worst = 0.0
        for i in range(g.shape[0]):
            if not active[i]:
                continue
            rate = 0.0
            gg = 0.0
            for k in range(n):
                rate += g[i, k] * qd[k]
                gg += g[i, k] * g[i, k]
            if rate < lo[i] and gg > 1e-24:
                worst = max(worst, lo[i] - rate)
                step = (lo[i] - rate) / gg
                for k in range(n):
                    qd[k] += step * g[i, k]
        if worst <= 1e-12:
            return True
    for k in range(n):
        qd[k] = keep[k]
    return False
