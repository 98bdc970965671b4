"""The synthesis line search: which trial steps the solver takes."""

from __future__ import annotations

import numpy as np

from reachwise.synthesis import solvers
from reachwise.synthesis.problem import SynthesisProblem
from reachwise.synthesis.solver_options import SolverOptions, row_weights

from .conftest import recovery_task, sb60


def _start(seed: int) -> tuple[SynthesisProblem, solvers._Iterate]:
    template = sb60()
    task, design, _ = recovery_task(template, np.random.default_rng(seed), 4)
    problem = SynthesisProblem(template, task)
    lo, hi = problem.bounds
    z = np.clip(
        np.concatenate([design * 0.9 + 0.1 * lo[: problem.p], np.zeros(problem.size - problem.p)]),
        lo,
        hi,
    )
    wx = row_weights(problem)
    return problem, solvers._iterate(problem, z, wx, None)


def test_a_step_across_a_flat_merit_is_taken() -> None:
    """A trial whose merit equals the current one is taken at full length: the stall
    rule, not the line search, ends an iteration that stops progressing."""
    problem, cur = _start(0)
    caps = solvers._step_caps(problem, SolverOptions())
    trial = solvers._line_search(
        problem, cur, [np.zeros(problem.size)], caps, row_weights(problem), None
    )
    assert trial.z is not None
    assert trial.alpha == 1.0
    assert trial.cost == cur.cost


def test_a_taken_step_never_raises_the_merit_beyond_flat() -> None:
    """Random steps: whatever the search takes has a merit within FLAT_MERIT of the
    current one (computed here from the problem's own evaluation), and a step none of
    whose halvings is that low is refused."""
    problem, cur = _start(1)
    caps = solvers._step_caps(problem, SolverOptions())
    wx = row_weights(problem)
    rng = np.random.default_rng(7)
    taken = refused = 0
    for _ in range(20):
        step = rng.normal(scale=0.5, size=problem.size)
        trial = solvers._line_search(problem, cur, [step], caps, wx, None)
        if trial.z is None:
            refused += 1
            continue
        taken += 1
        ev = problem.evaluate(trial.z)
        c = solvers.merit(problem, ev, wx, trial.z, None)
        assert c == trial.cost
        assert c <= cur.cost * (1.0 + solvers.FLAT_MERIT) + 1e-12
    assert taken and refused
