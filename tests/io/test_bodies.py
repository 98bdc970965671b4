"""Every URDF link is a body of its own: its shapes, its cloud and its pairs stay its
own whatever frame it rides on, and adjacency is MoveIt's rule (one joint, or only
links without shapes between), so a hand fixed to a flange is checked against the
wrist link beyond the joint that moves it."""

from __future__ import annotations

import numpy as np
import pytest

import reachwise
from reachwise.distance.engine import PairQuery
from reachwise.distance.self_pairs import (
    adjacent_reason,
    random_configurations,
    self_collision_pairs,
)
from reachwise.io.robot_clouds import link_mesh
from reachwise.kinematics.bodies import Body, adjacent_bodies
from tests._real_arms import ERD, needs_erd


def test_moveit_adjacency_on_a_tree() -> None:
    # a - b - c - d, c - e (a branch); b and e have no shapes
    tree = {
        "a": Body("f0"),
        "b": Body("f1", "a"),
        "c": Body("f1", "b"),
        "d": Body("f2", "c"),
        "e": Body("f2", "c"),
    }
    shaped = {"a", "c", "d"}
    assert adjacent_bodies(tree, shaped, "a", "c")  # through b, which has no shapes
    assert adjacent_bodies(tree, shaped, "c", "d")  # one joint
    assert not adjacent_bodies(tree, shaped, "d", "e")  # c, between them, has shapes
    assert adjacent_bodies(tree, shaped - {"c"}, "d", "e")  # it has none: adjacent
    assert not adjacent_bodies(tree, shaped, "a", "d")  # c has shapes in between
    assert adjacent_bodies(tree, shaped - {"c"}, "a", "d")


CASES = {
    "panda_collision": (
        "panda_description/urdf/panda_collision.urdf", "panda_hand", ("panda_link6", "panda_hand")
    ),
    "talos_left_arm": (
        "talos_data/robots/talos_left_arm.urdf",
        "gripper_left_base_link",
        ("arm_left_6_link", "wrist_left_ft_link"),
    ),
}  # fmt: skip


def _mesh_distance(robot: reachwise.Robot, a: str, b: str, q: np.ndarray) -> float:
    """The distance of the two links' true surfaces at ``q``: 5000 points sampled on
    ``a``'s shapes, each projected exactly onto ``b``'s triangles (trimesh)."""
    import trimesh

    F = robot.fk_all(q)
    ma = link_mesh(robot, a).copy()
    mb = link_mesh(robot, b).copy()
    ma.apply_transform(F[robot.link_index(a)])
    mb.apply_transform(F[robot.link_index(b)])
    pts = ma.sample(5000, seed=3)
    _, d, _ = trimesh.proximity.closest_point(mb, pts)
    return float(d.min())


@needs_erd
@pytest.mark.parametrize("case", sorted(CASES))
def test_a_link_fixed_to_a_flange_is_watched_against_the_wrist(case: str) -> None:
    path, tip, (a, b) = CASES[case]
    assert ERD is not None
    robot = reachwise.load_robot(ERD / path, tip=tip)
    clouds = reachwise.link_clouds(robot)
    links = list(clouds)
    assert a in links and b in links  # each its own cloud, not merged into a frame's
    assert adjacent_reason(robot, links, a, b) is None
    found = self_collision_pairs(robot, clouds, 0.01, samples=2000, seed=0)
    assert (a, b) in found.watched or (b, a) in found.watched
    # the exact surfaces do come that close: at the closest of 300 random configurations
    # by the clouds, the true surfaces are within 1 cm of touching too
    Q = random_configurations(robot, 300, 5)
    F = robot.fk_all(Q)
    query = PairQuery(clouds[a], clouds[b])
    ia, ib = robot.link_index(a), robot.link_index(b)
    k = int(np.argmin([query(f[ia], f[ib]).distance for f in F]))
    assert _mesh_distance(robot, a, b, Q[k]) < 0.01
