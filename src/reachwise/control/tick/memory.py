"""The guard's memory of past collision lines (``controller``, item 5): what is
remembered of a tick, and how the remembered lines are measured again and recalled.

A remembered line is a row of ``GuardMemory.lines`` (columns: see ``types.MEM_COLS``):
the robot part's point in its link frame and the other end — a point of a static
obstacle (world) or, for a self-collision pair, a point in the other link's frame.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from reachwise.control.tick.types import MEM_AGE, AvoidanceRows


@njit(cache=True)
def _into_frame(T, p, out):  # type: ignore[no-untyped-def]
    """``out = Rᵀ (p − t)``: the world point ``p`` in the coordinates of frame ``T``."""
    for j in range(3):
        acc = 0.0
        for c in range(3):
            acc += T[c, j] * (p[c] - T[c, 3])
        out[j] = acc


@njit(cache=True)
def _out_of_frame(T, x, out):  # type: ignore[no-untyped-def]
    """``out = R x + t``: the point ``x`` given in frame ``T``, in the world."""
    for j in range(3):
        out[j] = T[j, 0] * x[0] + T[j, 1] * x[1] + T[j, 2] * x[2] + T[j, 3]


@njit(cache=True)
def _same_line(x, y):  # type: ignore[no-untyped-def]
    """Whether two remembered lines (6 coordinates, see :func:`local_lines`) are the
    same point pair."""
    e = 0.0
    for j in range(6):
        e += abs(x[j] - y[j])
    return e < 1e-9


@njit(cache=True)
def local_lines(F, rows):  # type: ignore[no-untyped-def]
    """This tick's collision lines in the form they are remembered, ``(m, 6)``: the robot
    part's point in its link frame, then the other end — in its link frame for a
    self-collision pair, else the obstacle point ``p_a − ρ n`` in the world."""
    a_link = rows.a_link
    a_pt = rows.a_point
    b_link = rows.b_link
    b_pt = rows.b_point
    dist = rows.distance
    normal = rows.normal
    m = dist.shape[0]
    loc = np.empty((m, 6))
    for i in range(m):
        _into_frame(F[a_link[i]], a_pt[i], loc[i, 0:3])
        if b_link[i] >= 0:
            _into_frame(F[b_link[i]], b_pt[i], loc[i, 3:6])
        else:
            for j in range(3):
                loc[i, 3 + j] = a_pt[i, j] - dist[i] * normal[i, j]
    return loc


@njit(cache=True)
def static_rows(rows, loc):  # type: ignore[no-untyped-def]
    """Rows worth remembering: within their margin, finite, and against a still
    obstacle (a moving obstacle's point has moved on by the next tick)."""
    dist = rows.distance
    rho0 = rows.margin
    vobs = rows.obstacle_velocity
    m = dist.shape[0]
    out = np.zeros(m, dtype=np.bool_)
    for i in range(m):
        if not dist[i] <= rho0[i]:
            continue
        ok = True
        for j in range(3):
            if vobs[i, j] != 0.0:
                ok = False
        for j in range(6):
            if not math.isfinite(loc[i, j]):
                ok = False
        out[i] = ok
    return out


@njit(cache=True)
def _remeasure(F, rows, loc, memory):  # type: ignore[no-untyped-def]
    """The remembered lines measured again at frames ``F``: per line its end points
    ``pa``, ``pb`` (k, 3) and distance ``dd`` (k,), ``keep`` (k,) for those within
    their margin that repeat neither a row of this tick nor an earlier kept line, and
    how many are kept."""
    mem = memory.lines
    depth = memory.depth
    a_link = rows.a_link
    b_link = rows.b_link
    m = rows.distance.shape[0]
    k = mem.shape[0]
    keep = np.zeros(k, dtype=np.bool_)
    pa = np.empty((k, 3))
    pb = np.empty((k, 3))
    dd = np.empty(k)
    extra = 0
    for r in range(k):
        if not 1.0 <= mem[r, MEM_AGE] <= depth:
            continue
        al = int(mem[r, 0])
        bl = int(mem[r, 1])
        _out_of_frame(F[al], mem[r, 2:5], pa[r])
        if bl >= 0:
            _out_of_frame(F[bl], mem[r, 5:8], pb[r])
        else:
            for j in range(3):
                pb[r, j] = mem[r, 5 + j]
        d2 = 0.0
        for j in range(3):
            d2 += (pa[r, j] - pb[r, j]) ** 2
        dd[r] = math.sqrt(d2)
        if not (dd[r] > 1e-9 and dd[r] <= mem[r, 8]):
            continue
        # the same point pair as one of this tick's rows or an earlier recalled one
        line = mem[r, 2:8]
        same = False
        for i in range(m):
            if a_link[i] == al and b_link[i] == bl and _same_line(loc[i], line):
                same = True
                break
        for s in range(r):
            if same:
                break
            if keep[s] and mem[s, 0] == mem[r, 0] and mem[s, 1] == mem[r, 1]:
                same = _same_line(mem[s, 2:8], line)
        if not same:
            keep[r] = True
            extra += 1
    return keep, pa, pb, dd, extra


@njit(cache=True)
def recall(F, rows, velocity, loc, memory):  # type: ignore[no-untyped-def]
    """The avoidance rows of this tick (with ``velocity`` as their obstacle velocity)
    followed by the remembered collision lines, and which rows are recalled ones.

    A remembered line aged 1 … ``depth`` ticks is measured again at the current joint
    state (frames ``F``): both ends are points of the clouds, so the remembered pair is
    again an exact point pair: distance ``|p_a − p_b|`` and direction
    ``(p_a − p_b)/|p_a − p_b|``. Rows within their margin that do not repeat one of
    this tick's pairs (``loc``, see :func:`local_lines`) or an earlier recalled one are
    appended. Returns ``(AvoidanceRows, recalled)``.
    """
    mem = memory.lines
    a_link = rows.a_link
    b_link = rows.b_link
    m = rows.distance.shape[0]
    k = mem.shape[0]
    keep, pa, pb, dd, extra = _remeasure(F, rows, loc, memory)
    t = m + extra
    a_link2 = np.empty(t, dtype=np.int64)
    b_link2 = np.empty(t, dtype=np.int64)
    a_pt2 = np.empty((t, 3))
    b_pt2 = np.empty((t, 3))
    normal2 = np.empty((t, 3))
    vobs2 = np.zeros((t, 3))
    dist2 = np.empty(t)
    rho02 = np.empty(t)
    task2 = np.empty(t, dtype=np.bool_)
    recalled = np.zeros(t, dtype=np.bool_)
    a_link2[:m] = a_link
    b_link2[:m] = b_link
    a_pt2[:m] = rows.a_point
    b_pt2[:m] = rows.b_point
    normal2[:m] = rows.normal
    vobs2[:m] = velocity
    dist2[:m] = rows.distance
    rho02[:m] = rows.margin
    task2[:m] = rows.task_space
    i = m
    for r in range(k):
        if not keep[r]:
            continue
        a_link2[i] = int(mem[r, 0])
        b_link2[i] = int(mem[r, 1])
        for j in range(3):
            a_pt2[i, j] = pa[r, j]
            b_pt2[i, j] = pb[r, j] if mem[r, 1] >= 0 else math.nan
            normal2[i, j] = (pa[r, j] - pb[r, j]) / dd[r]
        dist2[i] = dd[r]
        rho02[i] = mem[r, 8]
        task2[i] = mem[r, 9] != 0.0
        recalled[i] = True
        i += 1
    out = AvoidanceRows(a_link2, a_pt2, b_link2, b_pt2, normal2, vobs2, dist2, rho02, task2)
    return out, recalled


@njit(cache=True)
def remember(memory, rows, loc, static):  # type: ignore[no-untyped-def]
    """Age the remembered lines by one tick, drop those ``depth`` ticks old and store
    this tick's ``static`` rows aged 1. The memory must hold ``depth`` × the largest
    number of rows per tick (the controller sees to it), so every new row finds an
    empty one."""
    mem = memory.lines
    depth = memory.depth
    for r in range(mem.shape[0]):
        if mem[r, MEM_AGE] >= depth:
            mem[r, MEM_AGE] = 0.0
        elif mem[r, MEM_AGE] > 0.0:
            mem[r, MEM_AGE] += 1.0
    r = 0
    for i in range(loc.shape[0]):
        if not static[i]:
            continue
        while r < mem.shape[0] and mem[r, MEM_AGE] != 0.0:
            r += 1
        if r == mem.shape[0]:
            return
        mem[r, 0] = rows.a_link[i]
        mem[r, 1] = rows.b_link[i]
        for j in range(6):
            mem[r, 2 + j] = loc[i, j]
        mem[r, 8] = rows.margin[i]
        mem[r, 9] = 1.0 if rows.task_space[i] else 0.0
        mem[r, MEM_AGE] = 1.0
