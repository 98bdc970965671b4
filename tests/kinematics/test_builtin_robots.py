"""The built-in robots: they load, round-trip through YAML, and follow their sources.

Expected structures are typed in from the thesis tables (P-I Table 1 and Table 3,
P-II Tables 1, 3–7 and §5.1) and from hand calculation, independently of the YAML.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from reachwise.io.robot_file import builtin_robots, load_robot, save_robot
from reachwise.kinematics.robot import Robot

H = math.pi / 2
EXPECTED = {
    "panda",
    "puma560",
    "stanford",
    "sb60",
    "hiab-xs033",
    *(f"p2-man{i}" for i in range(1, 7)),
}


def types(robot: Robot) -> str:
    return "".join({"revolute": "R", "prismatic": "P", "fixed": "F"}[j.type] for j in robot.joints)


def free(robot: Robot) -> set[tuple[int, str]]:
    return {(j, p) for kind, j, p in robot.design.free if kind == "joint"}


def test_every_builtin_loads() -> None:
    assert EXPECTED <= set(builtin_robots())
    for name in builtin_robots():
        robot = load_robot(name)
        assert robot.name == name
        T = robot.fk(np.zeros(robot.n))
        assert T.shape == (4, 4) and np.isfinite(T).all()


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_save_load_round_trip(name: str, tmp_path: Path, rng: np.random.Generator) -> None:
    robot = load_robot(name)
    path = tmp_path / f"{name}.yaml"
    save_robot(robot, path)
    back = load_robot(str(path))
    Q = rng.uniform(robot.lower, robot.upper, (50, robot.n))
    np.testing.assert_allclose(back.fk_all(Q), robot.fk_all(Q), atol=1e-12)
    assert back.convention == robot.convention
    np.testing.assert_array_equal(back.lower, robot.lower)
    np.testing.assert_array_equal(back.upper, robot.upper)
    np.testing.assert_array_equal(back.vmax, robot.vmax)
    np.testing.assert_array_equal(back.actuated, robot.actuated)
    assert back.design.free == robot.design.free
    assert sorted(back.geometry) == sorted(robot.geometry)


# ---- sb60: P-I Table 1 structure, Table 3 initial design, 10-15 m reach -------------
def test_sb60_follows_p1_table1() -> None:
    robot = load_robot("sb60")
    assert types(robot) == "RRPRRRRP"
    dh = robot.dh  # columns a, alpha, d, theta
    np.testing.assert_allclose(dh[:, 1], [0, H, H, H, H, H, -H, H], atol=1e-15)  # alpha_{i-1}
    np.testing.assert_allclose(dh[:, 3], [0, H, 0, H, H, 0, 0, 0], atol=1e-15)  # theta offsets
    # parameters Table 1 writes as 0: a_0, a_3, a_5, a_6, a_7 and d_1, d_2, d_5, d_8 (offset)
    assert all(dh[i, 0] == 0 for i in (0, 3, 5, 6, 7))
    assert all(dh[i, 2] == 0 for i in (0, 1, 4, 7))
    assert robot.n == 8 and robot.prismatic.tolist() == [0, 0, 1, 0, 0, 0, 0, 1]


def test_sb60_design_is_p1_table3() -> None:
    robot = load_robot("sb60")
    # a1, a2, d3 (offset), d4, a4, d6, d7 in P-I numbering -> (0-based joint, field)
    table3 = {
        (1, "a"): 0.3400,
        (2, "a"): 0.7100,
        (2, "d"): 0.6600,
        (3, "d"): 0.6250,
        (4, "a"): 0.4000,
        (5, "d"): 0.7400,
        (6, "d"): 0.6400,
    }
    assert free(robot) == set(table3)
    for (j, p), initial in table3.items():
        lo, hi = robot.design.joints[j][p]
        value = getattr(robot.joints[j], p)
        assert (value - lo) / (hi - lo) == pytest.approx(initial, abs=1e-12)
    base_initial = {"x": 0.75, "y": 0.5, "z": 0.6667}
    for k, (c, initial) in enumerate(base_initial.items()):
        lo, hi = robot.design.base[c]
        assert 3.0 <= hi - lo <= 4.0  # about +-2 m
        assert (robot.base[k, 3] - lo) / (hi - lo) == pytest.approx(initial, abs=1e-4)


def test_sb60_reach_is_10_to_15_m(rng: np.random.Generator) -> None:
    robot = load_robot("sb60")
    Q = rng.uniform(robot.lower, robot.upper, (20000, robot.n))
    reach = np.linalg.norm(robot.fk(Q)[:, :3, 3] - robot.base[:3, 3], axis=1)
    assert 10.0 <= reach.max() <= 15.0
    # fully stretched (booms and feed extended, everything in line): straight ahead
    q = np.zeros(robot.n)
    q[[2, 7]] = robot.upper[[2, 7]]
    p = robot.fk(q)[:3, 3] - robot.base[:3, 3]
    assert 10.0 <= p[0] <= 15.0
    np.testing.assert_allclose(robot.fk(q)[:3, 2], [1, 0, 0], atol=1e-15)  # drilling along +x


def test_sb60_and_hiab_have_geometry_and_velocity_limits() -> None:
    for name in ("sb60", "hiab-xs033"):
        robot = load_robot(name)
        assert set(robot.geometry) == {f"link_{i}" for i in range(len(robot.joints) + 1)}
        for shapes in robot.geometry.values():
            assert [g.shape in ("box", "cylinder") for g in shapes] == [True]
        assert np.isfinite(robot.vmax[robot.actuated]).all()


# ---- hiab-xs033: RRRP + two passive joints (P-V) ------------------------------------
def test_hiab_structure_and_hanging_grabber(rng: np.random.Generator) -> None:
    robot = load_robot("hiab-xs033")
    assert types(robot) == "RRRPRR"
    assert robot.actuated.tolist() == [True, True, True, True, False, False]
    for q in rng.uniform(robot.lower, robot.upper, (50, robot.n)):
        # the tool point (crane TCP) does not move with the passive joints
        moved = q.copy()
        moved[4:] = rng.uniform(robot.lower[4:], robot.upper[4:])
        np.testing.assert_allclose(robot.fk(moved)[:3, 3], robot.fk(q)[:3, 3], atol=1e-12)
        # at q5 = q2 + q3, q6 = 0 the grabber (link_6 x, tool z) hangs straight down
        q[4], q[5] = q[1] + q[2], 0.0
        F = robot.fk_all(q)
        np.testing.assert_allclose(F[6, :3, 0], [0, 0, -1], atol=1e-12)
        np.testing.assert_allclose(F[-1, :3, 2], [0, 0, -1], atol=1e-12)


def test_hiab_tip_by_hand() -> None:
    """At q = 0 booms are horizontal along x: tip = (0.15 + 2.2 + 1.9 + ext, 0, 1.3)."""
    robot = load_robot("hiab-xs033")
    np.testing.assert_allclose(robot.fk(np.zeros(6))[:3, 3], [4.25, 0, 1.3], atol=1e-15)
    q = np.array([H, 0, 0, 1.0, 0, 0])  # slew 90 deg, extension 1 m
    np.testing.assert_allclose(robot.fk(q)[:3, 3], [0, 5.25, 1.3], atol=1e-15)


# ---- stanford: classic DH after Corke's toolbox -------------------------------------
def test_stanford_classic_by_hand() -> None:
    robot = load_robot("stanford")
    assert robot.convention == "classic" and types(robot) == "RRPRRR"
    # q = 0 except the slide d3 = 0.5: d1 up, d2 along y, a3 = 0.0203 back along -y,
    # slide and d6 up: (0, 0.154 - 0.0203, 0.412 + 0.5 + 0.263)
    p = robot.fk([0, 0, 0.5, 0, 0, 0])[:3, 3]
    np.testing.assert_allclose(p, [0, 0.1337, 1.175], atol=1e-15)
    p = robot.fk([H, 0, 0.5, 0, 0, 0])[:3, 3]  # turn the base by 90 deg
    np.testing.assert_allclose(p, [-0.1337, 0, 1.175], atol=1e-15)
    np.testing.assert_allclose(robot.lower[2:3], [12 * 0.0254])
    np.testing.assert_allclose(robot.upper[2:3], [50 * 0.0254])


# ---- the six P-II templates ---------------------------------------------------------
P2 = {  # types, alpha_{i-1}, theta offsets, free (joint, field), from P-II Tables 3-7
    "p2-man1": (
        "RRPRRRP",
        [0, H, -H, 0, H, -H, -H],
        [0, -H, 0, -H, H, -H, 0],
        {(0, "a"), (1, "a"), (2, "d"), (3, "d"), (4, "d"), (6, "d")},
    ),
    "p2-man2": (
        "RRPRRRP",
        [0, H, H, H, H, H, 0],
        [0, H, 0, H, H, H, 0],
        {
            (1, "a"),
            (1, "d"),
            (2, "a"),
            (2, "d"),
            (3, "a"),
            (3, "d"),
            (4, "a"),
            (4, "d"),
            (5, "d"),
            (6, "a"),
        },
    ),
    "p2-man3": (
        "RRPRRR",
        [0, H, -H, 0, H, -H],
        [0, -H, 0, -H, H, -H],
        {(1, "a"), (2, "d"), (3, "d"), (4, "d"), (5, "a"), (5, "d")},
    ),
    "p2-man4": (
        "RRPRRR",
        [0, H, H, H, H, H],
        [0, H, 0, H, H, H],
        {
            (1, "a"),
            (2, "a"),
            (2, "d"),
            (3, "a"),
            (3, "d"),
            (4, "a"),
            (4, "d"),
            (5, "a"),
            (5, "d"),
        },
    ),
    "p2-man5": (
        "RPFRRRR",
        [0, -H, 0, 0, 0, -H, -H],
        [-H, 0, -H, 0, 0, -H, 0],
        {
            (2, "d"),
            (3, "a"),
            (3, "d"),
            (4, "a"),
            (4, "d"),
            (5, "a"),
            (5, "d"),
            (6, "a"),
            (6, "d"),
        },
    ),
}


@pytest.mark.parametrize("name", sorted(P2))
def test_p2_templates_follow_the_tables(name: str) -> None:
    robot = load_robot(name)
    jtypes, alpha, theta, design = P2[name]
    assert types(robot) == jtypes
    np.testing.assert_allclose(robot.dh[:, 1], alpha, atol=1e-15)
    np.testing.assert_allclose(robot.dh[:, 3], theta, atol=1e-15)
    assert free(robot) == design


@pytest.mark.parametrize("name", [f"p2-man{i}" for i in range(1, 7)])
def test_p2_bounds_are_those_of_section_5_1(name: str) -> None:
    robot = load_robot(name)
    assert robot.design.size > 0
    for params in robot.design.joints.values():
        for p, bounds in params.items():
            assert p in ("a", "d") and tuple(bounds) == (-2.0, 2.0)
    assert set(robot.design.base) == {"x", "y", "z"}
    for j in robot.joints:
        if j.type == "prismatic":
            assert j.limits == (0.0, 3.0)
        elif j.type == "revolute":
            assert j.limits == pytest.approx((-math.pi, math.pi), abs=1e-15)
        if j.movable:
            assert not j.passive
    for (j, p), (lo, hi) in (
        ((j, p), b) for j, ps in robot.design.joints.items() for p, b in ps.items()
    ):
        assert lo <= getattr(robot.joints[j], p) <= hi  # nominal inside the bounds


def test_p2_man6_is_seven_revolute() -> None:
    robot = load_robot("p2-man6")
    assert types(robot) == "RRRRRRR"
    assert all(abs(a) in (0.0, H) for a in robot.dh[:, 1])  # twist angles locked
