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
a link's collision surface is bounded by its 26-DOP (:func:`body_pieces`: the planes
normal to the 26 directions of the cube's faces, edges and corners, pushed out to its
farthest vertex), a convex superset of the piece at most a few millimetres wider than a
round link. Robot–robot pairs are watched on the robots' own link clouds, so every
robot's body is left out of the one map.

Pairs watched against a memory keep their margin plus the memory's inflation (half a
voxel's diagonal): an observed point lies that close to its voxel's centre, so the
controller keeps the scenario's margin from what the cameras saw.
"""

from __future__ import annotations

from collections.abc import Iterable
from itertools import product
from typing import TYPE_CHECKING, NamedTuple, Protocol

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from reachwise.distance.scene_memory import MemoryConfig, SceneMemory, ViewIntrinsics
from reachwise.geometry.cloud import PointCloud

if TYPE_CHECKING:
    from reachwise.distance.scene import SceneLike
    from reachwise.geometry.depth_camera import DepthCamera, DepthFrame
    from reachwise.sim.scenarios import MemorySpec

__all__ = ["BodyPiece", "MemoryFeed", "body_pieces"]

F64 = NDArray[np.float64]


class LinkSurface(Protocol):
    """A robot link's collision surface as :func:`body_pieces` reads it (the
    simulation's ``BodySurface``): its ``mesh`` ``(vertices, faces)`` in the frame
    ``index`` of scenario robot ``robot``."""

    @property
    def robot(self) -> str: ...

    @property
    def index(self) -> int: ...

    @property
    def mesh(self) -> tuple[F64, NDArray[np.int64]]: ...


def _dop_directions() -> F64:
    """The 26 unit directions of a 26-DOP, the three axes' six first."""
    dirs = [np.array(v, dtype=np.float64) for v in product((-1, 0, 1), repeat=3) if any(v)]
    dirs.sort(key=lambda v: int(np.count_nonzero(v)))
    return np.array([v / np.linalg.norm(v) for v in dirs])


_DOP = _dop_directions()


class BodyPiece(NamedTuple):
    """One convex piece around a part of a robot link: the half-spaces ``n · x ≤ d``
    (``normals`` ``(m, 3)``, ``offsets`` ``(m,)``) in the frame ``frame`` of robot
    ``robot``'s ``fk_all``."""

    robot: str
    frame: int
    normals: F64
    offsets: F64

    def placed(self, pose: F64) -> F64:
        """The half-spaces in the world (rows ``nx, ny, nz, d``) at the frame's ``pose``."""
        n = self.normals @ pose[:3, :3].T
        return np.column_stack([n, self.offsets + n @ pose[:3, 3]])


def body_pieces(bodies: Iterable[LinkSurface]) -> tuple[BodyPiece, ...]:
    """The 26-DOP of each connected piece of each link surface in ``bodies``."""
    out = []
    for b in bodies:
        v, f = b.mesh
        if len(f) == 0:
            continue
        edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]]])
        graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), (len(v), len(v)))
        _, label = connected_components(graph, directed=False)
        used = np.unique(f)
        for c in np.unique(label[used]):
            pts = v[used[label[used] == c]]
            out.append(BodyPiece(b.robot, b.index, _DOP, (pts @ _DOP.T).max(axis=0)))
    return tuple(out)


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
        frame poses ``frames``), or, while there are none, one point far above the box
        (a cloud has at least one point; it says "nothing here"). The voxels' cloud
        comes with its index (:meth:`SceneMemory.obstacle_cloud
        <reachwise.distance.scene_memory.SceneMemory.obstacle_cloud>`): the scene
        swaps it in without a build."""
        body = []
        if frames is not None:
            body = [p.placed(frames[p.robot][p.frame]) for p in self.body if p.robot in frames]
        cloud = self.memory.obstacle_cloud(body=body, name=self.name)
        if cloud is not None:
            return cloud
        lo, hi = self.memory.origin, np.asarray(self.spec.box.upper, dtype=np.float64)
        return PointCloud((0.5 * (lo + hi) + [0.0, 0.0, 1.0e3])[None], name=self.name)
