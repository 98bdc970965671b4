"""Automatic self-collision pairs cost no reach: UR5, Panda, xArm7, Kinova and Z1
(example-robot-data, their URDFs and collision meshes, packages resolved by our
loader) with ``pairs: auto`` and a 2 cm self margin reach 20 random reachable goals
each as often as the same controller without self pairs (within one goal).

A reachable goal is the tool position of a random configuration (seeded, uniform within
the joint limits) in which every watched pair is outside its margin (the controller's:
2 cm between the surfaces plus both clouds' resolutions, or the pair's own); goal ``k``
starts from the configuration of goal ``k − 1`` (the first from one more such
configuration), so every trial starts outside every margin and both
controllers start each trial from the same state. The loop is the controller's own fast
path, as ``reachwise bench control`` runs it: the distance scene's query, the conversion
into avoidance points and the controller step, the joints integrated kinematically (no
MuJoCo, no logging). Each goal gets 5 s (500 ticks of 10 ms); a goal counts as reached
when the controller says so within them. A goal the controller without pairs reaches by
driving two of the arm's links through each other (a watched pair's cloud distance below
5 mm at some tick: the clouds' points lie on the surfaces, a few millimetres apart, so
the surfaces touch or cross) does not count: it was not reached.

With the pairs the arm stays clear of itself: no watched pair comes closer than 5 mm
at any tick (the margin is 2 cm; the repulsion and the guard may let a pair into it,
never through it), nor a pair with a margin of its own under 1 cm (structurally close,
its clouds too coarse to promise its surfaces apart, like the UR5's forearm and
wrist_2) closer than half that margin, the damper's stop distance.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import reachwise
from reachwise.control.controller import Goal
from reachwise.distance.self_pairs import pair_hits, random_configurations
from reachwise.sim.resolve import ResolvedScenario, resolve_scenario
from reachwise.sim.world import World, build_world
from tests._real_arms import ARMS, ERD, needs_erd

pytestmark = needs_erd

ROBOTS = ("ur5", "panda", "xarm7", "kinova", "z1")
GOALS = 20
MARGIN = 0.02
DT = 0.01
TICKS = 500
CONTACT = 0.005  # a watched pair this close (cloud distance): the links touch
SLACK = 1e-4  # the damper holds a pair at its stop distance, to rounding and one tick


def _scenario(tmp_path: Path, name: str, self_pairs: bool) -> ResolvedScenario:
    """A scenario of arm ``name``: at 0 (moved into its limits), one placeholder goal
    (the test gives its own), and with ``self_pairs`` the automatic pairs."""
    assert ERD is not None
    urdf, tip = ARMS[name]
    robot = reachwise.load_robot(ERD / urdf, tip=tip)
    q0 = [float(v) for v in np.clip(np.zeros(robot.n), robot.lower, robot.upper)]
    watch = (
        f"watch:\n  - self: {{robot: arm, pairs: auto, samples: 2000}}\n    margin: {MARGIN}\n"
        if self_pairs
        else ""
    )
    text = f"""name: {name}-goals
dt: {DT}
duration: 1.0
robots:
  - name: arm
    robot: {{file: "{ERD / urdf}", tip: {tip}}}
    q0: {q0}
    controller: {{kv: 2.0, v_max: 0.5, mu: 2.0e-4, v_rep_max: 0.5, stop_distance: 0.03,
                  approach_speed: 0.15, position_tolerance: 0.005}}
    plant: {{kind: kinematic}}
    goals: [{{name: placeholder, xyz: [0.3, 0.0, 0.3], dims: 3}}]
{watch}"""
    path = tmp_path / f"{name}-{'pairs' if self_pairs else 'none'}.yaml"
    path.write_text(text)
    return resolve_scenario(path)


def _watched(world: World) -> list[tuple[str, str]]:
    return [tuple(p.split("|")[i].split("/", 1)[1] for i in (0, 1)) for p in world.pairs]  # type: ignore[misc]


def _trials(res: ResolvedScenario, world: World, seed: int) -> np.ndarray:
    """``GOALS + 1`` random configurations with every watched pair beyond its margin."""
    robot = world.robots["arm"]
    clouds = {k.split("/", 1)[1]: c for k, (c, _) in res.link_clouds.items()}
    Q = random_configurations(robot, 100 * (GOALS + 1), seed)
    clear = np.ones(len(Q), dtype=bool)
    for pair, margin in zip(_watched(world), world.margins, strict=True):
        clear &= ~pair_hits(robot, clouds, [pair], float(margin), Q)[:, 0]
    assert clear.sum() > GOALS, int(clear.sum())
    return Q[clear][: GOALS + 1]


def _reach(world: World, watch: World, starts: np.ndarray, goals: list[Goal]) -> tuple[int, float]:
    """How many goals the controller of ``world`` reaches, each from its start, without
    a watched pair of ``watch`` (the world with the pairs) closing below its contact
    distance (``CONTACT``, or half its margin when that is smaller: a structurally
    close pair whose own margin is below 0, its clouds too coarse to tell, is kept at
    least that far apart by the damper), and the smallest watched-pair distance less
    its contact distance at any tick."""
    agent = world.agents[0]
    robot, ctrl, scene = agent.robot, agent.controller, watch.scene
    floor = np.minimum(CONTACT, 0.5 * watch.margins)
    reached, closest = 0, np.inf
    for q0, goal in zip(starts, goals, strict=True):
        q = q0.copy()
        ctrl.reset()
        nearest = np.inf
        for k in range(TICKS):
            t = k * DT
            scene.set_joints("arm", q, stamp=t)
            res = scene.query_all()
            d = np.array([p.result.distance for p in res.pairs])
            nearest = min(nearest, float(np.min(d - floor)))
            pts = agent.converter(res, stamp=t) if world.avoidance else None
            cmd, st = ctrl.step(q, goal, pts, t)
            if st.state == "reached":
                reached += nearest > -SLACK
                break
            q = np.clip(q + np.clip(cmd, -robot.vmax, robot.vmax) * DT, robot.lower, robot.upper)
        closest = min(closest, nearest)
    return reached, closest


@pytest.mark.parametrize("name", ROBOTS)
def test_automatic_pairs_reach_as_many_random_goals_as_none(tmp_path: Path, name: str) -> None:
    res = _scenario(tmp_path, name, True)
    paired = build_world(res, True)
    bare = build_world(_scenario(tmp_path, name, False), False)
    assert len(paired.pairs) >= 5, paired.pairs  # the automatic pairs are watched
    assert not bare.pairs
    configs = _trials(res, paired, seed=ROBOTS.index(name))
    robot = paired.robots["arm"]
    goals = [Goal.at(robot.fk(q)[:3, 3]) for q in configs[1:]]
    with_pairs, closest = _reach(paired, paired, configs[:-1], goals)
    without, _ = _reach(bare, paired, configs[:-1], goals)
    print(f"{name}: {with_pairs}/{GOALS} with self pairs, {without}/{GOALS} without; "
          f"closest pair {closest * 1000:.1f} mm beyond its contact distance")  # fmt: skip
    assert with_pairs >= without - 1, (with_pairs, without)
    assert with_pairs >= 2 * GOALS // 5  # not a comparison of failures (measured: 10-15)
    assert closest > -SLACK
