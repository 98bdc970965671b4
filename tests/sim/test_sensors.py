"""Depth cameras in scenarios: the ``sensors:`` schema, the camera on a link, the
robot-body filter, the frame schedule, and the true-surface judge."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import trimesh

import reachwise
from reachwise.errors import InputError
from reachwise.sim.contact import Solid, true_clearance
from reachwise.sim.scenarios import load_scenario, scenario_from_dict
from reachwise.sim.world import build_world, move_objects

# the built-in scenarios' folder holds the Panda's stand-in link meshes
FOLDER = load_scenario("trap").folder
# hand down, the flange at (0.45, -0.35, 0.40) m
Q0 = [-0.7435, 0.0963, 0.0846, -2.0309, -0.0096, 2.1269, -0.6543]
LINKS = {
    "link_3": {"mesh": "meshes/panda-upper-arm.obj", "points": 200},
    "link_5": {"mesh": "meshes/panda-forearm.obj", "points": 200},
    "link_7": {"mesh": "meshes/panda-hand.obj", "points": 200},
}
FLOOR_TOP = 0.0


def scenario(**sensor: Any) -> dict[str, Any]:
    """A Panda over a floor (a box only the sensors see) and one depth camera."""
    cam = {
        "kind": "depth",
        "name": "cam",
        "pose": {"xyz": [1.6, 0.0, 0.8]},
        "look_at": [0.0, 0.0, 0.4],
        "width": 40,
        "height": 30,
    }
    cam.update(sensor)
    return {
        "name": "camera-test",
        "dt": 0.01,
        "duration": 0.3,
        "robots": [
            {
                "name": "arm",
                "robot": "panda",
                "q0": Q0,
                "links": list(LINKS),
                "link_clouds": LINKS,
                "goals": [{"xyz": [0.45, -0.30, 0.45], "dims": 3}],
            }
        ],
        "objects": [
            {
                "name": "floor",
                "box": [4.0, 4.0, 0.1],
                "pose": {"xyz": [0.0, 0.0, FLOOR_TOP - 0.05]},
                "scene": False,
            }
        ],
        "sensors": [cam],
        "watch": [{"robot": "arm", "environment": ["cam"], "margin": 0.05}],
    }


def load(data: dict[str, Any]) -> Any:
    return scenario_from_dict(data, "camera-test.yaml", FOLDER)


# --------------------------------------------------------------------------- schema


def _set(data: dict[str, Any], path: str, value: Any) -> None:
    *head, last = path.split(".")
    node: Any = data
    for part in head:
        node = node[int(part)] if part.isdigit() else node[part]
    if value is _DROP:
        del node[last]
    else:
        node[last] = value


_DROP = object()


@pytest.mark.parametrize(
    ("path", "value", "field", "reason"),
    [
        ("sensors.0.kind", "lidar", "sensors[0].kind", "depth"),
        ("sensors.0.rate", 0, "sensors[0].rate", "greater than 0"),
        ("sensors.0.width", 0, "sensors[0].width", "greater than 0"),
        ("sensors.0.dropout", 1.0, "sensors[0].dropout", "less than 1"),
        ("sensors.0.fov_deg", 190, "sensors[0].fov_deg", "less than 180"),
        ("sensors.0.far", 0.1, "sensors[0]", "must exceed near"),
        ("sensors.0.zoom", 2, "sensors[0].zoom", "Extra inputs"),
        ("sensors.0.pose", _DROP, "sensors[0]", "a pose or a link"),
        ("sensors.0.link", {"robot": "arm", "link": "link_7"}, "sensors[0]", "not both"),
        ("sensors.0.pose", {"xyz": [1, 0, 1], "rpy": [0, 0, 0]}, "sensors[0]", "look_at"),
        ("sensors.0.look_at", [1.6, 0.0, 0.8], "sensors[0]", "must differ"),
        ("sensors.0.fov", 1.0, "", "fov or fov_deg"),
        ("sensors.0.rate", 200.0, "", "one frame per tick"),
        ("sensors.0.name", "floor", "", "name of an object"),
        ("watch.0.environment", ["cam2"], "", "unknown object 'cam2'"),
        ("watch.0.environment", ["floor"], "", "not in the scene"),
    ],
)
def test_bad_sensors_name_the_file_field_and_reason(
    path: str, value: Any, field: str, reason: str
) -> None:
    data = scenario()
    if path == "sensors.0.fov":
        data["sensors"][0]["fov_deg"] = 50.0
    _set(data, path, value)
    with pytest.raises(InputError) as err:
        load(data)
    assert err.value.source == "camera-test.yaml"
    assert err.value.field.startswith(field), err.value.field
    assert reason in str(err.value), str(err.value)


def test_two_sensors_need_two_names_and_an_object_outside_the_scene_needs_a_surface() -> None:
    data = scenario()
    data["sensors"].append(copy.deepcopy(data["sensors"][0]))
    with pytest.raises(InputError, match="sensor names must be unique"):
        load(data)
    data = scenario()
    data["objects"].append({"name": "scan", "file": "x.ply", "scene": False})
    with pytest.raises(InputError, match="needs a surface: mesh or box") as err:
        load(data)
    assert err.value.field == "objects[1]"


def test_mounting_errors_name_the_robot_or_link() -> None:
    data = scenario(pose=None, look_at=None, link={"robot": "crane", "link": "link_7"})
    del data["sensors"][0]["pose"], data["sensors"][0]["look_at"]
    with pytest.raises(InputError, match="unknown robot 'crane'"):
        load(data)
    data["sensors"][0]["link"]["robot"] = "arm"
    data["sensors"][0]["link"]["link"] = "link_9"
    with pytest.raises(InputError, match="no link 'link_9'") as err:
        build_world(load(data))
    assert err.value.field == "sensors[0].link.link"
    data["sensors"][0]["link"]["link"] = "link_7"  # at the link origin: inside the hand
    with pytest.raises(InputError, match="inside arm/link_7") as err:
        build_world(load(data))
    assert err.value.field == "sensors[0]"


# --------------------------------------------------------------------------- geometry


def floor_points(pose: np.ndarray, rays: np.ndarray) -> np.ndarray:
    """Where the camera's pixel rays (camera frame) meet the plane z = FLOOR_TOP."""
    d = rays @ pose[:3, :3].T
    o = pose[:3, 3]
    t = (FLOOR_TOP - o[2]) / d[:, 2]
    return np.asarray(o + t[:, None] * d)


def on_hand_scenario() -> Any:
    """The camera 8 cm beside the hand axis on link_7, looking down the hand (link z)."""
    data = scenario(link={"robot": "arm", "link": "link_7", "offset": {"xyz": [0.08, 0, 0]}})
    del data["sensors"][0]["pose"], data["sensors"][0]["look_at"]
    data["sensors"][0].update(rate=25.0, latency=0.02, fov_deg=50.0)
    return load(data)


def arm_mesh(sight: Any, q: np.ndarray) -> trimesh.Trimesh:
    """The arm's link surfaces in world at joint state ``q``."""
    fk = sight.frames({"arm": q})
    links = []
    for b in sight.bodies.values():
        m = trimesh.Trimesh(*b.mesh, process=False)
        m.apply_transform(fk[b.robot][b.index])
        links.append(m)
    return trimesh.util.concatenate(links)


def test_a_camera_on_a_link_moves_with_it() -> None:
    """Frames stream in at their ticks, each one the analytic floor seen from the link's
    pose at its capture tick (the joints of that tick), less the pixels whose rays meet
    the arm first (found here with trimesh's own ray-triangle test), stamped with the
    capture time."""
    from trimesh.ray.ray_triangle import RayMeshIntersector

    world = build_world(on_hand_scenario())
    sensor, sight, scene = world.sensors[0], world.sight, world.scene
    assert sight is not None
    rays = sensor.camera.intrinsics.rays()
    robot = world.robots["arm"]
    offset = np.eye(4)
    offset[0, 3] = 0.08
    q0 = np.array(Q0)
    qs = [q0 + 0.02 * k * np.array([1.0, -0.5, 0.3, 0.4, 0.0, -0.6, 0.2]) for k in range(40)]
    seen = set()
    for tick, q in enumerate(qs):
        sensor.step(scene, tick, sight, {"arm": q})
        k = sensor.frame_in_use(tick)
        assert k == sensor.in_use
        capture = sensor.capture_tick(k)
        pose = robot.fk_all(qs[capture])[robot.link_index("link_7")] @ offset
        if k not in seen:
            d = rays @ pose[:3, :3].T
            arm = RayMeshIntersector(arm_mesh(sight, qs[capture]))
            hidden = arm.intersects_any(np.broadcast_to(pose[:3, 3], d.shape), d)
            assert 0 < hidden.sum() < 0.5 * len(hidden)  # the hand is in view
            np.testing.assert_allclose(
                scene.objects["cam"].cloud.points, floor_points(pose, rays)[~hidden], atol=1e-9
            )
        answer = scene.query_all()
        assert answer.cloud_stamps["cam"] == pytest.approx(capture * 0.01)
        seen.add(k)
    # 25 frames/s at 100 ticks/s: captures at ticks 0, 4, 8, …, each 2 ticks later in
    assert sorted(seen) == list(range(10))
    assert [sensor.delivery_tick(k) for k in (1, 2, 3)] == [6, 10, 14]


def test_the_self_filter_removes_the_robot_and_its_shadow_stays_empty() -> None:
    """A camera looking at the arm over the floor: filtered, every returned point lies
    on the floor and the arm's pixels return nothing; unfiltered, the arm's pixels
    return points on the arm's link surfaces."""
    pose = {"xyz": [1.3, -0.35, 1.2]}
    world = build_world(load(scenario(pose=pose, look_at=[0.45, -0.35, 0.2], width=80, height=60)))
    raw = build_world(
        load(
            scenario(pose=pose, look_at=[0.45, -0.35, 0.2], width=80, height=60, self_filter=False)
        )
    )
    qs = {"arm": np.array(Q0)}
    sight = world.sight
    assert sight is not None and raw.sight is not None
    kept = world.sensors[0].render(1, sight, qs)
    full = raw.sensors[0].render(1, raw.sight, qs)
    assert kept.body is not None and kept.body.sum() > 100  # the arm fills pixels
    np.testing.assert_allclose(kept.points[:, 2], FLOOR_TOP, atol=1e-9)
    assert np.isnan(kept.depth[kept.body]).all()
    off_floor = np.abs(full.points[:, 2] - FLOOR_TOP) > 1e-6
    assert off_floor.sum() == kept.body.sum()  # the same pixels, now returning the arm
    arm = arm_mesh(sight, qs["arm"])
    _, dist, _ = trimesh.proximity.closest_point(arm, full.points[off_floor])
    assert dist.max() < 1e-6


def test_a_camera_that_sees_nothing_hands_over_its_far_point() -> None:
    world = build_world(load(scenario(pose={"xyz": [0, 0, 3.0]}, look_at=[0.0, 5.0, 3.5])))
    sensor = world.sensors[0]
    cloud = world.scene.objects["cam"].cloud
    axis = sensor.offset[:3, 2]
    np.testing.assert_allclose(cloud.points, [[0.0, 0.0, 3.0] + sensor.spec.far * axis])


def test_the_controllers_get_no_ground_truth_of_an_object_outside_the_scene() -> None:
    data = scenario()
    data["objects"].append(
        {
            "name": "walker",
            "box": [0.4, 0.4, 1.7],
            "scene": False,
            "motion": {"velocity": [-0.5, 0, 0], "start": 0.0},
            "pose": {"xyz": [2.0, 0.0, 0.85]},
        }
    )
    world = build_world(load(data))
    assert set(world.scene.objects) == {"arm/link_3", "arm/link_5", "arm/link_7", "cam"}
    assert move_objects(world, 0.5) == {}  # no pose, no twist reaches the controllers
    assert {p.b for p in world.scene.pairs} == {"cam"}
    assert ("arm/link_7", "walker") in world.truth and ("arm/link_7", "floor") in world.truth


# --------------------------------------------------------------------------- runs


def test_frames_reach_the_scene_at_their_ticks_with_their_capture_stamps(tmp_path: Path) -> None:
    data = scenario(rate=30.0, latency=0.03, noise=0.003, dropout=0.05)
    sc = load(data)
    stamps: list[float] = []

    def hook(t: float, qs: dict[str, np.ndarray], res: Any) -> None:
        stamps.append(res.cloud_stamps["cam"])

    log = reachwise.simulate(sc, on_tick=hook)
    sensor = build_world(sc).sensors[0]
    ticks = np.arange(log.t.size)
    expect = np.array([sensor.frame_in_use(int(k)) for k in ticks])
    np.testing.assert_array_equal(log.frames["cam"], expect)
    capture = np.array([sensor.capture_tick(int(f)) * 0.01 for f in expect])
    np.testing.assert_allclose(stamps, capture, atol=1e-12)
    age = log.t - capture
    assert age.max() <= sensor.max_age() + 1e-9 and sensor.max_age() == pytest.approx(0.07)
    # reproducible: a second run, and the saved log read back, agree
    again = reachwise.simulate(sc)
    np.testing.assert_array_equal(again.distance, log.distance)
    np.testing.assert_array_equal(again.true_distance, log.true_distance)
    back = reachwise.sim.log.load_log(log.save(tmp_path / "run"), sc)
    np.testing.assert_array_equal(back.frames["cam"], log.frames["cam"])
    np.testing.assert_array_equal(back.true_distance, log.true_distance)
    assert back.true_pairs == log.true_pairs


# --------------------------------------------------------------------------- the judge


def test_true_clearance_is_the_surface_gap_or_the_depth_of_an_overlap() -> None:
    cube = trimesh.creation.box(extents=(0.2, 0.2, 0.2))
    mesh = (np.asarray(cube.vertices), np.asarray(cube.faces))
    solid = Solid("box", np.eye(4), np.full(3, 0.1))
    at = np.eye(4)

    def shifted(*xyz: float) -> np.ndarray:
        T = np.eye(4)
        T[:3, 3] = xyz
        return T

    assert true_clearance(mesh, solid, at, mesh, solid, shifted(0.35, 0, 0)) == pytest.approx(0.15)
    # a corner of each 3 cm deep in the other cube (a known violation)
    overlap = true_clearance(mesh, solid, at, mesh, solid, shifted(0.17, 0.17, 0.17))
    assert overlap == pytest.approx(-0.03)
    # faces crossing, no corner inside: touching counts as an overlap of depth 0
    assert true_clearance(mesh, solid, at, mesh, solid, shifted(0.17, 0, 0)) == 0.0
    small = trimesh.creation.box(extents=(0.05, 0.05, 0.05))
    inner = (np.asarray(small.vertices), np.asarray(small.faces))
    inside = true_clearance(mesh, solid, at, inner, Solid("box", np.eye(4), np.full(3, 0.025)), at)
    assert inside == pytest.approx(-0.075)  # its corners 7.5 cm inside the big cube
