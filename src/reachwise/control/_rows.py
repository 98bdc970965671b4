"""Compiled conversion of a scene answer's rows into one robot's avoidance points.

:class:`~reachwise.control.avoidance.SceneConverter` reads the (P, 13) answer rows of
:mod:`reachwise.distance.answers` directly when it can: one call selects the pairs
within their margins that involve the robot and lays their points out as
:class:`~reachwise.control.avoidance.AvoidancePoints` wants them — the same rules, row
by row, as the converter's loop over :class:`~reachwise.distance.scene.PairResult`
values (see that module's docstring), with no Python object per pair.
"""

from __future__ import annotations

import numpy as np
from numba import njit, types

__all__ = ["select_rows"]

_F2 = types.float64[:, ::1]
_F1 = types.float64[::1]
_I1 = types.int64[::1]
_B1 = types.boolean[::1]
_OUT = types.Tuple((_I1, _F2, _I1, _F2, _F2, _F2, _F1, _F1, _B1, _I1))


@njit(_OUT(types.Array(types.float64, 2, "C", readonly=True), _I1, _I1, _F1, _B1, _B1), cache=True)
def select_rows(rows, link_a, link_b, rho0, tool_a, tool_b):  # type: ignore[no-untyped-def]
    """Avoidance points of the rows within their margin ``rho0`` that touch the robot.

    Per row ``k``: ``link_a[k]``/``link_b[k]`` the robot frame its objects are fixed to
    (-1: not on this robot), ``tool_a``/``tool_b`` whether that frame is a tool part.
    Returns ``(a_link, a_point, b_link, b_point, normal, obstacle_velocity (zeros: the
    objects are taken as still), distance, margin, task_space, row)`` for the kept rows
    in order (``row`` their indices). A "no risk" row, a row
    with neither object on the robot and a row farther than ``rho0`` are dropped; a
    row whose numbers are NaN while it claims to be within its margin is kept (the
    controller's check then stops on it)."""
    n = rows.shape[0]
    keep = np.empty(n, np.int64)
    m = 0
    for k in range(n):
        if rows[k, 12] != 0.0 or (link_a[k] < 0 and link_b[k] < 0) or rows[k, 0] > rho0[k]:
            continue
        keep[m] = k
        m += 1
    a_link = np.empty(m, np.int64)
    a_point = np.empty((m, 3))
    b_link = np.empty(m, np.int64)
    b_point = np.empty((m, 3))
    normal = np.empty((m, 3))
    distance = np.empty(m)
    margin = np.empty(m)
    task = np.empty(m, np.bool_)
    velocity = np.zeros((m, 3))
    for i in range(m):
        k = keep[i]
        la = link_a[k]
        lb = link_b[k]
        distance[i] = rows[k, 0]
        margin[i] = rho0[k]
        if la >= 0:
            a_link[i] = la
            b_link[i] = lb  # a self-collision pair: both on the robot
            for c in range(3):
                a_point[i, c] = rows[k, 1 + c]
                b_point[i, c] = rows[k, 4 + c] if lb >= 0 else np.nan
                normal[i, c] = rows[k, 7 + c]
            task[i] = tool_a[k] and lb < 0
        else:
            a_link[i] = lb
            b_link[i] = -1
            for c in range(3):
                a_point[i, c] = rows[k, 4 + c]
                b_point[i, c] = np.nan
                normal[i, c] = -rows[k, 7 + c]
            task[i] = tool_b[k]
    return (
        a_link, a_point, b_link, b_point, normal, velocity, distance, margin, task,
        keep[:m].copy(),
    )  # fmt: skip
