"""The scene of ``reachwise bench realtime`` (:mod:`reachwise.benchmarks.realtime`): a
scanned room around the robot (floor, walls, ceiling, a table), panda-shelf's shelf, and
a depth camera whose frames see a person walk past (rays cast into boxes: exact, no
mesh)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "CAMERA_AT",
    "CAMERA_LOOKS_AT",
    "CAMERA_SIZE",
    "FRAMES",
    "ROOM",
    "ROOM_POINTS",
    "SHELF_PLATES",
    "TABLE",
    "camera_depth",
    "camera_frame",
    "camera_pose",
    "room_points",
]

#: Points of the scanned room.
ROOM_POINTS = 1_000_000
#: The depth camera's image (width, height) in pixels.
CAMERA_SIZE = (640, 480)
FRAMES = 12  # distinct camera frames, handed over in turn
ROOM = (np.array([-2.0, -2.5, 0.0]), np.array([3.0, 2.5, 2.8]))  # lo, hi corners (m)
TABLE = (np.array([-0.9, 0.5, 0.0]), np.array([-0.3, 1.3, 0.75]))  # a box on the floor
#: panda-shelf's shelf (meshes/shelf.obj at x = 0.45 m) as its seven 0.02 m plates: four
#: boards (bottoms at z = 0, 0.30, 0.62, 0.88 m), the back panel and two sides. Its
#: compartments stay open, so the scenario's goal inside the middle one stays reachable.
_SHELF_AT = np.array([0.45, 0.0, 0.0])
SHELF_PLATES = tuple(
    (np.array(lo) + _SHELF_AT, np.array(hi) + _SHELF_AT)
    for lo, hi in [
        *(([0.0, -0.4, z], [0.3, 0.4, z + 0.02]) for z in (0.0, 0.30, 0.62, 0.88)),
        ([0.28, -0.4, 0.0], [0.3, 0.4, 0.9]),
        ([0.0, -0.4, 0.0], [0.3, -0.38, 0.9]),
        ([0.0, 0.38, 0.0], [0.3, 0.4, 0.9]),
    ]
)
CAMERA_AT = np.array([2.2, -1.8, 1.9])
CAMERA_LOOKS_AT = np.array([0.3, 0.0, 0.5])


def _box_surface(lo: NDArray[np.float64], hi: NDArray[np.float64], n: int, rng: Any) -> Any:
    """``n`` points on the faces of box [lo, hi], area-weighted."""
    ext = hi - lo
    areas = np.array([ext[1] * ext[2], ext[0] * ext[2], ext[0] * ext[1]] * 2)
    face = rng.choice(6, size=n, p=areas / areas.sum())
    p = lo + rng.uniform(0.0, 1.0, size=(n, 3)) * ext
    for f in range(6):
        m = face == f
        axis = f % 3
        p[m, axis] = lo[axis] if f < 3 else hi[axis]
    return p


def room_points(n: int = ROOM_POINTS, seed: int = 3) -> NDArray[np.float64]:
    """A scanned room around the robot: floor (1 cm below the base), walls, ceiling and
    a table, ``n`` points with 2 mm noise."""
    rng = np.random.default_rng(seed)
    lo, hi = ROOM[0] - np.array([0.0, 0.0, 0.01]), ROOM[1]
    k = n // 10
    pts = np.vstack([_box_surface(lo, hi, n - k, rng), _box_surface(*TABLE, k, rng)])
    return np.asarray(pts + rng.normal(scale=0.002, size=pts.shape))


def _ray_box(o: Any, d: Any, lo: Any, hi: Any) -> Any:
    """Entry distance of rays ``o + t d`` into box [lo, hi] (inf where they miss)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (lo - o) / d
        t2 = (hi - o) / d
    tn = np.nanmax(np.minimum(t1, t2), axis=1)
    tf = np.nanmin(np.maximum(t1, t2), axis=1)
    hit = (tf >= tn) & (tf > 0)
    return np.where(hit, np.where(tn > 0, tn, np.inf), np.inf)


def _ray_room(o: Any, d: Any) -> Any:
    """Exit distance of rays from inside the room (the far wall, floor or ceiling)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(d > 0, (ROOM[1] - o) / d, (ROOM[0] - o) / d)
    t[~np.isfinite(t)] = np.inf
    return t.min(axis=1)


def camera_pose() -> tuple[NDArray[np.float64], float]:
    """The camera's optical frame (x right, y down, z forward) → world, and its focal
    length (pixels): 640×480 pixels, 60° wide, pixel ``(u, v)`` looking along
    ``(u − 319.5, v − 239.5, f)``."""
    fwd = CAMERA_LOOKS_AT - CAMERA_AT
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([right, -up, fwd])
    T[:3, 3] = CAMERA_AT
    return T, 0.5 * CAMERA_SIZE[0] / math.tan(math.radians(30.0))


def camera_depth(k: int, seed: int = 5) -> NDArray[np.float64]:
    """Frame ``k`` of :func:`camera_frame` as the camera's depth image (480 × 640, m
    along the optical axis of :func:`camera_pose`)."""
    T, _ = camera_pose()
    pts = camera_frame(k, seed).astype(np.float64)
    depth = (pts - CAMERA_AT) @ T[:3, 2]
    return depth.reshape(CAMERA_SIZE[1], CAMERA_SIZE[0])


def camera_frame(k: int, seed: int = 5) -> NDArray[np.float32]:
    """Depth frame ``k``: 640×480 pinhole rays (60° wide) from :data:`CAMERA_AT`, the
    first hit of each in the room, the table, the shelf's plates or a person (a 0.2 m
    radius, 1.75 m cylinder approximated by its bounding box) walking past, 4 mm noise;
    every ray hits (the room is closed): 307 200 points, float32 as a camera gives them."""
    w, h = CAMERA_SIZE
    T, f = camera_pose()
    right, up, fwd = T[:3, 0], -T[:3, 1], T[:3, 2]
    u, v = np.meshgrid(np.arange(w) - w / 2 + 0.5, np.arange(h) - h / 2 + 0.5)
    d = fwd * f + right * u.reshape(-1, 1) - up * v.reshape(-1, 1)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = np.broadcast_to(CAMERA_AT, d.shape)
    phase = 2.0 * math.pi * k / FRAMES
    person = np.array([1.2 + 0.3 * math.cos(phase), -0.9 + 0.6 * math.sin(phase), 0.0])
    body = (person - np.array([0.2, 0.2, 0.0]), person + np.array([0.2, 0.2, 1.75]))
    t = _ray_room(o, d)
    for lo, hi in (TABLE, *SHELF_PLATES, body):
        t = np.minimum(t, _ray_box(o, d, lo, hi))
    rng = np.random.default_rng([seed, k])
    pts = o + d * (t + rng.normal(scale=0.004, size=t.shape))[:, None]
    return pts.astype(np.float32)
