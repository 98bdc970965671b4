"""Scene memories in a simulation: depth cameras that feed one voxel map instead of
replacing a cloud each frame (:mod:`reachwise.distance.scene_memory`).

A scenario's ``memory:`` entries (:class:`~reachwise.sim.scenarios.MemorySpec`) become
:class:`MemoryFeed` objects. Each camera it names hands its frames to the feed on the
camera's own schedule (:mod:`reachwise.sim.sensors`: capture, latency, frame 0 at the
start); the feed fuses every frame delivered at a tick, then hands the occupied and
shadow voxels' centres to the scene object of the memory's ``name`` once, stamped with
the newest frame's capture time (so ``SafetyConfig.max_cloud_age`` applies). The robots'
pixels are the cameras' self-filter: the robot never enters its own map.

The robots never collide with the map either: at each hand-over the voxels their bodies
occupy at the joint state of that tick are left out (``body`` of
:meth:`~reachwise.distance.scene_memory.SceneMemory.obstacles`). Each connected piece of
a link's collision surface is bounded by its 26-DOP
(:func:`~reachwise.geometry.body_pieces.body_pieces`), a convex superset of the piece at
most a few millimetres wider than a round link. Robot–robot pairs are watched on the
robots' own link clouds, so every robot's body is left out of the one map.

Pairs watched against a memory keep their margin plus the memory's inflation (half a
voxel's diagonal): an observed point lies that close to its voxel's centre, so the
controller keeps the scenario's margin from what the cameras saw.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from reachwise.distance.scene_memories import memory_cloud
from reachwise.distance.scene_memory import MemoryConfig, SceneMemory, ViewIntrinsics
from reachwise.geometry.body_pieces import BodyPiece, body_pieces
from reachwise.geometry.cloud import PointCloud

if TYPE_CHECKING:
    from reachwise.distance.scene import SceneLike
    from reachwise.geometry.depth_camera import DepthCamera, DepthFrame
    from reachwise.sim.scenarios import MemorySpec

__all__ = ["BodyPiece", "MemoryFeed", "body_pieces"]

F64 = NDArray[np.float64]


class MemoryFeed:
    """One scene memory of a run: the map, and the frames fused since its last
    hand-over to the scene."""

    def __init__(self, spec: MemorySpec, body: Iterable[BodyPiece] = ()) -> None:
        self.spec = spec
        self.body = tuple(body)
        self.name = spec.name
        config = MemoryConfig(
            voxel=spec.voxel,
            shadow_depth=spec.shadow_depth,
            memory_s=spec.memory_s,
            free_hold_s=spec.free_hold_s,
        )
        self.memory = SceneMemory(spec.box.lower, spec.box.upper, config)
        self.dirty = False  # a frame was fused since the last hand-over
        self._added = False

    def reset(self) -> None:
        """Forget every frame fused: the map as at the start of a run, all unknown (a
        replay that fuses the frames again)."""
        self.memory.clear()
        self.dirty = True

    @property
    def inflation(self) -> float:
        """What the pairs against this memory add to their margin (m)."""
        return self.memory.inflation

    def fuse(self, camera: DepthCamera, frame: DepthFrame, stamp: float) -> None:
        """Fuse one frame of ``camera`` captured at ``stamp`` (s)."""
        i = camera.intrinsics
        view = ViewIntrinsics(i.fx, i.fy, i.cx, i.cy, camera.near, camera.far)
        depth = frame.depth
        if frame.body is not None and frame.body_depth is not None:
            depth = np.where(frame.body, frame.body_depth, frame.depth)
        self.memory.integrate(depth, frame.pose, view, stamp, frame.body)
        self.dirty = True

    def flush(self, scene: SceneLike, frames: dict[str, F64] | None = None) -> None:
        """Hand the map's obstacles to the scene when a frame was fused since the last
        hand-over (the first call adds the object), without the voxels of the robots'
        bodies at their frame poses ``frames`` (each robot's ``fk_all``; None: every
        voxel)."""
        if self._added and not self.dirty:
            return
        cloud = self.cloud(frames)
        if not self._added:
            scene.add_object(self.name, cloud)
            self._added = True
        stamp = self.memory.stamp
        scene.replace_cloud(
            self.name, cloud, block=True, stamp=stamp if np.isfinite(stamp) else None
        )
        self.dirty = False

    def cloud(self, frames: dict[str, F64] | None = None) -> PointCloud:
        """The occupied and shadow voxels' centres (without the robots' bodies at their
        frame poses ``frames``), or, while there are none, the point that says
        "nothing here" (:func:`~reachwise.distance.scene_memories.memory_cloud`, as a
        memory on the collision server). The voxels' cloud comes with its index: the
        scene swaps it in without a build."""
        body = []
        if frames is not None:
            body = [p.placed(frames[p.robot][p.frame]) for p in self.body if p.robot in frames]
        return memory_cloud(self.memory, body=body, name=self.name)
