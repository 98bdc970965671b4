"""The clearance-aware start of the synthesis: one IK start per branch cell of the
wide revolute joints, per pose the branch whose bodies keep the clearance, and the
number of solves of a clearance run (``SolverOptions.clearance_starts``)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from reachwise import load_robot, load_task
from reachwise.errors import InputError
from reachwise.synthesis.init import (
    beta_designs,
    branch_starts,
    initial_guess,
    seed_joints,
    seed_joints_clear,
)
from reachwise.synthesis.problem import SynthesisProblem
from reachwise.synthesis.solver_options import SolverOptions
from reachwise.synthesis.solvers import solve_dls
from reachwise.synthesis.starts import served, solve_from_starts
from reachwise.synthesis.synthesize import clearance_setup
from tests.synthesis.test_synthesis_clearance import _plans, brute_force_clearance

CLEARANCE = 0.1


def test_branch_starts_split_each_wide_revolute_joint() -> None:
    robot = load_robot("sb60")
    starts = branch_starts(robot)
    names = [j.name for j in robot.joints if j.movable]
    roll, tilt = names.index("feed_rotation"), names.index("feed_tilt")
    # ±180° roll: 4 cells of 90°; ±100° tilt: 3 cells of 66.7°; every combination
    assert starts.shape == (12, robot.n)
    assert np.allclose(np.unique(starts[:, roll]), np.deg2rad([-135.0, -45.0, 45.0, 135.0]))
    assert np.allclose(np.unique(starts[:, tilt]), np.deg2rad([-200 / 3, 0.0, 200 / 3]))
    assert len({(a, b) for a, b in starts[:, [roll, tilt]].round(9)}) == 12
    others = [j for j in range(robot.n) if j not in (roll, tilt)]
    mid = 0.5 * (robot.lower + robot.upper)
    assert np.array_equal(starts[:, others], np.tile(mid[others], (12, 1)))
    assert np.all(starts >= robot.lower) and np.all(starts <= robot.upper)


def test_clearance_aware_start_keeps_more_poses_clear() -> None:
    """On the same design, the joints chosen by reach and clearance reach at least the
    poses the reach-only IK reaches and keep more of them 0.1 m clear, both checked
    by forward kinematics and brute-force distances between the placed bodies."""
    task = _plans(load_task("tunnel-87"), ("P01", "P02", "P03", "P04", "P05", "P06"))
    template = load_robot("sb60")
    model, kept, _ = clearance_setup(template, task, task.envelope, CLEARANCE)
    assert model is not None and kept.envelope is not None
    problem = SynthesisProblem(template, kept)
    design = beta_designs(problem, np.random.default_rng(0), 4)[3]
    robot = problem.robot_at(design)
    counts = []
    envelope = kept.envelope
    for Q, _ in (
        seed_joints(problem, design, np.random.default_rng(0)),
        seed_joints_clear(problem, design, model),
    ):
        T = robot.fk(Q)
        pos = np.linalg.norm(T[:, :3, 3] - kept.poses[:, :3, 3], axis=1) <= kept.tol_position
        cosang = (np.einsum("kij,kij->k", T[:, :3, :3], kept.poses[:, :3, :3]) - 1) / 2
        ori = np.arccos(np.clip(cosang, -1, 1)) <= kept.tol_orientation
        clear = brute_force_clearance(robot, Q, envelope) >= CLEARANCE
        counts.append((int(np.sum(pos & ori)), int(np.sum(pos & ori & clear))))
    (reach_only, clear_only), (reach_aware, clear_aware) = counts
    assert reach_aware >= reach_only
    assert clear_aware > clear_only


def test_clearance_starts_is_the_number_of_solves_of_a_run() -> None:
    """``SolverOptions.clearance_starts``: by default a clearance run that does not
    converge is the one solve from the reach-only start; with 2 it also solves from the
    clearance-aware start of the stream ``(seed, 1)`` and keeps the solve that serves
    more poses (each solve recomputed here on its own)."""
    task = _plans(load_task("tunnel-87"), ("P01",))
    template = load_robot("sb60")
    model, kept, _ = clearance_setup(template, task, task.envelope, CLEARANCE)
    assert model is not None
    problem = SynthesisProblem(template, kept)
    seed, sets = 3, 2
    one = SolverOptions(max_iter=3)  # too few iterations to converge: the restart's case
    two = replace(one, clearance_starts=2)
    assert one.clearance_starts == 1

    rng = np.random.default_rng(seed)
    first = solve_dls(problem, initial_guess(problem, rng, sets).z, one, kept.envelope, rng, model)
    rng = np.random.default_rng((seed, 1))
    aware = initial_guess(problem, rng, sets, clearance=model)
    second = solve_dls(problem, aware.z, two, kept.envelope, rng, model)
    assert not first.converged

    single = solve_from_starts(problem, seed, sets, one, kept.envelope, model)
    assert np.array_equal(single.outcome.z, first.z)
    both = solve_from_starts(problem, seed, sets, two, kept.envelope, model)
    n1, n2 = served(problem, first, model), served(problem, second, model)
    lower = second.cost_history[-1] < first.cost_history[-1]
    keep_second = second.converged or n2 > n1 or (n2 == n1 and lower)
    assert np.array_equal(both.outcome.z, second.z if keep_second else first.z)
    assert served(problem, both.outcome, model) == max(n1, n2) or second.converged


def test_clearance_starts_must_be_a_positive_integer() -> None:
    for bad in (0, -1, 1.5, True):
        with pytest.raises(InputError, match="clearance_starts"):
            SolverOptions(clearance_starts=bad)  # type: ignore[arg-type]
