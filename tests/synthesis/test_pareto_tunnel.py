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

import numpy as np
import pytest

from reachwise import load_robot, load_task
from reachwise.synthesis.clearance import ClearanceModel
from reachwise.synthesis.pareto import ParetoResult, pareto_sweep
from reachwise.synthesis.problem import SynthesisProblem
from reachwise.synthesis.solver_options import SolverOptions
from reachwise.synthesis.synthesize import clearance_setup, run_once

from .test_pareto_clearance import reaches_every_pose
from .test_synthesis_clearance import brute_force_clearance

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
    env = load_task("tunnel-87").envelope
    assert env is not None
    designs = front.front
    assert len(designs) >= 5
    vals = np.array([[p.values["clearance"], p.values["size"]] for p in designs])
    for p in designs:
        assert reaches_every_pose(p.robot, p.q, prob.task)
        d = brute_force_clearance(p.robot, p.q, env)
        assert d.min() >= FRONT_CLEARANCE - 1e-9  # positive, and the clearance kept
        assert p.values["clearance"] >= d.min() - 2e-3
    # no design of the front dominates another (brute force), and it is a trade-off
    s = vals * np.array([1.0, -1.0])
    for i in range(len(s)):
        for j in range(len(s)):
            assert i == j or not (np.all(s[j] >= s[i]) and np.any(s[j] > s[i]))
    assert np.all(np.diff(vals[:, 0]) > 0) and np.all(np.diff(vals[:, 1]) > 0)
    start = front.start.values
    assert vals[:, 0].max() > start["clearance"]
    assert vals[:, 1].min() < start["size"]
