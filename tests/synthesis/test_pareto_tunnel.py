"""The (clearance, size) Pareto front on the whole tunnel-87 with the sb60 stand-in bodies.

The start design is solved with a 0.05 m clearance and two clearance starts (seed 4,
as ``synth --clearance 0.05 --clearance-starts 2`` solves it: its run serves every kept
pose that clear; the poses no design can serve are left out before the solve), and
every design of the front keeps 0.025 m, so the sweep can trade
clearance both ways. Every front design is checked independently: forward kinematics
at every kept pose and brute-force distances between the bodies placed by it
(``test_synthesis_clearance``).
"""

from __future__ import annotations

import pytest

from reachwise import load_robot, load_task
from reachwise.synthesis.clearance import ClearanceModel
from reachwise.synthesis.pareto import ParetoResult, pareto_sweep
from reachwise.synthesis.problem import SynthesisProblem
from reachwise.synthesis.solver_options import SolverOptions
from reachwise.synthesis.synthesize import clearance_setup, run_once

from .test_pareto_clearance import check_clearance_front

CLEARANCE = 0.05  # the start design's solve
FRONT_CLEARANCE = 0.025  # kept by every design of the sweep
SEED = 4


@pytest.fixture(scope="module")
def sweep() -> tuple[SynthesisProblem, ParetoResult]:
    task = load_task("tunnel-87")
    sb60 = load_robot("sb60")
    model, kept, bad = clearance_setup(sb60, task, task.envelope, CLEARANCE, needed=True)
    assert model is not None and len(bad) > 0
    prob = SynthesisProblem(sb60, kept)
    options = SolverOptions(clearance_starts=2)
    run = run_once(prob, SEED, options=options, workspace=task.envelope, clearance=model)
    assert run.reached.all()
    front_model = ClearanceModel(sb60, task.envelope, FRONT_CLEARANCE)
    z0 = prob.pack(run.design, run.q)
    return prob, pareto_sweep(
        prob, z0, ("clearance", "size"), 8, task.envelope, clearance=front_model
    )


def test_front_of_clearance_and_size_on_the_whole_tunnel(
    sweep: tuple[SynthesisProblem, ParetoResult],
) -> None:
    prob, front = sweep
    vals = check_clearance_front(prob, front, FRONT_CLEARANCE)
    start = front.start.values
    assert vals[:, 1].min() < start["size"]
