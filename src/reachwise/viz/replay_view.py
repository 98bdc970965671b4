"""A replayed recording in the viewer (``reachwise replay … --view``).

:class:`ReplayClouds` keeps the clouds a replay handed to its scene
(:func:`~reachwise.io.ros.replay.replay_recording`'s ``on_cloud``), each thinned to at
most ``max_points`` points for display (every k-th point), by object and stamp.

:class:`ReplayPlayback` plays a :class:`~reachwise.io.ros.replay.ReplayResult` back
with the controls of a simulation log's playback (:class:`~reachwise.viz.timeline.Timeline`):
at each frame the robot takes the joint positions the frame queried, each cloud
topic shows the cloud that frame's answers used (its stamp), and the closest-point
lines join each pair's closest points, red within the replay's margin, amber
beyond. Nothing is computed again: the frame shows the replay's own answers.

:class:`ReplayMemory` keeps the scene memory a replay fused its depth frames into
(:func:`~reachwise.io.ros.replay.replay_recording`'s ``on_memory``): its voxels'
states after each frame, by stamp (a full copy every ``every`` frames, the voxels
that changed in between). With it, the playback draws the memory the frame's
answers used as its occupied, shadow and free voxels
(:func:`~reachwise.viz.memory_voxels.show_memory_voxels`, as a simulation's view
does) instead of a plain cloud.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import InputError
from reachwise.viz.memory_voxels import show_memory_voxels
from reachwise.viz.scene_data import distance_colours, height_colours, node_name
from reachwise.viz.timeline import Timeline

if TYPE_CHECKING:
    from reachwise.distance.scene_memory import SceneMemory
    from reachwise.geometry.cloud import PointCloud
    from reachwise.io.ros.replay import ReplayResult
    from reachwise.kinematics.robot import Robot
    from reachwise.viz.canvas import Canvas

__all__ = ["ReplayClouds", "ReplayMemory", "ReplayPlayback"]

#: The robot's node name in the viewer.
ROBOT = "robot"
#: The scene object of a replay's scene memory (``reachwise.io.ros.replay.MEMORY``).
MEMORY = "memory"


class ReplayClouds:
    """The clouds of a replay for display: call it as the replay's ``on_cloud``; each
    cloud is kept thinned to at most ``max_points`` points (float32), by object and
    stamp."""

    def __init__(self, max_points: int = 5000) -> None:
        if max_points < 1:
            raise InputError("viewer", "max_points", f"must be >= 1, got {max_points}")
        self.max_points = max_points
        self.clouds: dict[str, dict[float, NDArray[np.float32]]] = {}

    def __call__(self, name: str, stamp: float, points: NDArray[np.float64]) -> None:
        step = max(1, math.ceil(len(points) / self.max_points))
        kept = np.ascontiguousarray(points[::step], dtype=np.float32)
        self.clouds.setdefault(name, {})[float(stamp)] = kept

    def at(self, name: str, stamp: float) -> NDArray[np.float32] | None:
        """The kept cloud of ``name`` with that stamp (None: none)."""
        return self.clouds.get(name, {}).get(float(stamp))


class ReplayMemory:
    """The states of a replay's scene memory after each fused frame: call it as the
    replay's ``on_memory``. A full copy of the voxel grid every ``every`` frames, the
    voxels whose state changed with each frame (flat index, new state); :meth:`state_at`
    rebuilds the grid of a stamp from the copy before it, or from the grid it gave
    last when that is nearer."""

    def __init__(self, every: int = 30) -> None:
        if every < 1:
            raise InputError("viewer", "every", f"must be >= 1, got {every}")
        self.every = every
        self.origin = np.zeros(3)
        self.voxel = 0.0
        self.shape: tuple[int, ...] = (0, 0, 0)
        self.frame: dict[float, int] = {}  # stamp -> its frame (the last with that stamp)
        self._copies: dict[int, NDArray[np.uint8]] = {}
        self._changes: list[tuple[NDArray[np.int64], NDArray[np.uint8]]] = []
        self._last: NDArray[np.uint8] | None = None
        self._shown: tuple[int, NDArray[np.uint8]] | None = None  # frame, its grid

    def __call__(self, stamp: float, memory: SceneMemory) -> None:
        state = memory.state.reshape(-1)
        k = len(self._changes)
        if self._last is None:
            self.origin = np.asarray(memory.origin, dtype=np.float64).copy()
            self.voxel = float(memory.config.voxel)
            self.shape = memory.state.shape
        if self._last is None:
            self._last = state.copy()
            self._changes.append((np.zeros(0, np.int64), np.zeros(0, np.uint8)))
        else:
            idx = np.flatnonzero(state != self._last)
            self._changes.append((idx, state[idx]))
            self._last[idx] = state[idx]
        if k % self.every == 0:
            self._copies[k] = state.copy()
        self.frame[float(stamp)] = k

    def state_at(self, stamp: float) -> NDArray[np.uint8] | None:
        """The voxel grid (its memory's shape) after the frame of ``stamp`` (None: no
        such frame). Read-only: the next call may change it."""
        k = self.frame.get(float(stamp))
        if k is None:
            return None
        j = k - k % self.every  # the copy before k
        if self._shown is not None and j <= self._shown[0] <= k:
            j, grid = self._shown  # go on from the grid given last
        else:
            grid = self._copies[j].copy()
        for idx, new in self._changes[j + 1 : k + 1]:
            grid[idx] = new
        self._shown = (k, grid)
        return grid.reshape(self.shape)


class ReplayPlayback(Timeline):
    """``result`` of a replay with ``robot`` (its links carrying ``link_clouds``) and
    the ``clouds`` kept while replaying, played back in ``viewer`` (see the module
    docstring); with ``memory`` (kept while replaying) the scene memory's object is
    drawn as its voxels."""

    def __init__(
        self,
        viewer: Canvas,
        result: ReplayResult,
        robot: Robot,
        link_clouds: Mapping[str, PointCloud],
        clouds: ReplayClouds,
        fps: float = 30.0,
        memory: ReplayMemory | None = None,
    ) -> None:
        if result.t.size == 0:
            raise InputError(result.bag, "joints", "the replay has no frames to show")
        if result.q.shape[1] != robot.n:
            raise InputError(result.bag, "robot", f"the replay's frames are not {robot.name}'s")
        super().__init__(viewer, result.t, fps)
        self.result, self.robot, self.clouds = result, robot, clouds
        self.memory = memory if memory is not None and memory.frame else None
        self.objects = sorted({p.split("|", 1)[1] for p in result.pairs})
        self._column = {o: result.pairs.index(next(p for p in result.pairs
                                                   if p.split("|", 1)[1] == o))
                        for o in self.objects}  # fmt: skip
        self._shown: dict[str, float] = {}
        watched = {p.split("|", 1)[0] for p in result.pairs}
        F = np.asarray(robot.fk_all(result.q[0]))
        content = [F[:, :3, 3]] + [c[:: max(1, len(c) // 500)] for o in clouds.clouds.values()
                                    for c in o.values()]  # fmt: skip
        allpts = np.vstack(content).astype(float)
        viewer.set_scale(allpts)
        viewer.add_robot(ROBOT, robot, result.q[0], link_clouds, watched)
        viewer.add_grid(allpts.mean(axis=0), z=min(0.0, float(allpts[:, 2].min())))
        viewer.frame_camera(allpts, direction=(0.9, -1.2, 0.8))
        step = float(np.median(np.diff(result.t))) if result.t.size > 1 else 0.01
        self.add_controls(step if step > 0 else 0.01)
        self.seek(0)
        viewer.set_info(
            f"**{Path(result.bag).name}** replayed with {robot.name}: {self.T} frames, "
            f"clouds {', '.join(self.objects)}; closest-point lines: red within "
            f"{result.margin:g} m, amber beyond"
        )
        self.start()

    def cloud_node(self, name: str) -> str:
        """The viewer node of object ``name``'s cloud."""
        return f"/replay/{node_name(name)}"

    def _show_memory(self, stamp: float) -> None:
        """The memory's voxels after the frame of ``stamp``, by state."""
        assert self.memory is not None
        grid = self.memory.state_at(stamp)
        if grid is not None:
            show_memory_voxels(self.viewer, MEMORY, grid, self.memory.origin, self.memory.voxel)
            self._shown[MEMORY] = stamp

    def segments(self, k: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Frame ``k``'s closest-point lines ``(M, 2, 3)`` of the pairs with an answer,
        and their distances."""
        r = self.result
        a, b, d = r.point_a[k], r.point_b[k], r.distance[k]
        ok = np.isfinite(d) & np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)
        return np.stack([a[ok], b[ok]], axis=1), d[ok]

    def show(self, k: int) -> None:
        """Frame ``k``: the robot at its joint positions, each object's cloud of that
        frame, the closest-point lines, the status line."""
        r, viewer = self.result, self.viewer
        viewer.robots[ROBOT].set_q(r.q[k])
        for name in self.objects:
            stamp = float(r.cloud_stamp[k, self._column[name]])
            if math.isnan(stamp) or self._shown.get(name) == stamp:
                continue
            if name == MEMORY and self.memory is not None:
                self._show_memory(stamp)
                continue
            pts = self.clouds.at(name, stamp)
            if pts is not None:
                viewer.add_cloud(self.cloud_node(name), pts, height_colours(pts))
                self._shown[name] = stamp
        seg, dist = self.segments(k)
        cols = distance_colours(dist, r.margin)
        viewer.set_segments("/distance/lines", seg, cols, "distance lines", 5.0)
        viewer.set_points(
            "/distance/ends", seg.reshape(-1, 3), cols.reshape(-1, 3), "distance lines",
            0.012 * viewer.scale,
        )  # fmt: skip
        md = float(r.min_distance[k])
        d = f"{md * 100:.1f} cm" if math.isfinite(md) else "no cloud yet"
        near = int(np.count_nonzero(r.near[k]))
        self.status.content = f"t = {r.t[k]:.3f} s · min distance {d} · {near} pairs near"
