"""Round trips: recordings written with rosbags (ROS 2 sqlite3, ROS 2 MCAP, ROS 1) read
back through :class:`Recording` decode to the same arrays as the messages written; a
file that is not a recording, and one cut short, are typed errors."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore

from reachwise.errors import InputError
from reachwise.io.ros.bag import Recording
from reachwise.io.ros.bag_writer import BagWriter
from reachwise.io.ros.depth_image import camera_from_info, depth_points
from reachwise.io.ros.joint_state import JointMatcher
from reachwise.io.ros.pointcloud2 import pointcloud2_points
from reachwise.io.ros.recording_error import RecordingError
from reachwise.io.ros.transform_tree import TransformTree
from tests.io.ros._messages import cloud_message, depth_message, field


def _messages(store: Any, ros1: bool) -> list[tuple[str, str, float, Any]]:
    """Padded big-endian organized non-dense cloud, both depth encodings, CameraInfo,
    /tf and /tf_static, JointState — as messages of ``store``."""
    T = store.types

    def header(t: float, frame: str) -> Any:
        stamp = T["builtin_interfaces/msg/Time"](sec=int(t), nanosec=round((t % 1) * 1e9))
        if ros1:
            return T["std_msgs/msg/Header"](seq=0, stamp=stamp, frame_id=frame)
        return T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)

    rng = np.random.default_rng(7)
    vals = {c: rng.uniform(-3, 3, (3, 4)) for c in "xyz"}
    vals["x"][1, 2] = np.nan
    vals["i"] = rng.integers(0, 255, (3, 4))
    fields = [field("z", 0, 8), field("i", 8, 2), field("x", 12, 7), field("y", 16, 8)]
    raw_cloud = cloud_message(
        vals, fields, height=3, width=4, point_step=28, row_step=4 * 28 + 12, big=True, dense=False
    )
    PF = T["sensor_msgs/msg/PointField"]
    cloud = T["sensor_msgs/msg/PointCloud2"](
        header=header(1.0, "cam"),
        height=3,
        width=4,
        fields=[PF(name=f.name, offset=f.offset, datatype=f.datatype, count=1) for f in fields],
        is_bigendian=True,
        point_step=28,
        row_step=4 * 28 + 12,
        data=np.asarray(raw_cloud.data, np.uint8).copy(),
        is_dense=False,
    )
    out: list[tuple[str, str, float, Any]] = [
        ("/points", "sensor_msgs/msg/PointCloud2", 1.0, cloud)
    ]
    mm = rng.integers(0, 5000, (5, 6)).astype(np.uint16)
    m = rng.uniform(0.1, 4, (5, 6)).astype(np.float32)
    m[0, :2] = np.nan
    for topic, raw, enc, step, big in (
        ("/depth_mm", mm, "16UC1", 14, False),
        ("/depth_m", m, "32FC1", 24, True),
    ):
        d = depth_message(raw, enc, step=step, big=big)
        img = T["sensor_msgs/msg/Image"](
            header=header(1.5, "cam_optical"),
            height=5,
            width=6,
            encoding=enc,
            is_bigendian=int(big),
            step=step,
            data=np.asarray(d.data, np.uint8).copy(),
        )
        out.append((topic, "sensor_msgs/msg/Image", 1.5, img))
    k = np.array([300.0, 0, 2.5, 0, 310.0, 2.0, 0, 0, 1])
    roi = T["sensor_msgs/msg/RegionOfInterest"](
        x_offset=0, y_offset=0, height=0, width=0, do_rectify=False
    )
    kw = (
        {"D": np.zeros(5), "K": k, "R": np.eye(3).ravel(), "P": np.zeros(12)}
        if ros1
        else {"d": np.zeros(5), "k": k, "r": np.eye(3).ravel(), "p": np.zeros(12)}
    )
    info = T["sensor_msgs/msg/CameraInfo"](
        header=header(1.5, "cam_optical"),
        height=5,
        width=6,
        distortion_model="plumb_bob",
        binning_x=0,
        binning_y=0,
        roi=roi,
        **kw,
    )
    out.append(("/camera_info", "sensor_msgs/msg/CameraInfo", 1.5, info))

    def tfm(t: float, parent: str, child: str, xyz: list[float], q: list[float]) -> Any:
        V, Q = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
        tr = T["geometry_msgs/msg/Transform"](
            translation=V(x=xyz[0], y=xyz[1], z=xyz[2]), rotation=Q(x=q[0], y=q[1], z=q[2], w=q[3])
        )
        ts = T["geometry_msgs/msg/TransformStamped"](
            header=header(t, parent), child_frame_id=child, transform=tr
        )
        return T["tf2_msgs/msg/TFMessage"](transforms=[ts])

    s = np.sqrt(0.5)
    out.append(
        (
            "/tf_static",
            "tf2_msgs/msg/TFMessage",
            0.5,
            tfm(0.5, "world", "cam", [1, 2, 3], [0, 0, s, s]),
        )
    )
    out.append(
        (
            "/tf",
            "tf2_msgs/msg/TFMessage",
            1.0,
            tfm(1.0, "cam", "cam_optical", [0, 0, 0], [0, 0, 0, 1]),
        )
    )
    out.append(
        (
            "/tf",
            "tf2_msgs/msg/TFMessage",
            2.0,
            tfm(2.0, "cam", "cam_optical", [0, 0, 1], [0, 0, 0, 1]),
        )
    )
    js = T["sensor_msgs/msg/JointState"](
        header=header(1.25, ""),
        name=["b", "a"],
        position=np.array([2.0, 1.0]),
        velocity=np.zeros(0),
        effort=np.zeros(0),
    )
    out.append(("/joint_states", "sensor_msgs/msg/JointState", 1.25, js))
    return out


def _decode(items: list[tuple[str, float, Any]]) -> dict[str, Any]:
    got: dict[str, Any] = {}
    tree = TransformTree()
    for topic, t, msg in items:
        got.setdefault("order", []).append((topic, t))
        if topic == "/points":
            got["points"] = pointcloud2_points(msg)
            got["organized"] = pointcloud2_points(msg, organized=True)
        elif topic in ("/depth_mm", "/depth_m"):
            got[topic] = msg
        elif topic == "/camera_info":
            got["camera"] = camera_from_info(msg)
        elif topic in ("/tf", "/tf_static"):
            tree.add_message(msg, static=topic == "/tf_static")
        elif topic == "/joint_states":
            got["q"] = JointMatcher(["a", "b"]).positions(msg)
    for topic in ("/depth_mm", "/depth_m"):
        got[topic] = depth_points(got[topic], got["camera"])
    got["tf"] = tree.lookup("world", "cam_optical", 1.5)
    return got


def _write(path: Path, kind: str) -> list[tuple[str, str, float, Any]]:
    if kind == "ros1":
        from rosbags.rosbag1 import Writer as W1
        from rosbags.typesys import get_types_from_msg

        store = get_typestore(Stores.ROS1_NOETIC)
        if "tf2_msgs/msg/TFMessage" not in store.types:  # not in the Noetic store's set
            store.register(
                get_types_from_msg(
                    "geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"
                )
            )
        msgs = _messages(store, ros1=True)
        with W1(path) as w:
            conns: dict[str, Any] = {}
            for topic, typ, t, msg in msgs:
                if topic not in conns:
                    conns[topic] = w.add_connection(topic, typ, typestore=store)
                w.write(conns[topic], round(t * 1e9), store.serialize_ros1(msg, typ))
        return msgs
    from rosbags.rosbag2 import StoragePlugin, Writer

    store = get_typestore(Stores.ROS2_HUMBLE)
    msgs = _messages(store, ros1=False)
    plugin = StoragePlugin.MCAP if kind == "mcap" else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as w:
        conns = {}
        for topic, typ, t, msg in msgs:
            if topic not in conns:
                conns[topic] = w.add_connection(topic, typ, typestore=store)
            w.write(conns[topic], round(t * 1e9), store.serialize_cdr(msg, typ))
    return msgs


@pytest.mark.parametrize("kind", ["sqlite3", "mcap", "ros1"])
def test_recording_reads_back_the_same_arrays(tmp_path: Path, kind: str) -> None:
    path = tmp_path / ("cell.bag" if kind == "ros1" else "cell")
    written = _write(path, kind)
    expected = _decode([(topic, t, msg) for topic, _, t, msg in written])
    with Recording(path) as rec:
        got = _decode([(m.topic, m.t, m.msg) for m in rec.messages(rec.topics)])
    assert got["order"] == sorted(expected["order"], key=lambda x: x[1])
    for key in ("points", "organized", "/depth_mm", "/depth_m", "q", "tf"):
        np.testing.assert_array_equal(got[key], expected[key])
    assert len(got["points"]) == 11  # the non-finite point dropped
    assert got["q"].tolist() == [1.0, 2.0]


def test_a_lone_storage_file_opens_too(tmp_path: Path) -> None:
    _write(tmp_path / "cell", "mcap")
    (storage,) = (tmp_path / "cell").glob("*.mcap")
    with Recording(storage) as rec:
        assert "/points" in rec.topics


def test_our_writer_round_trips(tmp_path: Path) -> None:
    pts = np.random.default_rng(1).normal(size=(50, 3))
    for name in ("out.mcap", "out_db"):
        with BagWriter(tmp_path / name) as w:
            w.write(
                "/c", "sensor_msgs/msg/PointCloud2", w.factory.point_cloud(0.25, "world", pts), 0.25
            )
        with Recording(tmp_path / name) as rec:
            (m,) = rec.messages(["/c"])
            assert m.t == 0.25
            np.testing.assert_array_equal(pointcloud2_points(m.msg), pts)
    with pytest.raises(InputError, match="exists"):
        BagWriter(tmp_path / "out.mcap")


def test_not_a_bag_is_an_input_error(tmp_path: Path) -> None:
    for name, data in (
        ("cell.bag", b"hello, not a bag"),
        ("cell.mcap", b"\x89MCAP0\r\n garbage"),
        ("cell.txt", b"x"),
    ):
        p = tmp_path / name
        p.write_bytes(data)
        with pytest.raises(InputError, match=str(name)):
            with Recording(p) as rec:
                list(rec.messages(rec.topics))
    with pytest.raises(InputError, match="no such file"):
        Recording(tmp_path / "missing.mcap")


@pytest.mark.parametrize("kind", ["mcap", "ros1"])
def test_truncated_recording_is_an_input_error(tmp_path: Path, kind: str) -> None:
    path = tmp_path / ("cell.bag" if kind == "ros1" else "cell")
    _write(path, kind)
    file = path if kind == "ros1" else next(path.glob("*.mcap"))
    data = file.read_bytes()
    cut = tmp_path / ("cut.bag" if kind == "ros1" else "cut.mcap")
    cut.write_bytes(data[: len(data) * 2 // 3])
    with pytest.raises(InputError, match="cut"):
        with Recording(cut) as rec:
            list(rec.messages(rec.topics))


def test_unknown_topic_lists_the_topics(tmp_path: Path) -> None:
    _write(tmp_path / "cell", "sqlite3")
    with Recording(tmp_path / "cell") as rec, pytest.raises(InputError, match="/joint_states"):
        rec.check_topic("/joints")
    with Recording(tmp_path / "cell") as rec, pytest.raises(RecordingError, match="JointState"):
        rec.check_topic("/points", ["sensor_msgs/msg/JointState"])


@pytest.mark.parametrize("name", ["out.bag", "out.mcap", "out_db"])
def test_every_message_we_write_round_trips_in_each_format(tmp_path: Path, name: str) -> None:
    """ROS 1 (.bag: Noetic types, a Header with seq, CameraInfo's K), MCAP and sqlite3:
    each kind of message the factory makes reads back to the arrays it was made of."""
    import json

    from reachwise.geometry.depth_camera import Intrinsics
    from reachwise.io.ros.depth_image import camera_from_info, depth_image_metres
    from reachwise.io.ros.transform_tree import TransformTree

    rng = np.random.default_rng(7)
    pts = rng.normal(size=(30, 3))
    depth = rng.uniform(0.5, 3.0, (4, 6))
    depth[1, 2] = np.nan
    intr = Intrinsics(6, 4, 5.0, 6.0, 2.5, 1.5)
    T = np.eye(4)
    T[:3, :3] = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    T[:3, 3] = [0.1, 0.2, 0.3]
    q = rng.normal(size=3)
    a, b = rng.normal(size=(2, 3)), rng.normal(size=(2, 3))
    with BagWriter(tmp_path / name) as w:
        f = w.factory
        w.write("/js", "sensor_msgs/msg/JointState", f.joint_state(0.5, ["j1", "j2", "j3"], q), 0.5)
        w.write("/img", "sensor_msgs/msg/Image", f.depth_image(0.5, "cam", depth), 0.5)
        w.write("/info", "sensor_msgs/msg/CameraInfo", f.camera_info(0.5, "cam", intr), 0.5)
        w.write("/pc", "sensor_msgs/msg/PointCloud2", f.point_cloud(0.5, "cam", pts), 0.5)
        w.write("/tf", "tf2_msgs/msg/TFMessage", f.tf([f.transform(0.5, "world", "cam", T)]), 0.5)
        w.write("/s", "std_msgs/msg/String", f.string(json.dumps(["x|y"])), 0.5)
        w.write("/f", "std_msgs/msg/Float64", f.float64(1.25), 0.5)
        w.write("/fa", "std_msgs/msg/Float64MultiArray", f.float64_array("p;q", q), 0.5)
        markers = f.line_markers(0.5, "world", a, b, [True, False])
        w.write("/m", "visualization_msgs/msg/MarkerArray", markers, 0.5)
    with Recording(tmp_path / name) as rec:
        assert rec.ros1 == (name == "out.bag")
        got = {m.topic: m for m in rec.messages(sorted(rec.topics))}
    assert {m.t for m in got.values()} == {0.5}
    assert list(got["/js"].msg.name) == ["j1", "j2", "j3"]
    np.testing.assert_array_equal(got["/js"].msg.position, q)
    np.testing.assert_array_equal(
        depth_image_metres(got["/img"].msg), depth.astype(np.float32).astype(np.float64)
    )
    assert camera_from_info(got["/info"].msg).intrinsics == intr
    np.testing.assert_array_equal(pointcloud2_points(got["/pc"].msg), pts)
    tree = TransformTree()
    tree.add_message(got["/tf"].msg, static=False)
    np.testing.assert_allclose(tree.lookup("world", "cam", 0.5), T, atol=1e-12)
    assert json.loads(got["/s"].msg.data) == ["x|y"]
    assert got["/f"].msg.data == 1.25
    np.testing.assert_array_equal(got["/fa"].msg.data, q)
    assert got["/fa"].msg.layout.dim[0].label == "p;q"
    (marker,) = got["/m"].msg.markers
    line = np.array([[p.x, p.y, p.z] for p in marker.points])
    np.testing.assert_array_equal(line, [a[0], b[0], a[1], b[1]])
    assert [c.r for c in marker.colors] == pytest.approx([1.0, 1.0, 0.1, 0.1])
