"""``reachwise.synthesize``: multi-start dimensional synthesis (P-I §3–4, P-II §4).

Each run draws its own initial design (``init``), solves the problem with the chosen
solver (``solvers``) and reports every task point's status. The best run (most points
reached, then smallest ``e_obj``) gives ``SynthesisResult.robot``. Statistics over the
runs reproduce P-I Tables 3–4 (normalized design parameters, mean and deviation).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Literal, get_args

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import InputError, check_choice
from reachwise.kinematics.indices import lci
from reachwise.kinematics.robot import Robot
from reachwise.synthesis.init import initial_guess
from reachwise.synthesis.problem import SynthesisProblem, locked_from_spec
from reachwise.synthesis.solvers import SolverOptions, Workspace, solve_dls, solve_trf
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

    @property
    def n_reached(self) -> int:
        return int(self.reached.sum())


@dataclass(frozen=True, eq=False)
class SynthesisResult:
    """All runs of a synthesis and the best one (``robot``, ``q``, ``reached``)."""

    problem: SynthesisProblem
    runs: tuple[RunResult, ...]
    best_index: int
    solver: SolverName = "dls"
    notes: tuple[str, ...] = field(default_factory=tuple)

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
        """Design values scaled to ``[0, 1]`` between their bounds (P-I Table 3)."""
        lo, hi = self.problem.bounds
        p = self.problem.p
        span = np.where(hi[:p] > lo[:p], hi[:p] - lo[:p], 1.0)
        return np.asarray((design - lo[:p]) / span)

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


def run_once(
    problem: SynthesisProblem,
    seed: int,
    solver: SolverName = "dls",
    init_sets: int = 8,
    options: SolverOptions | None = None,
    workspace: Workspace | None = None,
) -> RunResult:
    """One run: Beta/IK initialization from ``seed`` and one solve."""
    rng = np.random.default_rng(seed)
    guess = initial_guess(problem, rng, init_sets)
    d0, Q0 = problem.split(guess.z)
    if solver == "dls":
        out = solve_dls(problem, guess.z, options, workspace, rng)
    else:
        out = solve_trf(problem, guess.z, workspace, options)
    design, Q = problem.split(out.z)
    robot = problem.robot_at(design, name=f"{problem.template.name}-synth")
    pos_ok, ori_ok, status = problem.point_status(out.evaluation)
    ev = out.evaluation
    e_obj = float(np.sum(np.hypot(ev.position_error, ev.orientation_error)))
    return RunResult(
        seed=seed,
        robot=robot,
        design=design.copy(),
        q=Q,
        reached=pos_ok & ori_ok,
        status=tuple(status),
        position_error=ev.position_error,
        orientation_error=ev.orientation_error,
        e_obj=e_obj,
        iterations=out.iterations,
        converged=out.converged,
        initial_design=d0.copy(),
        lci_initial=_lci_at(problem, problem.robot_at(d0), Q0),
        lci_final=_lci_at(problem, robot, Q),
    )


def synthesize(
    task: Task,
    template: Robot | str,
    *,
    runs: int = 10,
    solver: SolverName = "dls",
    seed: int = 0,
    init_sets: int = 8,
    locked: Sequence[int] | dict[int, float] | None = None,
    workspace: Workspace | str | None = "task",
    options: SolverOptions | None = None,
    on_run: Callable[[RunResult], None] | None = None,
) -> SynthesisResult:
    """Find design parameters, base frame and joint values that reach every task pose.

    ``template`` is a Robot (or built-in name / file) whose ``design`` section lists
    the free parameters and bounds. Run ``i`` uses seed ``seed + i``; ``on_run`` is
    called after each run (progress, or keeping finished runs when interrupted).
    ``workspace="task"`` keeps the links inside the task's envelope (the tunnel of a
    drilling task) when it has one; pass ``None`` to ignore it, or any object with
    ``signed_distance`` and ``gradient``.
    """
    if isinstance(template, str):
        from reachwise.io.robot_file import load_robot

        template = load_robot(template)
    solver = check_choice(solver, SOLVERS, source="synthesize", kind="solver")
    if runs < 1:
        raise InputError("synthesize", "runs", "at least one run")
    problem = SynthesisProblem(template, task, locked_from_spec(template, locked))
    if isinstance(workspace, str):
        if workspace != "task":
            raise InputError("synthesize", "workspace", "'task', None or a workspace object")
        workspace = task.envelope
    results = []
    for i in range(runs):
        r = run_once(problem, seed + i, solver, init_sets, options, workspace)
        results.append(r)
        if on_run is not None:
            on_run(r)
    return result_of(problem, results, solver)


def result_of(
    problem: SynthesisProblem, runs: Sequence[RunResult], solver: SolverName = "dls"
) -> SynthesisResult:
    """Assemble a result from finished runs (also used for interrupted syntheses)."""
    if not runs:
        raise InputError("synthesize", "runs", "no finished run")
    best = min(range(len(runs)), key=lambda i: (-runs[i].n_reached, runs[i].e_obj, i))
    return SynthesisResult(problem, tuple(runs), best, solver)
