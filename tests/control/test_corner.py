"""The approach guard at an edge or corner of a sampled cloud (controller item 5, guard
memory).

The distance query answers one closest point pair per watched pair. Driven into a box
corner of a cloud sampled on the box surface, with the goal behind the corner, that
pair flips between points on either side of the edge from tick to tick; a guard that
constrains only this tick's pair lets the tool drift through the stop distance
``ρ_s``. Truth here is the distance measured by the scene itself (the exact closest
distance between the tool and the cloud) at every tick of a kinematic loop, and, for
one tick, the rate along a remembered collision line recomputed from forward
kinematics and a finite-difference Jacobian.
"""

from __future__ import annotations

import numpy as np
import pytest

import reachwise
from reachwise.control import AvoidancePoints, Controller, ControllerConfig, Goal, SafetyConfig
from reachwise.control.avoidance import SceneConverter
from reachwise.distance.scene import Scene
from reachwise.errors import InputError
from reachwise.geometry.cloud import PointCloud

Q0 = np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.7])
STOP = 0.08
MARGIN = 0.25
DT = 0.01


@pytest.fixture(scope="module")
def panda() -> reachwise.Robot:
    return reachwise.load_robot("panda")


def box_surface(lo: np.ndarray, hi: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` points uniformly distributed over the surface of the box ``[lo, hi]``."""
    ext = hi - lo
    areas = np.array([ext[1] * ext[2], ext[0] * ext[2], ext[0] * ext[1]])
    p = lo + rng.uniform(0.0, 1.0, (n, 3)) * ext
    face = rng.choice(3, n, p=areas / areas.sum())
    side = rng.integers(0, 2, n)
    p[np.arange(n), face] = np.where(side == 1, hi[face], lo[face])
    return p


def corner_run(
    robot: reachwise.Robot,
    goal_offset: list[float],
    n: int,
    seed: int,
    six: bool,
    memory: int,
    duration: float = 6.0,
) -> np.ndarray:
    """Drive the tool (one point) toward a goal behind the corner of a box whose
    surface is sampled with ``n`` points; the tool–box distance at every tick."""
    rng = np.random.default_rng(seed)
    T0 = robot.fk(Q0)
    tip = T0[:3, 3]
    # the box corner nearest the tool is 0.1 m away along x, y and -z
    lo, hi = tip + np.array([0.1, 0.1, -0.4]), tip + np.array([0.4, 0.4, -0.1])
    scene = Scene()
    scene.add_robot(robot, Q0)
    scene.add_object("hand", PointCloud(np.zeros((1, 3))), robot=robot.name, link="tool")
    scene.add_object("box", PointCloud(box_surface(lo, hi, n, rng)))
    scene.watch("hand", "box", MARGIN)
    conv = SceneConverter(scene, robot)
    cfg = ControllerConfig(stop_distance=STOP, guard_memory=memory, safety=SafetyConfig(dt=DT))
    ctrl = Controller(robot, cfg)
    G = T0.copy()
    G[:3, 3] = tip + goal_offset
    goal = Goal(G, 6 if six else 3)
    q = Q0.copy()
    dist = []
    for k in range(round(duration / DT)):
        t = k * DT
        scene.set_joints(robot.name, q, stamp=t)
        res = scene.query_all()
        dist.append(res.get("hand", "box").result.distance)
        qd, st = ctrl.step(q, goal, conv(res, stamp=t, computed=t), t)
        assert st.state in ("moving", "stalled")
        q = q + DT * qd
    return np.array(dist)


# (goal offset from the start tip, cloud size, seed, full pose goal)
CORNERS = [
    ([0.5, 0.5, -0.5], 1000, 1, False),
    ([0.55, 0.45, -0.45], 500, 3, False),
    ([0.54, 0.49, -0.44], 300, 11, True),
]


@pytest.mark.parametrize(("goal", "n", "seed", "six"), CORNERS)
def test_tool_stays_out_of_a_sampled_box_corner(
    panda: reachwise.Robot, goal: list[float], n: int, seed: int, six: bool
) -> None:
    """The tool is pressed into the corner (it comes within 3 mm of ``ρ_s``) and never
    goes more than 1 mm below ``ρ_s`` (the per-tick, first-order slack of the damper:
    a cloud point seen for the first time may be up to one step closer)."""
    d = corner_run(panda, goal, n, seed, six, memory=2)
    assert d.min() <= STOP + 0.003  # the guard was really at work
    assert d.min() >= STOP - 0.001, float(d.min())


@pytest.mark.parametrize(("goal", "n", "seed", "six"), CORNERS)
def test_without_memory_the_flipping_pair_drifts_through(
    panda: reachwise.Robot, goal: list[float], n: int, seed: int, six: bool
) -> None:
    """The defect the memory fixes: constraining only each tick's closest pair lets
    the tool drift 1 cm or more past ``ρ_s`` in the same runs."""
    d = corner_run(panda, goal, n, seed, six, memory=0)
    assert d.min() < STOP - 0.01, float(d.min())


def _fd_point_jacobian(robot: reachwise.Robot, q: np.ndarray, link: int, local: np.ndarray):  # type: ignore[no-untyped-def]
    """Central finite differences of the world position of a point fixed to ``link``."""
    J = np.empty((3, robot.n))
    h = 1e-6
    for k in range(robot.n):
        e = np.zeros(robot.n)
        e[k] = h
        Fp = robot.fk_all(q + e)[link]
        Fm = robot.fk_all(q - e)[link]
        J[:, k] = (Fp[:3, :3] @ local + Fp[:3, 3] - Fm[:3, :3] @ local - Fm[:3, 3]) / (2 * h)
    return J


def _one_point(
    seq: int, link: int, a: np.ndarray, b: np.ndarray, b_link: int = -1, b_world=None
) -> AvoidancePoints:  # type: ignore[no-untyped-def]
    """One avoidance point: robot point ``a`` (world), other end ``b`` (world)."""
    d = float(np.linalg.norm(a - b))
    return AvoidancePoints(
        seq, seq * DT, seq * DT, np.array([link]), a[None], np.array([b_link]),
        (np.full(3, np.nan) if b_link < 0 else b)[None], ((a - b) / d)[None], np.array([d]),
        np.array([MARGIN]), np.array([False]),
    )  # fmt: skip


@pytest.mark.parametrize("self_pair", [False, True])
def test_remembered_line_bounds_the_rate(panda: reachwise.Robot, self_pair: bool) -> None:
    """Tick 1 reports a point pair at ``ρ_s`` in front of link 6; tick 2 (another joint
    state) reports only a different, farther pair. With memory the tick-2 command keeps
    the tick-1 pair's distance rate ``ρ̇ = n·(J_a − J_b) q̇`` (recomputed at the tick-2
    state by finite differences) at or above the damper bound, 0 at ``ρ_s``; without
    memory it closes that gap. A self pair's other end rides on link 3."""
    link = panda.link_index("link_6")
    blink = panda.link_index("link_3")
    q1 = Q0.copy()
    q2 = Q0 + np.array([0.01, -0.01, 0.02, 0.01, -0.02, 0.01, 0.0])
    F1 = panda.fk_all(q1)
    a_loc = np.array([0.02, 0.05, 0.0])
    a1 = F1[link][:3, :3] @ a_loc + F1[link][:3, 3]
    toward = np.array([0.3, 0.2, -1.0]) / np.linalg.norm([0.3, 0.2, -1.0])
    b1 = a1 + STOP * toward  # the obstacle point, ρ_s away along ``toward``
    b_loc = F1[blink][:3, :3].T @ (b1 - F1[blink][:3, 3])
    # tick 2: a second obstacle point, 0.1 m away sideways
    F2 = panda.fk_all(q2)
    a2 = F2[link][:3, :3] @ a_loc + F2[link][:3, 3]
    side = np.cross(toward, [0.0, 0.0, 1.0])
    side /= np.linalg.norm(side)
    b2 = a2 + 0.1 * side
    # the goal drags the tool (and link 6) toward the remembered point
    G = panda.fk(q2).copy()
    G[:3, 3] += 0.3 * toward
    goal = Goal(G, 3)

    def rate(memory: int) -> float:
        cfg = ControllerConfig(
            stop_distance=STOP, guard_memory=memory, mu=0.0, safety=SafetyConfig(dt=DT)
        )
        c = Controller(panda, cfg)
        if self_pair:
            p1 = _one_point(1, link, a1, b1, b_link=blink)
        else:
            p1 = _one_point(1, link, a1, b1)
        c.step(q1, goal, p1, 1 * DT)
        qd, st = c.step(q2, goal, _one_point(2, link, a2, b2), 2 * DT)
        assert st.active_points == 1
        bb = F2[blink][:3, :3] @ b_loc + F2[blink][:3, 3] if self_pair else b1
        n = (a2 - bb) / np.linalg.norm(a2 - bb)
        J = _fd_point_jacobian(panda, q2, link, a_loc)
        if self_pair:
            J = J - _fd_point_jacobian(panda, q2, blink, b_loc)
        return float(n @ J @ qd)

    # the remembered pair's distance at the tick-2 state, and its damper bound
    bb = F2[blink][:3, :3] @ b_loc + F2[blink][:3, 3] if self_pair else b1
    rho = float(np.linalg.norm(a2 - bb))
    bound = -0.5 * min(max((rho - STOP) / (MARGIN - STOP), 0.0), 1.0)
    assert rate(2) >= bound - 1e-6
    assert rate(0) < bound - 0.01


def test_guard_memory_is_validated() -> None:
    for bad in (-1, 1.5, True, 11):
        with pytest.raises(InputError, match="guard_memory"):
            ControllerConfig(guard_memory=bad)  # type: ignore[arg-type]
