"""Starts of one synthesis run: the reach-only start, then clearance-aware restarts.

A run first solves from the start of P-I §3.3 (``init.initial_guess``: the best of
the Beta-drawn designs by reach error, IK joints per pose). Without bodies, or when
that solve converges, this is the run. With bodies to keep clear (a
``ClearanceModel``) a solve that does not converge ends at a local minimum of the
merit where reach rows and clearance rows balance; which one depends on the start's
design and on the IK branch of each pose. With ``SolverOptions.clearance_starts`` above
1 (default 1: one solve, as a reach-only run), the run then restarts, up to
``clearance_starts`` solves in all, from clearance-aware starts (``initial_guess`` with
the bodies: the design sets compared on reach error plus clearance excess, each pose
on its clearest IK branch) drawn from streams of their own, and keeps the solve that
serves the most poses (reached and clear), then the one with the lower merit. A run
whose first solve converges is the run it was without the restarts. The restarts do
what further runs (``synthesize``'s ``runs``, each from its own seed) also do, at the
cost of a longer run; a single run that should try harder asks for them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from reachwise.synthesis.clearance import ClearanceModel
from reachwise.synthesis.init import InitialGuess, initial_guess
from reachwise.synthesis.problem import SynthesisProblem
from reachwise.synthesis.solver_options import SolveOutcome, SolverOptions, Workspace
from reachwise.synthesis.solvers import solve_dls


@dataclass(frozen=True)
class StartedSolve:
    """One solve of a run: its ``start`` and its ``outcome``."""

    start: InitialGuess
    outcome: SolveOutcome


def served(problem: SynthesisProblem, out: SolveOutcome, clearance: ClearanceModel) -> int:
    """Poses of the solve within tolerance whose every clearance term keeps the
    clearance (``cost_history[-1]`` is the solve's final merit)."""
    pos, ori, _ = problem.point_status(out.evaluation)
    smallest, _ = clearance.terms(problem, out.z).smallest()
    return int(np.sum(pos & ori & (smallest >= clearance.clearance)))


def solve_from_starts(
    problem: SynthesisProblem,
    seed: int,
    init_sets: int,
    options: SolverOptions | None,
    workspace: Workspace | None,
    clearance: ClearanceModel | None,
) -> StartedSolve:
    """The run's solve by the damped least squares (module docstring): the reach-only
    start from ``seed``'s stream and, with ``clearance``, up to
    ``options.clearance_starts − 1`` clearance-aware restarts from the streams
    ``(seed, 1)``, ``(seed, 2)``, … until one converges."""
    starts = (options or SolverOptions()).clearance_starts
    rng = np.random.default_rng(seed)
    start = initial_guess(problem, rng, init_sets)
    best = StartedSolve(start, solve_dls(problem, start.z, options, workspace, rng, clearance))
    if clearance is None:
        return best
    best_served = served(problem, best.outcome, clearance)
    for attempt in range(1, starts):
        if best.outcome.converged:
            break
        rng = np.random.default_rng((seed, attempt))
        start = initial_guess(problem, rng, init_sets, clearance=clearance)
        out = solve_dls(problem, start.z, options, workspace, rng, clearance)
        n = served(problem, out, clearance)
        lower = out.cost_history[-1] < best.outcome.cost_history[-1]
        if out.converged or n > best_served or (n == best_served and lower):
            best, best_served = StartedSolve(start, out), n
    return best
