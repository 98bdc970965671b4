"""Avoidance points of a tick (thesis Eq. 3.14–3.17, P-V Eq. 6): which rows act, their
Khatib speeds, a moving obstacle's approach and feed-forward, and the Jacobian of each
robot part's point."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from reachwise.control.potential import khatib_speed
from reachwise.kinematics._kernels import point_jacobian_rows


class ActivePoints(NamedTuple):
    """Per row (``m``): ``active`` within the margin (after a moving obstacle's travel
    during the reaction time, ``deff``), the repulsive speed ``vrep`` (Eq. 3.17,
    :func:`~reachwise.control.potential.khatib_speed`; 0 for a recalled row), the
    obstacle's ``approach`` speed along the line, its feed-forward velocity ``ff``
    (m, 3) and the point Jacobian ``JO`` (m, 3, n) — relative for a
    self-collision pair. ``pR``: the tool parts' repulsion summed in task space
    (P-V Eq. 6). Counts: ``n_active`` rows that repel, ``n_guard`` rows the guard
    watches; ``dmin`` the smallest distance of this tick's own rows."""

    active: np.ndarray
    vrep: np.ndarray
    approach: np.ndarray
    ff: np.ndarray
    deff: np.ndarray
    JO: np.ndarray
    pR: np.ndarray
    n_active: int
    n_guard: int
    dmin: float


@njit(cache=True)
def obstacle_motion(rows, reaction_time):  # type: ignore[no-untyped-def]
    """Per row: a moving obstacle's ``approach`` speed along the collision line (0 if
    it recedes; m/s), the feed-forward velocity ``ff`` (m, 3) ``min(2u/|v_B|, 1) v_B``
    that carries the point along with it, and ``deff`` the distance left after the
    obstacle's travel during the robot's ``reaction_time`` (s)."""
    normal = rows.normal
    vobs = rows.obstacle_velocity
    dist = rows.distance
    m = dist.shape[0]
    approach = np.zeros(m)
    ff = np.zeros((m, 3))
    deff = np.empty(m)
    for i in range(m):
        u = 0.0
        sp = 0.0
        for j in range(3):
            u += normal[i, j] * vobs[i, j]
            sp += vobs[i, j] * vobs[i, j]
        approach[i] = max(u, 0.0)
        deff[i] = dist[i] - approach[i] * reaction_time
        if approach[i] > 0.0:
            sp = math.sqrt(sp)
            wgt = min(2.0 * approach[i] / sp, 1.0)
            for j in range(3):
                ff[i, j] = wgt * vobs[i, j]
    return approach, ff, deff


@njit(cache=True)
def row_jacobian(chain, passive, F, Jg, rows, i, Ja, Jb, JO):  # type: ignore[no-untyped-def]
    """The point Jacobian ``JO[i]`` (3, n) of row ``i`` at frames ``F``: a tool part
    moves with the tool — rigidly (its own point Jacobian), or, if it hangs on passive
    joints, with the tool point plus the tool's rotation about the vertical (the
    hanging part keeps only that rotation, tool Jacobian ``Jg``); a self-collision row
    is relative (a's point Jacobian minus b's). ``Ja``, ``Jb`` (6, n) are scratch."""
    kind = chain.kind
    qidx = chain.qidx
    classic = chain.classic
    a_link = rows.a_link
    a_pt = rows.a_point
    b_link = rows.b_link
    b_pt = rows.b_point
    N = kind.shape[0]
    n = Jg.shape[1]
    if rows.task_space[i]:
        hanging = False
        for jj in range(N):
            if qidx[jj] >= 0 and passive[qidx[jj]] and jj + 1 <= a_link[i]:
                hanging = True
        if hanging:
            T = F[N + 1]
            rx = a_pt[i, 0] - T[0, 3]
            ry = a_pt[i, 1] - T[1, 3]
            for k in range(n):
                wz = Jg[5, k]
                JO[i, 0, k] = Jg[0, k] - wz * ry
                JO[i, 1, k] = Jg[1, k] + wz * rx
                JO[i, 2, k] = Jg[2, k]
            return
    point_jacobian_rows(kind, qidx, classic, F, a_link[i], a_pt[i, 0], a_pt[i, 1], a_pt[i, 2], Ja)
    if not rows.task_space[i] and b_link[i] >= 0:
        point_jacobian_rows(
            kind, qidx, classic, F, b_link[i], b_pt[i, 0], b_pt[i, 1], b_pt[i, 2], Jb
        )
        for j in range(3):
            for k in range(n):
                JO[i, j, k] = Ja[j, k] - Jb[j, k]
        return
    for j in range(3):
        for k in range(n):
            JO[i, j, k] = Ja[j, k]


@njit(cache=True)
def active_points(chain, passive, F, Jg, rows, recalled, m_now, gains, settings):  # type: ignore[no-untyped-def]
    """The avoidance points of ``rows`` (this tick's ``m_now`` rows, then recalled ones)
    at frames ``F`` with tool Jacobian ``Jg``; see :class:`ActivePoints`."""
    normal = rows.normal
    dist = rows.distance
    rho0 = rows.margin
    n = Jg.shape[1]
    m = dist.shape[0]
    approach, ff, deff = obstacle_motion(rows, settings.reaction_time)
    active = np.zeros(m, dtype=np.bool_)
    vrep = np.zeros(m)
    JO = np.zeros((m, 3, n))
    Ja = np.empty((6, n))
    Jb = np.empty((6, n))
    pR = np.zeros(3)
    n_active = 0
    n_guard = 0
    dmin = math.inf
    for i in range(m):
        if i < m_now and dist[i] < dmin:
            dmin = dist[i]
        if not (deff[i] <= rho0[i]):
            continue
        active[i] = True
        n_guard += 1
        if not recalled[i]:
            n_active += 1
            vrep[i] = khatib_speed(deff[i], rho0[i], gains.mu, gains.v_rep_max)
        row_jacobian(chain, passive, F, Jg, rows, i, Ja, Jb, JO)
        if rows.task_space[i] and settings.avoidance and not recalled[i]:
            # a tool part's repulsion is summed in task space (P-V Eq. 6)
            for j in range(3):
                pR[j] += vrep[i] * normal[i, j] + ff[i, j]
    return ActivePoints(active, vrep, approach, ff, deff, JO, pR, n_active, n_guard, dmin)
