"""The ``always`` rule against the true shapes: the UR5's pairs excluded as always
within 2 cm with the default clouds (each covering its shapes within 1 cm) are within
2 cm by exact mesh distances (:func:`reachwise.geometry.mesh_distance.mesh_distance`,
triangle against triangle, not our clouds) in at least 95 % of a separate set of
random configurations, so they are structurally close on the real meshes, not by an
artefact of the clouds; 1000-point sampled clouds, with no coverage guarantee, put
base_link-upper_arm_link within 2 cm in fewer than 95 % of the same configurations
(measured over 300: 38 % against 100 % by the meshes, its sampled clouds overstating
the surface distance by up to 16.9 mm, the covering clouds by up to 5.0 mm)."""

from __future__ import annotations

import numpy as np

import reachwise
from reachwise.distance.engine import PairQuery
from reachwise.distance.self_pairs import (
    ALWAYS_FRACTION,
    random_configurations,
    self_collision_pairs,
)
from reachwise.geometry.mesh_distance import mesh_distance
from reachwise.io.robot_clouds import link_mesh
from tests._real_arms import arm_path, needs_erd

pytestmark = needs_erd
MARGIN, CONFIGS = 0.02, 100


def test_ur5_pairs_always_within_2cm_are_so_on_the_meshes() -> None:
    robot = reachwise.load_robot(arm_path("ur5"), tip="tool0")
    clouds = reachwise.link_clouds(robot)
    found = self_collision_pairs(robot, clouds, MARGIN, samples=2000, seed=0)
    always = {(p.a, p.b) for p in found.always}
    assert {("base_link", "upper_arm_link"), ("forearm_link", "wrist_2_link")} <= always
    F = robot.fk_all(random_configurations(robot, CONFIGS, 7))
    for a, b in sorted(always):
        ia, ib = robot.link_index(a), robot.link_index(b)
        ma, mb = link_mesh(robot, a), link_mesh(robot, b)
        d = np.array([mesh_distance(ma, mb, f[ia], f[ib]) for f in F])
        assert np.mean(d <= MARGIN) >= ALWAYS_FRACTION, (a, b, float(np.mean(d <= MARGIN)))
    sampled = reachwise.link_clouds(robot, points=1000)
    a, b = "base_link", "upper_arm_link"
    query = PairQuery(sampled[a], sampled[b])
    ia, ib = robot.link_index(a), robot.link_index(b)
    d = np.array([query(f[ia], f[ib]).distance for f in F])
    assert np.mean(d <= MARGIN) < ALWAYS_FRACTION  # the sampled clouds' artefact
