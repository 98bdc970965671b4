"""The distance scene's own registered operations (:mod:`reachwise.distance.scene_ops`):
each is written here once and answers in process and through the collision server."""

from __future__ import annotations

from typing import Annotated

import numpy as np
from numpy.typing import NDArray

from reachwise.distance.scene import Scene
from reachwise.distance.scene_ops import ArrayShape, scene_operation

__all__ = ["Pose", "object_poses"]

#: A 4x4 homogeneous transform (m), finite.
Pose = Annotated[NDArray[np.float64], ArrayShape((4, 4))]


@scene_operation
def object_poses(scene: Scene) -> dict[str, Pose]:
    """The current world pose (4x4) of every object of ``scene``."""
    return scene.poses()
