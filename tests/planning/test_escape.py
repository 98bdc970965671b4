"""The OMPL escape planner: paths checked by brute force, goals, failures, seeds."""

from __future__ import annotations

import itertools
import math
import sys
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from reachwise.control.controller import Goal
from reachwise.distance import closest_points
from reachwise.distance.scene import Scene
from reachwise.errors import MissingDependency
from reachwise.geometry.cloud import PointCloud
from reachwise.io.clouds import load_mesh_cloud
from reachwise.io.robot_file import load_robot
from reachwise.kinematics.robot import Robot
from reachwise.kinematics.transforms import pose_from_xyz_rpy
from reachwise.planning import (
    ClearanceChecker,
    PlannerConfig,
    PlanResult,
    ompl_available,
    plan_path,
    require_ompl,
)
from reachwise.planning.escape import conditioning, held_robot, plan_escape

#: OMPL itself is needed (per test: the missing-extra error and the pure maths run
#: without it).
needs_ompl = pytest.mark.skipif(
    not ompl_available(), reason='needs OMPL: pip install "reachwise[plan]"'
)
#: OMPL's planning budget (s): a hang guard only. RRT-Connect stops at its first
#: solution, and with a fixed seed that solution is the same whatever the machine's
#: load, so no result here depends on how fast the machine is, unless it hangs.
BUDGET = 600.0

MESHES = Path(str(resources.files("reachwise.data"))) / "scenarios" / "meshes"
LINKS = {"link_3": "panda-upper-arm", "link_5": "panda-forearm", "link_7": "panda-hand"}
MARGIN = 0.1
# the trap scenario's start (tool at (0.45, 0.5, 0.3), hand down) and goal behind the cup
Q_START = np.array([0.8307, 0.5112, 0.0084, -1.6943, -0.0051, 2.2055, 0.841])
GOAL = Goal.at([0.45, -0.5, 0.3])
CUP_POSE = pose_from_xyz_rpy([0.45, 0.0, 0.3], [0.0, 0.0, 0.0])


def _scene(extra: dict[str, tuple[PointCloud, np.ndarray]] | None = None) -> tuple[Robot, Scene]:
    """The panda with capsule clouds on three links, and the trap's cup (small clouds,
    so the brute-force reference stays quick)."""
    robot = load_robot("panda")
    scene = Scene()
    scene.add_robot(robot, Q_START)
    for k, (link, mesh) in enumerate(LINKS.items()):
        cloud = load_mesh_cloud(MESHES / f"{mesh}.obj", 120, seed=k, name=link)
        scene.add_object(f"panda/{link}", cloud, robot="panda", link=link)
    objects = {"cup": (load_mesh_cloud(MESHES / "trap-cup.obj", 900, seed=7), CUP_POSE)}
    objects.update(extra or {})
    for name, (cloud, pose) in objects.items():
        scene.add_object(name, cloud, pose)
        for link in LINKS:
            scene.watch(f"panda/{link}", name, MARGIN)
    return robot, scene


def _brute(scene: Scene, robot: Robot, checker: ClearanceChecker, q: np.ndarray) -> np.ndarray:
    """Every checked pair's exact distance at ``q``, by brute force over all point pairs."""
    frames = robot.fk_all(q)
    objs = scene.objects
    poses = scene.poses()
    out = []
    for name in checker.pairs:
        a, b = name.split("|")
        pa = frames[robot.link_names.index(a.split("/")[1])]
        out.append(closest_points(objs[a].cloud, objs[b].cloud, pa, poses[b], strategy="brute"))
    return np.array([r.distance for r in out])


def _dense(path: np.ndarray, spacing: float) -> np.ndarray:
    """The path's straight joint-space segments sampled at most ``spacing`` apart."""
    out = [path[:1]]
    for a, b in itertools.pairwise(path):
        m = max(1, int(np.ceil(np.linalg.norm(b - a) / spacing)))
        out.append(a + np.linspace(0.0, 1.0, m + 1)[1:, None] * (b - a))
    return np.concatenate(out)


@pytest.fixture(scope="module")
def world() -> tuple[Robot, Scene, ClearanceChecker]:
    robot, scene = _scene()
    return robot, scene, ClearanceChecker(scene, robot)


@pytest.fixture(scope="module")
def planned(world: tuple[Robot, Scene, ClearanceChecker]) -> PlanResult:
    checker = world[2]
    return plan_path(checker, Q_START, GOAL, PlannerConfig(time_limit=BUDGET, seed=3))


@needs_ompl
def test_straight_line_is_blocked(
    world: tuple[Robot, Scene, ClearanceChecker], planned: PlanResult
) -> None:
    # the problem needs a planner: the joint-space line to the goal configuration hits
    # the cup (else the tests below would not show anything)
    _, _, checker = world
    line = _dense(np.array([Q_START, planned.path[-1]]), 0.02)
    assert not all(checker.is_valid(q) for q in line)


@needs_ompl
def test_every_state_of_the_path_keeps_the_margin_by_brute_force(
    world: tuple[Robot, Scene, ClearanceChecker], planned: PlanResult
) -> None:
    robot, scene, checker = world
    assert planned.success, planned.reason
    assert planned.status == "Exact solution"
    np.testing.assert_allclose(planned.clearance, MARGIN)  # a start clear of every margin
    dense = _dense(planned.path, planned.resolution / 3.0)
    assert dense.shape[0] > 3 * planned.path.shape[0]
    worst = np.inf
    for q in dense:
        assert np.all(q >= robot.lower) and np.all(q <= robot.upper)
        worst = min(worst, float(_brute(scene, robot, checker, q).min()))
    assert worst >= MARGIN, worst


@needs_ompl
def test_path_starts_at_start_and_ends_at_the_goal(
    world: tuple[Robot, Scene, ClearanceChecker], planned: PlanResult
) -> None:
    robot, _, _ = world
    np.testing.assert_array_equal(planned.path[0], Q_START)
    tip = robot.fk(planned.path[-1])[:3, 3]
    assert np.linalg.norm(tip - GOAL.position) < 1e-3
    # the end is one of the offered goal configurations (IK solutions)
    assert np.min(np.abs(planned.goals - planned.path[-1]).max(axis=1)) < 1e-9
    assert planned.planning_time > 0.0 and planned.simplify_time >= 0.0
    assert planned.checks > 0 and planned.raw_states >= planned.path.shape[0]


@needs_ompl
def test_six_d_goal_is_reached_with_its_orientation(
    world: tuple[Robot, Scene, ClearanceChecker],
) -> None:
    robot, _, checker = world
    T = pose_from_xyz_rpy([0.45, -0.5, 0.3], [np.pi, 0.0, 0.0])  # hand down
    res = plan_path(checker, Q_START, Goal(T, 6), PlannerConfig(time_limit=BUDGET, seed=5))
    assert res.success, res.reason
    E = robot.fk(res.path[-1])
    assert np.linalg.norm(E[:3, 3] - T[:3, 3]) < 1e-3
    assert np.arccos(np.clip((np.trace(E[:3, :3].T @ T[:3, :3]) - 1) / 2, -1, 1)) < 1e-3


@needs_ompl
def test_seeds_make_it_reproducible(world: tuple[Robot, Scene, ClearanceChecker]) -> None:
    _, _, checker = world
    runs = [
        plan_path(checker, Q_START, GOAL, PlannerConfig(time_limit=BUDGET, seed=s))
        for s in (11, 11, 12)
    ]
    assert all(r.success for r in runs)
    np.testing.assert_array_equal(runs[0].path, runs[1].path)
    assert runs[0].path.shape != runs[2].path.shape or not np.array_equal(
        runs[0].path, runs[2].path
    )


def _sigma_min(robot: Robot, path: np.ndarray, cols: list[int], per_segment: int = 10) -> float:
    """Brute force: the smallest singular value of the tool Jacobian's columns ``cols``
    at every waypoint and ``per_segment`` states along each segment of ``path``."""
    states = [path[-1]]
    for a, b in itertools.pairwise(path):
        states += [a + u * (b - a) for u in np.arange(per_segment) / per_segment]
    return min(float(np.linalg.svd(robot.jacobian(q)[:, cols])[1][-1]) for q in states)


@needs_ompl
def test_held_joints_stay_and_the_rest_is_well_conditioned(
    world: tuple[Robot, Scene, ClearanceChecker],
) -> None:
    """The held joint is the one the documented rule picks, checked by brute force
    over every candidate: rank all 7 single-joint holds by the conditioning of the
    remaining joints along the all-free path, plan the best three with their joint
    held, take the first whose own path stays at sigma >= 0.05 (else the best)."""
    robot, _, checker = world
    cfg = PlannerConfig(time_limit=BUDGET, seed=3)
    res = plan_escape(checker, Q_START, GOAL, cfg)
    assert res.success, res.reason
    assert len(res.held) == 1  # 7 actuated joints, 6-D follower
    k = res.held[0]
    np.testing.assert_array_equal(res.path[:, k], Q_START[k])
    for q in _dense(res.path, res.resolution):
        assert checker.is_valid(q)
    # brute force: every candidate, scored independently of `conditioning`
    first = plan_path(checker, Q_START, GOAL, cfg)
    joints = list(range(robot.n))

    def free(h: int) -> list[int]:
        return [j for j in joints if j != h]

    scores = {h: _sigma_min(robot, first.path, free(h)) for h in joints}
    ranked = sorted(joints, key=lambda h: -scores[h])
    tried = {}
    for h in ranked[:3]:
        run = plan_path(checker, Q_START, GOAL, cfg, hold=[h])
        tried[h] = _sigma_min(robot, run.path, free(h)) if run.success else -np.inf
        if tried[h] >= 0.05:
            break
    expected = next((h for h in tried if tried[h] >= 0.05), max(tried, key=tried.__getitem__))
    assert k == expected, (k, scores, tried)
    assert res.plans == 1 + len(tried)
    assert math.isclose(conditioning(robot, res.path, free(k)), tried[k], rel_tol=1e-12)
    assert tried[k] >= 0.05


def test_held_robot_has_the_same_kinematics(rng: np.random.Generator) -> None:
    robot = load_robot("panda")
    q = rng.uniform(robot.lower, robot.upper)
    hold = np.array([False, False, True, False, False, True, False])
    sub = held_robot(robot, q, hold)
    assert sub.n == robot.n - 2
    np.testing.assert_allclose(sub.fk_all(q[~hold]), robot.fk_all(q), atol=1e-12)


@needs_ompl
def test_goal_inside_the_obstacle_fails_clearly(
    world: tuple[Robot, Scene, ClearanceChecker],
) -> None:
    _, _, checker = world
    res = plan_path(checker, Q_START, Goal.at([0.45, -0.11, 0.3]), PlannerConfig(seed=2))
    assert not res.success
    assert "no collision-free goal configuration" in res.reason
    np.testing.assert_array_equal(res.path, Q_START[None, :])


@needs_ompl
def test_enclosed_hand_has_no_path_and_fails_without_exception() -> None:
    # a closed spherical shell of points around the hand: valid start, goal outside,
    # no path exists; only the hand is watched against the shell
    robot = load_robot("panda")
    hand = robot.fk_all(Q_START)[robot.link_names.index("link_7")]
    centre = hand[:3, :3] @ np.array([0.0, 0.0, 0.085]) + hand[:3, 3]
    g = np.random.default_rng(0).normal(size=(3000, 3))
    shell = PointCloud(0.3 * g / np.linalg.norm(g, axis=1, keepdims=True) + centre)
    scene = Scene()
    scene.add_robot(robot, Q_START)
    cloud = load_mesh_cloud(MESHES / "panda-hand.obj", 120, seed=0)
    scene.add_object("panda/link_7", cloud, robot="panda", link="link_7")
    scene.add_object("shell", shell)
    scene.watch("panda/link_7", "shell", 0.05)
    checker = ClearanceChecker(scene, robot)
    assert checker.is_valid(Q_START)
    far = np.array([-0.8307, 0.5112, 0.0084, -1.6943, -0.0051, 2.2055, 0.841])  # mirrored
    assert checker.is_valid(far)
    res = plan_path(checker, Q_START, far[None, :], PlannerConfig(time_limit=0.5, seed=1))
    assert not res.success
    assert "no path within 0.5 s" in res.reason and res.status != "Exact solution"


@needs_ompl
def test_explicit_goal_in_collision_and_start_outside_limits_fail_clearly(
    world: tuple[Robot, Scene, ClearanceChecker],
) -> None:
    robot, _, checker = world
    q_bad = Q_START.copy()
    q_bad[0] = 5.0  # beyond joint 1's limit of 2.90 rad
    res = plan_path(checker, q_bad, GOAL)
    assert not res.success and "outside the joint limits" in res.reason
    # the tool on the cup's back plate
    wall = robot.ik(pose_from_xyz_rpy([0.45, -0.11, 0.3], [0, 0, 0]), q0=Q_START, mask=3)
    assert wall.success and not checker.is_valid(wall.q)
    res = plan_path(checker, Q_START, wall.q[None, :])
    assert not res.success and "in collision" in res.reason


@needs_ompl
def test_a_start_inside_a_margin_may_leave_but_not_come_closer() -> None:
    robot, scene = _scene()
    checker = ClearanceChecker(scene, robot)
    # the tool 16 cm in front of the cup's mouth: the forearm is within the 10 cm margin
    T = pose_from_xyz_rpy([0.45, 0.28, 0.3], [np.pi / 2, 0.0, 0.0])
    q0 = robot.ik(T, q0=Q_START, mask=3).q
    d0 = checker.distances(q0, exact=True)
    assert d0.min() < MARGIN and not checker.is_valid(q0)
    res = plan_path(checker, q0, GOAL, PlannerConfig(time_limit=BUDGET, seed=4))
    assert res.success, res.reason
    inside = d0 < MARGIN + 0.5 * res.step
    np.testing.assert_allclose(res.clearance[inside], 0.99 * d0[inside] - 0.5 * res.step)
    for q in _dense(res.path, res.resolution / 2.0):
        d = _brute(scene, robot, checker, q)
        assert np.all(d >= res.clearance - 1e-12)


def test_sweep_bounds_bound_every_point_speed(rng: np.random.Generator) -> None:
    from reachwise.planning.validity import WatchedPart, sweep_bounds
    from tests.conftest import random_chain

    for classic in (False, True):
        robot = random_chain(rng, 6, classic=classic)
        local = rng.normal(size=(40, 3)) * 0.3
        frames = list(range(1, len(robot.link_names)))
        parts = [WatchedPart(f, float(np.linalg.norm(local, axis=1).max())) for f in frames]
        R = sweep_bounds(robot, parts)
        for _ in range(30):
            q = rng.uniform(np.maximum(robot.lower, -3), np.minimum(robot.upper, 3))
            dq = rng.normal(size=robot.n) * 1e-6
            F0, F1 = robot.fk_all(q), robot.fk_all(q + dq)
            for f in frames:
                p0 = local @ F0[f, :3, :3].T + F0[f, :3, 3]
                p1 = local @ F1[f, :3, :3].T + F1[f, :3, 3]
                moved = np.linalg.norm(p1 - p0, axis=1).max()
                assert moved <= np.abs(dq) @ R * (1 + 1e-6) + 1e-15


def test_missing_ompl_is_a_clear_error(
    monkeypatch: pytest.MonkeyPatch, world: tuple[Robot, Scene, ClearanceChecker]
) -> None:
    """Runs whether or not OMPL is installed: the import is blocked."""
    monkeypatch.setitem(sys.modules, "ompl", None)  # import ompl -> ImportError
    hint = (
        r"the local-minimum escape needs the optional package 'ompl': "
        r'pip install "reachwise\[plan\]"'
    )
    with pytest.raises(MissingDependency, match=hint) as info:
        require_ompl()
    assert isinstance(info.value, ImportError)
    assert (info.value.package, info.value.extra) == ("ompl", "plan")
    assert not ompl_available()
    with pytest.raises(MissingDependency, match=hint):  # before any planning work
        plan_path(world[2], Q_START, GOAL)
