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
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import InputError
from reachwise.viz.scene_data import distance_colours, height_colours, node_name
from reachwise.viz.timeline import Timeline

if TYPE_CHECKING:
    from reachwise.geometry.cloud import PointCloud
    from reachwise.io.ros.replay import ReplayResult
    from reachwise.kinematics.robot import Robot
    from reachwise.viz.canvas import Canvas

__all__ = ["ReplayClouds", "ReplayPlayback"]

#: The robot's node name in the viewer.
ROBOT = "robot"


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


class ReplayPlayback(Timeline):
    """``result`` of a replay with ``robot`` (its links carrying ``link_clouds``) and
    the ``clouds`` kept while replaying, played back in ``viewer`` (see the module
    docstring)."""

    def __init__(
        self,
        viewer: Canvas,
        result: ReplayResult,
        robot: Robot,
        link_clouds: Mapping[str, PointCloud],
        clouds: ReplayClouds,
        fps: float = 30.0,
    ) -> None:
        if result.t.size == 0:
            raise InputError(result.bag, "joints", "the replay has no frames to show")
        if result.q.shape[1] != robot.n:
            raise InputError(result.bag, "robot", f"the replay's frames are not {robot.name}'s")
        super().__init__(viewer, result.t, fps)
        self.result, self.robot, self.clouds = result, robot, clouds
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
