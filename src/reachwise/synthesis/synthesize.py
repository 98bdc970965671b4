"""``reachwise.synthesize``: multi-start dimensional synthesis (P-I §3–4, P-II §4).

Each run draws its own initial design (``init``), solves the problem with the chosen
solver (``solvers``) and reports every task point's status. With an ``objective``
(weights of named design objectives, ``objectives``; default the template's
``design.objective``) a run that reaches every pose then improves its design in the
null space of the task (``improve``), keeping every pose reached; the reach-only
design stays in the run (``reach_design``) for comparison. The best run (most points
reached, then the smallest weighted objective, then the smallest ``e_obj``) gives
``SynthesisResult.robot``. Statistics over the runs reproduce P-I Tables 3–4
(normalized design parameters, mean and deviation); ``bound_hits`` flags every design
parameter that ended at a bound.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Literal, get_args

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import InputError, check_choice
from reachwise.kinematics.indices import gci, kci, lci
from reachwise.kinematics.robot import Robot
from reachwise.synthesis.bound_hits import BoundHit, bound_hits
from reachwise.synthesis.clearance import ClearanceModel, Unservable, unservable_poses
from reachwise.synthesis.improve import ImproveOptions, improve
from reachwise.synthesis.init import initial_guess
from reachwise.synthesis.keep import check_keep, default_keep
from reachwise.synthesis.objectives import (
    OBJECTIVES,
    Objective,
    check_objective,
    evaluate_terms,
    smallest_designable,
)
from reachwise.synthesis.problem import SynthesisProblem, locked_from_spec
from reachwise.synthesis.rank import best_run_index
from reachwise.synthesis.solvers import SolverOptions, Workspace, solve_trf
from reachwise.synthesis.starts import solve_from_starts
from reachwise.tasks.task import Task

Array = NDArray[np.float64]
#: A synthesis solver: ``dls`` (the thesis's damped least squares, P-I Eq. 13–14) or
#: ``trf`` (scipy's trust-region reflective least squares, the baseline).
SolverName = Literal["dls", "trf"]
SOLVERS: tuple[SolverName, ...] = get_args(SolverName)


@dataclass(frozen=True, eq=False)
class RunResult:
    """One synthesis run from one seed."""

    seed: int
    robot: Robot
    design: Array
    q: Array
    reached: NDArray[np.bool_]
    status: tuple[str, ...]
    position_error: Array
    orientation_error: Array
    e_obj: float
    iterations: int
    converged: bool
    initial_design: Array
    lci_initial: Array
    lci_final: Array
    reach_design: Array | None = None
    reach_q: Array | None = None
    lci_reach: Array | None = None
    objective_start: dict[str, float] = field(default_factory=dict)
    objective_final: dict[str, float] = field(default_factory=dict)
    improve_iterations: int = 0
    kept: tuple[str, ...] = ()
    clearance: Array | None = None
    clearance_pairs: tuple[tuple[str, str], ...] = ()

    @property
    def n_reached(self) -> int:
        return int(self.reached.sum())

    @property
    def improved(self) -> bool:
        """True when an objective improved this run's reaching design."""
        return self.reach_design is not None


@dataclass(frozen=True, eq=False)
class SynthesisResult:
    """All runs of a synthesis and the best one (``robot``, ``q``, ``reached``)."""

    problem: SynthesisProblem
    runs: tuple[RunResult, ...]
    best_index: int
    solver: SolverName = "dls"
    notes: tuple[str, ...] = field(default_factory=tuple)
    objective: dict[str, float] = field(default_factory=dict)
    unservable: tuple[Unservable, ...] = ()
    clearance: float = 0.0

    @property
    def best(self) -> RunResult:
        return self.runs[self.best_index]

    @property
    def robot(self) -> Robot:
        return self.best.robot

    @property
    def q(self) -> Array:
        return self.best.q

    @property
    def reached(self) -> NDArray[np.bool_]:
        return self.best.reached

    def normalized(self, design: Array) -> Array:
        """Design values scaled to ``[0, 1]`` between their declared bounds (P-I Table 3)."""
        lo, hi = self.problem.declared_bounds
        span = np.where(hi > lo, hi - lo, 1.0)
        return np.asarray((design - lo) / span)

    def bound_hits(self, run: RunResult | None = None, tolerance: float = 0.01) -> list[BoundHit]:
        """Design parameters of ``run`` (default the best) at or within ``tolerance`` of
        the range from a bound (``bound_hits``)."""
        return bound_hits(self.problem, (run or self.best).design, tolerance)

    def unconstrained(self, tolerance: float = 1e-6) -> tuple[str, ...]:
        """The design parameters the task leaves free: every run that reached every
        pose kept them within ``tolerance`` of the range from its (random) start
        design, so joint motion alone served each pose. Few poses (or position-only
        points) for many design parameters do this; the result is then any design the
        random start happened to give. Empty when no run reached every pose."""
        ok = [r for r in self.runs if r.reached.all()]
        if not ok:
            return ()
        lo, hi = self.problem.declared_bounds
        span = np.where(hi > lo, hi - lo, 1.0)
        still = np.ones(len(self.problem.design_names), dtype=bool)
        for r in ok:
            start = r.initial_design
            final = r.design if r.reach_design is None else r.reach_design
            still &= np.abs(final - start) <= tolerance * span
        return tuple(n for n, s in zip(self.problem.design_names, still, strict=True) if s)

    def table3(self) -> list[dict[str, float | str]]:
        """Initial and optimized normalized design of the best run (P-I Table 3)."""
        a = self.normalized(self.best.initial_design)
        b = self.normalized(self.best.design)
        return [
            {"parameter": n, "initial": float(x), "optimized": float(y),
             "changed_percent": float(100 * (y - x))}
            for n, x, y in zip(self.problem.design_names, a, b, strict=True)
        ]  # fmt: skip

    def table4(self) -> list[dict[str, float | str]]:
        """Mean and standard deviation of the normalized design over the runs that
        reached every point (P-I Table 4); over all runs if none did."""
        ok = [r for r in self.runs if r.reached.all()] or list(self.runs)
        X = np.stack([self.normalized(r.design) for r in ok])
        return [
            {"parameter": n, "mean": float(m), "std": float(s), "runs": len(ok)}
            for n, m, s in zip(self.problem.design_names, X.mean(0), X.std(0), strict=True)
        ]


def _lci_at(problem: SynthesisProblem, robot: Robot, Q: Array) -> Array:
    """LCI of the full 6-row Jacobian at every task configuration (P-I Fig. 6)."""
    return np.asarray(lci(robot, Q))


def design_values(
    problem: SynthesisProblem, z: Array, lcis: Array, bodies: ClearanceModel | None = None
) -> dict[str, float]:
    """Every design objective's value at ``z`` (``objectives``), with GCI and KCI as
    P-II Eq. 38–39 define them (``lcis``: the LCI at every task posture) and, with the
    bodies' model, the clearance objective's true value (the smallest term a design
    can change, ``objectives.designable_terms``)."""
    margin = problem.template.design.margin
    values = evaluate_terms(problem, z, ("size", "limits", "bounds"), margin=margin).values
    out = {"gci": float(np.mean(lcis)), "kci": float(np.min(lcis)), **values}
    if bodies is not None:
        out["clearance"] = smallest_designable(bodies, problem, z)
    return out


def run_once(
    problem: SynthesisProblem,
    seed: int,
    solver: SolverName = "dls",
    init_sets: int = 8,
    options: SolverOptions | None = None,
    workspace: Workspace | None = None,
    objective: dict[str, float] | None = None,
    improve_options: ImproveOptions | None = None,
    clearance: ClearanceModel | None = None,
    keep: Sequence[str] | None = None,
) -> RunResult:
    """One run: Beta/IK initialization from ``seed``, one solve (with ``clearance``, up
    to ``options.clearance_starts`` in all, from clearance-aware restarts) and, with an
    ``objective`` (weights) and every pose reached, the null-space improvement, which
    never makes an index in ``keep`` worse than at the reach-only design (``None``:
    ``keep.default_keep``, the KCI when the GCI is weighted). With
    ``clearance`` (``clearance_setup``) the solve and the improvement keep every watched
    pair of bodies at least its clearance apart at every pose, and a pose counts as
    reached only when it is within tolerance *and* clear."""
    if solver == "dls":
        started = solve_from_starts(problem, seed, init_sets, options, workspace, clearance)
        guess, out = started.start, started.outcome
    else:
        if clearance is not None:
            raise InputError("synthesize", "solver", "the clearance needs the dls solver")
        guess = initial_guess(problem, np.random.default_rng(seed), init_sets)
        out = solve_trf(problem, guess.z, workspace, options)
    d0, Q0 = problem.split(guess.z)
    z, ev, iterations = out.z, out.evaluation, out.iterations
    weights = check_objective(objective)
    extra: dict[str, object] = {}
    if weights and out.converged:
        kept = default_keep(weights) if keep is None else check_keep(keep)
        obj = Objective(weights, margin=problem.template.design.margin, keep=kept)
        better = improve(problem, out.z, obj, workspace, improve_options, clearance)
        reach_d, reach_q = problem.split(out.z)
        z, ev = better.z, better.evaluation
        lci_reach = _lci_at(problem, problem.robot_at(reach_d), reach_q)
        fd, fq = problem.split(z)
        extra = {
            "reach_design": reach_d.copy(),
            "reach_q": reach_q,
            "lci_reach": lci_reach,
            "objective_start": design_values(problem, out.z, lci_reach, clearance),
            "objective_final": design_values(
                problem, z, _lci_at(problem, problem.robot_at(fd), fq), clearance
            ),
            "kept": tuple(better.floors),
            "improve_iterations": better.iterations,
        }
    design, Q = problem.split(z)
    robot = problem.robot_at(design, name=f"{problem.template.name}-synth")
    pos_ok, ori_ok, status = problem.point_status(ev)
    e_obj = float(np.sum(np.hypot(ev.position_error, ev.orientation_error)))
    clear_ok = np.ones(problem.K, dtype=np.bool_)
    if clearance is not None:
        smallest, pairs = clearance.terms(problem, z).smallest()
        clear_ok = smallest >= clearance.clearance
        extra["clearance"] = smallest
        extra["clearance_pairs"] = tuple(pairs)
    return RunResult(
        seed=seed,
        robot=robot,
        design=design.copy(),
        q=Q,
        reached=pos_ok & ori_ok & clear_ok,
        status=tuple(status),
        position_error=ev.position_error,
        orientation_error=ev.orientation_error,
        e_obj=e_obj,
        iterations=iterations,
        converged=out.converged,
        initial_design=d0.copy(),
        lci_initial=_lci_at(problem, problem.robot_at(d0), Q0),
        lci_final=_lci_at(problem, robot, Q),
        **extra,  # type: ignore[arg-type]
    )


@dataclass(frozen=True)
class SynthesisSettings:
    """How :func:`synthesize` searches: ``runs`` multi-start runs with ``solver``, run
    i seeded ``seed + i`` and started from the best of ``init_sets`` initial guesses;
    the joint variables ``locked`` (indices, or index → value); the ``workspace`` the
    links stay inside (``"task"``: the task's envelope, ``None``: none); the solver's
    ``options``; the ``objective`` weights (``None``: the template's
    ``design.objective``) and how the design is improved for them
    (``improve_options``) and the indices the improvement must ``keep`` (``None``: the
    KCI when the GCI is weighted, ``synthesis.keep``); the bodies' ``clearance`` (m;
    ``None``: the template's ``design.clearance``, 0: none). Every field is also a
    keyword of :func:`synthesize`."""

    runs: int = 10
    solver: SolverName = "dls"
    seed: int = 0
    init_sets: int = 8
    locked: Sequence[int] | dict[int, float] | None = None
    workspace: Workspace | str | None = "task"
    options: SolverOptions | None = None
    objective: Mapping[str, float] | None = None
    improve_options: ImproveOptions | None = None
    clearance: float | None = None
    keep: Sequence[str] | None = None


def synthesize(
    task: Task,
    template: Robot,
    settings: SynthesisSettings | None = None,
    *,
    on_run: Callable[[RunResult], None] | None = None,
    **keywords: Any,
) -> SynthesisResult:
    """Find design parameters, base frame and joint values that reach every task pose.

    ``template`` is a Robot whose ``design`` section lists the free parameters and
    bounds (``reachwise.synthesize`` also takes built-in names and files). The search
    is set by ``settings`` (:class:`SynthesisSettings`) or by its fields as keywords
    (``runs=10, seed=0, objective={"gci": 1.0}``), a keyword overriding ``settings``.
    Run ``i`` uses seed ``seed + i``; ``on_run`` is called after each run (progress,
    or keeping finished runs when interrupted).
    ``workspace="task"`` keeps the links inside the task's envelope (the tunnel of a
    drilling task) when it has one; pass ``None`` to ignore it, or any object with
    ``signed_distance`` and ``gradient``. ``objective`` maps objective names
    (``objectives.OBJECTIVES``: ``gci``, ``kci``, ``size``, ``limits``, ``bounds``) to
    weights; ``None`` takes the template's ``design.objective``, ``{}`` none. ``keep``
    names the indices the improvement must not make worse than the reach-only design's
    (``synthesis.keep``; ``None``: the KCI when the GCI is weighted, ``()``: none).
    ``clearance`` (m; ``None``: the template's ``design.clearance``, 0: none) keeps the
    template's bodies that far apart and from the workspace at every pose
    (``clearance_setup``); poses no design can serve are left out before the solve and
    listed in ``SynthesisResult.unservable``.
    """
    s = replace(settings or SynthesisSettings(), **keywords)
    runs, seed, init_sets, options = s.runs, s.seed, s.init_sets, s.options
    workspace, objective, improve_options = s.workspace, s.objective, s.improve_options
    solver = s.solver
    solver = check_choice(solver, SOLVERS, source="synthesize", kind="solver")
    if runs < 1:
        raise InputError("synthesize", "runs", "at least one run")
    if isinstance(workspace, str):
        if workspace != "task":
            raise InputError("synthesize", "workspace", "'task', None or a workspace object")
        workspace = task.envelope
    weights = check_objective(
        template.design.objective if objective is None else objective, "synthesize"
    )
    kept = None if s.keep is None else check_keep(s.keep, "synthesize")
    needs_bodies = "clearance" in weights or "clearance" in (kept or ())
    model, task, unservable = clearance_setup(template, task, workspace, s.clearance, needs_bodies)
    problem = SynthesisProblem(template, task, locked_from_spec(template, s.locked))
    results = []
    for i in range(runs):
        r = run_once(
            problem, seed + i, solver, init_sets, options, workspace, weights, improve_options,
            model, kept,
        )  # fmt: skip
        results.append(r)
        if on_run is not None:
            on_run(r)
    return result_of(problem, results, solver, weights, unservable, model)


def clearance_setup(
    template: Robot,
    task: Task,
    workspace: Workspace | None,
    clearance: float | None,
    needed: bool = False,
) -> tuple[ClearanceModel | None, Task, tuple[Unservable, ...]]:
    """The clearance model of ``template``'s bodies (``None`` when the clearance is 0
    and the model is not ``needed``), the task without the poses no design can serve,
    and those poses with the reason.

    ``clearance`` ``None`` takes ``design.clearance``. A workspace that is not a tunnel
    envelope (no ``signed_distance_and_gradient``) adds no environment terms.
    ``needed`` (the ``clearance`` objective, or a kept clearance) builds the model even
    at a clearance of 0: the bodies then only must not overlap.
    """
    c = template.design.clearance if clearance is None else float(clearance)
    if not (np.isfinite(c) and c >= 0):
        raise InputError("synthesize", "clearance", f"must be >= 0, got {c}")
    if c == 0 and not needed:
        return None, task, ()
    if not template.design.bodies:
        why = f"a clearance of {c} m" if c > 0 else "the clearance objective"
        raise InputError(template.name, "design.bodies", f"{why} needs bodies to keep apart")
    env = workspace if hasattr(workspace, "signed_distance_and_gradient") else None
    model = ClearanceModel(template, env, c)  # type: ignore[arg-type]
    bad = tuple(unservable_poses(model, task.poses, task.dims, task.names))
    if not bad:
        return model, task, ()
    drop = {u.index for u in bad}
    keep = [i for i in range(len(task)) if i not in drop]
    if not keep:
        raise InputError(task.name, "points", "no pose can be served with the clearance")
    return model, task.subset(keep), bad


def objective_costs(runs: Sequence[RunResult], weights: Mapping[str, float]) -> list[float]:
    """The weighted objective of each run's final design on one common scale: each term
    divided by its median magnitude over the runs' reach-only designs (``objectives``)."""
    names = [n for n, w in weights.items() if w > 0]
    if not names:
        return [0.0] * len(runs)
    ref = {}
    for n in names:
        mags = [abs(r.objective_start[n]) for r in runs if n in r.objective_start]
        m = float(np.median(mags)) if mags else 1.0
        ref[n] = m if m > 1e-12 else 1.0
    out = []
    for r in runs:
        if not all(n in r.objective_final for n in names):
            out.append(float("inf"))
            continue
        out.append(
            float(sum(-OBJECTIVES[n] * weights[n] * r.objective_final[n] / ref[n] for n in names))
        )
    return out


def _conditioning(run: RunResult, n_points: int) -> tuple[float, float]:
    """(GCI, KCI) of a run that reaches every point, P-II Eq. 38–39 (a figure that is
    not finite, and a run short of a point, the worst)."""
    v = np.asarray(run.lci_final, dtype=np.float64)
    if run.n_reached != n_points or v.size != n_points or not np.isfinite(v).all():
        return (-math.inf, -math.inf)
    return (gci(v), kci(v))


def result_of(
    problem: SynthesisProblem,
    runs: Sequence[RunResult],
    solver: SolverName = "dls",
    objective: Mapping[str, float] | None = None,
    unservable: Sequence[Unservable] = (),
    clearance: ClearanceModel | None = None,
) -> SynthesisResult:
    """Assemble a result from finished runs (also used for interrupted syntheses)."""
    if not runs:
        raise InputError("synthesize", "runs", "no finished run")
    weights = check_objective(objective, "synthesize")
    costs = objective_costs(runs, weights) if weights else None
    conditioning = [_conditioning(r, problem.K) for r in runs]
    best = best_run_index(
        [r.n_reached for r in runs], [r.e_obj for r in runs], costs, conditioning, problem.K
    )
    notes = tuple(f"left out {u.name}: {u.reason}" for u in unservable)
    return SynthesisResult(
        problem, tuple(runs), best, solver, notes, weights, tuple(unservable),
        clearance.clearance if clearance is not None else 0.0,
    )  # fmt: skip
