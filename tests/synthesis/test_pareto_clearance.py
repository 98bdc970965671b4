"""The (clearance, size) Pareto front of the sb60 stand-in bodies in the tunnel.

Plans P01–P06 of tunnel-87 (the poses no design can serve with the feed's own body left
out): the start design is solved with a 0.1 m clearance, and every design of the front
keeps 0.05 m, so the sweep can trade clearance both ways. On these plans the sweep once
collapsed to its start design: restoring a trial onto the task moved joints by a radian
near a singular posture, through the bodies (``improve.restore``). Every front design is
checked independently: forward kinematics at every pose and brute-force distances
between the bodies placed by it (``test_synthesis_clearance``).
"""

from __future__ import annotations

import numpy as np
import pytest

from reachwise import load_robot, load_task
from reachwise.synthesis.clearance import ClearanceModel
from reachwise.synthesis.improve import restore
from reachwise.synthesis.pareto import (
    ParetoOptions,
    ParetoProgress,
    ParetoResult,
    classify,
    pareto_sweep,
)
from reachwise.synthesis.problem import SynthesisProblem
from reachwise.synthesis.solvers import row_weights
from reachwise.synthesis.synthesize import clearance_setup, run_once
from reachwise.tasks.task import Task

from .test_synthesis_clearance import brute_force_clearance

CLEARANCE = 0.1  # the start design's solve
FRONT_CLEARANCE = 0.05  # kept by every design of the sweep
PLANS = ("P01", "P02", "P03", "P04", "P05", "P06")


def reaches_every_pose(robot, q: np.ndarray, task: Task) -> bool:  # type: ignore[no-untyped-def]
    T = robot.fk(q)
    pos = np.linalg.norm(T[:, :3, 3] - task.positions, axis=1)
    cos = np.clip((np.trace(task.poses[:, :3, :3] @ np.swapaxes(T[:, :3, :3], 1, 2),
                            axis1=1, axis2=2) - 1) / 2, -1, 1)  # fmt: skip
    return bool(np.all(pos <= task.tol_position) and np.all(np.arccos(cos) <= task.tol_orientation))


@pytest.fixture(scope="module")
def watched() -> tuple[SynthesisProblem, ParetoResult, list[ParetoProgress]]:
    """The sweep, with the progress it reported (one event per solve)."""
    task = load_task("tunnel-87")
    task = task.subset([i for i, n in enumerate(task.names) if n.split("/")[0] in PLANS])
    sb60 = load_robot("sb60")
    model, kept, bad = clearance_setup(sb60, task, task.envelope, CLEARANCE, needed=True)
    assert model is not None and len(bad) > 0
    prob = SynthesisProblem(sb60, kept)
    run = run_once(prob, 0, workspace=task.envelope, clearance=model)
    assert run.reached.all()
    z0 = prob.pack(run.design, run.q)
    front_model = ClearanceModel(sb60, task.envelope, FRONT_CLEARANCE)
    events: list[ParetoProgress] = []
    front = pareto_sweep(
        prob, z0, ("clearance", "size"), 6, task.envelope, clearance=front_model,
        options=ParetoOptions(progress=events.append),
    )  # fmt: skip
    return prob, front, events


@pytest.fixture(scope="module")
def sweep(
    watched: tuple[SynthesisProblem, ParetoResult, list[ParetoProgress]],
) -> tuple[SynthesisProblem, ParetoResult]:
    return watched[0], watched[1]


def check_clearance_front(
    prob: SynthesisProblem, front: ParetoResult, front_clearance: float
) -> np.ndarray:
    """Check a (clearance, size) front independently of the sweep and return its
    ``(n, 2)`` values: at least five designs, each reaching every pose by forward
    kinematics and ``front_clearance`` clear by brute-force distances between its
    placed bodies, none dominating another, clearance and size rising together, the
    clearance end clearer than the start."""
    env = load_task("tunnel-87").envelope
    assert env is not None
    designs = front.front
    assert len(designs) >= 5
    vals = np.array([[p.values["clearance"], p.values["size"]] for p in designs])
    for p in designs:
        assert reaches_every_pose(p.robot, p.q, prob.task)
        d = brute_force_clearance(p.robot, p.q, env)
        assert d.min() >= front_clearance - 1e-9  # positive, and the clearance kept
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
    assert vals[:, 0].max() > front.start.values["clearance"]
    return vals


def test_front_of_clearance_and_size(sweep: tuple[SynthesisProblem, ParetoResult]) -> None:
    prob, front = sweep
    vals = check_clearance_front(prob, front, FRONT_CLEARANCE)
    start = front.start.values
    assert vals[:, 1].min() <= start["size"] + 1e-9 * abs(start["size"])


def test_the_clearance_objective_needs_the_bodies(
    sweep: tuple[SynthesisProblem, ParetoResult],
) -> None:
    from reachwise.errors import InputError

    prob, front = sweep
    with pytest.raises(InputError, match="clearance"):
        pareto_sweep(prob, front.start.z, ("clearance", "size"), 4)


def test_restoring_a_reaching_design_stays_near_it(
    sweep: tuple[SynthesisProblem, ParetoResult],
) -> None:
    """The start reaches every pose within its tolerance; restoring it to a thousandth of
    the tolerance lowers the residual and moves no variable by more than 0.05 (m or
    rad; measured 0.011, where the undamped Gauss–Newton step moved a joint by 1 rad),
    so the bodies keep their clearance."""
    prob, front = sweep
    z0 = front.start.z
    ev0 = prob.evaluate(z0)
    z1, ev1 = restore(prob, z0, 6, 1e-3)
    wx = row_weights(prob)
    assert np.sum((ev1.e * wx) ** 2) <= np.sum((ev0.e * wx) ** 2)
    assert np.abs(z1 - z0).max() <= 0.05
    model = ClearanceModel(prob.template, load_task("tunnel-87").envelope, FRONT_CLEARANCE)
    assert model.distances(prob, z1).min() >= FRONT_CLEARANCE


def test_the_progress_counts_every_solve(
    watched: tuple[SynthesisProblem, ParetoResult, list[ParetoProgress]],
) -> None:
    """One event per design of the sweep, in order: its stage and two objective values,
    the solves done, a budget never below them, and the front of the designs found so
    far (counted again here from the result's designs); the last is the result's."""
    _, front, events = watched
    assert len(events) == len(front.points) > 0
    names = front.names
    for k, (e, p) in enumerate(zip(events, front.points, strict=True)):
        assert e.solves == k + 1 <= e.budget and e.stage == p.stage
        assert e.values == (p.values[names[0]], p.values[names[1]])
        so_far = classify(front.points[: k + 1], names, front.same)
        assert e.front == sum(not q.dominated for q in so_far)
    assert events[-1].front == len(front.front)
    assert {e.stage for e in events} >= {"end", "level", "polish", "settle"}
    assert len({e.budget for e in events}) <= 2  # the budget, or one past it at the end
    assert not front.partial


def test_a_stopped_sweep_returns_the_designs_it_found(
    watched: tuple[SynthesisProblem, ParetoResult, list[ParetoProgress]],
) -> None:
    """``stop`` raising KeyboardInterrupt (a command's Ctrl-C) before the fourth solve:
    a partial result with the first three designs of the whole sweep (the same solves
    from the same start), classified among themselves. A KeyboardInterrupt raised
    elsewhere is not taken for a stop."""
    prob, whole, _ = watched
    calls = {"n": 0}

    def ctrl_c_at_fourth() -> None:
        calls["n"] += 1
        if calls["n"] == 4:
            raise KeyboardInterrupt

    env = load_task("tunnel-87").envelope
    model = ClearanceModel(prob.template, env, FRONT_CLEARANCE)
    part = pareto_sweep(
        prob, whole.start.z, ("clearance", "size"), 6, env, clearance=model, stop=ctrl_c_at_fourth
    )
    assert part.partial and calls["n"] == 4
    assert [p.index for p in part.points] == [0, 1, 2]
    for p, q in zip(part.points, whole.points[:3], strict=True):
        assert p.values == q.values and p.stage == q.stage
        np.testing.assert_array_equal(p.z, q.z)
    first = classify(whole.points[:3], whole.names, whole.same)
    assert [p.dominated for p in part.points] == [p.dominated for p in first]
    assert len(part.front) >= 1

    def ctrl_c_in_a_solve(event: ParetoProgress) -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        pareto_sweep(
            prob, whole.start.z, ("clearance", "size"), 6, env, clearance=model,
            options=ParetoOptions(progress=ctrl_c_in_a_solve),
        )  # fmt: skip
