"""Solvers of the synthesis problem: ``dls`` (the thesis method) and ``trf`` (scipy).

``dls`` — P-I Eq. 22 and P-II Eq. 24–33: damped least squares on the stacked,
block-structured Jacobian (``linalg``) with

- row weights ``W_x``: position rows 1, orientation rows ``tol_p / tol_o`` (m/rad), so a
  pose that is exactly at its position and orientation tolerance weighs the same;
- the σ_min damping schedule of P-I Eq. 14 on the stacked matrix, faded with the
  residual like the IK (quadratic final convergence), plus a Levenberg–Marquardt boost
  when a step fails to lower the cost;
- dynamic weighting of the columns (P-II Eq. 25–28) with a working set of the bounds
  (``active_set``): a variable at a bound that the step drives outward gets weight 0
  and the step is solved again; when the iteration stalls, a fixed variable whose
  multiplier has the wrong sign is released. The iterate is then projected into the
  bounds, so every design parameter, base coordinate and joint value always lies
  within its range;
- step control: the step is capped per block (the design, and each task point's
  joints, by their own ratio to the caps), then halved until the cost falls; the
  Levenberg–Marquardt boost is bounded (``max_boost``);
- workspace avoidance (P-II Eq. 29–33, P-I Eq. 27–31): link points closer than a margin
  to the workspace boundary (e.g. the tunnel envelope) are pushed back by the Khatib-
  style velocity ``k (margin − distance)`` along the boundary normal, mapped through the
  transposed point Jacobians and projected into the null space of the task (where P-I
  writes ``Jᵀ`` inside the projector, the pseudo-inverse is used). A step with this
  motion that does not lower the cost is retried without it;
- re-seeding: when a window of ``reseed_every`` iterations lowered the cost by less than
  ``reseed_progress``, the joints of the unreached points are re-solved by IK.

Why runs stalled before (tunnel-87 seeds 4, 8, 9; issue "Design that optimizes"): a
working set of the bounds built from the step's sign alone, which creates false
stationary points (``active_set``); a single step ratio for all task points, so one
point's large joint step shrank every step (and the iteration count grew with the
number of points); and, near the tunnel walls, a wall motion that raised the cost made
every step fail while the unbounded boost damped the task step to nothing.

``trf`` — ``scipy.optimize.least_squares`` (trust-region reflective) with bounds, the
exact sparse Jacobian and the same workspace penalty as extra residuals: the baseline.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from reachwise.kinematics.dls import EPSILON_SOLVER, LAMBDA_MAX, damping_squared
from reachwise.synthesis.active_set import VariableBox, bounded_step
from reachwise.synthesis.clearance import ClearanceModel
from reachwise.synthesis.clearance_rows import (
    Rows,
    clearance_motion,
    merit,
    pose_merits,
    stacked_rows,
)
from reachwise.synthesis.linalg import (
    BlockSystem,
    null_space_project,
    smallest_singular_value,
    weighted,
)
from reachwise.synthesis.problem import Evaluation, SynthesisProblem
from reachwise.synthesis.workspace_points import link_points

Array = NDArray[np.float64]


class Workspace(Protocol):
    """Constraint geometry: signed distance (> 0 inside the free space) and its gradient."""

    def signed_distance(self, points: Array) -> Array: ...

    def gradient(self, points: Array) -> Array: ...


@dataclass(frozen=True)
class SolverOptions:
    """Tuning of the ``dls`` solver (lengths in m, angles in rad); ``lambda_max`` and
    ``epsilon``: the damping schedule (``reachwise.kinematics.dls``)."""

    max_iter: int = 1000
    lambda_max: float = LAMBDA_MAX
    epsilon: float = EPSILON_SOLVER
    err_ref: float = 0.05
    max_step_angle: float = 0.3
    max_step_length: float = 0.5
    workspace_margin: float = 0.1
    workspace_gain: float = 0.5
    samples_per_link: int = 4
    stall_iterations: int = 100
    reseed_every: int = 15
    reseed_restarts: int = 8
    stall_decrease: float = 1e-3
    reseed_progress: float = 0.5
    max_boost: float = 1.0


@dataclass(frozen=True)
class SolveOutcome:
    """What one solver run returns: the final vector, its evaluation and the history."""

    z: Array
    evaluation: Evaluation
    iterations: int
    converged: bool
    cost_history: list[float] = field(default_factory=list)


def row_weights(problem: SynthesisProblem) -> Array:
    """``W_x`` per padded row: 1 for position rows, ``tol_p/tol_o`` for orientation rows."""
    w = np.ones((problem.K, 6))
    w[:, 3:] = (problem.task.tol_position / problem.task.tol_orientation)[:, None]
    return np.where(problem.active_rows, w, 0.0)


def converged(problem: SynthesisProblem, ev: Evaluation) -> bool:
    pos_ok, ori_ok, _ = problem.point_status(ev)
    return bool(pos_ok.all() and ori_ok.all())


def _max_steps(problem: SynthesisProblem) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """Per-variable step caps: angles ``max_step_angle``, lengths ``max_step_length``."""
    tpl = problem.template
    angle_d = np.array(
        [p in ("alpha", "theta", "roll", "pitch", "yaw") for _, _, p in tpl.design.free]
    )
    return angle_d, tpl.prismatic[problem.free_joints]


def solve_dls(
    problem: SynthesisProblem,
    z0: Array,
    options: SolverOptions | None = None,
    workspace: Workspace | None = None,
    rng: np.random.Generator | None = None,
    clearance: ClearanceModel | None = None,
) -> SolveOutcome:
    """Iterate the weighted, damped, bounded least-squares update from ``z0``.

    Every ``reseed_every`` iterations the joints of unreached points are re-solved by
    IK on the current design (``reseed_points``), drawing restarts from ``rng``. With
    ``clearance`` its terms near the clearance join the rows (``clearance_rows``) and a
    run converges only when every term keeps the clearance.
    """
    opt = options or SolverOptions()
    rng = rng if rng is not None else np.random.default_rng(0)
    lo, hi = problem.bounds
    p, K, nf = problem.p, problem.K, problem.n_free_joints
    angle_d, pris_q = _max_steps(problem)
    cap_d = np.where(angle_d, opt.max_step_angle, opt.max_step_length)
    cap_q = np.where(pris_q, opt.max_step_length, opt.max_step_angle)
    wx = row_weights(problem)
    z = np.clip(z0, lo, hi)
    ev = problem.evaluate(z)
    rows = stacked_rows(problem, ev, wx, z, clearance)
    cost = rows.cost
    c_min = clearance.clearance if clearance is not None else 0.0
    history = [cost]
    boost = 0.0
    best_cost, since_best = cost, 0
    release = False  # stalled on the working set of the bounds: check the multipliers
    window_start = cost  # merit when the current re-seeding window began
    it = 0
    for it in range(1, opt.max_iter + 1):
        if _done(problem, ev, rows, c_min, z, workspace, opt):
            return SolveOutcome(z, ev, it - 1, True, history)
        e, D, J, active = rows.e, rows.D, rows.J, rows.active
        zd, zq = z[:p], z[p:].reshape(K, nf)
        lod, hid = lo[:p], hi[:p]
        loq, hiq = lo[p:].reshape(K, nf), hi[p:].reshape(K, nf)
        wd, wq = np.ones(p), np.ones((K, nf))
        # σ_min of the weighted stacked Jacobian, for the Eq. 14 schedule
        Dw, Jw = weighted(D, J, wd, wq)
        sys0 = BlockSystem.build(Dw, Jw, active, 1e-12)
        smin = smallest_singular_value(sys0, active, 1e-12)
        lam2 = damping_squared(smin, opt.epsilon, opt.lambda_max)
        lam2 *= min(1.0, np.sqrt(2 * cost) / opt.err_ref) ** 2
        lam2 += boost
        bs = bounded_step(
            D,
            J,
            active,
            e,
            lam2,
            VariableBox((zd, zq), (lod, loq), (hid, hiq), (cap_d, np.tile(cap_q, (K, 1)))),
            release,
        )
        sd, sq, wd, wq = bs.design, bs.joints, bs.weight_design, bs.weight_joints
        task_step = np.concatenate([sd, sq.ravel()])
        steps = [task_step]
        nd, nq = (
            (None, None) if workspace is None else _workspace_motion(problem, z, workspace, opt)
        )
        if rows.terms is not None:
            push = clearance_motion(rows.terms, c_min, opt.workspace_gain)
            if push is not None:
                nd = push[0] if nd is None else nd + push[0]
                nq = push[1] if nq is None else nq + push[1]
        if nd is not None and nq is not None:
            Dw, Jw = weighted(D, J, wd, wq)
            sysn = BlockSystem.build(Dw, Jw, active, 1e-12)
            pd, pq = null_space_project(sysn, wd * nd, wq * nq, active)
            # the wall motion first together with the task step, alone the task step
            steps.insert(0, task_step + np.concatenate([wd * pd, (wq * pq).ravel()]))
        caps = np.concatenate([cap_d, np.tile(cap_q, K)])
        accepted = False
        alpha = 1.0
        c_try = cost
        for step in steps:
            step, _ = _capped(step, caps, p, K, nf)
            alpha = 1.0
            for _ in range(5):
                z_try = np.clip(z + alpha * step, lo, hi)
                ev_try = problem.evaluate(z_try)
                c_try = merit(problem, ev_try, wx, z_try, clearance)
                if c_try < cost or (step is not task_step and c_try <= cost * 1.000001 + 1e-12):
                    accepted = True
                    break
                alpha *= 0.5
            if accepted:
                break
        release = not accepted or c_try > cost * (1 - opt.stall_decrease)
        if accepted:
            z, ev, cost = z_try, ev_try, c_try
            rows = stacked_rows(problem, ev, wx, z, clearance)
            boost = boost / 4.0 if alpha == 1.0 else boost
        else:
            boost = min(max(4.0 * boost, 1e-6), opt.max_boost)
        history.append(cost)
        if cost < best_cost * (1 - 1e-4):
            best_cost, since_best = cost, 0
        else:
            since_best += 1
            if since_best >= opt.stall_iterations:
                break
        if opt.reseed_every and it % opt.reseed_every == 0:
            # re-seed only when the window made little progress (a trapped branch), not
            # while the iteration converges on its own
            slow = cost > (1.0 - opt.reseed_progress) * window_start
            z2 = reseed_points(problem, z, ev, rng, opt.reseed_restarts) if slow else None
            if z2 is not None and clearance is not None:
                z2 = _keep_clearer(problem, z, ev, z2, wx, clearance)
            if z2 is not None:
                ev2 = problem.evaluate(z2)
                rows2 = stacked_rows(problem, ev2, wx, z2, clearance)
                c2 = rows2.cost
                if c2 < cost * (1 - 1e-4):  # a real improvement restarts the stall count
                    best_cost, since_best = c2, 0
                z, ev, cost, rows = z2, ev2, c2, rows2
            window_start = cost
    done = _done(problem, ev, rows, c_min, z, workspace, opt)
    return SolveOutcome(z, ev, it, done, history)


def _done(
    problem: SynthesisProblem,
    ev: Evaluation,
    rows: Rows,
    clearance: float,
    z: Array,
    workspace: Workspace | None,
    opt: SolverOptions,
) -> bool:
    """Every pose reached, every clearance term kept, every link point inside."""
    return (
        converged(problem, ev)
        and rows.clear(clearance)
        and _workspace_clear(problem, z, workspace, opt)
    )


def _capped(step: Array, caps: Array, p: int, K: int, nf: int) -> tuple[Array, float]:
    """The step within its caps, scaled per block: the design part by its own ratio and
    each task point's joints by theirs (a trust region per block). One point's large
    joint step then no longer shrinks every other point's step — with a single global
    ratio the iteration count grew with the number of task points. Returns the step and
    the largest ratio."""
    r = np.abs(step) / caps
    rd = max(1.0, float(r[:p].max(initial=0.0)))
    rq = np.maximum(1.0, r[p:].reshape(K, nf).max(axis=1))
    out = np.concatenate([step[:p] / rd, (step[p:].reshape(K, nf) / rq[:, None]).ravel()])
    return out, max(rd, float(rq.max(initial=1.0)))


def _keep_clearer(
    problem: SynthesisProblem,
    z: Array,
    ev: Evaluation,
    z2: Array,
    wx: Array,
    clearance: ClearanceModel,
) -> Array | None:
    """``z2`` (re-seeded joints, same design as ``z``) with each pose's joints kept only
    where they lower that pose's share of the merit, clearance rows included: the IK of
    ``reseed_points`` knows the task only, and joints that reach a pose through a body
    would raise the merit and undo the solver's progress. None if no pose gained."""
    before = pose_merits(problem, ev, wx, z, clearance)
    after = pose_merits(problem, problem.evaluate(z2), wx, z2, clearance)
    better = after < before
    if not better.any():
        return None
    p, nf = problem.p, problem.n_free_joints
    Q = np.where(better[:, None], z2[p:].reshape(-1, nf), z[p:].reshape(-1, nf))
    return np.concatenate([z[:p], Q.ravel()])


def reseed_points(
    problem: SynthesisProblem,
    z: Array,
    ev: Evaluation,
    rng: np.random.Generator,
    restarts: int,
) -> Array | None:
    """Re-solve the joints of every unreached task point by IK on the current design.

    Given the design, the task points are independent inverse-kinematics problems; a
    point whose joints are trapped (a wrong branch, a joint stuck at a limit) gets
    fresh random restarts. A point's joints are replaced only when IK lowers its
    weighted error. Returns the new vector, or None if nothing improved.
    """
    from reachwise.kinematics.ik import solve_ik
    from reachwise.synthesis.init import locked_robot

    pos_ok, ori_ok, _ = problem.point_status(ev)
    todo = np.flatnonzero(~(pos_ok & ori_ok))
    if todo.size == 0:
        return None
    design, Q = problem.split(z)
    robot = locked_robot(problem, problem.robot_at(design))
    task = problem.task
    w = task.tol_position / task.tol_orientation
    improved = False
    for k in todo:
        res = solve_ik(
            robot, task.poses[k], q0=Q[k], mask=int(task.dims[k]), rng=rng,
            tol_position=float(task.tol_position[k]),
            tol_orientation=float(task.tol_orientation[k]), max_iter=80, restarts=restarts,
        )  # fmt: skip
        before = ev.position_error[k] + w[k] * ev.orientation_error[k]
        if res.position_error + w[k] * res.orientation_error < before:
            Q[k] = res.q
            improved = True
    return problem.pack(design, Q) if improved else None


def _workspace_clear(
    problem: SynthesisProblem, z: Array, ws: Workspace | None, opt: SolverOptions
) -> bool:
    if ws is None:
        return True
    pts, _, _, _ = link_points(problem, z, opt.samples_per_link)
    return bool(np.all(ws.signed_distance(pts.reshape(-1, 3)) >= 0.0))


def _workspace_motion(
    problem: SynthesisProblem, z: Array, ws: Workspace, opt: SolverOptions
) -> tuple[Array | None, Array | None]:
    """``Σ J_dᵀ k (margin − distance) n`` over violating link points (P-II Eq. 29–31)."""
    pts, Jd, Jq, owner = link_points(problem, z, opt.samples_per_link)
    flat = pts.reshape(-1, 3)
    sd = ws.signed_distance(flat)
    bad = np.flatnonzero(sd < opt.workspace_margin)
    if bad.size == 0:
        return None, None
    g = ws.gradient(flat[bad])
    v = opt.workspace_gain * (opt.workspace_margin - sd[bad])[:, None] * g  # (k, 3)
    Jd_bad = Jd.reshape(-1, 3, problem.p)[bad]
    Jq_bad = Jq.reshape(-1, 3, problem.n_free_joints)[bad]
    nd = np.einsum("kia,ki->a", Jd_bad, v)
    nq = np.zeros((problem.K, problem.n_free_joints))
    np.add.at(nq, owner.reshape(-1)[bad], np.einsum("kia,ki->ka", Jq_bad, v))
    return nd, nq


def solve_trf(
    problem: SynthesisProblem,
    z0: Array,
    workspace: Workspace | None = None,
    options: SolverOptions | None = None,
    max_nfev: int | None = None,
) -> SolveOutcome:
    """``scipy.optimize.least_squares(method="trf")`` with bounds, the exact sparse
    Jacobian and, with a workspace, one penalty residual ``max(0, margin − distance)``
    per sampled link point."""
    from scipy.optimize import least_squares
    from scipy.sparse import csr_matrix

    opt = options or SolverOptions()
    lo, hi = problem.bounds
    wx = row_weights(problem)
    act = problem.active_rows
    p, K, nf = problem.p, problem.K, problem.n_free_joints
    rows_idx = np.flatnonzero(act.ravel())
    cols = np.empty((K, 6, p + nf), dtype=np.int64)
    cols[:, :, :p] = np.arange(p)
    cols[:, :, p:] = p + np.arange(K)[:, None, None] * nf + np.arange(nf)
    cols_flat = cols.reshape(K * 6, p + nf)[rows_idx]
    rr = np.repeat(np.arange(rows_idx.size), p + nf)

    def blocks(z: Array) -> tuple[Evaluation, Array]:
        ev = problem.evaluate(np.clip(z, lo, hi))
        return ev, -(ev.e * wx).ravel()[rows_idx]

    def ws_terms(z: Array) -> tuple[Array, Array, NDArray[np.int64]]:
        if workspace is None:
            return np.zeros(0), np.zeros((0, p + nf)), np.zeros(0, int)
        pts, Jd, Jq, owner = link_points(problem, np.clip(z, lo, hi), opt.samples_per_link)
        flat = pts.reshape(-1, 3)
        sd = workspace.signed_distance(flat)
        pen = np.maximum(0.0, opt.workspace_margin - sd)
        g = workspace.gradient(flat)
        Jall = np.concatenate([Jd.reshape(-1, 3, p), Jq.reshape(-1, 3, nf)], axis=2)
        # d pen / dz = −gᵀ J where violated, 0 otherwise
        dpen = -np.einsum("ki,kia->ka", g, Jall) * (pen > 0)[:, None]
        return pen, dpen, owner.reshape(-1)

    def fun(z: Array) -> Array:
        _, r = blocks(z)
        pen, _, _ = ws_terms(z)
        return np.concatenate([r, pen])

    def jac(z: Array) -> csr_matrix:
        ev, _ = blocks(z)
        D = (ev.D * wx[:, :, None]).reshape(K * 6, p)[rows_idx]
        J = (ev.J * wx[:, :, None]).reshape(K * 6, nf)[rows_idx]
        vals = np.concatenate([D, J], axis=1).ravel()
        m = rows_idx.size
        pen, dpen, owner = ws_terms(z)
        if pen.size:
            wcols = np.empty((pen.size, p + nf), dtype=np.int64)
            wcols[:, :p] = np.arange(p)
            wcols[:, p:] = p + owner[:, None] * nf + np.arange(nf)
            r2 = m + np.repeat(np.arange(pen.size), p + nf)
            data = np.concatenate([vals, dpen.ravel()])
            ri = np.concatenate([rr, r2])
            ci = np.concatenate([cols_flat.ravel(), wcols.ravel()])
            return csr_matrix((data, (ri, ci)), shape=(m + pen.size, problem.size))
        return csr_matrix((vals, (rr, cols_flat.ravel())), shape=(m, problem.size))

    z_init = np.clip(z0, lo, hi)
    # least_squares needs strictly feasible starts and lo < hi
    span = hi - lo
    fixed = span <= 0
    lo_s = np.where(fixed, lo - 1e-12, lo)
    hi_s = np.where(fixed, hi + 1e-12, hi)
    res = least_squares(
        fun, z_init, jac=jac, bounds=(lo_s, hi_s), method="trf", tr_solver="lsmr",
        x_scale="jac", max_nfev=max_nfev or 200, xtol=1e-12, ftol=1e-12, gtol=1e-12,
    )  # fmt: skip
    z = np.clip(res.x, lo, hi)
    ev = problem.evaluate(z)
    done = converged(problem, ev) and _workspace_clear(problem, z, workspace, opt)
    return SolveOutcome(z, ev, int(res.nfev), done, [float(res.cost)])
