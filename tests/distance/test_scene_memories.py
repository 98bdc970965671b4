"""A scene memory as an object of the distance scene (in process): depth frames of a
known box fused into it give the watched pair the distance to the box's observed points
within the memory's inflation; a frame with the box gone frees it; the object ages with
its newest frame; bad input is a typed error naming the field."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
import trimesh
from numpy.typing import NDArray

from reachwise.control.safety import SafetyConfig, check_data
from reachwise.distance.scene import Scene
from reachwise.distance.scene_memories import (
    add_memory,
    fuse_depth,
    memories_of,
    memory_inflation,
    memory_margin,
    watch_memory,
)
from reachwise.distance.scene_memory import STATES, MemoryConfig
from reachwise.errors import InputError, NameTaken, UnknownName
from reachwise.geometry.depth_camera import DepthCamera, Intrinsics
from reachwise.kinematics.robot import Joint, Robot

#: The memory's box (m, world); the camera sits at the origin looking along +z.
LOWER, UPPER = np.array([-0.5, -0.5, 1.0]), np.array([0.5, 0.5, 2.0])
CAMERA = DepthCamera(Intrinsics(width=64, height=48, fx=60.0, fy=60.0, cx=31.5, cy=23.5))
INTRINSICS = (60.0, 60.0, 31.5, 23.5, CAMERA.near, CAMERA.far)
POSE = np.eye(4)
#: A probe point between the camera and the box, and the pair's margin (m).
PROBE = np.array([[0.02, -0.03, 0.8]])
MARGIN = 5.0


def box_mesh() -> trimesh.Trimesh:
    """A 0.3 m cube centred 1.5 m in front of the camera."""
    return trimesh.creation.box(extents=(0.3, 0.3, 0.3), transform=_at([0.0, 0.0, 1.5]))


def wall_mesh() -> trimesh.Trimesh:
    """A wall behind the memory's box: its rays carve the box free."""
    return trimesh.creation.box(extents=(6.0, 6.0, 0.05), transform=_at([0.0, 0.0, 2.4]))


def _at(p: list[float]) -> NDArray[np.float64]:
    T = np.eye(4)
    T[:3, 3] = p
    return T


def frames() -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The depth image with the box in front of the wall, and with the wall only."""
    return CAMERA.depth([box_mesh(), wall_mesh()], POSE), CAMERA.depth([wall_mesh()], POSE)


#: A one-joint robot whose ``link_1`` slides along world x at z = 1.8 m: a 0.2 m cube,
#: out of the camera's view at ``AWAY``, between the camera and the wall at ``IN_FRONT``.
SLIDER = Robot(
    name="slider",
    joints=(Joint("prismatic", limits=(-3.0, 3.0)),),
    base=np.array([[0.0, 0, 1, 0], [1, 0, 0, 0], [0, 1, 0, 1.8], [0, 0, 0, 1]]),
)
AWAY, IN_FRONT = np.array([1.5]), np.array([0.0])
#: The wall's memory box (it holds the wall's near face, z = 2.375 m) and a probe in
#: the space the cube hides from the camera, 0.075 m in front of the wall.
WALL_LOWER, WALL_UPPER = np.array([-0.5, -0.5, 1.0]), np.array([0.5, 0.5, 2.6])
HIDDEN = np.array([[0.0, 0.0, 2.3]])


def cube_cloud() -> NDArray[np.float64]:
    """The cube's surface sampled on a 2 cm grid, in the link's frame."""
    g = np.linspace(-0.1, 0.1, 11)
    a, b = (m.ravel() for m in np.meshgrid(g, g))
    faces = []
    for k in range(3):
        for side in (-0.1, 0.1):
            face = np.empty((len(a), 3))
            face[:, k], face[:, (k + 1) % 3], face[:, (k + 2) % 3] = side, a, b
            faces.append(face)
    return np.unique(np.concatenate(faces).round(12), axis=0)


def slider_frame(q: NDArray[np.float64]) -> NDArray[np.float64]:
    """The depth image of the wall with the robot's cube at joint state ``q``."""
    cube = trimesh.creation.box(extents=(0.2, 0.2, 0.2), transform=SLIDER.fk_all(q)[1])
    return CAMERA.depth([wall_mesh(), cube], POSE)


def slider_scene(scene: Any) -> None:
    """The robot at ``AWAY`` with its cube cloud on ``link_1``, a memory of the wall's
    box, and both the cube and the ``hidden`` probe watched against it (``scene``: a
    :class:`Scene` or a server's client)."""
    scene.add_robot(SLIDER, AWAY)
    scene.add_object("cube", cube_cloud(), robot="slider", link="link_1")
    add_memory(scene, "memory", WALL_LOWER, WALL_UPPER, MemoryConfig(voxel=0.03))
    scene.add_object("hidden", HIDDEN)
    watch_memory(scene, "cube", "memory", MARGIN)
    watch_memory(scene, "hidden", "memory", MARGIN)


def wall_distances() -> tuple[float, float]:
    """Brute force: the cube at ``IN_FRONT`` and the hidden probe to the wall's points
    the camera sees with the robot away."""
    observed = CAMERA.points(slider_frame(AWAY), POSE)
    wall = observed[np.all((observed >= WALL_LOWER) & (observed <= WALL_UPPER), axis=1)]
    cube = cube_cloud() @ SLIDER.fk_all(IN_FRONT)[1][:3, :3].T + SLIDER.fk_all(IN_FRONT)[1][:3, 3]
    d_cube = float(np.min(np.linalg.norm(cube[:, None] - wall[None], axis=2)))
    return d_cube, float(np.linalg.norm(wall - HIDDEN, axis=1).min())


def memory_scene() -> Scene:
    scene = Scene()
    add_memory(scene, "memory", LOWER, UPPER, MemoryConfig(voxel=0.03))
    scene.add_object("probe", PROBE)
    watch_memory(scene, "probe", "memory", MARGIN)
    return scene


def pair_distance(scene: Scene) -> float:
    (pair,) = scene.query_all().pairs
    return float(pair.result.distance)


def test_fused_frames_answer_within_the_inflation_and_a_box_gone_is_freed() -> None:
    scene = memory_scene()
    with_box, without = frames()
    inflation = memory_inflation(scene, "memory")
    assert inflation == pytest.approx(0.5 * math.sqrt(3.0) * 0.03)
    (pair,) = scene.pairs
    assert pair.margin == pytest.approx(MARGIN + inflation)
    assert pair_distance(scene) == math.inf  # nothing seen yet: beyond the margin

    version = fuse_depth(scene, "memory", with_box, POSE, INTRINSICS, 1.0)
    assert version == 1
    d = pair_distance(scene)
    observed = CAMERA.points(with_box, POSE)
    seen = observed[np.all((observed >= LOWER) & (observed <= UPPER), axis=1)]
    d_observed = float(np.linalg.norm(seen - PROBE, axis=1).min())
    assert abs(d - d_observed) <= inflation + 1e-9
    # exactly the brute force over the memory's own voxel centres
    centres = memories_of(scene)["memory"].obstacles()
    assert d == pytest.approx(float(np.linalg.norm(centres - PROBE, axis=1).min()), abs=1e-12)

    assert fuse_depth(scene, "memory", without, POSE, INTRINSICS, 2.0) == 2
    assert pair_distance(scene) > d + 1.0  # the box is gone: freed
    assert len(memories_of(scene)["memory"].obstacles()) == 0
    scene.close()


def test_the_memory_object_ages_with_its_newest_frame() -> None:
    """Before its first frame the memory's age is unknown (NaN): stale under
    ``max_cloud_age`` at any time; then it is its newest frame's age."""
    scene = memory_scene()
    with_box, _ = frames()
    res = scene.query_all()
    assert math.isnan(res.cloud_stamps["memory"])  # nothing seen yet
    safety = SafetyConfig(dt=0.01, max_cloud_age=0.05)

    def check(now: float) -> bool:
        return check_data(
            1, now, None, now, safety, cloud_stamp=res.cloud_stamps["memory"], cloud="memory"
        ).ok

    assert not check(0.0) and not check(10.0)
    assert check_data(1, 1.0, None, 1.0, SafetyConfig(), cloud_stamp=math.nan).ok  # no bound
    fuse_depth(scene, "memory", with_box, POSE, INTRINSICS, 10.0)
    res = scene.query_all()
    assert res.cloud_stamps["memory"] == 10.0
    assert check(10.04)
    assert not check(10.06)  # older than max_cloud_age: stale
    fuse_depth(scene, "memory", with_box, POSE, INTRINSICS, 10.06)
    res = scene.query_all()
    assert check(10.08)
    scene.close()


def test_bad_frames_and_names_are_typed_errors_naming_the_field() -> None:
    scene = memory_scene()
    with_box, _ = frames()
    with pytest.raises(InputError) as err:
        fuse_depth(scene, "memory", with_box[0], POSE, INTRINSICS, 1.0)
    assert err.value.field == "depth"
    bad = POSE.copy()
    bad[0, 3] = np.nan
    with pytest.raises(InputError) as err:
        fuse_depth(scene, "memory", with_box, bad, INTRINSICS, 1.0)
    assert err.value.field == "pose"
    with pytest.raises(InputError) as err:
        fuse_depth(scene, "memory", with_box, POSE, (60.0, 60.0, 31.5), 1.0)  # type: ignore[arg-type]
    assert err.value.field == "intrinsics"
    with pytest.raises(UnknownName) as unknown:
        fuse_depth(scene, "memroy", with_box, POSE, INTRINSICS, 1.0)
    assert "memory" in str(unknown.value)
    for taken in ("probe", "memory"):  # an object's name, a memory's
        with pytest.raises(NameTaken, match="already exists") as err:
            add_memory(scene, taken, LOWER, UPPER)
        assert isinstance(err.value, InputError) and err.value.field == "name"
    with pytest.raises(NameTaken):
        scene.add_object("memory", PROBE)
    with pytest.raises(InputError) as err:
        add_memory(scene, "other", UPPER, LOWER)
    assert err.value.field == "upper"
    assert pair_distance(scene) == math.inf  # nothing of the bad calls was fused
    scene.close()


def test_the_memory_margin_adds_each_memory_in_the_pair() -> None:
    inflation = {"m1": 0.02, "m2": 0.05}
    assert memory_margin(inflation, "probe", "m1", 0.1) == pytest.approx(0.12)
    assert memory_margin(inflation, "m1", "m2", 0.1) == pytest.approx(0.17)
    assert memory_margin(inflation, "a", "b", 0.1) == 0.1


def test_the_robot_never_enters_its_own_map_at_the_joint_state_given_with_the_frame() -> None:
    """The wall seen with the robot away, then the robot's cube in front of it: the
    cube's distance to the memory stays its distance to the wall, and the wall voxels
    it hides stay occupied. Fused at the scene's latest joint state (set before the
    frame) or at the one given with the frame, the memory is the same; given a wrong
    state, the cube's own points enter the map."""
    inflation = 0.5 * math.sqrt(3.0) * 0.03
    d_cube, d_hidden = wall_distances()
    away, front = slider_frame(AWAY), slider_frame(IN_FRONT)
    answers = []
    for case in ("latest", "given", "wrong"):
        scene = Scene()
        slider_scene(scene)
        fuse_depth(scene, "memory", away, POSE, INTRINSICS, 1.0)
        memory = memories_of(scene)["memory"]
        column = [memory.voxel_of([0.0, 0.0, z]) for z in np.arange(2.0, 2.6, 0.01)]
        before = [int(memory.state[v]) for v in column if v is not None]
        if case == "latest":
            scene.set_joints("slider", IN_FRONT)
            fuse_depth(scene, "memory", front, POSE, INTRINSICS, 1.1)
        else:
            q = IN_FRONT if case == "given" else AWAY
            fuse_depth(scene, "memory", front, POSE, INTRINSICS, 1.1, q={"slider": q})
            scene.set_joints("slider", IN_FRONT)
        res = scene.query_all()
        answers.append([res.get(a, "memory").result.distance for a in ("cube", "hidden")])
        after = [int(memory.state[v]) for v in column if v is not None]
        if case != "wrong":  # what the cube hides keeps its state: free, wall, shadow
            assert after == before
            assert {STATES["free"], STATES["occupied"], STATES["shadow"]} <= set(after)
        scene.close()
    (cube, hidden), given, (wrong_cube, _) = answers
    assert abs(cube - d_cube) <= inflation + 1e-9
    assert abs(hidden - d_hidden) <= inflation + 1e-9
    assert given == pytest.approx([cube, hidden], abs=1e-12)
    assert wrong_cube < 0.05 < d_cube - inflation  # the robot's own surface, as an obstacle


def test_joint_states_of_unknown_robots_are_typed_errors() -> None:
    scene = Scene()
    slider_scene(scene)
    with pytest.raises(UnknownName):
        fuse_depth(scene, "memory", slider_frame(AWAY), POSE, INTRINSICS, 1.0, q={"arm": AWAY})
    scene.close()
