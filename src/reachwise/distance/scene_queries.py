"""The distance scene's own registered operations (:mod:`reachwise.distance.scene_ops`):
each is written here once and answers in process and through the collision server."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Literal

import numpy as np
from numpy.typing import NDArray

from reachwise.distance.engine import StrategyName
from reachwise.distance.pairs import WatchedPair
from reachwise.distance.scene import Fixed, OnLink, Scene
from reachwise.distance.scene_ops import ArrayShape, scene_operation
from reachwise.kinematics.robot import Robot

__all__ = ["ObjectInfo", "Pose", "SceneDescription", "describe", "object_poses"]

#: A 4x4 homogeneous transform (m), finite.
Pose = Annotated[NDArray[np.float64], ArrayShape((4, 4))]


@scene_operation
def object_poses(scene: Scene) -> dict[str, Pose]:
    """The current world pose (4x4) of every object of ``scene``."""
    return scene.poses()


@dataclass(frozen=True, eq=False)
class ObjectInfo:
    """One object of a scene: ``source`` is ``fixed`` (``pose`` in world), ``link``
    (``pose`` the offset from ``robot``'s ``link``) or ``runtime`` (``pose`` the current
    world pose); ``points`` its cloud's size, ``cloud`` (N, 3) only when asked for."""

    name: str
    points: int
    source: Literal["fixed", "link", "runtime"]
    pose: Pose
    robot: str | None = None
    link: str | None = None
    cloud: Annotated[NDArray[np.float64], ArrayShape((None, 3))] | None = None


@dataclass(frozen=True, eq=False)
class SceneDescription:
    """A scene's contents: distance ``strategy``, ``robots`` and the ``joints`` set for
    them, ``objects`` in insertion order, watched ``pairs`` in query order."""

    strategy: StrategyName
    robots: dict[str, Robot]
    joints: dict[str, Annotated[NDArray[np.float64], ArrayShape((None,))]]
    objects: tuple[ObjectInfo, ...]
    pairs: tuple[WatchedPair, ...]


@scene_operation
def describe(scene: Scene, clouds: bool = False) -> SceneDescription:
    """The contents of ``scene`` (:class:`SceneDescription`), the clouds in use (those
    indexed so far) with their points if ``clouds``."""
    scene.swap_in()
    poses = scene.poses()
    objects = []
    for name, obj in scene.objects.items():
        src = obj.source
        cloud = obj.cloud.points if clouds else None
        if isinstance(src, OnLink):
            info = ObjectInfo(name, len(obj.cloud), "link", src.offset, src.robot, src.link, cloud)
        elif isinstance(src, Fixed):
            info = ObjectInfo(name, len(obj.cloud), "fixed", src.pose, cloud=cloud)
        else:
            info = ObjectInfo(name, len(obj.cloud), "runtime", poses[name], cloud=cloud)
        objects.append(info)
    robots = {k: r for k, r in scene.robots.items() if isinstance(r, Robot)}
    joints = {k: q for k in robots if (q := scene.joint_state(k)) is not None}
    return SceneDescription(scene.strategy, robots, joints, tuple(objects), scene.pairs)
