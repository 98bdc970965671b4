"""Arrays to ROS 2 or ROS 1 messages (the types of a :mod:`rosbags` typestore), for the
bags reachwise writes: joint states, depth images and their CameraInfo, point clouds,
``/tf``, and the replay's results (``std_msgs`` and ``visualization_msgs``)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation

from reachwise.geometry.depth_camera import Intrinsics

__all__ = ["MessageFactory"]


#: Fields of the ROS 2 types that their ROS 1 versions lack (visualization_msgs/Marker's
#: texture and mesh file): left out when the typestore's type has no such field.
_ROS2_ONLY = frozenset({"texture_resource", "texture", "uv_coordinates", "mesh_file"})


class MessageFactory:
    """Builds messages from arrays with the classes of ``store`` (a typestore: ROS 2, or
    ROS 1 ``ros1_noetic``, whose types differ in a few fields, see ``_new``)."""

    def __init__(self, store: Any) -> None:
        self.types = store.types

    def _t(self, name: str) -> Any:
        return self.types[name]

    def _new(self, typename: str, /, **values: Any) -> Any:
        """A ``typename`` message of ``values`` (given by their ROS 2 field names), fitted
        to the store's type: in ROS 1 a ``Header`` has a ``seq`` (0 here), CameraInfo's
        matrices are ``D``, ``K``, ``R``, ``P``, and a Marker has no texture or mesh
        file (:data:`_ROS2_ONLY`, left out)."""
        cls = self._t(typename)
        fields = cls.__dataclass_fields__
        kw: dict[str, Any] = {}
        for key, value in values.items():
            if key in fields:
                kw[key] = value
            elif key.upper() in fields:
                kw[key.upper()] = value
            elif key not in _ROS2_ONLY:
                kw[key] = value  # unknown: the type's constructor names it
        if "seq" in fields and "seq" not in kw:
            kw["seq"] = 0
        return cls(**kw)

    def time(self, t: float) -> Any:
        """``builtin_interfaces/Time`` of ``t`` (s, >= 0)."""
        sec = math.floor(t)
        nsec = round((t - sec) * 1e9)
        if nsec >= 1_000_000_000:
            sec, nsec = sec + 1, nsec - 1_000_000_000
        return self._new("builtin_interfaces/msg/Time", sec=int(sec), nanosec=int(nsec))

    def header(self, t: float, frame: str) -> Any:
        return self._new("std_msgs/msg/Header", stamp=self.time(t), frame_id=frame)

    def joint_state(self, t: float, names: Sequence[str], q: ArrayLike) -> Any:
        """``sensor_msgs/JointState`` with ``position`` = ``q``."""
        pos = np.asarray(q, dtype=np.float64).reshape(-1)
        return self._new(
            "sensor_msgs/msg/JointState",
            header=self.header(t, ""),
            name=list(names),
            position=pos.copy(),
            velocity=np.zeros(0),
            effort=np.zeros(0),
        )

    def depth_image(self, t: float, frame: str, depth: ArrayLike) -> Any:
        """A ``32FC1`` depth image (m, NaN: no return) of ``depth`` (``(h, w)``)."""
        z = np.ascontiguousarray(depth, dtype="<f4")
        h, w = z.shape
        return self._new(
            "sensor_msgs/msg/Image",
            header=self.header(t, frame),
            height=h,
            width=w,
            encoding="32FC1",
            is_bigendian=0,
            step=w * 4,
            data=z.view(np.uint8).reshape(-1).copy(),
        )

    def camera_info(self, t: float, frame: str, intr: Intrinsics) -> Any:
        """``sensor_msgs/CameraInfo`` of a pinhole without distortion."""
        k = np.array([intr.fx, 0.0, intr.cx, 0.0, intr.fy, intr.cy, 0.0, 0.0, 1.0])
        p = np.array([intr.fx, 0.0, intr.cx, 0.0, 0.0, intr.fy, intr.cy, 0.0, 0.0, 0.0, 1.0, 0.0])
        roi = self._new(
            "sensor_msgs/msg/RegionOfInterest",
            x_offset=0,
            y_offset=0,
            height=0,
            width=0,
            do_rectify=False,
        )
        return self._new(
            "sensor_msgs/msg/CameraInfo",
            header=self.header(t, frame),
            height=intr.height,
            width=intr.width,
            distortion_model="plumb_bob",
            d=np.zeros(5),
            k=k,
            r=np.eye(3).reshape(-1),
            p=p,
            binning_x=0,
            binning_y=0,
            roi=roi,
        )

    def point_cloud(self, t: float, frame: str, points: ArrayLike) -> Any:
        """An unorganized, dense ``sensor_msgs/PointCloud2`` of float64 ``x, y, z``."""
        pts = np.ascontiguousarray(points, dtype="<f8").reshape(-1, 3)
        field = self._t("sensor_msgs/msg/PointField")
        fields = [field(name=c, offset=8 * j, datatype=8, count=1) for j, c in enumerate("xyz")]
        return self._new(
            "sensor_msgs/msg/PointCloud2",
            header=self.header(t, frame),
            height=1,
            width=len(pts),
            fields=fields,
            is_bigendian=False,
            point_step=24,
            row_step=24 * len(pts),
            data=pts.view(np.uint8).reshape(-1).copy(),
            is_dense=True,
        )

    def transform(self, t: float, parent: str, child: str, T: ArrayLike) -> Any:
        """``geometry_msgs/TransformStamped`` of the 4 × 4 ``T`` (child in parent)."""
        M = np.asarray(T, dtype=np.float64)
        x, y, z, w = Rotation.from_matrix(M[:3, :3]).as_quat()
        tr = self._new("geometry_msgs/msg/Vector3", x=M[0, 3], y=M[1, 3], z=M[2, 3])
        rot = self._new("geometry_msgs/msg/Quaternion", x=x, y=y, z=z, w=w)
        return self._new(
            "geometry_msgs/msg/TransformStamped",
            header=self.header(t, parent),
            child_frame_id=child,
            transform=self._new("geometry_msgs/msg/Transform", translation=tr, rotation=rot),
        )

    def tf(self, transforms: Sequence[Any]) -> Any:
        """``tf2_msgs/TFMessage`` of ``TransformStamped`` messages."""
        return self._new("tf2_msgs/msg/TFMessage", transforms=list(transforms))

    def string(self, text: str) -> Any:
        return self._new("std_msgs/msg/String", data=text)

    def float64(self, value: float) -> Any:
        return self._new("std_msgs/msg/Float64", data=float(value))

    def float64_array(self, label: str, values: ArrayLike) -> Any:
        """``std_msgs/Float64MultiArray``: one dimension ``label`` of the ``values``."""
        data = np.asarray(values, dtype=np.float64).reshape(-1).copy()
        dim = self._new(
            "std_msgs/msg/MultiArrayDimension", label=label, size=data.size, stride=data.size
        )
        layout = self._new("std_msgs/msg/MultiArrayLayout", dim=[dim], data_offset=0)
        return self._new("std_msgs/msg/Float64MultiArray", layout=layout, data=data)

    def line_markers(
        self,
        t: float,
        frame: str,
        starts: ArrayLike,
        ends: ArrayLike,
        near: ArrayLike,
        *,
        ns: str = "reachwise",
    ) -> Any:
        """``visualization_msgs/MarkerArray``: one ``LINE_LIST`` marker from each start to
        its end point (the closest points of each pair), red where ``near`` else green."""
        a = np.asarray(starts, dtype=np.float64).reshape(-1, 3)
        b = np.asarray(ends, dtype=np.float64).reshape(-1, 3)
        close = np.asarray(near, dtype=bool).reshape(-1)
        P = self._t("geometry_msgs/msg/Point")
        C = self._t("std_msgs/msg/ColorRGBA")
        red, green = C(r=1.0, g=0.1, b=0.1, a=1.0), C(r=0.1, g=0.8, b=0.2, a=1.0)
        points, colors = [], []
        for i in range(len(a)):
            if not (np.isfinite(a[i]).all() and np.isfinite(b[i]).all()):
                continue
            points += [P(x=a[i, 0], y=a[i, 1], z=a[i, 2]), P(x=b[i, 0], y=b[i, 1], z=b[i, 2])]
            colors += [red if close[i] else green] * 2
        M = self._t("visualization_msgs/msg/Marker")
        ros2: dict[str, Any] = {}
        if "texture" in M.__dataclass_fields__:
            ros2["texture"] = self._new(
                "sensor_msgs/msg/CompressedImage",
                header=self.header(t, ""),
                format="",
                data=np.zeros(0, np.uint8),
            )
            ros2["mesh_file"] = self._new(
                "visualization_msgs/msg/MeshFile", filename="", data=np.zeros(0, np.uint8)
            )
        pose = self._new(
            "geometry_msgs/msg/Pose",
            position=P(x=0.0, y=0.0, z=0.0),
            orientation=self._new("geometry_msgs/msg/Quaternion", x=0.0, y=0.0, z=0.0, w=1.0),
        )
        marker = self._new(
            "visualization_msgs/msg/Marker",
            header=self.header(t, frame),
            ns=ns,
            id=0,
            type=M.LINE_LIST,
            action=M.ADD,
            pose=pose,
            scale=self._new("geometry_msgs/msg/Vector3", x=0.005, y=0.0, z=0.0),
            color=green,
            lifetime=self._new("builtin_interfaces/msg/Duration", sec=0, nanosec=0),
            frame_locked=False,
            points=points,
            colors=colors,
            texture_resource="",
            uv_coordinates=[],
            text="",
            mesh_resource="",
            mesh_use_embedded_materials=False,
            **ros2,
        )
        return self._new("visualization_msgs/msg/MarkerArray", markers=[marker])
