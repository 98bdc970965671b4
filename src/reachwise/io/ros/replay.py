"""Replaying a recording through the distance scene.

:func:`replay_recording` drives a :class:`~reachwise.distance.scene.Scene` from a
recording in the recording's own order and time: the robot's joint states as they come
(each one a :meth:`~reachwise.distance.Scene.set_joints` and, at most every
``every`` seconds of recording time, one :meth:`~reachwise.distance.Scene.query_all`,
a *frame*), and each cloud topic's messages decoded to points in the fixed frame and
handed over with :meth:`~reachwise.distance.Scene.replace_cloud`. Messages
received at the same time are taken clouds first, then joint states, so a frame counts
every cloud received at or before its time (bag formats keep such ties in different
orders). By default the hand-over blocks, so every frame uses the newest cloud
received by its time, the same on any machine. ``block=False`` hands clouds over as a
live robot does: a frame uses the newest cloud whose index is ready, and says which
(its stamp); with ``rate`` the replay is paced at ``rate`` times the recording's speed
(1: as recorded; the worker that indexes clouds then has the time it had live),
without it the replay runs as fast as it can and frames use older clouds the faster it
runs. The robot's links carry the clouds of ``link_clouds``; every watched link is
paired with every cloud topic.

A cloud topic is a ``sensor_msgs/PointCloud2`` or a depth ``sensor_msgs/Image`` with
its ``sensor_msgs/CameraInfo`` (by default the sibling topic ``camera_info``). Clouds
are moved into the fixed frame ``frame`` (the frame the robot's base pose is given in)
along ``/tf`` and ``/tf_static`` at their header stamp (all TF messages are read
first, so a cloud may use a transform recorded after it). The distances are exact on
the clouds (watched with an infinite margin); ``margin`` only marks the frames that
came closer.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from itertools import groupby
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from reachwise.distance.scene import Scene
from reachwise.distance.scene_memory import MemoryConfig, SceneMemory
from reachwise.errors import InputError, UnknownName
from reachwise.geometry.cloud import PointCloud
from reachwise.io.ros.bag import BagMessage, Recording
from reachwise.io.ros.cloud_topic import IMAGE, NOWHERE, POINTCLOUD2, CloudTopic
from reachwise.io.ros.joint_state import JointMatcher, robot_joint_names
from reachwise.io.ros.recording_error import RecordingError
from reachwise.io.ros.stamps import header_stamp
from reachwise.io.ros.transform_tree import TransformTree
from reachwise.kinematics.robot import Robot

__all__ = ["CloudHook", "MemoryHook", "ReplayResult", "ReplaySpec", "replay_recording"]

F64 = NDArray[np.float64]
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
JOINT_STATE = "sensor_msgs/msg/JointState"
TF_TOPICS = ("/tf", "/tf_static")
#: Where a cloud topic's object sits until its first message (far from everything);
#: its pairs' answers are not reported until then.
_NOWHERE = NOWHERE
#: The scene object of the scene memory.
MEMORY = "memory"
#: ``on_cloud(object, stamp, points)``: told of each cloud handed to the scene.
CloudHook = Callable[[str, float, NDArray[np.float64]], None]
#: ``on_memory(stamp, memory)``: told after each depth frame fused into the scene memory.
MemoryHook = Callable[[float, SceneMemory], None]


@dataclass(frozen=True)
class ReplaySpec:
    """What to replay: the ``joints`` topic, the ``clouds`` topics, the ``margin`` (m)
    that marks near frames, the fixed ``frame``, each depth topic's CameraInfo topic
    (``camera_info``; default its sibling ``camera_info``), the watched ``links``
    (default: every link with a cloud), the least recording time between two frames
    ``every`` (s; 0: a frame per joint state), ``block`` (hand clouds over blocking:
    each frame then uses the newest cloud received), the pace ``rate`` (a multiple of
    the recording's speed; None: as fast as possible), the scene's ``voxel`` thinning
    (m, or None) and the TF ``tf_tolerance`` (s). With ``memory`` (a
    ``reachwise.distance.scene_memory.MemoryConfig``) the depth-image topics are
    fused into one scene memory of the box ``memory_box`` (lower and upper corner, m,
    in ``frame``) instead of replacing a cloud each: the scene object ``memory``, the
    occupied and shadow voxels' centres, paired with every link."""

    joints: str
    clouds: tuple[str, ...]
    margin: float = 0.05
    frame: str = "world"
    camera_info: Mapping[str, str] = field(default_factory=dict)
    links: tuple[str, ...] | None = None
    every: float = 0.0
    block: bool = True
    rate: float | None = None
    voxel: float | None = None
    tf_tolerance: float = 0.0
    memory: MemoryConfig | None = None
    memory_box: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None

    def __post_init__(self) -> None:
        if not self.clouds:
            raise InputError("replay", "clouds", "give at least one cloud topic")
        for name in ("margin", "every", "tf_tolerance"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0):
                raise InputError("replay", name, f"must be a finite number >= 0, got {v!r}")
        if (self.memory is None) != (self.memory_box is None):
            raise InputError("replay", "memory_box", "give memory and memory_box together")
        if self.rate is not None and not (math.isfinite(self.rate) and self.rate > 0):
            raise InputError("replay", "rate", f"must be a finite number > 0, got {self.rate!r}")

    def info_topic(self, topic: str) -> str:
        """The CameraInfo topic of depth topic ``topic``."""
        if topic in self.camera_info:
            return self.camera_info[topic]
        return topic.rsplit("/", 1)[0] + "/camera_info"


@dataclass(frozen=True, eq=False)
class ReplayResult:
    """The answers of a replay, one row per frame (query): ``t`` (F,) recording time
    (s) of the joint state queried; per watched pair (``pairs``, ``"link|topic"``):
    ``distance`` (F, P, m; NaN before the pair's cloud arrived), ``cloud_stamp``
    (F, P, s; the stamp of the cloud the answer used, NaN before; ``link|memory`` for
    the scene memory), ``point_a``,
    ``point_b`` (F, P, 3; the closest points in the fixed frame); ``margin``;
    ``clouds`` (per topic, the number of clouds handed over) and ``swapped`` (how many
    of them some frame used); ``q`` (F, n): the robot's joint positions queried;
    ``ros1``: the recording is a ROS 1 bag."""

    bag: str
    robot: str
    frame: str
    pairs: tuple[str, ...]
    t: F64
    q: F64
    distance: F64
    cloud_stamp: F64
    point_a: F64
    point_b: F64
    margin: float
    clouds: dict[str, int]
    swapped: dict[str, int]
    ros1: bool = False

    @property
    def min_distance(self) -> F64:
        """The smallest distance over the pairs of each frame (NaN without any)."""
        d = np.where(np.isnan(self.distance), np.inf, self.distance)
        m = d.min(axis=1, initial=np.inf)
        return np.where(np.isfinite(m), m, np.nan)

    @property
    def near(self) -> NDArray[np.bool_]:
        """(F, P): the pair came closer than the margin in that frame."""
        with np.errstate(invalid="ignore"):
            return np.asarray(self.distance < self.margin)


def _read_tf_and_info(
    rec: Recording, spec: ReplaySpec, sources: dict[str, CloudTopic]
) -> TransformTree:
    """Every TF message into one tree, and the first CameraInfo of each depth topic."""
    tree = TransformTree(tolerance=spec.tf_tolerance)
    infos = {s.info_topic: s for s in sources.values() if s.info_topic is not None}
    topics = [t for t in TF_TOPICS if t in rec.topics] + list(infos)
    for m in rec.messages(topics):
        if m.topic in infos:
            src = infos[m.topic]
            if src.projector is None:
                src.set_info(m.msg)
            continue
        try:
            tree.add_message(m.msg, static=m.topic == "/tf_static")
        except InputError as exc:
            raise RecordingError(m.topic, m.t, "transforms", str(exc), bag=rec.source) from None
    return tree


def _sources(rec: Recording, spec: ReplaySpec) -> dict[str, CloudTopic]:
    out = {}
    for topic in spec.clouds:
        msgtype = rec.check_topic(topic, (POINTCLOUD2, IMAGE))
        info = spec.info_topic(topic) if msgtype == IMAGE else None
        if info is not None:
            rec.check_topic(info, (CAMERA_INFO,))
        out[topic] = CloudTopic(topic, msgtype, info)
    return out


def _scene(
    robot: Robot, link_clouds: Mapping[str, PointCloud], spec: ReplaySpec, objects: list[str]
) -> tuple[Scene, list[tuple[str, str]]]:
    links = list(link_clouds) if spec.links is None else list(spec.links)
    for link in links:
        if link not in link_clouds:
            raise UnknownName("replay", "link with a cloud", link, link_clouds)
    if not links:
        raise InputError("replay", "links", f"robot {robot.name!r} has no link with a cloud")
    scene = Scene(voxel=spec.voxel)
    scene.add_robot(robot)
    for link in links:
        # a URDF link fixed to a chain link (a flange, a hand) rides on that frame
        scene.add_object(link, link_clouds[link], robot=robot.name, link=robot.frame_of(link))
    pairs = []
    for name in objects:
        scene.add_object(name, _NOWHERE)
        for link in links:
            scene.watch(link, name, math.inf, kind="robot-environment")
            pairs.append((link, name))
    return scene, pairs


def replay_recording(
    bag: str | Path,
    robot: Robot,
    spec: ReplaySpec,
    *,
    link_clouds: Mapping[str, PointCloud],
    on_cloud: CloudHook | None = None,
    on_memory: MemoryHook | None = None,
) -> ReplayResult:
    """Replay recording ``bag`` (see the module docstring) with ``robot``, whose links
    carry ``link_clouds`` (link name → cloud in the link frame). ``on_cloud(object,
    stamp, points)`` is called with each cloud handed to the scene (its object: the
    topic, or ``memory``; its stamp, s; its points in the fixed frame, read-only), e.g.
    to keep them for a viewer; ``on_memory(stamp, memory)`` after each depth frame
    fused into the scene memory (the ``reachwise.distance.scene_memory.SceneMemory``
    itself, to read, not to change)."""
    matcher = JointMatcher(robot_joint_names(robot))
    with Recording(bag) as rec:
        ros1 = rec.ros1
        rec.check_topic(spec.joints, (JOINT_STATE,))
        sources = _sources(rec, spec)
        try:
            tree = _read_tf_and_info(rec, spec, sources)
            fused = spec.memory is not None
            objects = [t for t, s in sources.items() if not (fused and s.msgtype == IMAGE)]
            if fused:
                objects.append(MEMORY)
            scene, pairs = _scene(robot, link_clouds, spec, objects)
            try:
                hooks = (on_cloud, on_memory)
                rows = _drive(rec, spec, sources, tree, scene, pairs, matcher, robot.name, hooks)
            finally:
                scene.close()
        except RecordingError as exc:
            raise exc.in_bag(rec.source) from None
    t, q, dist, stamp, pa, pb, used = rows
    return ReplayResult(
        bag=str(bag),
        robot=robot.name,
        frame=spec.frame,
        pairs=tuple(f"{a}|{b}" for a, b in pairs),
        t=t,
        q=q,
        distance=dist,
        cloud_stamp=stamp,
        point_a=pa,
        point_b=pb,
        margin=float(spec.margin),
        clouds={s.topic: s.count for s in sources.values()},
        swapped=used,
        ros1=ros1,
    )


def _drive(
    rec: Recording,
    spec: ReplaySpec,
    sources: dict[str, CloudTopic],
    tree: TransformTree,
    scene: Scene,
    pairs: list[tuple[str, str]],
    matcher: JointMatcher,
    robot: str,
    hooks: tuple[CloudHook | None, MemoryHook | None],
) -> tuple[F64, F64, F64, F64, F64, F64, dict[str, int]]:
    """The replay loop: joint states and clouds in recording order, a frame per joint
    state (at most every ``spec.every`` s); ``hooks``: ``on_cloud`` and ``on_memory``."""
    infos = {s.info_topic: s for s in sources.values() if s.info_topic is not None}
    topics: list[str] = [spec.joints, *sources, *infos]
    cloud_of = [b for _, b in pairs]
    ts: list[float] = []
    qs: list[F64] = []
    rows: list[F64] = []  # each frame's (P, 7) distance and closest points
    masks: list[NDArray[np.bool_]] = []  # the pairs whose cloud has arrived
    stamps: list[F64] = []
    versions: Mapping[str, int] | None = None
    fresh = np.zeros(len(cloud_of), dtype=bool)
    stamp_row = np.full(len(cloud_of), math.nan)
    memory = None
    if spec.memory is not None and spec.memory_box is not None:
        memory = SceneMemory(spec.memory_box[0], spec.memory_box[1], spec.memory)
    objects = sorted(set(cloud_of))
    seen: dict[str, set[int]] = {name: set() for name in objects}
    last = -math.inf
    pace = _Pace(spec.rate)
    rank = {topic: 0 for topic in infos} | {topic: 1 for topic in sources} | {spec.joints: 2}
    for m in _in_time_order(rec.messages(topics), rank):
        pace.wait(m.t)
        if m.topic in infos:
            infos[m.topic].set_info(m.msg)
        elif m.topic in sources:
            _take_cloud(sources[m.topic], m, memory, tree, spec, scene, hooks)
        else:
            q = matcher.positions(m.msg, topic=m.topic)
            t = _joint_time(m.msg, m.t)
            scene.set_joints(robot, q, stamp=t)
            if t - last < spec.every:
                continue
            last = t
            res = scene.query_all()
            if res.versions is not versions:  # a cloud was swapped in: new masks
                versions = res.versions
                fresh = np.array([versions.get(c, 0) > 0 for c in cloud_of])
                stamp_row = np.array([res.cloud_stamps.get(c, math.nan) if f else math.nan
                                      for c, f in zip(cloud_of, fresh, strict=True)])  # fmt: skip
                for c in objects:
                    v = versions.get(c, 0)
                    if v > 0:
                        seen[c].add(v)
            ts.append(t)
            qs.append(q)
            rows.append(res.rows[:, :7])  # a fresh, read-only array per query
            masks.append(fresh)
            stamps.append(stamp_row)
    F, P = len(ts), len(pairs)
    R = np.array(rows, dtype=np.float64).reshape(F, P, 7)
    fresh_all = np.array(masks, dtype=bool).reshape(F, P)
    return (
        np.array(ts, dtype=np.float64),
        np.array(qs, dtype=np.float64).reshape(F, len(matcher.names)),
        np.where(fresh_all, R[..., 0], np.nan),
        np.array(stamps, dtype=np.float64).reshape(F, P),
        np.where(fresh_all[..., None], R[..., 1:4], np.nan),
        np.where(fresh_all[..., None], R[..., 4:7], np.nan),
        {c: len(v) for c, v in seen.items()},
    )


def _take_cloud(
    src: CloudTopic,
    m: BagMessage,
    memory: SceneMemory | None,
    tree: TransformTree,
    spec: ReplaySpec,
    scene: Scene,
    hooks: tuple[CloudHook | None, MemoryHook | None],
) -> None:
    """A cloud topic's message into the scene: a depth image fused into the scene
    memory (which replaces the memory's cloud; ``on_memory`` is told) when there is
    one, else its points replace the topic's cloud; ``on_cloud`` is told either way."""
    src.count += 1
    on_cloud, on_memory = hooks
    if memory is not None and src.msgtype == IMAGE:
        voxels, stamp = src.fuse(memory, m.msg, m.t, tree, spec.frame)
        scene.replace_cloud(MEMORY, voxels, block=spec.block, stamp=stamp)
        if on_memory is not None:
            on_memory(stamp, memory)
        if on_cloud is not None:
            points = voxels.points if isinstance(voxels, PointCloud) else voxels
            on_cloud(MEMORY, stamp, points)
    else:
        cloud, stamp = src.points(m.msg, m.t, tree, spec.frame)
        scene.replace_cloud(m.topic, cloud, block=spec.block, stamp=stamp)
        if on_cloud is not None:
            on_cloud(m.topic, stamp, cloud.points if isinstance(cloud, PointCloud) else cloud)


def _in_time_order(messages: Iterable[BagMessage], rank: dict[str, int]) -> Iterator[BagMessage]:
    """``messages`` (in receive-time order) with those of one receive time ordered by
    the ``rank`` of their topic: camera infos, then clouds, then joint states, so a
    frame uses every cloud received at or before its time whatever order the storage
    kept ties in."""
    for _, group in groupby(messages, key=lambda m: m.t):
        yield from sorted(group, key=lambda m: rank[m.topic])


class _Pace:
    """Waits until the wall clock reaches a recording time at ``rate`` times the
    recording's speed (no waiting without a rate)."""

    def __init__(self, rate: float | None) -> None:
        self.rate = rate
        self.start: tuple[float, float] | None = None

    def wait(self, t: float) -> None:
        if self.rate is None:
            return
        now = time.perf_counter()
        if self.start is None:
            self.start = (t, now)
            return
        ahead = self.start[1] + (t - self.start[0]) / self.rate - now
        if ahead > 0.0:
            time.sleep(ahead)


def _joint_time(msg: Any, t: float) -> float:
    """A joint state's time: its header stamp, or the bag time when it has none."""
    try:
        return header_stamp(msg) or t
    except AttributeError:
        return t
