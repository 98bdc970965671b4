"""A replay's cloud topic: its messages decoded to points in the fixed frame.

A ``sensor_msgs/PointCloud2`` or a depth ``sensor_msgs/Image`` (with the
``sensor_msgs/CameraInfo`` of its camera) becomes points in the replay's fixed frame,
moved along the transform tree at the message's header stamp. A depth image, and an
organized PointCloud2 (``height`` > 1), come as a cloud already indexed over the
Z-order of their pixels (``reachwise.distance.index.index_of_ordered``: no sort,
exact like any index of the distance layer), which the scene then takes as it is.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from reachwise.distance.index import INDICES, index_of_ordered
from reachwise.distance.scene_memory import SceneMemory, ViewIntrinsics
from reachwise.errors import InputError
from reachwise.geometry.cloud import PointCloud
from reachwise.io.ros.depth_image import (
    DepthProjector,
    camera_from_info,
    depth_image_pixels,
    depth_points,
    pixel_z_order,
)
from reachwise.io.ros.pointcloud2 import pointcloud2_points
from reachwise.io.ros.recording_error import RecordingError
from reachwise.io.ros.stamps import header_frame, header_stamp
from reachwise.io.ros.transform_tree import TransformTree

__all__ = ["IMAGE", "NOWHERE", "POINTCLOUD2", "CloudTopic"]

F64 = NDArray[np.float64]
POINTCLOUD2 = "sensor_msgs/msg/PointCloud2"
IMAGE = "sensor_msgs/msg/Image"
#: Where a cloud topic's object sits when a message returns no point: far from
#: everything.
NOWHERE = np.full((1, 3), 1.0e6)
#: The far limit given to the scene memory: the image's own invalid pixels are NaN or 0.
_FAR = 1.0e3


class CloudTopic:
    """One cloud topic: decodes its messages to points in the fixed frame."""

    def __init__(self, topic: str, msgtype: str, info_topic: str | None) -> None:
        self.topic = topic
        self.msgtype = msgtype
        self.info_topic = info_topic
        self.projector: DepthProjector | None = None
        self._info_key: tuple[Any, ...] | None = None
        self._z_key: tuple[int, int] | None = None
        self._z_order: tuple[NDArray[np.int64], NDArray[np.int64]] = (np.zeros(0, np.int64),) * 2
        self.count = 0

    def set_info(self, msg: Any) -> None:
        k = getattr(msg, "k", None)
        key = (int(msg.width), int(msg.height), tuple(np.asarray(k if k is not None else msg.K)))
        if key != self._info_key:
            self.projector = DepthProjector(camera_from_info(msg, topic=self.info_topic or ""))
            self._info_key = key

    def pose(self, msg: Any, t: float, tree: TransformTree, frame: str) -> tuple[F64 | None, float]:
        """Where the message's frame is in ``frame`` at its stamp (None: it is ``frame``),
        and the stamp (s; the bag time when the header has none)."""
        stamp = header_stamp(msg) or t
        source = header_frame(msg)
        if not source:
            raise RecordingError(self.topic, stamp, "header.frame_id", "is empty")
        if source == frame:
            return None, stamp
        try:
            return tree.lookup(frame, source, stamp), stamp
        except InputError as exc:
            raise RecordingError(self.topic, stamp, "header.frame_id", str(exc)) from None

    def _projector(self, stamp: float) -> DepthProjector:
        if self.projector is None:
            raise RecordingError(
                self.topic, stamp, "camera_info", f"no CameraInfo on {self.info_topic} yet"
            )
        return self.projector

    def points(
        self, msg: Any, t: float, tree: TransformTree, frame: str
    ) -> tuple[F64 | PointCloud, float]:
        """The message's points in ``frame`` and their stamp (s). A depth image's, and
        an organized PointCloud2's (``height`` > 1), come as a cloud already indexed
        over its pixels' Z-order (no sort:
        ``reachwise.distance.index.index_of_ordered``), which the scene takes as
        it is."""
        T, stamp = self.pose(msg, t, tree, frame)
        if self.msgtype == POINTCLOUD2:
            ordered = self._organized(msg, T)
            if ordered is not None:
                return _indexed(*ordered, self.topic), stamp
            pts = pointcloud2_points(msg, topic=self.topic)
            if T is not None:
                pts = pts @ T[:3, :3].T + T[:3, 3]
        else:
            proj = self._projector(stamp)
            pose = np.eye(4) if T is None else T
            pts, codes, centroid = proj.ordered_points(msg, pose, topic=self.topic)
            if len(pts):
                return _indexed(pts, codes, centroid, self.topic), stamp
        if len(pts) == 0:  # nothing returned: the frame says "nothing near"
            pts = NOWHERE
        return np.ascontiguousarray(pts, dtype=np.float64), stamp

    def _organized(self, msg: Any, T: F64 | None) -> tuple[F64, NDArray[np.int64], F64] | None:
        """An organized PointCloud2's finite points in pixel Z-order (moved by ``T``),
        their codes and mean; None for an unorganized one, one without a finite point,
        or a dense one with a non-finite point (the row-major path reports it)."""
        h, w = int(msg.height), int(msg.width)
        if h < 2:
            return None
        grid = pointcloud2_points(msg, organized=True, topic=self.topic)
        if self._z_key != (h, w):
            self._z_order, self._z_key = pixel_z_order(h, w), (h, w)
        order, codes = self._z_order
        in_order = grid.reshape(-1, 3)[order]
        finite = np.isfinite(in_order).all(axis=1)
        if not finite.any() or (msg.is_dense and not finite.all()):
            return None
        pts: F64 = np.ascontiguousarray(in_order[finite], dtype=np.float64)
        if T is not None:
            pts = np.ascontiguousarray(pts @ T[:3, :3].T + T[:3, 3], dtype=np.float64)
        kept: NDArray[np.int64] = np.ascontiguousarray(codes[finite])
        return pts, kept, np.asarray(pts.mean(axis=0), dtype=np.float64)

    def fuse(
        self, memory: SceneMemory, msg: Any, t: float, tree: TransformTree, frame: str
    ) -> tuple[PointCloud | F64, float]:
        """Fuse the depth image ``msg`` into ``memory``; its obstacles (voxel centres in
        ``frame``: a cloud with its index built, or :data:`NOWHERE` while there are
        none) and the image's stamp."""
        T, stamp = self.pose(msg, t, tree, frame)
        cam = self._projector(stamp).camera
        z, scale = depth_image_pixels(msg, topic=self.topic)  # read as the camera sent it
        if z.shape != cam.shape:
            depth_points(msg, cam, topic=self.topic)  # raises the size error
        i = cam.intrinsics
        view = ViewIntrinsics(i.fx, i.fy, i.cx, i.cy, 0.0, _FAR)
        memory.integrate(z, np.eye(4) if T is None else T, view, stamp, depth_scale=scale)
        cloud = memory.obstacle_cloud(stamp, name=self.topic)
        return (NOWHERE if cloud is None else cloud), stamp


def _indexed(points: F64, codes: NDArray[np.int64], centroid: F64, topic: str) -> PointCloud:
    """The cloud of ``points`` (in pixel Z-order, with their ``codes``) with its index
    built over that order and kept in :data:`~reachwise.distance.index.INDICES`."""
    index = index_of_ordered(points, codes, centroid)
    # the cloud and its index share the points (a read-only view for the cloud; the
    # compiled queries take the index's arrays as writable)
    cloud = PointCloud.of_checked(points.view(), name=topic)
    INDICES.put(cloud, index)
    return cloud
