"""A robot in the browser scene: link clouds on their link frames, the visual meshes of a
robot loaded from a URDF, the skeleton, the tool frame (thesis §3.1: the robot parts as
clouds of surface points, P-III §5).

Scene-node names nest as ``/robots/<name>/<link>/cloud`` under the link frame
``/robots/<name>/<link>``: moving the robot only sets each link frame's pose (from
``Robot.fk_all(q)``), the cloud's points are sent once.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.viz.scene_data import skeleton_segments, wxyz_position

if TYPE_CHECKING:
    from reachwise.geometry.cloud import PointCloud
    from reachwise.kinematics.robot import Robot

__all__ = ["CLOUD_RGB", "WATCHED_RGB", "NodeHost", "RobotView", "robot_size"]


class NodeHost(Protocol):
    """Where a :class:`RobotView` puts its nodes: a viser server and the viewer's node
    registry (:meth:`reachwise.viz.viewer.Viewer.add_node`)."""

    server: Any

    def add_node(self, name: str, handle: Any, category: str | None = None) -> Any: ...


#: Link clouds: plain links, and links whose clouds are watched for collisions.
CLOUD_RGB = (120, 150, 190)
WATCHED_RGB = (240, 130, 30)
SKELETON_RGB = (40, 40, 40)
#: Visual meshes (a URDF's <visual> shapes), drawn half transparent over the clouds.
MESH_RGB = (200, 200, 205)


def robot_size(robot: Robot, q: ArrayLike) -> float:
    """A length scale of ``robot`` at ``q``: the diagonal of its frames' bounding box
    (at least 0.5 m)."""
    o = np.asarray(robot.fk_all(np.asarray(q, dtype=float)))[:, :3, 3]
    return max(float(np.linalg.norm(o.max(axis=0) - o.min(axis=0))), 0.5)


class RobotView:
    """One robot in a :class:`~reachwise.viz.viewer.Viewer`: ``set_q(q)`` moves it."""

    def __init__(
        self,
        viewer: NodeHost,
        name: str,
        robot: Robot,
        q: ArrayLike,
        clouds: Mapping[str, PointCloud] | None = None,
        watched: set[str] | frozenset[str] = frozenset(),
        size: float | None = None,
    ) -> None:
        self.viewer = viewer
        self.name = name
        self.robot = robot
        self.root = f"/robots/{name}"
        q0 = np.asarray(q, dtype=float).reshape(-1)
        scale = robot_size(robot, q0) if size is None else size
        scene = viewer.server.scene
        viewer.add_node(self.root, scene.add_frame(self.root, show_axes=False))
        clouds = dict(clouds or {})
        visuals = dict(getattr(robot, "visual", {}) or {})
        self.links: list[tuple[int, str]] = []
        self.frames: dict[str, object] = {}
        self.mesh_notes: list[str] = []
        last = len(robot.link_names) - 1
        for k, link in enumerate(robot.link_names):
            on = [
                b for b in robot.body_names if robot.frame_of(b) == link
            ]  # the bodies riding on frame k
            if k != last and not any(b in clouds or b in visuals for b in on):
                continue
            path = f"{self.root}/{link}"
            is_tool = k == last
            frame = scene.add_frame(
                path,
                show_axes=is_tool,
                axes_length=0.06 * scale,
                axes_radius=0.004 * scale,
            )
            viewer.add_node(path, frame, "frames" if is_tool else None)
            self.frames[link] = frame
            self.links.append((k, link))
            for body in on:
                self._add_body(path if body == link else f"{path}/{body}", body, clouds,
                               visuals, body in watched, scale)  # fmt: skip
        self.skeleton = viewer.add_node(
            f"{self.root}/skeleton",
            scene.add_line_segments(
                f"{self.root}/skeleton",
                skeleton_segments(robot, q0),
                np.array(SKELETON_RGB, dtype=np.uint8),
                thickness=3.0,
                thickness_units="screen",
            ),
            "skeleton",
        )
        self.q = q0.copy()
        self.set_q(q0)

    def _add_body(
        self,
        path: str,
        body: str,
        clouds: dict[str, Any],
        visuals: dict[str, Any],
        watched: bool,
        scale: float,
    ) -> None:
        """One body's cloud and visual meshes under ``path`` (in its frame)."""
        if body in clouds:
            rgb = WATCHED_RGB if watched else CLOUD_RGB
            pts = np.asarray(clouds[body].points, dtype=np.float32)
            self.viewer.add_node(
                f"{path}/cloud",
                self.viewer.server.scene.add_point_cloud(
                    f"{path}/cloud",
                    pts,
                    np.array(rgb, dtype=np.uint8),
                    point_size=0.0035 * scale,
                    precision="float32",
                ),
                "robot clouds",
            )
        for i, g in enumerate(visuals.get(body, ())):
            self._add_mesh(f"{path}/mesh_{i}", body, i, g)

    def _add_mesh(self, name: str, link: str, i: int, g: object) -> None:
        """One visual shape as a mesh under its link frame; a shape that cannot be read
        is noted (``mesh_notes``) and left out of the view."""
        from reachwise.errors import ReachwiseError
        from reachwise.io.robot_clouds import shape_mesh

        try:
            mesh = shape_mesh(self.robot, link, i, g)  # type: ignore[arg-type]
        except ReachwiseError as exc:
            self.mesh_notes.append(str(exc))
            return
        self.viewer.add_node(
            name,
            self.viewer.server.scene.add_mesh_simple(
                name,
                np.asarray(mesh.vertices, dtype=np.float32),
                np.asarray(mesh.faces, dtype=np.uint32),
                color=MESH_RGB,
                opacity=0.6,
            ),
            "robot meshes",
        )

    def set_q(self, q: ArrayLike) -> None:
        """Put the robot at joint vector ``q``: every link frame to its FK pose."""
        qv = np.asarray(q, dtype=float).reshape(-1)
        F = np.asarray(self.robot.fk_all(qv))
        with self.viewer.server.atomic():
            for k, link in self.links:
                wxyz, pos = wxyz_position(F[k])
                h = self.frames[link]
                h.wxyz = wxyz  # type: ignore[attr-defined]
                h.position = pos  # type: ignore[attr-defined]
            self.skeleton.points = _segments_f32(F[:, :3, 3])  # type: ignore[attr-defined]
        self.q = qv.copy()

    def frame_origins(self) -> NDArray[np.float64]:
        """World positions of the robot's frames at its current ``q``."""
        return np.asarray(self.robot.fk_all(self.q))[:, :3, 3]


def _segments_f32(origins: NDArray[np.float64]) -> NDArray[np.float32]:
    return np.stack([origins[:-1], origins[1:]], axis=1).astype(np.float32)
