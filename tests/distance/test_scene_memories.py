"""A scene memory as an object of the distance scene (in process): depth frames of a
known box fused into it give the watched pair the distance to the box's observed points
within the memory's inflation; a frame with the box gone frees it; the object ages with
its newest frame; bad input is a typed error naming the field."""

from __future__ import annotations

import math

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
from reachwise.distance.scene_memory import MemoryConfig
from reachwise.errors import InputError, UnknownName
from reachwise.geometry.depth_camera import DepthCamera, Intrinsics

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
    scene = memory_scene()
    with_box, _ = frames()
    fuse_depth(scene, "memory", with_box, POSE, INTRINSICS, 10.0)
    res = scene.query_all()
    assert res.cloud_stamps["memory"] == 10.0
    safety = SafetyConfig(dt=0.01, max_cloud_age=0.05)

    def check(now: float) -> bool:
        return check_data(
            1, now, None, now, safety, cloud_stamp=res.cloud_stamps["memory"], cloud="memory"
        ).ok

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
    with pytest.raises(InputError, match="already exists"):
        add_memory(scene, "probe", LOWER, UPPER)
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
