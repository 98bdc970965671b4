"""Compiled controller tick (numba): thesis Eq. 3.8–3.18 with P-V Eq. 6, joint limits
and the approach guard. The documentation of the law is in ``controller.py``; this
module is its arithmetic, on plain arrays, compiled once and cached on disk.

Avoidance point arrays (``m`` rows): ``a_link`` frame index of the robot part,
``a_pt`` its closest point (world); ``b_link`` the other part's frame index on the same
robot (self-collision: the Jacobian is the relative one ``J_a − J_b``) or ``-1``;
``normal`` unit collision-line vector pointing away from the other part; ``vobs`` the
world velocity of the other part's closest point (a moving obstacle; zero if static);
``dist``, ``rho0`` distance and margin; ``task_pt`` True for a tool part handled in
task space.

``diag`` out: 0 position error, 1 orientation error (rad), 2 σ_min, 3 λ, 4 task scale
``s``, 5 limit scale ``α``, 6 active avoidance points, 7 guard scale, 8 min distance.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from reachwise.kinematics._kernels import frames, point_jacobian_rows, tool_jacobian
from reachwise.kinematics.dls import damped_pinv
from reachwise.kinematics.orientation import quaternion_error_into

DIAG = 9


@njit(cache=True)
def _bounded(v, vmax):  # type: ignore[no-untyped-def]
    """Eq. 3.12/3.13: scale a 3-vector down to norm ``vmax`` if it is longer."""
    nrm = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    if nrm > vmax:
        f = vmax / nrm
        v[0] *= f
        v[1] *= f
        v[2] *= f


@njit(cache=True)
def _task_velocity(s, pG, pR, wG, six, vlin, wmax, xd):  # type: ignore[no-untyped-def]
    """``ẋ(s) = [bound(s ṗ_G + Σ ṗ_O); bound(s ω)]`` (Eq. 3.11–3.13, P-V Eq. 6–7)."""
    v = np.empty(3)
    for i in range(3):
        v[i] = s * pG[i] + pR[i]
    _bounded(v, vlin)
    for i in range(3):
        xd[i] = v[i]
    if six:
        w = np.empty(3)
        for i in range(3):
            w[i] = s * wG[i]
        _bounded(w, wmax)
        for i in range(3):
            xd[3 + i] = w[i]


@njit(cache=True)
def control_step(  # type: ignore[no-untyped-def]
    kind,
    qidx,
    dh,
    classic,
    base,
    tool,
    q,
    Td,
    six,
    kv,
    kw,
    vlin,
    wmax,
    lambda_max,
    epsilon,
    lower,
    upper,
    vmax,
    usable,
    passive,
    k_lim,
    zone,
    a_link,
    a_pt,
    b_link,
    b_pt,
    normal,
    vobs,
    dist,
    rho0,
    mu,
    vrep_max,
    task_pt,
    avoid_on,
    guard_on,
    rho_stop,
    xi,
    t_react,
    vel_aware,
    mem,
    depth,
    qdot,
    diag,
):
    """One controller tick; writes ``qdot`` (n,), ``diag`` (see module docstring) and
    updates ``mem``, the guard's remembered collision lines (see :func:`_recall`)."""
    N = kind.shape[0]
    n = q.shape[0]
    F = np.empty((N + 2, 4, 4))
    frames(kind, qidx, dh, classic, base, tool, q, F)
    Jg = np.empty((6, n))
    tool_jacobian(kind, qidx, classic, F, n, Jg)
    T = F[N + 1]
    r = 6 if six else 3
    J = Jg[:r].copy()

    # ---- primary task: bounded P control of position and orientation (Eq. 3.8–3.13)
    pG = np.empty(3)
    ep2 = 0.0
    for i in range(3):
        d = Td[i, 3] - T[i, 3]
        pG[i] = kv * d
        ep2 += d * d
    wG = np.zeros(3)
    ang = 0.0
    if six:
        eo = np.empty(3)
        ang = quaternion_error_into(T[:3, :3], Td[:3, :3], eo)
        for i in range(3):
            wG[i] = kw * eo[i]
    diag[0] = math.sqrt(ep2)
    diag[1] = ang

    # ---- remembered collision lines join the guard (not the repulsion)
    m_now = dist.shape[0]
    loc = _local_lines(F, a_link, a_pt, b_link, b_pt, normal, dist)
    static = _static_rows(vobs, dist, rho0, loc)
    if not vel_aware:
        vobs = np.zeros_like(normal)
    if depth > 0:
        a_link, a_pt, b_link, b_pt, normal, vobs, dist, rho0, task_pt, mu, recalled = _recall(
            F, a_link, a_pt, b_link, b_pt, normal, vobs, dist, rho0, task_pt, mu, loc, mem, depth
        )
        _remember(mem, depth, a_link, b_link, loc, rho0, task_pt, static)
    else:
        recalled = np.zeros(m_now, dtype=np.bool_)

    # ---- avoidance points: Khatib speeds (Eq. 3.17), Jacobians, task-space sum (P-V Eq. 6)
    m = dist.shape[0]
    active = np.zeros(m, dtype=np.bool_)
    vrep = np.zeros(m)
    # a moving obstacle's approach speed along the collision line (0 if it recedes),
    # and the feed-forward velocity u/|v_B| v_B that carries the point along with it
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
        # the distance left after the obstacle's travel during the robot's reaction
        deff[i] = dist[i] - approach[i] * t_react
        if approach[i] > 0.0:
            sp = math.sqrt(sp)
            wgt = min(2.0 * approach[i] / sp, 1.0)
            for j in range(3):
                ff[i, j] = wgt * vobs[i, j]
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
            rho = max(deff[i], 1e-6)
            v = mu[i] * (1.0 / rho - 1.0 / rho0[i]) / (rho * rho)
            vrep[i] = min(v, vrep_max)
        if task_pt[i]:
            # a tool part moves with the tool: rigidly (its own point Jacobian), or, if
            # it hangs on passive joints, with the tool point plus the tool's rotation
            # about the vertical (the hanging part keeps only that rotation)
            hanging = False
            for jj in range(N):
                if qidx[jj] >= 0 and passive[qidx[jj]] and jj + 1 <= a_link[i]:
                    hanging = True
            if hanging:
                rx = a_pt[i, 0] - T[0, 3]
                ry = a_pt[i, 1] - T[1, 3]
                for k in range(n):
                    wz = Jg[5, k]
                    JO[i, 0, k] = Jg[0, k] - wz * ry
                    JO[i, 1, k] = Jg[1, k] + wz * rx
                    JO[i, 2, k] = Jg[2, k]
            else:
                point_jacobian_rows(
                    kind, qidx, classic, F, a_link[i], a_pt[i, 0], a_pt[i, 1], a_pt[i, 2], Ja
                )
                for j in range(3):
                    for k in range(n):
                        JO[i, j, k] = Ja[j, k]
            if avoid_on and not recalled[i]:
                for j in range(3):
                    pR[j] += vrep[i] * normal[i, j] + ff[i, j]
        else:
            point_jacobian_rows(
                kind, qidx, classic, F, a_link[i], a_pt[i, 0], a_pt[i, 1], a_pt[i, 2], Ja
            )
            if b_link[i] >= 0:
                point_jacobian_rows(
                    kind, qidx, classic, F, b_link[i], b_pt[i, 0], b_pt[i, 1], b_pt[i, 2], Jb
                )
                for j in range(3):
                    for k in range(n):
                        JO[i, j, k] = Ja[j, k] - Jb[j, k]
            else:
                for j in range(3):
                    for k in range(n):
                        JO[i, j, k] = Ja[j, k]
    diag[6] = n_active
    diag[8] = dmin

    # ---- guard, tool parts: remove from the goal velocity the part that would close
    # a tool part's gap faster than the velocity damper allows, keep the part along
    # the obstacle (the tool slides around it instead of stopping)
    if guard_on and avoid_on:
        for _ in range(3):
            for i in range(m):
                if not (active[i] and task_pt[i]):
                    continue
                span = max(rho0[i] - rho_stop, 1e-9)
                frac = min(max((deff[i] - rho_stop) / span, 0.0), 1.0)
                rate = 0.0
                for j in range(3):
                    rate += normal[i, j] * (pG[j] + pR[j])
                lo = -xi * frac
                if approach[i] > 0.0:
                    lo = _moving_bound(deff[i], rho0[i], rho_stop, xi, approach[i])
                if rate < lo:
                    for j in range(3):
                        pG[j] += (lo - rate) * normal[i, j]

    # ---- joints: usable ones get weight 1; a joint outside its limits recovers inward
    rec = np.zeros(n)
    w = np.zeros(n)
    for k in range(n):
        if not usable[k]:
            continue
        if q[k] < lower[k]:
            rec[k] = min(k_lim * (lower[k] - q[k]), vmax[k])
        elif q[k] > upper[k]:
            rec[k] = -min(k_lim * (q[k] - upper[k]), vmax[k])
        else:
            w[k] = 1.0
    # the recovering joints' motion is known: the others solve for what is left
    xrec = np.zeros(r)
    for j in range(r):
        acc = 0.0
        for k in range(n):
            acc += J[j, k] * rec[k]
        xrec[j] = acc

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
        M, P, smin, lam = damped_pinv(Phi, epsilon, lambda_max, True)
        # ---- secondary goal: Eq. 3.18, every body point through the null space
        unull[:] = 0.0
        if avoid_on:
            zsum = np.zeros(n)
            for i in range(m):
                if not active[i] or task_pt[i] or recalled[i]:
                    continue
                PhiO = np.empty((3, n))
                for j in range(3):
                    for k in range(n):
                        PhiO[j, k] = JO[i, j, k] * w[k]
                MO = damped_pinv(PhiO, epsilon, lambda_max, False).inverse
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
        _task_velocity(1.0, pG, pR, wG, six, vlin, wmax, xd)
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
    diag[2] = smin
    diag[3] = lam

    # ---- guard: the task is scaled down (s < 1) before any pair closes in too fast
    s = 1.0
    guard = 1.0
    if guard_on and n_guard > 0:
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
            span = max(rho0[i] - rho_stop, 1e-9)
            frac = min(max((deff[i] - rho_stop) / span, 0.0), 1.0)
            lo_static[i] = -xi * frac
            lo_rate[i] = lo_static[i]
            if approach[i] > 0.0:
                lo_rate[i] = _moving_bound(deff[i], rho0[i], rho_stop, xi, approach[i])
        qs = np.empty(n)
        moving = False
        for i in range(m):
            if active[i] and approach[i] > 0.0:
                moving = True
        # feasibility of a task scale: every active pair's rate above its bound
        lo_s = 0.0
        hi_s = 1.0
        for it in range(16):
            trial = 1.0 if it == 0 else (0.0 if it == 1 else 0.5 * (lo_s + hi_s))
            _task_velocity(trial, pG, pR, wG, six, vlin, wmax, xd)
            for k in range(n):
                acc = 0.0
                for j in range(r):
                    acc += M[k, j] * (xd[j] - xrec[j])
                qs[k] = w[k] * (acc + unull[k]) + rec[k]
            ok = True
            # a moving obstacle's pair is checked on the command actually sent, after
            # the joint-speed scaling (scaling slows a retreat down as well)
            a_s = _limit_scale(qs, 1.0, rec, q, lower, upper, vmax, k_lim) if moving else 1.0
            for i in range(m):
                if not active[i]:
                    continue
                rate = 0.0
                for k in range(n):
                    rate += g[i, k] * qs[k]
                if rate < lo_rate[i] - 1e-12:
                    ok = False
                    break
                if approach[i] > 0.0 and a_s * rate < lo_rate[i] - 1e-12:
                    ok = False
                    break
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
        _task_velocity(s, pG, pR, wG, six, vlin, wmax, xd)
        for k in range(n):
            acc = 0.0
            for j in range(r):
                acc += M[k, j] * (xd[j] - xrec[j])
            qd1[k] = w[k] * (acc + unull[k]) + rec[k]
        # still closing in too fast with no task left: slow the whole motion down. Only
        # the robot's own approach can be slowed (the static damper); a robot too slow
        # to outrun an approaching obstacle keeps retreating as fast as it can
        for i in range(m):
            if not active[i]:
                continue
            rate = 0.0
            for k in range(n):
                rate += g[i, k] * qd1[k]
            if rate < lo_static[i]:
                f = lo_static[i] / rate if rate < 0.0 else 0.0
                guard = min(guard, max(f, 0.0))
    diag[4] = s
    diag[7] = guard

    # ---- limits: scale the whole vector (never clip one joint into another direction)
    alpha = _limit_scale(qd1, guard, rec, q, lower, upper, vmax, k_lim)
    for k in range(n):
        qdot[k] = alpha * qd1[k]
    diag[5] = alpha / guard if guard > 0.0 else 0.0


#: Columns of the guard memory ``mem`` (one remembered collision line per row): frame
#: indices of the robot part and of the other part (-1: a static obstacle), the robot
#: part's point in its link frame, the other end (world, or in the other link's frame),
#: the margin, the tool-part flag and the age in ticks (0: an empty row).
MEM_COLS = 11
#: Column of ``mem`` holding the age.
MEM_AGE = 10


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
    """Whether two remembered lines (6 coordinates, see :func:`_local_lines`) are the
    same point pair."""
    e = 0.0
    for j in range(6):
        e += abs(x[j] - y[j])
    return e < 1e-9


@njit(cache=True)
def _local_lines(F, a_link, a_pt, b_link, b_pt, normal, dist):  # type: ignore[no-untyped-def]
    """This tick's collision lines in the form they are remembered, ``(m, 6)``: the robot
    part's point in its link frame, then the other end — in its link frame for a
    self-collision pair, else the obstacle point ``p_a − ρ n`` in the world."""
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
def _static_rows(vobs, dist, rho0, loc):  # type: ignore[no-untyped-def]
    """Rows worth remembering: within their margin, finite, and against a still
    obstacle (a moving obstacle's point has moved on by the next tick)."""
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
def _recall(  # type: ignore[no-untyped-def]
    F, a_link, a_pt, b_link, b_pt, normal, vobs, dist, rho0, task_pt, mu, loc, mem, depth
):
    """The avoidance rows of this tick followed by the remembered collision lines.

    A remembered line (a row of ``mem`` aged 1 … ``depth`` ticks) is the robot part's
    point in its link frame and the other end: a point of a static obstacle (world) or,
    for a self-collision pair, a point in the other link's frame. Both ends are points
    of the clouds, so at the current joint state the remembered pair is again an exact
    point pair: distance ``|p_a − p_b|`` and direction ``(p_a − p_b)/|p_a − p_b|``.
    Rows within their margin that do not repeat one of this tick's pairs (``loc``, see
    :func:`_local_lines`) or an earlier recalled one are appended (flag ``recalled``).
    """
    m = dist.shape[0]
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
    mu2 = np.zeros(t)
    recalled = np.zeros(t, dtype=np.bool_)
    a_link2[:m] = a_link
    b_link2[:m] = b_link
    a_pt2[:m] = a_pt
    b_pt2[:m] = b_pt
    normal2[:m] = normal
    vobs2[:m] = vobs
    dist2[:m] = dist
    rho02[:m] = rho0
    task2[:m] = task_pt
    mu2[:m] = mu
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
    return a_link2, a_pt2, b_link2, b_pt2, normal2, vobs2, dist2, rho02, task2, mu2, recalled


@njit(cache=True)
def _remember(mem, depth, a_link, b_link, loc, rho0, task_pt, static):  # type: ignore[no-untyped-def]
    """Age the remembered lines by one tick, drop those ``depth`` ticks old and store
    this tick's ``static`` rows (the first ``loc.shape[0]`` avoidance rows) aged 1.
    ``mem`` must hold ``depth`` × the largest number of rows per tick (the caller sees
    to it), so every new row finds an empty one."""
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
        mem[r, 0] = a_link[i]
        mem[r, 1] = b_link[i]
        for j in range(6):
            mem[r, 2 + j] = loc[i, j]
        mem[r, 8] = rho0[i]
        mem[r, 9] = 1.0 if task_pt[i] else 0.0
        mem[r, MEM_AGE] = 1.0


@njit(cache=True)
def _moving_bound(rho, rho0, rho_stop, xi, u):  # type: ignore[no-untyped-def]
    """Lowest rate ``n_iᵀ J_Oi q̇`` allowed against an obstacle approaching at ``u``:
    the velocity damper on the true distance rate, ``u − ξ (ρ − ρ_s)/(ρ_O − ρ_s)``,
    continued below ``ρ_s`` (down to ``u + ξ`` at ``2ρ_s − ρ_O``) so that a point the
    obstacle pushed inside ``ρ_s`` must open the gap again, not only hold it."""
    span = max(rho0 - rho_stop, 1e-9)
    frac = min(max((rho - rho_stop) / span, -1.0), 1.0)
    return u - xi * frac


@njit(cache=True)
def _limit_scale(qd, guard, rec, q, lower, upper, vmax, k_lim):  # type: ignore[no-untyped-def]
    """The factor ``α ≤ guard`` that brings ``guard · qd`` within every joint's speed
    bound and position-limit damper (a recovering joint may only move inward)."""
    alpha = guard
    for k in range(qd.shape[0]):
        v = qd[k] * guard
        if rec[k] != 0.0:
            hi = vmax[k] if rec[k] > 0.0 else 0.0
            lo = -vmax[k] if rec[k] < 0.0 else 0.0
        else:
            hi = min(vmax[k], max(k_lim * (upper[k] - q[k]), 0.0))
            lo = max(-vmax[k], min(k_lim * (lower[k] - q[k]), 0.0))
        if v > hi:
            alpha = min(alpha, guard * hi / v if v > 0.0 else 0.0)
        elif v < lo:
            alpha = min(alpha, guard * lo / v if v < 0.0 else 0.0)
    return max(alpha, 0.0)


def warm_up() -> None:
    """Compile the controller kernel for the signature used at run time."""
    kind = np.array([0, 1, 0], dtype=np.int64)
    qidx = np.array([0, 1, 2], dtype=np.int64)
    dh = np.zeros((3, 4))
    dh[1, 0] = 0.5
    eye = np.eye(4)
    n = 3
    for six in (False, True):
        for m in (0, 1):
            control_step(
                kind, qidx, dh, False, eye, eye, np.zeros(n), eye, six,
                1.0, 1.0, 1.0, 1.0, 0.1, 0.01,
                np.full(n, -1.0), np.full(n, 1.0), np.ones(n), np.ones(n, np.bool_),
                np.zeros(n, np.bool_), 2.0,
                np.full(n, 0.1),
                np.zeros(m, np.int64), np.zeros((m, 3)), np.full(m, -1, np.int64),
                np.zeros((m, 3)), np.zeros((m, 3)), np.zeros((m, 3)), np.full(m, 0.1),
                np.full(m, 0.2),
                np.full(m, 1e-3), 1.0, np.zeros(m, np.bool_), True, True, 0.03, 0.5, 0.0,
                True, np.zeros((2 * m, MEM_COLS)), 2,
                np.empty(n), np.empty(DIAG),
            )  # fmt: skip
