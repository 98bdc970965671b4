"""A link fixed to a flange is watched against the wrist, and kept apart from it: on
example-robot-data's ``panda_collision`` (``panda_hand`` against ``panda_link6``) and
Talos's left arm (``wrist_left_ft_link`` against ``arm_left_6_link``), a scenario with
automatic self pairs drives the two together: its goal is the tool pose at the start
configuration with the last joint turned to where the two links' surfaces are closest
(7.7 mm for the Panda, 3.5 mm for Talos, near its joint limit; the distance of these
pairs depends on that joint alone). The conventional controller brings the surfaces
within 1 cm of each other; with avoidance the pair is watched and the surfaces stay at
least 1 mm farther apart than without, the pair's cloud distance (what the controller
sees) never below the damper's stop distance (half the margin). Measured: Panda 8.9 mm
without, 18.6 mm with; Talos 4.3 mm without, 5.9 mm with. Judged by exact mesh distances
(:func:`reachwise.geometry.mesh_distance.mesh_distance`, triangle against triangle; not
our clouds) at every 5th tick of the logged joint trajectory.

Talos's pair is never more than 14.9 mm apart, so its margin is 1.4 cm (within it in
about 93 % of the joint space: watched; at 2 cm it is excluded as always within the
margin).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import reachwise
from reachwise.geometry.mesh_distance import mesh_distance
from reachwise.io.robot_clouds import link_mesh
from reachwise.sim.log import SimulationLog
from reachwise.sim.resolve import resolve_scenario
from tests._real_arms import ERD, needs_erd

pytestmark = needs_erd

#: name -> (URDF, tip, the two links, start configuration, last joint at the goal, margin)
CASES = {
    "panda_collision": (
        "panda_description/urdf/panda_collision.urdf", "panda_hand",
        ("panda_link6", "panda_hand"), [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, -2.17], -0.72,
        0.02,
    ),
    "talos_left_arm": (
        "talos_data/robots/talos_left_arm.urdf", "gripper_left_base_link",
        ("arm_left_6_link", "wrist_left_ft_link"), [0.3, 0.3, -0.3, -1.0, 0.0, 0.0], -0.68,
        0.014,
    ),
}  # fmt: skip


def _scenario(tmp_path: Path, case: str) -> Path:
    assert ERD is not None
    urdf, tip, _, q0, last, margin = CASES[case]
    goal = [*q0[:-1], last]
    text = f"""name: {case}-together
dt: 0.01
duration: 4.0
robots:
  - name: arm
    robot: {{file: "{ERD / urdf}", tip: {tip}}}
    q0: {q0}
    controller: {{kv: 1.0, kw: 1.0, v_max: 0.25, w_max: 0.8, mu: 2.0e-4, v_rep_max: 0.5,
                  stop_distance: 0.03, approach_speed: 0.15}}
    plant: {{kind: kinematic}}
    goals: [{{name: together, q: {goal}, dims: 6}}]
watch:
  - self: {{robot: arm, pairs: auto, samples: 2000}}
    margin: {margin}
"""
    path = tmp_path / f"{case}.yaml"
    path.write_text(text)
    return path


def _surfaces(robot: reachwise.Robot, log: SimulationLog, a: str, b: str) -> np.ndarray:
    """The exact distance of links ``a`` and ``b``'s collision meshes at every 5th tick."""
    ma, mb = link_mesh(robot, a), link_mesh(robot, b)
    ia, ib = robot.link_index(a), robot.link_index(b)
    F = robot.fk_all(log.q["arm"][::5])
    return np.array([mesh_distance(ma, mb, f[ia], f[ib]) for f in F])


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_scenario_driving_flange_link_and_wrist_together_keeps_them_apart(
    tmp_path: Path, case: str
) -> None:
    assert ERD is not None
    urdf, tip, (a, b), _, _, _ = CASES[case]
    resolved = resolve_scenario(_scenario(tmp_path, case))  # read once, run twice
    avoid = reachwise.simulate(resolved)
    base = reachwise.simulate(resolved, avoidance=False)
    assert f"arm/{a}|arm/{b}" in avoid.pairs  # watched, picked automatically
    robot = reachwise.load_robot(ERD / urdf, tip=tip)
    near = _surfaces(robot, base, a, b)
    apart = _surfaces(robot, avoid, a, b)
    print(f"{case}: surfaces {near.min() * 1e3:.1f} mm apart at the closest without avoidance, "
          f"{apart.min() * 1e3:.1f} mm with")  # fmt: skip
    assert near.min() < 0.01, near.min()  # without avoidance: driven within 1 cm
    assert apart.min() >= near.min() + 0.001, (apart.min(), near.min())
    # what the controller sees, its clouds, never closer than the damper's stop distance
    k = avoid.pairs.index(f"arm/{a}|arm/{b}")  # its margin: the controller's, with the
    stop = min(0.03, 0.5 * float(avoid.margins[k]))  # resolutions or its own (stop_within)
    assert avoid.distance[:, k].min() >= stop - 1e-4, (avoid.distance[:, k].min(), stop)
    assert avoid.first_collision is None
