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

So every accepted iterate reaches every pose and is never worse in a kept index. The
loop ends when the radius or the relative decrease over ``window`` accepted steps falls
below its tolerance. The first iterate is the start restored to a fraction of the task
tolerance (``restore``), so that every trial lies well inside it; that restoration
moves the design too when the joints alone cannot restore the poses, and may cost
objective (on the SB60 family a size-minimal design restored 0.27 % larger, and the
steps won back only 0.06 %). So the result is compared with the start as given, when
that reaches every pose and keeps every guard: the cheaper of the two (objective plus
barriers, the cost the steps lower) is returned, and the result is never worse than
the design it started from (``ImproveOptions.never_worse``).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from reachwise.synthesis.clearance import ClearanceModel
from reachwise.synthesis.clearance_rows import MOTION_BAND, clearance_barrier
from reachwise.synthesis.keep import keep_barrier, kept_floors
from reachwise.synthesis.linalg import BlockSystem, null_space_project, weighted
from reachwise.synthesis.objectives import OBJECTIVES, Objective, Terms, size_columns
from reachwise.synthesis.problem import Evaluation, SynthesisProblem
from reachwise.synthesis.restore import RESTORE_DAMPING, restore, variable_spans
from reachwise.synthesis.solver_options import Workspace, converged, row_weights
from reachwise.synthesis.workspace_points import link_points

__all__ = ["RESTORE_DAMPING", "ImproveOptions", "ImproveOutcome", "improve", "restore"]

Array = NDArray[np.float64]


@dataclass(frozen=True)
class ImproveOptions:
    """Tuning of the null-space improvement (step sizes are fractions of each variable's
    range; ``restore_tolerance`` is a fraction of the task tolerances;
    ``clearance_band`` (m) is how far above the clearance the bodies' barrier acts;
    ``never_worse``: return the start as given when the steps end above its cost — the
    Pareto sweep turns it off, its starts being designs it has found already, for which
    a different design, even a worse one, is one more candidate for the front)."""

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
    clearance_band: float = MOTION_BAND
    never_worse: bool = True


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
    v2, g2, ok2 = clearance_barrier(problem, z, clearance, opt.clearance_band)
    return value + opt.workspace_weight * v2, g + opt.workspace_weight * g2, ok and ok2


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


@dataclass(frozen=True)
class _Guards:
    """What every accepted iterate must keep: the walls' barriers (``_walls``) and the
    kept indices' (``keep``). Called with a vector it returns the barriers' value, their
    gradient and whether the vector keeps them all."""

    problem: SynthesisProblem
    workspace: Workspace | None
    opt: ImproveOptions
    clearance: ClearanceModel | None
    objective: Objective
    floors: dict[str, float]

    def __call__(self, x: Array) -> tuple[float, Array, bool]:
        value, g, ok = _walls(self.problem, x, self.workspace, self.opt, self.clearance)
        if not self.floors or self.opt.keep_weight <= 0:
            return value, g, ok and self._floors_hold(x)
        v2, g2, ok2 = keep_barrier(
            self.problem, x, self.floors, self.objective.bodies, self.objective.margin
        )
        w = self.opt.keep_weight
        return value + w * v2, g + w * g2, ok and ok2

    def _floors_hold(self, x: Array) -> bool:
        obj = self.objective
        now = kept_floors(self.problem, x, obj.keep, obj.bodies, obj.margin)
        return all(OBJECTIVES[n] * (now[n] - f) >= 0 for n, f in self.floors.items())


@dataclass(frozen=True)
class _Context:
    """The improvement's fixed data: the problem, the referenced objective, the options,
    the guards, the variables' ``span`` and ``scale`` (``x = z / scale``) and the rows'
    weights ``wx``."""

    problem: SynthesisProblem
    obj: Objective
    opt: ImproveOptions
    guards: _Guards
    span: Array
    scale: Array
    wx: Array


@dataclass(frozen=True)
class _Direction:
    """One iteration's search direction: ``d`` in scaled coordinates, the step ``w ∘ d``
    in ``z``, the effective bounds (``_kinks``), the projected gradient ``gx`` that
    makes the next curvature pair and the L-BFGS pairs it was built with."""

    d: Array
    step: Array
    lo: Array
    hi: Array
    gx: Array
    pairs: list[tuple[Array, Array]]


def _direction(
    ctx: _Context, z: Array, g: Array, terms: Terms, ev: Evaluation,
    pairs: list[tuple[Array, Array]], last: tuple[Array, Array] | None,
) -> _Direction:  # fmt: skip
    """Step 2 of the module docstring: the scaled, bound-aware L-BFGS direction in the
    null space of the task from the gradient ``g``, with the working set of the bounds
    (a fixed variable whose multiplier has the wrong sign is released once, a free one
    that the step drives out is fixed)."""
    problem, opt, span, scale = ctx.problem, ctx.opt, ctx.span, ctx.scale
    p, K, nf = problem.p, problem.K, problem.n_free_joints
    active = problem.active_rows
    Dx, Jx = ev.D * ctx.wx[:, :, None], ev.J * ctx.wx[:, :, None]
    near = opt.active_band * span  # this close to a bound counts as at it
    g, lo_e, hi_e = _kinks(problem, ctx.obj, terms, z, g, near)
    lo_z, hi_z = z <= lo_e + near, z >= hi_e - near
    # a variable at a bound that the descent −g pushes outward stays (weight 0)
    w = scale * ~((lo_z & (g > 0)) | (hi_z & (g < 0)))
    D, J = weighted(Dx, Jx, w[:p], w[p:].reshape(K, nf))
    gx = _project(BlockSystem.build(D, J, active, 1e-12), w, w * g, p, active)
    if last is not None:  # the curvature pair of the last accepted step
        s_, y_ = z / scale - last[0], gx - last[1]
        if float(s_ @ y_) > 1e-10 * float(np.linalg.norm(s_) * np.linalg.norm(y_)):
            pairs = [*pairs[-7:], (s_, y_)]
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
    return _Direction(d, step, lo_e, hi_e, gx, pairs)


def _step_lengths(z: Array, di: _Direction, alpha: float, min_radius: float) -> list[float]:
    """The projected search's trial lengths along ``di.step``: halving from ``alpha`` down
    to the ratio test's length, where the first free variable meets its bound, and
    below it down to ``min_radius`` (scaled). Steps past a bound are clipped there (the
    restoration repairs the task): with ~K·n_f joints near their limits, stopping at the
    first bound (one new bound per iteration) made the steps vanishingly short and ended
    the improvement early."""
    biggest = float(np.max(np.abs(di.d)))
    step = di.step
    with np.errstate(divide="ignore", invalid="ignore"):
        room = np.where(
            step < 0, (di.lo - z) / step, np.where(step > 0, (di.hi - z) / step, np.inf)
        )
    first = min(alpha, float(np.min(np.maximum(room, 0.0))))
    trials = []
    while alpha > first and alpha * biggest >= min_radius:
        trials.append(alpha)
        alpha *= 0.5
    alpha = first
    while alpha * biggest >= min_radius:
        trials.append(alpha)
        alpha *= 0.5
    return trials


@dataclass(frozen=True)
class _Iterate:
    """An accepted iterate: the vector, its evaluation, the objective's terms, the cost
    (objective plus barriers) and the barriers' gradient."""

    z: Array
    ev: Evaluation
    terms: Terms
    cost: float
    gwall: Array


def _first_descent(
    ctx: _Context, now: _Iterate, di: _Direction, trials: list[float]
) -> tuple[_Iterate, float] | None:
    """Step 3–4 of the module docstring: the first trial length whose restored vector
    reaches every pose, keeps every guard and lowers the cost, with that length."""
    opt = ctx.opt
    for alpha in trials:
        z_try, ev_try = restore(
            ctx.problem, np.clip(now.z + alpha * di.step, di.lo, di.hi), opt.restore_iter,
            opt.restore_tolerance,
        )  # fmt: skip
        if converged(ctx.problem, ev_try):
            t_try = ctx.obj.terms(ctx.problem, z_try)
            w_try, gw_try, in_try = ctx.guards(z_try)
            c_try = ctx.obj.cost(t_try) + w_try
            if in_try and c_try < now.cost:
                return _Iterate(z_try, ev_try, t_try, c_try, gw_try), alpha
    return None


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
    lo, hi = problem.bounds
    span = variable_spans(problem)
    # coordinates x = z / scale: each variable in units of its range; a posture's joints
    # weigh sqrt(K) more, since each posture carries 1/K of a mean over the task
    scale = np.where(span > 0, span, 1.0)
    scale[problem.p :] *= np.sqrt(problem.K)
    z = np.clip(np.asarray(z0, dtype=np.float64), lo, hi)
    ev = problem.evaluate(z)
    floors = kept_floors(problem, z, objective.keep, objective.bodies, objective.margin)
    guards = _Guards(problem, workspace, opt, clearance, objective, floors)
    feasible = opt.never_worse and converged(problem, ev) and guards(z)[2]
    given = (z, ev) if feasible else None  # the start as given, to return if it is better
    if converged(problem, ev):  # every iterate from here on lies well inside the tolerance
        z1, ev1 = restore(problem, z, opt.restore_iter, opt.restore_tolerance)
        if converged(problem, ev1) and guards(z1)[2]:  # restoring may cost clearance
            z, ev = z1, ev1
    start = objective.terms(problem, z)
    obj = objective if objective.reference else objective.referenced(start)
    wall, gwall, inside = guards(z)
    if not (converged(problem, ev) and inside):
        return ImproveOutcome(z, ev, start, start, obj, 0, 0, [], floors)
    ctx = _Context(problem, obj, opt, guards, span, scale, row_weights(problem))
    now = _Iterate(z, ev, start, obj.cost(start) + wall, gwall)
    history = [now.cost]
    pairs: list[tuple[Array, Array]] = []
    last: tuple[Array, Array] | None = None  # (x, reduced gradient) of the last iterate
    radius = opt.radius
    accepted = it = 0
    while it < opt.max_iter:
        it += 1
        g = obj.gradient(now.terms) + now.gwall
        di = _direction(ctx, now.z, g, now.terms, now.ev, pairs, last)
        pairs, last = di.pairs, (now.z / scale, di.gx)
        biggest = float(np.max(np.abs(di.d)))
        if biggest <= 0 or not np.isfinite(biggest):
            break
        alpha = min(1.0 if pairs else radius / biggest, opt.max_radius / biggest)
        found = _first_descent(ctx, now, di, _step_lengths(now.z, di, alpha, opt.min_radius))
        if found is None:
            if not pairs:
                break
            pairs, last = [], None  # retry along the steepest descent
            continue
        now, alpha = found
        radius = min(2.0 * alpha * biggest, opt.max_radius)
        accepted += 1
        history.append(now.cost)
        if len(history) > opt.window:
            ref = history[-1 - opt.window]
            if ref - now.cost <= opt.tolerance * max(abs(ref), 1.0):
                break
    if given is not None and given[0] is not now.z:  # never worse than the start as given
        t0 = obj.terms(problem, given[0])
        w0, gw0, _ = guards(given[0])
        if obj.cost(t0) + w0 < now.cost:
            now = _Iterate(given[0], given[1], t0, obj.cost(t0) + w0, gw0)
    return ImproveOutcome(now.z, now.ev, start, now.terms, obj, it, accepted, history, floors)
