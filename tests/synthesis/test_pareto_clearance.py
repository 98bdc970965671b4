"""The (clearance, size) Pareto front of the sb60 stand-in bodies in the tunnel.

Plans P01–P03 of tunnel-87 (the poses no design can serve with the feed's own body left
out), a 0.1 m clearance kept by every design. The whole tunnel-87 front is run by
``reachwise synth --pareto clearance,size`` (quoted in the CHANGELOG). Every front design
is checked independently: forward kinematics at every pose and brute-force distances
between the bodies placed by it (``test_synthesis_clearance``).
"""

from __future__ import annotations

import numpy as np
import pytest

from reachwise import load_robot, load_task
from reachwise.synthesis.pareto import ParetoResult, pareto_sweep
from reachwise.synthesis.problem import SynthesisProblem
from reachwise.synthesis.synthesize import clearance_setup, run_once
from reachwise.tasks.task import Task

from .test_synthesis_clearance import brute_force_clearance

CLEARANCE = 0.1
PLANS = ("P01", "P02", "P03")


def reaches_every_pose(robot, q: np.ndarray, task: Task) -> bool:  # type: ignore[no-untyped-def]
    T = robot.fk(q)
    pos = np.linalg.norm(T[:, :3, 3] - task.positions, axis=1)
    cos = np.clip((np.trace(task.poses[:, :3, :3] @ np.swapaxes(T[:, :3, :3], 1, 2),
                            axis1=1, axis2=2) - 1) / 2, -1, 1)  # fmt: skip
    return bool(np.all(pos <= task.tol_position) and np.all(np.arccos(cos) <= task.tol_orientation))


@pytest.fixture(scope="module")
def sweep() -> tuple[SynthesisProblem, ParetoResult]:
    task = load_task("tunnel-87")
    task = task.subset([i for i, n in enumerate(task.names) if n.split("/")[0] in PLANS])
    sb60 = load_robot("sb60")
    model, kept, bad = clearance_setup(sb60, task, task.envelope, CLEARANCE, needed=True)
    assert model is not None and len(bad) > 0
    prob = SynthesisProblem(sb60, kept)
    run = run_once(prob, 0, workspace=task.envelope, clearance=model)
    assert run.reached.all()
    z0 = prob.pack(run.design, run.q)
    return prob, pareto_sweep(prob, z0, ("clearance", "size"), 6, task.envelope, clearance=model)


def test_front_of_clearance_and_size(sweep: tuple[SynthesisProblem, ParetoResult]) -> None:
    prob, front = sweep
    env = load_task("tunnel-87").envelope
    assert env is not None
    designs = front.front
    assert len(designs) >= 5
    vals = np.array([[p.values["clearance"], p.values["size"]] for p in designs])
    for p in designs:
        assert reaches_every_pose(p.robot, p.q, prob.task)
        d = brute_force_clearance(p.robot, p.q, env)
        assert d.min() >= CLEARANCE - 1e-9  # positive, and the clearance kept
        # the objective's clearance (the terms a design can change) is at least the
        # smallest of all (brute force; sampling overestimates by under 2 mm)
        assert p.values["clearance"] >= d.min() - 2e-3
    # no design of the front dominates another (brute force), and it is a trade-off:
    # ordered by clearance the size rises
    s = vals * np.array([1.0, -1.0])
    for i in range(len(s)):
        for j in range(len(s)):
            assert i == j or not (np.all(s[j] >= s[i]) and np.any(s[j] > s[i]))
    assert np.all(np.diff(vals[:, 0]) > 0) and np.all(np.diff(vals[:, 1]) > 0)
    start = front.start.values
    assert vals[:, 0].max() > start["clearance"]
    assert vals[:, 1].min() <= start["size"] + 1e-9 * abs(start["size"])


def test_the_clearance_objective_needs_the_bodies(
    sweep: tuple[SynthesisProblem, ParetoResult],
) -> None:
    from reachwise.errors import InputError

    prob, front = sweep
    with pytest.raises(InputError, match="clearance"):
        pareto_sweep(prob, front.start.z, ("clearance", "size"), 4)
