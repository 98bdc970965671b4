"""Scene memories in a simulation: depth cameras that feed one voxel map instead of
replacing a cloud each frame (:mod:`reachwise.distance.scene_memory`).

A scenario's ``memory:`` entries (:class:`~reachwise.sim.scenarios.MemorySpec`) become
:class:`MemoryFeed` objects. Each camera it names hands its frames to the feed on the
camera's own schedule (:mod:`reachwise.sim.sensors`: capture, latency, frame 0 at the
start); the feed fuses every frame delivered at a tick, then hands the occupied and
shadow voxels' centres to the scene object of the memory's ``name`` once, stamped with
the newest frame's capture time (so ``SafetyConfig.max_cloud_age`` applies). The robots'
pixels are the cameras' self-filter: the robot never enters its own map.

Pairs watched against a memory keep their margin plus the memory's inflation (half a
voxel's diagonal): an observed point lies that close to its voxel's centre, so the
controller keeps the scenario's margin from what the cameras saw.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from reachwise.distance.scene_memory import MemoryConfig, SceneMemory, ViewIntrinsics
from reachwise.geometry.cloud import PointCloud

if TYPE_CHECKING:
    from reachwise.distance.scene import SceneLike
    from reachwise.geometry.depth_camera import DepthCamera, DepthFrame
    from reachwise.sim.scenarios import MemorySpec

__all__ = ["MemoryFeed"]


class MemoryFeed:
    """One scene memory of a run: the map, and the frames fused since its last
    hand-over to the scene."""

    def __init__(self, spec: MemorySpec) -> None:
        self.spec = spec
        self.name = spec.name
        config = MemoryConfig(
            voxel=spec.voxel,
            shadow_depth=spec.shadow_depth,
            memory_s=spec.memory_s,
            free_hold_s=spec.free_hold_s,
        )
        self.memory = SceneMemory(spec.box.lower, spec.box.upper, config)
        self._dirty = False
        self._added = False

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
        self._dirty = True

    def flush(self, scene: SceneLike) -> None:
        """Hand the map's obstacles to the scene when a frame was fused since the last
        hand-over (the first call adds the object)."""
        if self._added and not self._dirty:
            return
        cloud = self.cloud()
        if not self._added:
            scene.add_object(self.name, cloud)
            self._added = True
        stamp = self.memory.stamp
        scene.replace_cloud(
            self.name, cloud, block=True, stamp=stamp if np.isfinite(stamp) else None
        )
        self._dirty = False

    def cloud(self) -> PointCloud:
        """The occupied and shadow voxels' centres, or, while there are none, one point
        far above the box (a cloud has at least one point; it says "nothing here")."""
        pts = self.memory.obstacles()
        if len(pts) == 0:
            lo, hi = self.memory.origin, np.asarray(self.spec.box.upper, dtype=np.float64)
            pts = (0.5 * (lo + hi) + [0.0, 0.0, 1.0e3])[None]
        return PointCloud(pts, name=self.name)
