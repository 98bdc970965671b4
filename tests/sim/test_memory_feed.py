"""Scene memories in scenarios: the schema's rules, and a camera's frames fused into the
memory object of the scene (against the memory fed directly)."""

from __future__ import annotations

import copy
from importlib.resources import files
from pathlib import Path

import numpy as np
import pytest
import trimesh
import yaml

from reachwise.distance.scene import Scene
from reachwise.distance.scene_memory import ViewIntrinsics
from reachwise.errors import InputError
from reachwise.geometry.depth_camera import DepthCamera, Intrinsics
from reachwise.sim.memory_feed import MemoryFeed
from reachwise.sim.scenarios import MemorySpec, scenario_from_dict

FIXTURE = Path(__file__).parent / "data" / "panda-memory-far-side.yaml"


FOLDER = Path(str(files("reachwise.data") / "scenarios"))  # the fixture's meshes


def spec_dict() -> dict:
    return yaml.safe_load(FIXTURE.read_text(encoding="utf-8"))


def test_the_memory_scenario_watches_the_memory_not_its_camera() -> None:
    sc = scenario_from_dict(spec_dict(), source=FIXTURE.name, folder=FOLDER)
    assert [m.name for m in sc.spec.memory] == ["cell"]
    assert sc.spec.memory[0].sensors == ["camera"]
    assert all(w.environment == ["cell"] for w in sc.spec.watch)


@pytest.mark.parametrize(
    ("edit", "reason"),
    [
        (lambda d: d["memory"][0].update(sensors=["nope"]), "unknown sensor 'nope'"),
        (lambda d: d["memory"].append({**d["memory"][0], "name": "second"}), "feeds two"),
        (lambda d: d["memory"][0].update(name="camera"), "name of an object or a sensor"),
        (lambda d: d["watch"][0].update(environment=["camera"]), "watch the memory"),
        (lambda d: d["memory"][0]["box"].update(upper=[1.0, 1.0, 0.0]), "must exceed"),
        (lambda d: d["memory"][0].update(voxel=0.0), "voxel"),
        (lambda d: d["memory"][0].update(shadow=0.3), "shadow"),
    ],
)
def test_a_wrong_memory_entry_is_an_input_error(edit, reason: str) -> None:
    data = copy.deepcopy(spec_dict())
    edit(data)
    with pytest.raises(InputError, match=reason):
        scenario_from_dict(data, source="cell.yaml", folder=FOLDER)


def test_frames_reach_the_scene_as_the_memorys_obstacles() -> None:
    cam = DepthCamera(Intrinsics.from_fov(64, 48, 1.0), near=0.2, far=6.0)
    T = np.eye(4)  # looking along world +z
    wall = trimesh.creation.box(
        [4.0, 4.0, 0.02], trimesh.transformations.translation_matrix([0, 0, 3])
    )
    person = trimesh.creation.box(
        [0.4, 0.4, 0.3], trimesh.transformations.translation_matrix([0, 0, 1.5])
    )
    robot = trimesh.creation.box(
        [0.3, 0.3, 0.1], trimesh.transformations.translation_matrix([0.5, 0, 1.0])
    )
    spec = MemorySpec(
        name="cell", box={"lower": [-1.5, -1.5, 0.5], "upper": [1.5, 1.5, 3.5]}, sensors=["cam"],
        voxel=0.05,
    )  # fmt: skip
    feed, direct = MemoryFeed(spec), MemoryFeed(spec)
    scene = Scene()
    feed.flush(scene)  # nothing seen yet: one point far above the box
    scene.query_all()
    assert scene.objects["cell"].cloud.points[:, 2].min() > 100.0
    frame = cam.frame([wall, person], T, body=[robot])
    assert frame.body is not None and frame.body.any()
    # the self-filter's depth: the robot's box, 0.95 to 1.05 m from the camera
    zb = frame.body_depth[frame.body]
    assert np.all((zb >= 0.95 - 1e-9) & (zb <= 1.05 + 1e-9)) and np.isclose(np.median(zb), 0.95)
    assert np.isnan(frame.body_depth[~frame.body]).all()
    feed.fuse(cam, frame, 0.5)
    feed.flush(scene)
    scene.query_all()
    got = scene.objects["cell"].cloud.points
    depth = np.where(frame.body, frame.body_depth, frame.depth)
    i = cam.intrinsics
    direct.memory.integrate(
        depth, T, ViewIntrinsics(i.fx, i.fy, i.cx, i.cy, 0.2, 6.0), 0.5, frame.body
    )
    assert np.array_equal(np.sort(got, axis=0), np.sort(direct.memory.obstacles(), axis=0))
    # the person's front face is occupied, the robot is not in the map
    centre = frame.points[np.argmin(np.linalg.norm(frame.points[:, :2], axis=1))]
    assert direct.memory.state[direct.memory.voxel_of(centre)] == 2
    assert all(np.linalg.norm(got - [0.5, 0.0, 1.0], axis=1) > 0.1)


def test_a_built_memory_scenario_watches_the_map_with_the_inflation_and_runs() -> None:
    from reachwise.sim.simulate import simulate
    from reachwise.sim.world import build_world

    sc = scenario_from_dict(spec_dict(), source=FIXTURE.name, folder=FOLDER)
    world = build_world(sc)
    assert "cell" in world.scene.objects and "camera" not in world.scene.objects
    (feed,) = world.memories
    assert world.sensors[0].feed is feed
    assert {p.b for p in world.scene.pairs} == {"cell"}
    assert np.allclose(world.margins, 0.25 + feed.inflation)
    assert all(
        p.margin == pytest.approx(0.25 + sc.spec.monitor + feed.inflation)
        for p in world.scene.pairs
    )
    log = simulate(sc, duration=0.3)
    assert log.frames["camera"].max() >= 8  # 30 frames/s for 0.3 s, all fused
    assert not np.isnan(log.distance).any()  # inf: beyond the monitor range, no risk
    assert log.first_collision is None


def test_the_feed_leaves_the_robots_body_out_of_the_map_and_keeps_its_state() -> None:
    """A person seen in front of a robot part shadows the part's volume; handed over
    with the part's pose, no voxel centre within the inflation of the part's surface
    (nor inside it) is in the scene's cloud, the voxels stay shadow, and without the
    pose (or once the part moved away) they are obstacles again."""
    from reachwise.sim.contact import solid_of_mesh
    from reachwise.sim.memory_feed import body_pieces
    from reachwise.sim.sensors import BodySurface

    cam = DepthCamera(Intrinsics.from_fov(64, 48, 1.0), near=0.2, far=6.0)
    person = trimesh.creation.box(
        [0.6, 0.6, 0.3], trimesh.transformations.translation_matrix([0, 0, 1.5])
    )
    part = trimesh.creation.cylinder(radius=0.06, height=0.4)  # along z in its frame
    surface = (np.asarray(part.vertices, float), np.asarray(part.faces, np.int64))
    link = BodySurface("arm/link", "arm", "link", 2, surface, solid_of_mesh(part))
    (piece,) = body_pieces([link])
    assert np.all(surface[0] @ piece.normals.T <= piece.offsets + 1e-12)  # holds the part
    spec = MemorySpec(
        name="cell", box={"lower": [-1.0, -1.0, 0.5], "upper": [1.0, 1.0, 2.5]}, sensors=["cam"],
        voxel=0.05, shadow_depth=0.5,
    )  # fmt: skip
    feed = MemoryFeed(spec, [piece])
    feed.fuse(cam, cam.frame([person], np.eye(4)), 0.0)
    pose = trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0])
    pose[:3, 3] = [0.05, 0.0, 1.8]  # lying across the person's shadow
    frames = {"arm": np.stack([np.eye(4), np.eye(4), pose])}
    everything = feed.cloud().points
    kept = feed.cloud(frames).points
    placed = trimesh.Trimesh(surface[0] @ pose[:3, :3].T + pose[:3, 3], surface[1])
    near_part = trimesh.proximity.signed_distance(placed, everything) > -feed.inflation
    assert near_part.sum() >= 10  # the shadow reached into the part
    kept_set = {tuple(p) for p in np.round(kept, 9)}
    assert not kept_set & {tuple(p) for p in np.round(everything[near_part], 9)}
    assert len(kept) >= len(everything) - 3 * near_part.sum()  # only near the part
    states = [feed.memory.state[feed.memory.voxel_of(p)] for p in everything[near_part]]
    assert set(states) <= {2, 3}  # occupied or shadow: not free
    away = {"arm": frames["arm"].copy()}
    away["arm"][2, :3, 3] = [0.0, 0.0, 0.3]  # moved out of the box
    assert len(feed.cloud(away).points) == len(everything)
