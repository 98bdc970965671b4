"""Improving a reaching design in the null space of the task (P-I §3.2, Eq. 23–25, 32).

P-I keeps constraints satisfied by "internal motions": a secondary velocity projected
into the null space of the task Jacobian, ``(I − Φ⁺Φ) ζ̇₀``, changes the decision vector
without changing the task poses to first order (Eq. 23–24); the thesis uses it for the
parameter bounds (Eq. 25–26) and the tunnel walls (Eq. 31–32). Here the same mechanism
improves the design once every pose is reached: the secondary motion is the steepest
descent of a weighted objective (``objectives``), and the stacked task Jacobian ``Φ``
couples each design change with the joint motion of every task point that compensates
it. One iteration:

1. gradient ``g`` of the objective plus a barrier that keeps every sampled link point
   ``workspace_margin`` inside the workspace (the tunnel), where it is closer;
2. scaled, bound-aware direction ``Δz = −W (I − Φ_w⁺ Φ_w) W g``, ``Φ_w = Φ W`` with ``W`` the
   variables' ranges and 0 for a variable at a bound that ``g`` pushes outward
   (P-II Eq. 25–28; the projection is the block-sparse one of ``linalg``, linear in K);
3. a trial ``z + α Δz`` (``α`` from a trust radius on the scaled step), projected into the
   bounds, then restored onto the reaching set by Gauss–Newton steps (the bounded DLS
   step of ``active_set`` with ``λ → 0``): the null-space step leaves a second-order
   residual only;
4. the trial is accepted only if every pose is within tolerance (position and
   orientation), every link point is inside the workspace, every kept index
   (``Objective.keep``, ``keep``) is at least as good as at the start and the objective
   decreased; the radius then grows, otherwise it shrinks.

So every accepted iterate reaches every pose: the result is never worse than the
reach-only design it started from, and never worse in a kept index. The loop ends when
the radius or the relative decrease over ``window`` accepted steps falls below its
tolerance.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from reachwise.synthesis.active_set import VariableBox, bounded_step
from reachwise.synthesis.clearance import ClearanceModel
from reachwise.synthesis.clearance_rows import clearance_barrier
from reachwise.synthesis.keep import keep_barrier, kept_floors
from reachwise.synthesis.linalg import BlockSystem, null_space_project, weighted
from reachwise.synthesis.objectives import OBJECTIVES, Objective, Terms, size_columns
from reachwise.synthesis.problem import Evaluation, SynthesisProblem
from reachwise.synthesis.solvers import Workspace, converged, row_weights
from reachwise.synthesis.workspace_points import link_points

Array = NDArray[np.float64]


@dataclass(frozen=True)
class ImproveOptions:
    """Tuning of the null-space improvement (step sizes are fractions of each variable's
    range; ``restore_tolerance`` is a fraction of the task tolerances)."""

    max_iter: int = 500
    radius: float = 0.02
    max_radius: float = 0.2
    min_radius: float = 1e-4
    window: int = 8
    tolerance: float = 1e-4
    restore_iter: int = 6
    restore_tolerance: float = 1e-3
    workspace_margin: float = 0.1
    workspace_weight: float = 1.0
    samples_per_link: int = 4
    active_band: float = 1e-3
    max_passes: int = 60
    keep_weight: float = 1.0


@dataclass(frozen=True)
class ImproveOutcome:
    """The improved vector, its evaluation, the objective's terms at the start and the end,
    how many steps were tried and accepted, and the kept indices' values at the start
    (``floors``, ``keep``)."""

    z: Array
    evaluation: Evaluation
    start: Terms
    final: Terms
    objective: Objective
    iterations: int
    accepted: int
    cost_history: list[float] = field(default_factory=list)
    floors: dict[str, float] = field(default_factory=dict)


def _spans(problem: SynthesisProblem) -> Array:
    lo, hi = problem.bounds
    return np.asarray(np.maximum(hi - lo, 0.0))


def _wall(
    problem: SynthesisProblem, z: Array, ws: Workspace | None, opt: ImproveOptions
) -> tuple[float, Array, bool]:
    """Barrier ``Σ max(0, m − d)² / m²`` over link points, its gradient, and whether
    every link point is inside the workspace (``d >= 0``)."""
    g = np.zeros(problem.size)
    if ws is None:
        return 0.0, g, True
    pts, Jd, Jq, owner = link_points(problem, z, opt.samples_per_link)
    flat = pts.reshape(-1, 3)
    sd = ws.signed_distance(flat)
    inside = bool(np.all(sd >= 0.0))
    m = opt.workspace_margin
    near = np.flatnonzero(sd < m)
    if near.size == 0 or opt.workspace_weight <= 0:
        return 0.0, g, inside
    depth = m - sd[near]
    value = opt.workspace_weight * float(np.sum(depth * depth)) / (m * m)
    n = ws.gradient(flat[near])  # (k, 3): increasing signed distance
    c = (-2.0 * opt.workspace_weight / (m * m)) * depth[:, None] * n  # d value / d point
    p, nf = problem.p, problem.n_free_joints
    g[:p] = np.einsum("kia,ki->a", Jd.reshape(-1, 3, p)[near], c)
    gq = np.zeros((problem.K, nf))
    np.add.at(gq, owner.reshape(-1)[near], np.einsum("kia,ki->ka", Jq.reshape(-1, 3, nf)[near], c))
    g[p:] = gq.ravel()
    return value, g, inside


def _walls(
    problem: SynthesisProblem,
    z: Array,
    ws: Workspace | None,
    opt: ImproveOptions,
    clearance: ClearanceModel | None,
) -> tuple[float, Array, bool]:
    """The tunnel wall's barrier (``_wall``) plus, with ``clearance``, the bodies'."""
    value, g, ok = _wall(problem, z, ws, opt)
    if clearance is None:
        return value, g, ok
    v2, g2, ok2 = clearance_barrier(problem, z, clearance)
    return value + opt.workspace_weight * v2, g + opt.workspace_weight * g2, ok and ok2


def _reached(problem: SynthesisProblem, ev: Evaluation, fraction: float = 1.0) -> bool:
    task = problem.task
    pos = ev.position_error <= fraction * task.tol_position
    ori = (ev.orientation_error <= fraction * task.tol_orientation) | (task.dims == 3)
    return bool(pos.all() and ori.all())


def _worst(problem: SynthesisProblem, ev: Evaluation) -> float:
    """The largest error over the task in units of its tolerance."""
    task = problem.task
    ori = np.where(task.dims == 3, 0.0, ev.orientation_error / task.tol_orientation)
    return float(max(np.max(ev.position_error / task.tol_position), np.max(ori)))


def restore(
    problem: SynthesisProblem, z: Array, iterations: int = 6, fraction: float = 0.25
) -> tuple[Array, Evaluation]:
    """Gauss–Newton steps (bounded DLS, ``λ → 0``) from ``z`` until every pose is within
    ``fraction`` of its tolerance (or ``iterations`` are spent). The joints alone are
    moved first — the design stays what the improvement chose — and the design too
    only if the joints cannot restore the poses. Returns the last iterate."""
    lo, hi = problem.bounds
    p, K, nf = problem.p, problem.K, problem.n_free_joints
    wx = row_weights(problem)
    span = _spans(problem)
    ev = problem.evaluate(z)
    joints_only = iterations
    worst = np.inf
    for i in range(2 * iterations):
        if _reached(problem, ev, fraction):
            break
        now = _worst(problem, ev)
        if i < joints_only and now > 0.5 * worst:
            joints_only = i  # the joints alone stall (one at a limit): move the design too
        worst = now
        D, J = ev.D * wx[:, :, None], ev.J * wx[:, :, None]
        if i < joints_only:
            D = np.zeros_like(D)
        bs = bounded_step(
            D, J, problem.active_rows, ev.e * wx, 1e-12,
            VariableBox(
                (z[:p], z[p:].reshape(K, nf)), (lo[:p], lo[p:].reshape(K, nf)),
                (hi[:p], hi[p:].reshape(K, nf)), (span[:p], span[p:].reshape(K, nf)),
            ),
        )  # fmt: skip
        z = np.clip(z + np.concatenate([bs.design, bs.joints.ravel()]), lo, hi)
        ev = problem.evaluate(z)
    return z, ev


def _kinks(
    problem: SynthesisProblem, obj: Objective, terms: Terms, z: Array, g: Array, near: Array
) -> tuple[Array, Array, Array]:
    """The ``size`` term's kinks: ``|a|`` and ``|d|`` at 0 (orthant-wise, as OWL-QN does
    for an L1 term; Andrew & Gao 2007).

    Minimizing Σ|a| + Σ|d| drives lengths to exactly 0, where ``|x|`` has a kink (its
    smoothing ``abs_smoothing`` has curvature 1e4 there): a step that crosses 0 raises
    the cost while the gradient promised a decrease, so every step fails and the
    improvement stops — this is what stalled the ε-constraint points of the (gci, size)
    front. Here 0 acts as a bound on the side of the length's sign (the ratio test stops
    a step there), and a length within ``near`` of 0 moves only if the rest of the
    cost's gradient beats the size term's slope ``c`` (its subgradient is ``[−c, c]``),
    in the direction it wins, with gradient ``g_rest ± c``; otherwise it stays.
    Returns the gradient and the effective lower and upper bounds."""
    lo, hi = problem.bounds
    c = obj.slopes(terms).get("size", 0.0)
    if c <= 0:
        return g, lo, hi
    g, lo_e, hi_e = g.copy(), lo.copy(), hi.copy()
    for i in size_columns(problem):
        if not lo[i] < 0 < hi[i]:
            continue  # a length that cannot change sign has no kink inside its range
        if z[i] > near[i]:
            lo_e[i] = 0.0
        elif z[i] < -near[i]:
            hi_e[i] = 0.0
        else:
            rest = g[i] - c * terms.gradients["size"][i]
            if rest < -c:  # the descent raises it
                g[i], lo_e[i] = rest + c, z[i]
            elif rest > c:  # the descent lowers it
                g[i], hi_e[i] = rest - c, z[i]
            else:  # the kink holds it
                g[i], lo_e[i], hi_e[i] = rest, z[i], z[i]
    return g, lo_e, hi_e


def _project(sysn: BlockSystem, w: Array, v: Array, p: int, active: NDArray[np.bool_]) -> Array:
    """``(I − Φ_w⁺ Φ_w) v`` (``sysn`` factorizes ``Φ_w``), 0 on fixed variables (``w = 0``)."""
    K, nf = active.shape[0], (v.size - p) // active.shape[0]
    vd, vq = null_space_project(sysn, v[:p], v[p:].reshape(K, nf), active)
    return np.concatenate([vd, vq.ravel()]) * (w > 0)


def _reduced_gradient(
    sysn: BlockSystem, Df: Array, Jf: Array, w: Array, g: Array, scale: Array,
    active: NDArray[np.bool_],
) -> Array:  # fmt: skip
    """``G − Φ_sᵀ μ`` in scaled coordinates (``G = s ∘ g``, ``Φ_s = Φ diag(s)``, blocks
    ``Df``, ``Jf``) with the task multipliers ``μ = (Φ_w Φ_wᵀ)⁻¹ Φ_w (w ∘ g)`` of the
    free variables (``sysn`` factorizes ``Φ_w``): on a free variable the projected
    gradient, on a fixed one the multiplier of its bound. A variable at its lower bound
    with ``r < 0`` (upper: ``r > 0``) would lower the cost by moving inside, with the
    free variables compensating through the task: a false member of the working set
    (P-II's dynamic weighting fixes it for good; that stalled the Pareto sweep)."""
    p = Df.shape[2]
    K, nf = Jf.shape[0], Jf.shape[2]
    G = w * g
    mu = sysn.solve(np.where(active, sysn.apply(G[:p], G[p:].reshape(K, nf)), 0.0))
    rd = np.einsum("kia,ki->a", Df, mu)
    rq = np.einsum("kia,ki->ka", Jf, mu)
    return np.asarray(scale * g - np.concatenate([rd, rq.ravel()]))


def _two_loop(g: Array, pairs: list[tuple[Array, Array]]) -> Array:
    """L-BFGS: ``H g`` from the stored ``(s, y)`` pairs (Nocedal & Wright, Alg. 7.4)."""
    q = g.copy()
    alphas = []
    for s, y in reversed(pairs):
        a = float(s @ q) / float(y @ s)
        alphas.append(a)
        q -= a * y
    if pairs:
        s, y = pairs[-1]
        q *= float(s @ y) / float(y @ y)
    for (s, y), a in zip(pairs, reversed(alphas), strict=True):
        b = float(y @ q) / float(y @ s)
        q += (a - b) * s
    return q


def improve(
    problem: SynthesisProblem,
    z0: Array,
    objective: Objective,
    workspace: Workspace | None = None,
    options: ImproveOptions | None = None,
    clearance: ClearanceModel | None = None,
) -> ImproveOutcome:
    """Lower ``objective`` from the reaching vector ``z0`` while every pose stays reached
    (module docstring). ``objective`` without reference magnitudes is referenced to
    ``z0``. If ``z0`` does not reach every pose it is returned unchanged. With
    ``clearance`` every accepted iterate keeps every clearance term, and a barrier on
    the terms near it joins the tunnel wall's (``clearance`` is also the model of the
    ``clearance`` objective when ``objective`` has none). Every index in
    ``objective.keep`` stays at least as good as at ``z0`` (``keep``)."""
    opt = options or ImproveOptions()
    if clearance is not None and objective.bodies is None:
        objective = replace(objective, bodies=clearance)
    bodies = objective.bodies
    lo, hi = problem.bounds
    p, K, nf = problem.p, problem.K, problem.n_free_joints
    span = _spans(problem)
    # coordinates x = z / scale: each variable in units of its range; a posture's joints
    # weigh sqrt(K) more, since each posture carries 1/K of a mean over the task
    scale = np.where(span > 0, span, 1.0)
    scale[p:] *= np.sqrt(K)
    z = np.clip(np.asarray(z0, dtype=np.float64), lo, hi)
    ev = problem.evaluate(z)
    margin = objective.margin
    floors = kept_floors(problem, z, objective.keep, bodies, margin)

    def barriers(x: Array) -> tuple[float, Array, bool]:
        """The walls' barriers and the kept indices', and whether ``x`` keeps all."""
        value, g, ok = _walls(problem, x, workspace, opt, clearance)
        if not floors or opt.keep_weight <= 0:
            return value, g, ok and kept_floors_hold(x)
        v2, g2, ok2 = keep_barrier(problem, x, floors, bodies, margin)
        return value + opt.keep_weight * v2, g + opt.keep_weight * g2, ok and ok2

    def kept_floors_hold(x: Array) -> bool:
        now = kept_floors(problem, x, objective.keep, bodies, margin)
        return all(OBJECTIVES[n] * (now[n] - f) >= 0 for n, f in floors.items())

    if converged(problem, ev):  # every iterate from here on lies well inside the tolerance
        z1, ev1 = restore(problem, z, opt.restore_iter, opt.restore_tolerance)
        if converged(problem, ev1) and barriers(z1)[2]:  # restoring may cost clearance
            z, ev = z1, ev1
    start = objective.terms(problem, z)
    obj = objective if objective.reference else objective.referenced(start)
    terms = start
    wall, gwall, inside = barriers(z)
    if not (converged(problem, ev) and inside):
        return ImproveOutcome(z, ev, start, start, obj, 0, 0, [], floors)
    cost = obj.cost(terms) + wall
    history = [cost]
    wx = row_weights(problem)
    active = problem.active_rows
    pairs: list[tuple[Array, Array]] = []
    last: tuple[Array, Array] | None = None  # (x, reduced gradient) of the last iterate
    radius = opt.radius
    accepted = 0
    it = 0
    Dx, Jx = ev.D * wx[:, :, None], ev.J * wx[:, :, None]
    while it < opt.max_iter:
        it += 1
        g = obj.gradient(terms) + gwall
        x = z / scale
        near = opt.active_band * span  # this close to a bound counts as at it
        g, lo_e, hi_e = _kinks(problem, obj, terms, z, g, near)
        lo_z, hi_z = z <= lo_e + near, z >= hi_e - near
        # a variable at a bound that the descent −g pushes outward stays (weight 0)
        w = scale * ~((lo_z & (g > 0)) | (hi_z & (g < 0)))
        D, J = weighted(Dx, Jx, w[:p], w[p:].reshape(K, nf))
        gx = _project(BlockSystem.build(D, J, active, 1e-12), w, w * g, p, active)
        if last is not None:  # the curvature pair of the last accepted step
            s_, y_ = x - last[0], gx - last[1]
            if float(s_ @ y_) > 1e-10 * float(np.linalg.norm(s_) * np.linalg.norm(y_)):
                pairs = [*pairs[-7:], (s_, y_)]
        # the working set: a fixed variable whose multiplier has the wrong sign is
        # released (once per iteration), a free one that the step drives out is fixed
        movable = (span > 0) & (lo_e < hi_e)  # not a fixed parameter, not held at a kink
        released = np.zeros(problem.size, dtype=np.bool_)
        Df, Jf = weighted(Dx, Jx, scale[:p], scale[p:].reshape(K, nf))
        for _ in range(opt.max_passes):  # each pass fixes or releases variables
            D, J = weighted(Dx, Jx, w[:p], w[p:].reshape(K, nf))
            sysn = BlockSystem.build(D, J, active, 1e-12)
            gw = _project(sysn, w, w * g, p, active)
            d = _project(sysn, w, -_two_loop(gw, pairs), p, active)
            if float(gw @ d) >= 0:  # not a descent direction: steepest descent
                d, pairs = -gw, []
            step = w * d
            out = (lo_z & (step < 0)) | (hi_z & (step > 0))
            if out.any():
                w = np.where(out, 0.0, w)  # coupling through Φ pushes it out: fix it too
                continue
            r = _reduced_gradient(sysn, Df, Jf, w, g, scale, active)
            wrong = (w == 0) & movable & ~released & ((lo_z & (r < 0)) | (hi_z & (r > 0)))
            if not wrong.any():
                break
            w = np.where(wrong, scale, w)
            released |= wrong
        last = (x, gx)
        biggest = float(np.max(np.abs(d)))
        if biggest <= 0 or not np.isfinite(biggest):
            break
        alpha = 1.0 if pairs else radius / biggest
        alpha = min(alpha, opt.max_radius / biggest)
        # projected search: steps that carry variables past their bounds are clipped
        # there (the restoration repairs the task); halving down to the ratio test's
        # step, where the first free variable meets its bound, and below. With ~K·n_f
        # joints near their limits, stopping at the first bound (one new bound per
        # iteration) made the steps vanishingly short and ended the improvement early.
        with np.errstate(divide="ignore", invalid="ignore"):
            room = np.where(
                step < 0, (lo_e - z) / step, np.where(step > 0, (hi_e - z) / step, np.inf)
            )
        first = min(alpha, float(np.min(np.maximum(room, 0.0))))
        trials = []
        while alpha > first and alpha * biggest >= opt.min_radius:
            trials.append(alpha)
            alpha *= 0.5
        alpha = first
        while alpha * biggest >= opt.min_radius:
            trials.append(alpha)
            alpha *= 0.5
        ok = False
        for alpha in trials:
            z_try, ev_try = restore(
                problem, np.clip(z + alpha * step, lo_e, hi_e), opt.restore_iter,
                opt.restore_tolerance,
            )  # fmt: skip
            if converged(problem, ev_try):
                t_try = obj.terms(problem, z_try)
                w_try, gw_try, in_try = barriers(z_try)
                c_try = obj.cost(t_try) + w_try
                if in_try and c_try < cost:
                    ok = True
                    break
        if not ok:
            if not pairs:
                break
            pairs, last = [], None  # retry along the steepest descent
            continue
        radius = min(2.0 * alpha * biggest, opt.max_radius)
        z, ev, terms, cost, gwall = z_try, ev_try, t_try, c_try, gw_try
        Dx, Jx = ev.D * wx[:, :, None], ev.J * wx[:, :, None]
        accepted += 1
        history.append(cost)
        if len(history) > opt.window:
            ref = history[-1 - opt.window]
            if ref - cost <= opt.tolerance * max(abs(ref), 1.0):
                break
    return ImproveOutcome(z, ev, start, terms, obj, it, accepted, history, floors)
