"""End-to-end dimensional synthesis: recovery of known designs, bounds, bad input."""

from __future__ import annotations

import numpy as np
import pytest

import reachwise
from reachwise import load_robot
from reachwise.errors import InputError, ReachwiseError
from reachwise.synthesis.synthesize import synthesize
from reachwise.tasks.task import Task
from tests.synthesis.conftest import recovery_task, sb60


def test_sb60_recovery_87_poses_five_seeds() -> None:
    """Only the template, its bounds and the poses are given; ≥ 4 of 5 seeds reach
    all 87 poses within 1 mm / 1 mrad with every variable inside its bounds."""
    robot = sb60()
    task, _, _ = recovery_task(robot, np.random.default_rng(2017), 87)
    ok = 0
    for seed in range(5):
        res = synthesize(task, robot, runs=1, seed=seed)
        best = res.best
        # independent check: FK of the returned design at the returned joints
        T = res.robot.fk(res.q)
        ep = np.linalg.norm(T[:, :3, 3] - task.positions, axis=1)
        Rerr = np.einsum("kji,kjl->kil", T[:, :3, :3], task.rotations)
        eo = np.arccos(np.clip((np.trace(Rerr, axis1=1, axis2=2) - 1) / 2, -1, 1))
        z = res.problem.pack(best.design, res.q)
        inside = res.problem.within_bounds(z)
        all_reached = bool(np.all(ep <= 1e-3) and np.all(eo <= 1e-3 + 1e-9) and inside)
        assert all_reached == bool(best.reached.all() and inside)
        ok += all_reached
    assert ok >= 4


def test_five_d_task_and_trf_baseline_on_small_problem() -> None:
    robot = sb60()
    task, _, _ = recovery_task(robot, np.random.default_rng(5), 12, dims=5)
    res = synthesize(task, robot, runs=1, seed=0)
    assert res.reached.all()
    trf = synthesize(task, robot, runs=1, seed=0, solver="trf")
    z = trf.problem.pack(trf.best.design, trf.q)
    assert trf.problem.within_bounds(z)
    assert trf.best.e_obj < 10.0  # the baseline runs and returns a bounded design


def test_same_seed_same_result() -> None:
    robot = sb60()
    task, _, _ = recovery_task(robot, np.random.default_rng(8), 10)
    a = synthesize(task, robot, runs=2, seed=3)
    b = synthesize(task, robot, runs=2, seed=3)
    np.testing.assert_array_equal(a.best.design, b.best.design)
    np.testing.assert_array_equal(a.q, b.q)
    assert len(a.runs) == 2 and {r.seed for r in a.runs} == {3, 4}
    t4 = a.table4()
    assert [r["parameter"] for r in t4] == list(a.problem.design_names)


def test_bad_input() -> None:
    with pytest.raises(ReachwiseError):
        Task.from_arrays("empty", np.zeros((0, 3)))
    with pytest.raises(ReachwiseError, match="points\\[1\\]"):
        Task.from_arrays("nan", [[0, 0, 0], [np.nan, 0, 0]], dims=3)
    with pytest.raises(ReachwiseError, match="tol"):
        Task.from_arrays("tol", [[0, 0, 0]], dims=3, tol_position=0.0)
    task = Task.from_arrays("ok", [[5.0, 0, 1.0]], dims=3)
    with pytest.raises(InputError, match="no free design parameter"):
        synthesize(task, load_robot("panda"))
    with pytest.raises(ReachwiseError, match="no-such-template"):
        reachwise.synthesize(task, "no-such-template")
    with pytest.raises(InputError, match="solver"):
        synthesize(task, sb60(), solver="newton")
