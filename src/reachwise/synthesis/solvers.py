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
- stopping: a run ends when every pose is reached and clear (converged); or at a
  constrained stationary point of the merit: a window of ``reseed_every`` iterations,
  its re-seeding included, lowered the merit by less than ``stationary_decrease``
  (relative) and the projected gradient of the merit ``½‖e‖²``, ``Φᵀe`` on the free
  variables (a variable at a bound that the descent pushes outward counts as fixed), is
  at most ``stationary_gradient · ‖e‖`` in every component: the first-order conditions
  of the bounded least squares hold, with multipliers of the right sign, so no small
  step lowers the merit and the re-seeding did not find another branch; or after
  ``stall_iterations`` without a real decrease (1e-4 relative), or ``max_iter``. The
  stationary test applies to runs with clearance terms (``stationary_without_clearance``
  extends it to every run): there the merit balances reach rows against clearance rows,
  and a run that cannot serve every pose (tunnel-87 at 0.1 m) reaches its final merit
  within 1e-3 by iteration ~60–100. A reach-only run's nonzero stationary merit is
  more often a wrong branch of some poses that a later re-seeding escapes: a topology
  run of the sweep tests met the test at iteration 300 and converged at 452.

Why runs stalled before (tunnel-87 seeds 4, 8, 9; issue "Design that optimizes"): a
working set of the bounds built from the step's sign alone, which creates false
stationary points (``active_set``); a single step ratio for all task points, so one
point's large joint step shrank every step (and the iteration count grew with the
number of points); and, near the tunnel walls, a wall motion that raised the cost made
every step fail while the unbounded boost damped the task step to nothing.

The pieces live in their own modules: the options, outcome and row weights
(``solver_options``), the workspace motion (``workspace_motion``) and the re-seeding
(``reseed``). ``trf`` (``trf.solve_trf``) — ``scipy.optimize.least_squares``
(trust-region reflective) with bounds, the exact sparse Jacobian and the same workspace
penalty as extra residuals: the baseline.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from reachwise.kinematics.dls import damping_squared
from reachwise.synthesis.active_set import BoundedStep, VariableBox, bounded_step
from reachwise.synthesis.clearance import ClearanceModel
from reachwise.synthesis.clearance_rows import Rows, clearance_motion, merit, stacked_rows
from reachwise.synthesis.linalg import (
    BlockSystem,
    null_space_project,
    smallest_singular_value,
    weighted,
)
from reachwise.synthesis.problem import Evaluation, SynthesisProblem
from reachwise.synthesis.reseed import keep_clearer, reseed_points
from reachwise.synthesis.solver_options import (
    SolveOutcome,
    SolverOptions,
    Workspace,
    converged,
    row_weights,
)
from reachwise.synthesis.trf import solve_trf
from reachwise.synthesis.workspace_motion import workspace_clear, workspace_motion

__all__ = [
    "SolveOutcome",
    "SolverOptions",
    "Workspace",
    "converged",
    "projected_gradient",
    "reseed_points",
    "row_weights",
    "solve_dls",
    "solve_trf",
]

Array = NDArray[np.float64]

#: A trial step whose merit is at most this much higher (relative) is taken: the merit
#: counts as flat there.
FLAT_MERIT = 1e-6


def _max_steps(problem: SynthesisProblem) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """Per-variable step caps: angles ``max_step_angle``, lengths ``max_step_length``."""
    tpl = problem.template
    angle_d = np.array(
        [p in ("alpha", "theta", "roll", "pitch", "yaw") for _, _, p in tpl.design.free]
    )
    return angle_d, tpl.prismatic[problem.free_joints]


@dataclass(frozen=True)
class _Iterate:
    """The solver's current point: vector, evaluation, rows and merit ``½‖e‖²``."""

    z: Array
    ev: Evaluation
    rows: Rows
    cost: float


@dataclass(frozen=True)
class _Trial:
    """The outcome of a line search: the point (None when no step lowered the merit),
    its evaluation, the merit of the last step tried (of a rejected one, possibly only
    its task rows' share, already too high: ``clearance_rows.merit``) and that step's
    length."""

    z: Array | None
    ev: Evaluation | None
    cost: float
    alpha: float


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
    wx = row_weights(problem)
    caps = _step_caps(problem, opt)
    c_min = clearance.clearance if clearance is not None else 0.0
    cur = _iterate(problem, np.clip(z0, lo, hi), wx, clearance)
    history = [cur.cost]
    boost = 0.0
    best_cost, since_best = cur.cost, 0
    release = False  # stalled on the working set of the bounds: check the multipliers
    window_start = cur.cost  # merit when the current re-seeding window began
    it = 0
    for it in range(1, opt.max_iter + 1):
        if _done(problem, cur.ev, cur.rows, c_min, cur.z, workspace, opt):
            return SolveOutcome(cur.z, cur.ev, it - 1, True, history)
        lam2 = _damping(problem, cur, opt) + boost
        bs = _bounded_task_step(problem, cur, lam2, caps, release)
        steps = _candidate_steps(problem, cur, bs, workspace, c_min, opt)
        trial = _line_search(problem, cur, steps, caps, wx, clearance)
        release = trial.z is None or trial.cost > cur.cost * (1 - opt.stall_decrease)
        if trial.z is not None:
            cur = replace(_iterate(problem, trial.z, wx, clearance, trial.ev), cost=trial.cost)
            boost = boost / 4.0 if trial.alpha == 1.0 else boost
        else:
            boost = min(max(4.0 * boost, 1e-6), opt.max_boost)
        history.append(cur.cost)
        if cur.cost < best_cost * (1 - 1e-4):
            best_cost, since_best = cur.cost, 0
        else:
            since_best += 1
            if since_best >= opt.stall_iterations:
                break
        if opt.reseed_every and it % opt.reseed_every == 0:
            # re-seed only when the window made little progress (a trapped branch), not
            # while the iteration converges on its own
            if cur.cost > (1.0 - opt.reseed_progress) * window_start:
                new = _reseeded(problem, cur, rng, opt, wx, clearance)
                if new is not None:
                    if new.cost < cur.cost * (1 - 1e-4):  # a real improvement restarts
                        best_cost, since_best = new.cost, 0  # the stall count
                    cur = new
            stationary_ok = clearance is not None or opt.stationary_without_clearance
            if stationary_ok and _stationary(problem, cur, window_start, opt):
                break
            window_start = cur.cost
    done = _done(problem, cur.ev, cur.rows, c_min, cur.z, workspace, opt)
    return SolveOutcome(cur.z, cur.ev, it, done, history)


@dataclass(frozen=True)
class _StepCaps:
    """Step caps (``max_step_angle`` / ``max_step_length``) of the design variables
    ``(p,)`` and of each task point's joints ``(K, n_f)``, and both as one vector."""

    design: Array
    joints: Array
    flat: Array


def _step_caps(problem: SynthesisProblem, opt: SolverOptions) -> _StepCaps:
    angle_d, pris_q = _max_steps(problem)
    cap_d = np.where(angle_d, opt.max_step_angle, opt.max_step_length)
    cap_q = np.tile(np.where(pris_q, opt.max_step_length, opt.max_step_angle), (problem.K, 1))
    return _StepCaps(cap_d, cap_q, np.concatenate([cap_d, cap_q.ravel()]))


def _iterate(
    problem: SynthesisProblem,
    z: Array,
    wx: Array,
    clearance: ClearanceModel | None,
    ev: Evaluation | None = None,
) -> _Iterate:
    """The point ``z`` with its rows (gradients of the clearance terms included)."""
    ev = problem.evaluate(z) if ev is None else ev
    rows = stacked_rows(problem, ev, wx, z, clearance)
    return _Iterate(z, ev, rows, rows.cost)


def _damping(problem: SynthesisProblem, cur: _Iterate, opt: SolverOptions) -> float:
    """``λ²`` of the P-I Eq. 14 schedule on σ_min of the stacked Jacobian, faded with
    the residual like the IK (quadratic final convergence)."""
    rows = cur.rows
    Dw, Jw = weighted(
        rows.D, rows.J, np.ones(problem.p), np.ones((problem.K, problem.n_free_joints))
    )
    smin = smallest_singular_value(
        BlockSystem.build(Dw, Jw, rows.active, 1e-12), rows.active, 1e-12
    )
    lam2 = damping_squared(smin, opt.epsilon, opt.lambda_max)
    return float(lam2 * min(1.0, np.sqrt(2 * cur.cost) / opt.err_ref) ** 2)


def _bounded_task_step(
    problem: SynthesisProblem, cur: _Iterate, lam2: float, caps: _StepCaps, release: bool
) -> BoundedStep:
    """The task's DLS step with the working set of the bounds (``active_set``)."""
    p, K, nf = problem.p, problem.K, problem.n_free_joints
    lo, hi = problem.bounds
    rows, z = cur.rows, cur.z
    return bounded_step(
        rows.D, rows.J, rows.active, rows.e, lam2,
        VariableBox(
            (z[:p], z[p:].reshape(K, nf)),
            (lo[:p], lo[p:].reshape(K, nf)),
            (hi[:p], hi[p:].reshape(K, nf)),
            (caps.design, caps.joints),
        ),
        release,
    )  # fmt: skip


def _candidate_steps(
    problem: SynthesisProblem,
    cur: _Iterate,
    bs: BoundedStep,
    workspace: Workspace | None,
    c_min: float,
    opt: SolverOptions,
) -> list[Array]:
    """The steps to try, in order: the task step plus the null-space motion away from
    the workspace boundary and the bodies (P-II Eq. 29–33) when any is near, then the
    task step alone."""
    wd, wq = bs.weight_design, bs.weight_joints
    task_step = np.concatenate([bs.design, bs.joints.ravel()])
    nd, nq = (None, None) if workspace is None else workspace_motion(problem, cur.z, workspace, opt)
    if cur.rows.terms is not None:
        push = clearance_motion(cur.rows.terms, c_min, opt.workspace_gain)
        if push is not None:
            nd = push[0] if nd is None else nd + push[0]
            nq = push[1] if nq is None else nq + push[1]
    if nd is None or nq is None:
        return [task_step]
    rows = cur.rows
    Dw, Jw = weighted(rows.D, rows.J, wd, wq)
    sysn = BlockSystem.build(Dw, Jw, rows.active, 1e-12)
    pd, pq = null_space_project(sysn, wd * nd, wq * nq, rows.active)
    return [task_step + np.concatenate([wd * pd, (wq * pq).ravel()]), task_step]


def _line_search(
    problem: SynthesisProblem,
    cur: _Iterate,
    steps: list[Array],
    caps: _StepCaps,
    wx: Array,
    clearance: ClearanceModel | None,
) -> _Trial:
    """The first of ``steps`` (capped per block, then halved up to four times) that
    does not raise the merit beyond ``1e-6`` relative (``FLAT_MERIT``): a step across a
    flat merit is taken, so the iteration moves on and the stall rule, not the line
    search, decides when it has stopped progressing (a step that lowers the merit by
    less than ``stall_decrease`` releases the bounds). The merit of a trial is computed
    from the distances alone, and not even those when its task rows alone already
    raise it too far (``clearance_rows.merit``)."""
    lo, hi = problem.bounds
    c_try, alpha = cur.cost, 1.0
    limit = cur.cost * (1.0 + FLAT_MERIT) + 1e-12
    for raw in steps:
        step, _ = _capped(raw, caps.flat, problem.p, problem.K, problem.n_free_joints)
        alpha = 1.0
        for _ in range(5):
            z_try = np.clip(cur.z + alpha * step, lo, hi)
            ev_try = problem.evaluate(z_try)
            c_try = merit(problem, ev_try, wx, z_try, clearance, limit=limit)
            if c_try <= limit:
                return _Trial(z_try, ev_try, c_try, alpha)
            alpha *= 0.5
    return _Trial(None, None, c_try, alpha)


def _reseeded(
    problem: SynthesisProblem,
    cur: _Iterate,
    rng: np.random.Generator,
    opt: SolverOptions,
    wx: Array,
    clearance: ClearanceModel | None,
) -> _Iterate | None:
    """The point with the unreached poses' joints re-solved by IK (``reseed_points``),
    with the clearance only where they lower their pose's merit; None if none moved."""
    z2 = reseed_points(problem, cur.z, cur.ev, rng, opt.reseed_restarts)
    if z2 is not None and clearance is not None:
        z2 = keep_clearer(problem, cur.z, cur.ev, z2, wx, clearance)
    return None if z2 is None else _iterate(problem, z2, wx, clearance)


def projected_gradient(problem: SynthesisProblem, z: Array, rows: Rows) -> Array:
    """The gradient ``−Φᵀe`` of the merit ``½‖e‖²`` (``rows``: the weighted rows at ``z``)
    projected on the bounds: 0 for a fixed variable and for one at a bound that the
    descent ``Φᵀe`` pushes outward. Its norm is 0 exactly at a first-order stationary
    point of the bounded problem (the KKT conditions, multipliers of the right sign)."""
    e = np.where(rows.active, rows.e, 0.0)
    g = -np.concatenate(
        [np.einsum("kra,kr->a", rows.D, e), np.einsum("kra,kr->ka", rows.J, e).ravel()]
    )
    lo, hi = problem.bounds
    blocked = ((z <= lo) & (g > 0)) | ((z >= hi) & (g < 0)) | (hi <= lo)
    return np.asarray(np.where(blocked, 0.0, g))


def _stationary(
    problem: SynthesisProblem, cur: _Iterate, window_start: float, opt: SolverOptions
) -> bool:
    """The window since ``window_start`` (re-seeding included) lowered the merit by less
    than ``stationary_decrease`` and the projected gradient is at most
    ``stationary_gradient · ‖e‖`` (module docstring: stopping)."""
    if cur.cost <= (1.0 - opt.stationary_decrease) * window_start:
        return False
    g = projected_gradient(problem, cur.z, cur.rows)
    return float(np.max(np.abs(g), initial=0.0)) <= opt.stationary_gradient * np.sqrt(
        2.0 * cur.cost
    )


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
        and workspace_clear(problem, z, workspace, opt)
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
