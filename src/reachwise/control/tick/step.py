"""One controller tick (thesis Eq. 3.8–3.18 with P-V Eq. 6, joint limits and the
approach guard), composed of the steps of this package. The law is documented in
``reachwise.control.controller``; the inputs and the result in ``types``.

``control_step`` is the compiled entry point: its groups arrive as plain tuples in
their named tuple's field order (see ``reachwise.kinematics._jit``). ``run_tick`` is the
checked Python entry: it validates every group (a clear :class:`InputError` naming the
group and the field, before any motion is computed) and calls ``control_step``.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from reachwise.control.tick.guard import deflect_for_tool_parts, guard_scales
from reachwise.control.tick.joints import JointMotion, joint_weights, limit_scale
from reachwise.control.tick.memory import local_lines, recall, remember, static_rows
from reachwise.control.tick.points import active_points
from reachwise.control.tick.solve import solve_joints
from reachwise.control.tick.task import TaskParts, primary_task
from reachwise.control.tick.types import (
    GAINS,
    LIMITS,
    MEMORY,
    ROWS,
    SETTINGS,
    TARGET,
    AvoidanceRows,
    AvoidanceSettings,
    Gains,
    GuardMemory,
    JointLimits,
    Target,
    TickDiagnostics,
    check_tick_inputs,
)
from reachwise.kinematics._jit import RO_F8_1D
from reachwise.kinematics._kernels import frames, tool_jacobian
from reachwise.kinematics.chain import CHAIN, Chain

__all__ = ["control_step", "run_tick", "tick"]


@njit(cache=True)
def _check_frames(rows, frames_count):  # type: ignore[no-untyped-def]
    """Refuse frame indices outside the chain before anything is computed."""
    for i in range(rows.distance.shape[0]):
        if rows.a_link[i] < 0 or rows.a_link[i] >= frames_count:
            raise IndexError("AvoidanceRows.a_link: frame index outside the chain")
        if rows.b_link[i] < -1 or rows.b_link[i] >= frames_count:
            raise IndexError("AvoidanceRows.b_link: frame index outside the chain")


@njit(cache=True)
def tick(chain, limits, gains, settings, target, rows, memory, q):  # type: ignore[no-untyped-def]
    """One controller tick on named groups; returns ``(q̇, TickDiagnostics)`` and
    updates ``memory.lines`` (the guard's remembered collision lines)."""
    N = chain.kind.shape[0]
    n = q.shape[0]
    _check_frames(rows, N + 2)
    F = np.empty((N + 2, 4, 4))
    frames(chain.kind, chain.qidx, chain.dh, chain.classic, chain.base, chain.tool, q, F)
    Jg = np.empty((6, n))
    tool_jacobian(chain.kind, chain.qidx, chain.classic, F, n, Jg)
    six = target.six
    r = 6 if six else 3
    J = Jg[:r].copy()
    avoid = settings.avoidance
    guard_on = settings.guard and avoid

    # ---- primary task: bounded P control of position and orientation (Eq. 3.8–3.13)
    pG, wG, position_error, orientation_error = primary_task(F[N + 1], target, gains)

    # ---- remembered collision lines join the guard (not the repulsion)
    m_now = rows.distance.shape[0]
    loc = local_lines(F, rows)
    static = static_rows(rows, loc)
    if settings.velocity_aware:
        extended, recalled = recall(F, rows, rows.obstacle_velocity, loc, memory)
    else:
        extended, recalled = recall(F, rows, np.zeros((m_now, 3)), loc, memory)
    if memory.depth > 0:
        remember(memory, rows, loc, static)

    # ---- avoidance points: Khatib speeds (Eq. 3.17), Jacobians, task-space sum (P-V Eq. 6)
    pts = active_points(chain, limits.passive, F, Jg, extended, recalled, m_now, gains, settings)

    # ---- guard, tool parts: deflect the goal velocity along the obstacle
    if guard_on:
        deflect_for_tool_parts(pG, pts.pR, extended, pts, settings)

    # ---- joints: usable ones get weight 1; a joint outside its limits recovers inward;
    # the recovering joints' motion is known: the others solve for what is left
    w, rec = joint_weights(q, limits, gains.k_limit)
    xrec = np.zeros(r)
    for j in range(r):
        acc = 0.0
        for k in range(n):
            acc += J[j, k] * rec[k]
        xrec[j] = acc

    # ---- damped pseudo-inverse, avoidance in the null space (Eq. 3.5–3.7, 3.18)
    joints = JointMotion(q, w, rec, xrec)
    task = TaskParts(pG, pts.pR, wG, six)
    sol = solve_joints(J, joints, task, limits, extended, pts, recalled, gains, avoid)

    # ---- guard: the task is scaled down (s < 1) before any pair closes in too fast;
    # where even s = 0 would stop all motion, the closing part is projected out
    s = 1.0
    guard = 1.0
    qd1 = sol.qd
    if guard_on and pts.n_guard > 0:
        s, guard, qd1 = guard_scales(sol, joints, task, limits, extended, pts, gains, settings)

    # ---- limits: scale the whole vector (never clip one joint into another direction)
    alpha = limit_scale(qd1, guard, q, limits, gains.k_limit)
    qdot = np.empty(n)
    for k in range(n):
        qdot[k] = alpha * qd1[k]
    diag = TickDiagnostics(
        position_error,
        orientation_error,
        sol.sigma_min,
        sol.damping,
        s,
        alpha / guard if guard > 0.0 else 0.0,
        pts.n_active,
        guard,
        pts.dmin,
    )
    return qdot, diag


@njit(
    (CHAIN, LIMITS, GAINS, SETTINGS, TARGET, ROWS, MEMORY, RO_F8_1D),
    cache=True,
)
def control_step(chain, limits, gains, settings, target, rows, memory, q):  # type: ignore[no-untyped-def]
    """The compiled entry point of :func:`tick`; every group as ``tuple(group)``."""
    return tick(
        Chain(*chain),
        JointLimits(*limits),
        Gains(*gains),
        AvoidanceSettings(*settings),
        Target(*target),
        AvoidanceRows(*rows),
        GuardMemory(*memory),
        q,
    )


def run_tick(
    chain: Chain,
    limits: JointLimits,
    gains: Gains,
    settings: AvoidanceSettings,
    target: Target,
    rows: AvoidanceRows,
    memory: GuardMemory,
    q: NDArray[np.float64],
) -> tuple[NDArray[np.float64], TickDiagnostics]:
    """One tick with every input checked first (see the module docstring)."""
    check_tick_inputs(chain, limits, gains, settings, target, rows, memory, q)
    qdot, diag = control_step(  # type: ignore[call-arg]
        tuple(chain), tuple(limits), tuple(gains), tuple(settings), tuple(target),
        tuple(rows), tuple(memory), q,
    )  # fmt: skip
    return qdot, diag
