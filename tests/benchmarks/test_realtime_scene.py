"""The world ``reachwise bench realtime`` times its loop in must be the one it describes:
the camera sees panda-shelf's shelf as the mesh it is (open compartments, not a solid
box), and the arm shuttles between the scenario's goals there instead of standing still
(each pair judged at the controller's margin, not at the scene's watch range)."""

from __future__ import annotations

import numpy as np
import trimesh

from reachwise.benchmarks import realtime as R
from reachwise.data import scenarios


def test_the_shelf_plates_fill_exactly_the_shelf_mesh() -> None:
    mesh = trimesh.load(scenarios.__path__[0] + "/meshes/shelf.obj", force="mesh")
    mesh.apply_translation([0.45, 0.0, 0.0])  # where panda-shelf stands it
    rng = np.random.default_rng(2)
    lo, hi = mesh.bounds
    p = rng.uniform(lo - 0.01, hi + 0.01, size=(20_000, 3))
    in_plates = np.zeros(len(p), np.bool_)
    near_face = np.zeros(len(p), np.bool_)
    for a, b in R.SHELF_PLATES:
        in_plates |= np.all((p >= a) & (p <= b), axis=1)
        inside_grown = np.all((p >= a - 1e-3) & (p <= b + 1e-3), axis=1)
        inside_shrunk = np.all((p >= a + 1e-3) & (p <= b - 1e-3), axis=1)
        near_face |= inside_grown & ~inside_shrunk
    in_mesh = mesh.contains(p)
    judged = ~near_face  # the mesh's edges are bevelled by 0.5 mm
    assert np.count_nonzero(in_plates & judged) > 1000
    np.testing.assert_array_equal(in_plates[judged], in_mesh[judged])


def test_the_bench_arm_reaches_a_goal_at_1_khz_in_the_bench_room() -> None:
    arm, converter, _ = R.loop_scene(R.room_points(100_000), R.camera_frame(0))
    scene, robot, ctrl = arm.scene, arm.robot, arm.controller
    q = arm.q.copy()
    closest = np.inf
    try:
        for k in range(8000):
            t = k * R.DT
            scene.set_joints(robot.name, q, stamp=t)
            res = scene.query_all()
            for p in res.pairs:
                if p.b in ("room", "camera"):
                    closest = min(closest, p.result.distance)
            cmd, status = ctrl.step(q, arm.goals[0], converter(res, stamp=t), t)
            if status.state == "reached":
                break
            q = np.clip(q + cmd * R.DT, robot.lower, robot.upper)
    finally:
        scene.close()
    assert status.state == "reached", f"after {k + 1} ticks: {status}"
    assert closest > 0.0
