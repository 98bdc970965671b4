"""The clearance-aware start of the synthesis: one IK start per branch cell of the
wide revolute joints, and per pose the branch whose bodies keep the clearance."""

from __future__ import annotations

import numpy as np

from reachwise import load_robot, load_task
from reachwise.synthesis.init import beta_designs, branch_starts, seed_joints, seed_joints_clear
from reachwise.synthesis.problem import SynthesisProblem
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
