"""The primary task of a tick: bounded proportional control of the tool (thesis
Eq. 3.8–3.13) with the tool parts' repulsion added in task space (P-V Eq. 6–7)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from reachwise.kinematics.orientation import quaternion_error_into


class TaskParts(NamedTuple):
    """The parts of a tick's task velocity: the goal's linear ``pG`` (3,, m/s) and
    angular ``wG`` (3,, rad/s) velocities, the tool parts' repulsion ``pR`` (3,, m/s,
    P-V Eq. 6) and ``six`` (a 6-D goal: the angular part is controlled)."""

    pG: np.ndarray
    pR: np.ndarray
    wG: np.ndarray
    six: bool


@njit(cache=True)
def primary_task(T, target, gains):  # type: ignore[no-untyped-def]
    """Goal velocities ``ṗ_G = k_v (p_d − p)`` (Eq. 3.8) and, for a 6-D goal,
    ``ω_G = k_w e_O`` with the quaternion error of Eq. 3.9 (Eq. 3.10), at the tool pose
    ``T``. Returns ``(ṗ_G, ω_G, position error, orientation angle)``."""
    Td = target.pose
    pG = np.empty(3)
    ep2 = 0.0
    for i in range(3):
        d = Td[i, 3] - T[i, 3]
        pG[i] = gains.kv * d
        ep2 += d * d
    wG = np.zeros(3)
    ang = 0.0
    if target.six:
        eo = np.empty(3)
        ang = quaternion_error_into(T[:3, :3], Td[:3, :3], eo)
        for i in range(3):
            wG[i] = gains.kw * eo[i]
    return pG, wG, math.sqrt(ep2), ang


@njit(cache=True)
def bounded(v, vmax):  # type: ignore[no-untyped-def]
    """Eq. 3.12/3.13: scale a 3-vector down to norm ``vmax`` if it is longer."""
    nrm = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    if nrm > vmax:
        f = vmax / nrm
        v[0] *= f
        v[1] *= f
        v[2] *= f


@njit(cache=True)
def task_velocity(s, task, gains, xd):  # type: ignore[no-untyped-def]
    """``ẋ(s) = [bound(s ṗ_G + Σ ṗ_O); bound(s ω_G)]`` into ``xd`` (Eq. 3.11–3.13,
    P-V Eq. 6–7) from the :class:`TaskParts` ``task``: the goal part scaled by the
    guard's task scale ``s``, the tool parts' repulsion ``pR`` not."""
    v = np.empty(3)
    for i in range(3):
        v[i] = s * task.pG[i] + task.pR[i]
    bounded(v, gains.v_max)
    for i in range(3):
        xd[i] = v[i]
    if task.six:
        w = np.empty(3)
        for i in range(3):
            w[i] = s * task.wG[i]
        bounded(w, gains.w_max)
        for i in range(3):
            xd[3 + i] = w[i]
