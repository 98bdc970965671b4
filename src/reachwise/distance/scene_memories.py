"""Scene memories as objects of a distance scene: depth frames fused where the scene
lives, in process and through the collision server alike.

:func:`add_memory` gives a :class:`~reachwise.distance.scene.Scene` a voxel memory
(:class:`~reachwise.distance.scene_memory.SceneMemory`) of a world box and an object of
the same name that pairs watch like any cloud. :func:`fuse_depth` fuses one depth frame
into it and hands the memory's occupied and shadow voxels' centres to that object, with
the hand-over rules of :meth:`Scene.replace_cloud
<reachwise.distance.scene.Scene.replace_cloud>`: the cloud comes with its distance
index built already (:meth:`SceneMemory.obstacle_cloud
<reachwise.distance.scene_memory.SceneMemory.obstacle_cloud>`), so the swap builds
nothing, and it is stamped with the newest frame's capture time, so the object's age is
the age of that frame and ``SafetyConfig.max_cloud_age`` applies to it as to a camera's
cloud. While the memory holds no obstacle, the object is one point far above its box
("nothing here": a cloud has a point). Before its first frame a memory has seen nothing,
so its object's time stamp is unknown (NaN): a controller with ``max_cloud_age`` treats
it as stale, as a camera's cloud of unknown time, until a frame is fused.

Every centre lies within :attr:`SceneMemory.inflation
<reachwise.distance.scene_memory.SceneMemory.inflation>` (half a voxel's diagonal) of
the points it stands for, so a pair watched against a memory keeps its margin plus the
memory's inflation (:func:`memory_margin`, the rule the simulation's memories follow
too); :func:`watch_memory` watches a pair so.

The scene's robots never enter a memory: :func:`fuse_depth` leaves the pixels that see
a robot's link clouds (bounded by their 26-DOP, :mod:`reachwise.geometry.body_pieces`,
as the simulation bounds its link meshes) out of the map and their voxels out of the
obstacles, at the joint state given with the frame or the scene's latest.

The functions are registered scene operations (:mod:`reachwise.distance.scene_ops`):
called with a ``reachwise.server.client.SceneClient`` they run on the collision
server's scene, the depth image travelling as a float64 array (NaN: no return). Adding
a memory and watching against it change the scene's rules (``scene_change``); a frame
only replaces the memory object's cloud, as a streamed cloud does, so the server neither
persists nor re-sends its layout per frame. A server's state directory does not keep a
memory's map: after a restart the memory is there with its setup and its watched pairs
(:func:`memory_setups`), every voxel unknown (never free) and its age unknown (stale
under ``max_cloud_age``) until frames come.
"""

from __future__ import annotations

import math
import threading
import weakref
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Annotated

import numpy as np
from numpy.typing import NDArray

from reachwise.distance.pairs import PairKind, WatchedPair
from reachwise.distance.scene import Scene
from reachwise.distance.scene_memory import MemoryConfig, SceneMemory, ViewIntrinsics
from reachwise.distance.scene_ops import (
    ArrayShape,
    scene_change,
    scene_operation,
    staged_operation,
)
from reachwise.distance.scene_types import OnLink
from reachwise.errors import InputError, NameTaken, UnknownName
from reachwise.geometry.body_pieces import (
    DOP26,
    body_pixels,
    dop_bounds,
    dop_offsets,
    place_halfspaces,
)
from reachwise.geometry.cloud import PointCloud

__all__ = [
    "DepthImage",
    "JointStates",
    "MemorySetup",
    "add_memory",
    "fuse_depth",
    "memories_of",
    "memory_cloud",
    "memory_inflation",
    "memory_margin",
    "memory_setups",
    "watch_memory",
]

#: A point or a box corner (m, world): three finite numbers.
Vec3 = Annotated[NDArray[np.float64], ArrayShape((3,))]
#: A 4 × 4 homogeneous transform (m), finite.
Pose = Annotated[NDArray[np.float64], ArrayShape((4, 4))]
#: A depth image, ``(height, width)``, m along the optical axis; NaN (or 0): no return.
DepthImage = Annotated[NDArray[np.float64], ArrayShape((None, None), finite=False)]
#: A depth image's pinhole model ``(fx, fy, cx, cy, near, far)``
#: (:class:`~reachwise.distance.scene_memory.ViewIntrinsics`).
Intrinsics = tuple[float, float, float, float, float, float]

#: Joint states by robot name (one value per joint), given with a frame.
JointStates = dict[str, Annotated[NDArray[np.float64], ArrayShape((None,))]]

#: How far above its box the point of an empty memory lies (m).
_EMPTY_LIFT = 1.0e3


@dataclass(frozen=True)
class _Piece:
    """A link object's 26-DOP offsets in its own frame, for the ``cloud`` it holds."""

    cloud: PointCloud
    offsets: NDArray[np.float64]


@dataclass(eq=False)
class _Held:
    """A scene's memory with its guards: ``fusing`` lets one frame at a time into it,
    ``swap`` orders the hand-overs; ``frames`` fused so far, the latest ``swapped`` in;
    the robots' link ``pieces`` by object name."""

    memory: SceneMemory
    lower: NDArray[np.float64]
    upper: NDArray[np.float64]
    fusing: threading.Lock = field(default_factory=threading.Lock)
    swap: threading.Lock = field(default_factory=threading.Lock)
    frames: int = 0
    swapped: int = 0
    pieces: dict[str, _Piece] = field(default_factory=dict)


# per scene: its generation when its memories were added, and the memories by name
_MEMORIES: weakref.WeakKeyDictionary[Scene, tuple[int, dict[str, _Held]]] = (
    weakref.WeakKeyDictionary()
)


def _memories(scene: Scene) -> dict[str, _Held]:
    """The memories of ``scene`` (kept in it): none after :meth:`Scene.clear`."""
    generation, held = _MEMORIES.get(scene, (-1, {}))
    if generation != scene.generation:
        held = {}
        _MEMORIES[scene] = (scene.generation, held)
    return held


def memories_of(scene: Scene) -> Mapping[str, SceneMemory]:
    """The memories of ``scene`` by name (read them; change them through
    :func:`fuse_depth`)."""
    return {name: held.memory for name, held in _memories(scene).items()}


@dataclass(frozen=True)
class MemorySetup:
    """What :func:`add_memory` was given for the memory ``name``: its world box
    ``lower`` … ``upper`` (m) and its ``config``; enough to add it again (its map
    starts unknown)."""

    name: str
    lower: NDArray[np.float64]
    upper: NDArray[np.float64]
    config: MemoryConfig


def memory_setups(scene: Scene) -> tuple[MemorySetup, ...]:
    """The setup of every memory of ``scene``, in the order they were added."""
    return tuple(
        MemorySetup(name, held.lower.copy(), held.upper.copy(), held.memory.config)
        for name, held in _memories(scene).items()
    )


def memory_margin(inflation: Mapping[str, float], a: str, b: str, margin: float) -> float:
    """The margin (m) of the pair ``a``, ``b`` watched with ``margin``: plus the
    ``inflation`` of each scene memory in it (objects not in ``inflation`` add
    nothing), so a distance to the memory's voxel centres within it is never larger
    than the distance to the observed points."""
    return margin + inflation.get(a, 0.0) + inflation.get(b, 0.0)


@scene_change
def add_memory(
    scene: Scene, name: str, lower: Vec3, upper: Vec3, config: MemoryConfig | None = None
) -> float:
    """Add a scene memory of the world box ``lower`` … ``upper`` (m) fusing frames
    under ``config`` (default :class:`~reachwise.distance.scene_memory.MemoryConfig`),
    and the object ``name`` that holds its obstacles; returns the memory's inflation
    (m), what pairs against it add to their margin; a name in use raises
    :class:`~reachwise.errors.NameTaken`. Until the first frame is fused the
    object's time stamp is unknown (NaN): the memory has seen nothing yet."""
    if name in scene.objects:
        raise NameTaken("scene", "name", f"object {name!r} already exists")
    memory = SceneMemory(lower, upper, config)
    scene.add_object(name, memory_cloud(memory, name=name), stamp=math.nan)
    box = (np.array(lower, dtype=np.float64), np.array(upper, dtype=np.float64))
    _memories(scene)[name] = _Held(memory, *box)
    return memory.inflation


@scene_operation
def memory_inflation(scene: Scene, name: str) -> float:
    """The inflation (m) of the memory ``name``: half its voxel's diagonal."""
    return _memory(scene, name).inflation


@scene_change
def watch_memory(
    scene: Scene, a: str, memory: str, margin: float, kind: PairKind = "robot-environment"
) -> WatchedPair:
    """Watch object ``a`` against the memory ``memory`` with ``margin`` (m) plus the
    memory's inflation (:func:`memory_margin`)."""
    m = _memory(scene, memory)
    return scene.watch(
        a, memory, memory_margin({memory: m.inflation}, a, memory, margin), kind=kind
    )


@dataclass(frozen=True)
class _Fused:
    """A fused frame's obstacles, ready to swap in: the memory's ``held`` record, the
    ``frame`` count they include, the ``cloud`` (index built) and its ``stamp`` (s)."""

    name: str
    held: _Held
    frame: int
    cloud: PointCloud
    stamp: float


def _swap_in(scene: Scene, fused: _Fused) -> int:
    """The hand-over of :func:`fuse_depth`: the fused cloud replaces the memory
    object's cloud, unless a cloud of a later frame is in already (two frames fused at
    once swap in their order); returns the cloud's version in use."""
    held = _held(scene, fused.name)
    if held is not fused.held:  # the memory was removed (and maybe added again)
        raise UnknownName("scene", "memory", fused.name, _memories(scene))
    with held.swap:
        if fused.frame <= held.swapped:
            return scene.versions[fused.name]
        held.swapped = fused.frame
        return scene.replace_cloud(fused.name, fused.cloud, block=True, stamp=fused.stamp)


@staged_operation(_swap_in)
def fuse_depth(
    scene: Scene,
    name: str,
    depth: DepthImage,
    pose: Pose,
    intrinsics: Intrinsics,
    t: float,
    body: DepthImage | None = None,
    q: JointStates | None = None,
) -> _Fused:
    """Fuse one ``depth`` image taken at time ``t`` (s) by a camera at ``pose`` (4 × 4,
    optical frame → world) with ``intrinsics`` into the memory ``name``
    (:meth:`SceneMemory.integrate
    <reachwise.distance.scene_memory.SceneMemory.integrate>`) and swap the memory's
    obstacles in as the object's cloud, stamped with the newest frame's time; returns
    the cloud's version.

    The robots of the scene never enter the map: each link object is bounded by the
    26-DOP of its cloud (:func:`~reachwise.geometry.body_pieces.cloud_piece`), placed
    at the robot's joint state ``q[robot]`` when given (the state at the frame's
    capture: exact), else at the scene's latest (:meth:`Scene.joint_state
    <reachwise.distance.scene.Scene.joint_state>`: the last tick's, as many
    milliseconds old as the frame); a robot with neither is not left out. The pixels
    within the memory's inflation of a piece are the robot's
    (:func:`~reachwise.geometry.body_pieces.body_pixels`, or the caller's ``body`` mask: nonzero
    where the pixel saw the robot): they only free the space in front of it, so what
    the robot hides keeps its state; and the voxels the pieces reach into are left out
    of the obstacles (:meth:`SceneMemory.obstacles
    <reachwise.distance.scene_memory.SceneMemory.obstacles>`).

    On the collision server the fusing runs without the scene lock (one frame at a
    time per memory), so queries are answered meanwhile; only the swap of the ready
    cloud holds it."""
    held = _held(scene, name)
    view = ViewIntrinsics(*_intrinsics(intrinsics))
    with held.fusing:
        memory = held.memory
        pieces, bounds = _robot_body(scene, held, q)
        mask = _self_filter(depth, pose, view, body, pieces, bounds, memory.inflation)
        memory.integrate(depth, pose, view, t, mask)
        cloud = memory_cloud(memory, body=pieces, name=name)
        held.frames += 1
        return _Fused(name, held, held.frames, cloud, memory.stamp)


def _robot_body(
    scene: Scene, held: _Held, q: JointStates | None
) -> tuple[list[NDArray[np.float64]], tuple[NDArray[np.float64], NDArray[np.float64]]]:
    """The placed 26-DOP (world half-space rows) of every link object of the scene's
    robots at their joint states (``q`` first, else the scene's latest), and a world
    box holding them all."""
    robots = scene.robots
    given = dict(q or {})
    for robot in given:
        if robot not in robots:
            raise UnknownName("scene memory", "q: robot", robot, robots)
    frames = {}
    for robot, model in robots.items():
        state = given.get(robot, scene.joint_state(robot))
        if state is not None:
            frames[robot] = np.asarray(model.fk_all(state), dtype=np.float64)
    pieces = []
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for obj in scene.objects.values():
        source = obj.source
        if not isinstance(source, OnLink) or source.robot not in frames:
            continue
        link = robots[source.robot].link_names.index(source.link)
        T = frames[source.robot][link] @ source.offset
        piece = held.pieces.get(obj.name)
        if piece is None or piece.cloud is not obj.cloud:
            piece = held.pieces[obj.name] = _Piece(obj.cloud, dop_offsets(obj.cloud.points))
        pieces.append(place_halfspaces(DOP26, piece.offsets, T))
        a, b = dop_bounds(piece.offsets, T)
        lo, hi = np.minimum(lo, a), np.maximum(hi, b)
    return pieces, (lo, hi)


def _self_filter(
    depth: object,
    pose: object,
    view: ViewIntrinsics,
    body: object,
    pieces: list[NDArray[np.float64]],
    bounds: tuple[NDArray[np.float64], NDArray[np.float64]],
    reach: float,
) -> NDArray[np.bool_] | None:
    """The robot's pixels of a frame: those that see a point within ``reach`` of one
    of the ``pieces``, and those nonzero in the caller's ``body``. A frame whose depth
    or pose is malformed gets the caller's mask as it is, for
    :meth:`SceneMemory.integrate
    <reachwise.distance.scene_memory.SceneMemory.integrate>` to name the bad field."""
    given = None if body is None else np.asarray(body) != 0
    z = np.asarray(depth, dtype=np.float64)
    T = np.asarray(pose, dtype=np.float64)
    if not pieces or z.ndim != 2 or T.shape != (4, 4) or not np.isfinite(T).all():
        return given
    own = body_pixels(z, (view.fx, view.fy, view.cx, view.cy), T, pieces, reach, bounds)
    if given is None:
        return own
    return own | given if given.shape == own.shape else given


def _held(scene: Scene, name: str) -> _Held:
    memories = _memories(scene)
    held = memories.get(name)
    if held is None:
        raise UnknownName("scene", "memory", name, memories)
    return held


def _memory(scene: Scene, name: str) -> SceneMemory:
    return _held(scene, name).memory


def _intrinsics(value: object) -> tuple[float, ...]:
    try:
        row = tuple(float(v) for v in value)  # type: ignore[attr-defined]
    except (TypeError, ValueError):
        raise InputError(
            "scene memory", "intrinsics", f"expected six numbers, got {value!r}"
        ) from None
    if len(row) != 6:
        raise InputError(
            "scene memory", "intrinsics", f"expected (fx, fy, cx, cy, near, far), got {value!r}"
        )
    return row


def memory_cloud(
    memory: SceneMemory, *, body: Sequence[NDArray[np.float64]] = (), name: str = ""
) -> PointCloud:
    """The cloud a scene holds for ``memory``: its occupied and shadow voxels' centres
    without the ``body`` pieces (:meth:`SceneMemory.obstacle_cloud
    <reachwise.distance.scene_memory.SceneMemory.obstacle_cloud>`, index built), or,
    while there are none, one point 1 km above the centre of its box: a cloud has a
    point, and this one says "nothing here" (beyond every margin)."""
    cloud = memory.obstacle_cloud(body=body, name=name)
    if cloud is not None:
        return cloud
    top = memory.origin + np.asarray(memory.shape) * memory.config.voxel
    centre = 0.5 * (memory.origin + top)
    return PointCloud((centre + np.array([0.0, 0.0, _EMPTY_LIFT]))[None], name=name)
