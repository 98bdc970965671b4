"""A scene memory: depth frames from several cameras fused into one voxel map, so that
what the cameras cannot see now is never taken for free space.

A depth camera sees surfaces, not volumes: a cloud that replaces the last one each frame
forgets what left the view and knows nothing of the body behind a surface (P-V's
occlusion gap, live). The memory keeps four states per voxel of a box-shaped grid:

- **unknown** — never observed; never free, never an obstacle of the distance query;
- **free** — some camera's ray passed through it (its centre lies in front of the depth
  measured at its pixel by more than the surface band); cleared at once, whatever it
  held before: a person who leaves is forgotten with the first frame that sees them gone;
- **occupied** — it holds an observed surface point (every returned pixel's point marks
  its voxel at the frame's time);
- **shadow** — at or behind an observed surface, up to ``shadow_depth`` beyond it: it
  counts as occupied until some camera sees it free (Flacco et al. 2014 and workcell
  monitoring practice treat the volume behind a depth pixel as possibly occupied).
  Occupied voxels not re-observed for ``memory_s`` fade to shadow, never to free.

Pixels without a return change nothing. Pixels that see the robot (a camera's
self-filter) only free the space in front of the robot, when their depth is given: the
space the robot hides from a camera keeps what that camera saw there before, and the
robot never enters its own map.

**The robot never collides with its own map.** A camera that saw a person in front of
the arm shadows the volume behind the person, the arm's own included, and the arm then
hides that volume from the camera: the shadow would sit on the arm for good. So the
voxels the robot's body occupies *now* are left out of the obstacles: those whose
centre lies within :attr:`~SceneMemory.inflation` of one of its convex pieces (the
``body`` of :meth:`~SceneMemory.obstacles`, at the current joint state), i.e. every
voxel the body reaches into. They cannot hold a person: the robot is there. Their state
does not change — they are not free (no camera saw through them), and once the robot
moves on they are obstacles again until a camera sees them free.

**The distance answer.** The occupied and shadow voxels enter the distance scene as
their centres; every observed point lies in an occupied voxel, within ``inflation`` =
half the voxel's diagonal of its centre, so a distance to the centres minus
``inflation`` is never larger than the distance to the observed points (watch the memory
with the margin plus :attr:`SceneMemory.inflation`). Against the true surface, add the
camera's sampling: neighbouring pixels' points lie :meth:`DepthCamera.pixel_spacing
<reachwise.geometry.depth_camera.DepthCamera.pixel_spacing>` apart.

**Defaults and why.** ``voxel`` 3 cm (the P-V downsampling); ``shadow_depth`` 0.5 m —
the safety practice above sets no limit, but an unlimited shadow fills the cell behind
every surface up to the far wall and freezes an arm working behind a table; a person's
body is 0.3–0.5 m deep, so 0.5 m covers the person a camera sees from one side;
``memory_s`` 3 s; ``free_hold_s`` 0.1 s — a voxel one camera saw free within the last
0.1 s is not shadowed again by another camera's view from the other side (three frames
at 30 Hz), so two cameras looking at one person from opposite sides do not make the
space between them flicker.

The update is the projective one of nvblox (each voxel projected into the depth image),
with bricks of 8³ voxels culled against the view frustum first; the kernels are in
:mod:`reachwise.distance._memory_kernel`. Times are passed in (seconds, any epoch):
nothing here reads a clock.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.distance._memory_collect import MORTON_AXIS_BITS, brick_order, collect_ordered
from reachwise.distance._memory_kernel import (
    BLOCK,
    BRICK,
    FREE,
    HELD_OBSTACLE,
    OCCUPIED,
    SHADOW,
    UNKNOWN,
    from_blocks,
    mark_points,
    prepare_frame,
    project_frame,
    tile_levels,
    to_blocks,
)
from reachwise.distance.index import INDICES, index_of_ordered
from reachwise.errors import InputError
from reachwise.geometry.body_pieces import near_pieces
from reachwise.geometry.cloud import PointCloud

__all__ = [
    "STATES",
    "MemoryConfig",
    "MemoryCounts",
    "MemorySnapshot",
    "SceneMemory",
    "ViewIntrinsics",
]

_SRC = "scene memory"
#: Most voxels one memory may hold (about 140 MB of state).
MAX_VOXELS = 8_000_000
#: The depth pixel types read as they come (:meth:`SceneMemory.integrate`).
_PIXEL_TYPES = (np.dtype(np.float64), np.dtype(np.float32), np.dtype(np.uint16))
#: The state codes of :attr:`SceneMemory.state`.
STATES = {
    "unknown": int(UNKNOWN),
    "free": int(FREE),
    "occupied": int(OCCUPIED),
    "shadow": int(SHADOW),
}


def _positive(value: object, name: str, *, zero: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating | np.integer):
        raise InputError(_SRC, name, f"must be a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v) or v < 0.0 or (v == 0.0 and not zero):
        raise InputError(_SRC, name, f"must be finite and {'≥' if zero else '>'} 0, got {value!r}")
    return v


@dataclass(frozen=True)
class MemoryConfig:
    """How the memory fuses frames (module docstring): ``voxel`` edge (m),
    ``shadow_depth`` behind each observed surface (m), ``memory_s`` before an occupied
    voxel not re-observed fades to shadow (s), ``free_hold_s`` during which a voxel seen
    free is not shadowed again (s), and the surface ``band`` (m; default: half the
    voxel's diagonal): a centre closer than that in front of the measured depth is not
    carved free."""

    voxel: float = 0.03
    shadow_depth: float = 0.5
    memory_s: float = 3.0
    free_hold_s: float = 0.1
    band: float | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "voxel", _positive(self.voxel, "voxel"))
        object.__setattr__(
            self, "shadow_depth", _positive(self.shadow_depth, "shadow_depth", zero=True)
        )
        object.__setattr__(self, "memory_s", _positive(self.memory_s, "memory_s", zero=True))
        object.__setattr__(
            self, "free_hold_s", _positive(self.free_hold_s, "free_hold_s", zero=True)
        )
        if self.band is not None:
            object.__setattr__(self, "band", _positive(self.band, "band", zero=True))

    @property
    def surface_band(self) -> float:
        """The band in front of a measured depth that is not carved free (m)."""
        return self.band if self.band is not None else 0.5 * math.sqrt(3.0) * self.voxel


class ViewIntrinsics(NamedTuple):
    """A depth image's pinhole model: focal lengths ``fx``, ``fy`` and principal point
    ``cx``, ``cy`` (pixels; pixel ``(u, v)`` looks along ``((u − cx)/fx, (v − cy)/fy,
    1)`` in the optical frame) and the valid depth range ``near``, ``far`` (m)."""

    fx: float
    fy: float
    cx: float
    cy: float
    near: float
    far: float


class PreparedFrame(NamedTuple):
    """A depth frame read once for the memory's update (:meth:`SceneMemory.prepare`):
    the ``code`` image and the ``tiles`` table of
    :func:`~reachwise.distance._memory_kernel.prepare_frame`, the ``camera`` row
    ``[fx, fy, cx, cy, near, far]``, the camera's pose both ways (4 × 4), the update's
    ``rules`` ``[band, shadow, t, hold, farthest return]`` and its time ``t`` (s)."""

    code: NDArray[np.float32]
    tiles: NDArray[np.float64]
    camera: NDArray[np.float64]
    world_to_camera: NDArray[np.float64]
    camera_to_world: NDArray[np.float64]
    rules: NDArray[np.float64]
    t: float


class MemoryCounts(NamedTuple):
    """How many voxels hold each state."""

    unknown: int
    free: int
    occupied: int
    shadow: int


class MemorySnapshot(NamedTuple):
    """A copy of a :class:`SceneMemory`'s state (:meth:`SceneMemory.snapshot`): every
    voxel's state, when it was last seen occupied and seen free (s), and the newest
    frame's capture time."""

    state: NDArray[np.uint8]
    seen_at: NDArray[np.float64]
    freed_at: NDArray[np.float64]
    stamp: float


class SceneMemory:
    """The voxel memory of the axis-aligned box ``lower`` … ``upper`` (m, world frame)
    under ``config``; :meth:`integrate` fuses one depth frame, :meth:`obstacles` gives
    the occupied and shadow voxels' centres for the distance scene (:meth:`obstacle_cloud`
    with their index). ``state`` and ``seen_at`` are the map per voxel: read them, do
    not write them (the kernels keep a summary per brick of ``BRICK``³ voxels beside
    them: which may hold an occupied or shadow voxel, which are all free);
    :attr:`freed_at` is a copy."""

    def __init__(self, lower: ArrayLike, upper: ArrayLike, config: MemoryConfig | None = None):
        self.config = config or MemoryConfig()
        lo = _vector(lower, "lower")
        hi = _vector(upper, "upper")
        if not np.all(hi > lo):
            raise InputError(_SRC, "upper", f"must exceed lower in x, y and z: {lo} … {hi}")
        vox = self.config.voxel
        shape = tuple(math.ceil((h - l) / vox - 1e-9) for l, h in zip(lo, hi, strict=True))
        if math.prod(shape) > MAX_VOXELS:
            raise InputError(
                _SRC, "voxel", f"{shape[0]} × {shape[1]} × {shape[2]} voxels exceed the "
                f"{MAX_VOXELS} a memory may hold: a larger voxel or a smaller box"
            )  # fmt: skip
        if max(shape) > 1 << MORTON_AXIS_BITS:
            raise InputError(
                _SRC, "voxel", f"{max(shape)} voxels along one side exceed the "
                f"{1 << MORTON_AXIS_BITS} a memory may hold: a larger voxel or a smaller box"
            )  # fmt: skip
        self.shape: tuple[int, int, int] = shape  # type: ignore[assignment]
        self.origin = lo
        self._grid = np.array([*lo, vox])
        self._grid.setflags(write=False)
        self.state = np.zeros(shape, dtype=np.uint8)
        self.seen_at = np.full(shape, -np.inf)
        bricks = tuple(-(-n // BRICK) for n in shape)
        # when a voxel was last seen free: the later of its own stamp and its block's
        # (a frame that frees a whole block of BLOCK**3 voxels stamps the block only);
        # the voxels' own stamps are kept block by block (to_blocks)
        blocks = tuple(-(-n // BLOCK) for n in shape)
        self._freed_voxel = np.full((*blocks, BLOCK**3), -np.inf)
        self._freed_block = np.full(blocks, -np.inf)
        # per brick of BRICK**3 voxels: HELD_NONE, HELD_OBSTACLE (may hold an occupied
        # or shadow voxel) or HELD_FREE (every voxel free)
        self._held = np.zeros(bricks, dtype=np.uint8)
        self._stamp = -math.inf
        self._order = brick_order(shape)
        for a in self._order:
            a.setflags(write=False)
        self._capacity = 1024  # rows of the next collection's arrays (grows as needed)

    @property
    def inflation(self) -> float:
        """Half a voxel's diagonal (m): how far an observed point may lie from the centre
        of its voxel. Subtract it from distances to :meth:`obstacles` (or add it to the
        margin) for an answer never larger than the distance to the observed points."""
        return 0.5 * math.sqrt(3.0) * self.config.voxel

    @property
    def freed_at(self) -> NDArray[np.float64]:
        """When each voxel was last seen free (s; -inf: never), a read-only copy: the
        later of the voxel's own stamp and that of its block of ``BLOCK``³ voxels (half
        a brick's edge), which a frame that frees the whole block stamps instead of its
        voxels."""
        stamps = np.maximum(self._freed_voxel, self._freed_block[..., None])
        out = from_blocks(stamps, self.shape)
        out.setflags(write=False)
        return out

    @property
    def stamp(self) -> float:
        """The capture time of the newest frame fused (s; -inf before the first)."""
        return self._stamp

    def integrate(
        self,
        depth: ArrayLike,
        pose: ArrayLike,
        intrinsics: ViewIntrinsics,
        t: float,
        body: ArrayLike | None = None,
        *,
        depth_scale: float = 1.0,
    ) -> None:
        """Fuse one ``depth`` image (``(height, width)``, along the optical axis in units
        of ``depth_scale`` m, NaN or 0 where there is no return) taken at time ``t`` (s)
        by a camera at ``pose`` (4 × 4, optical frame → world) with ``intrinsics``;
        ``body`` marks the pixels that saw the robot: their depth, when given, is the
        robot's, and frees only the space in front of it; they never mark anything
        occupied or shadow (the robot never enters its own map, and what it hides keeps
        what was seen before).

        The image is read in the sensor's own pixel type when it is float32 or float64
        metres (``32FC1``) or uint16 (``16UC1`` millimetres: ``depth_scale=0.001``),
        without a float64 copy; other types are converted to float64 first."""
        frame = self.prepare(depth, pose, intrinsics, t, body, depth_scale=depth_scale)
        self.project(frame)
        self.mark(frame)

    def prepare(
        self,
        depth: ArrayLike,
        pose: ArrayLike,
        intrinsics: ViewIntrinsics,
        t: float,
        body: ArrayLike | None = None,
        *,
        depth_scale: float = 1.0,
    ) -> PreparedFrame:
        """The first of :meth:`integrate`'s three passes (same arguments): the frame
        checked and read once into the form the other two take (:class:`PreparedFrame`).
        :meth:`integrate` is ``prepare``, :meth:`project`, :meth:`mark`; apart, they are
        timed one by one (``reachwise bench memory``)."""
        z = np.asarray(depth)
        z = np.ascontiguousarray(z if z.dtype in _PIXEL_TYPES else z.astype(np.float64))
        scale = _positive(depth_scale, "depth_scale")
        if z.ndim != 2 or z.size == 0:
            raise InputError(_SRC, "depth", f"expected a (height, width) image, got {z.shape}")
        near, far = float(intrinsics.near), float(intrinsics.far)
        mask = (
            np.zeros(z.shape, dtype=np.bool_)
            if body is None
            else np.ascontiguousarray(body, dtype=np.bool_)
        )
        if mask.shape != z.shape:
            raise InputError(_SRC, "body", f"expected shape {z.shape}, got {mask.shape}")
        T = _pose(pose)
        camera = np.array([float(v) for v in intrinsics], dtype=np.float64)
        if not (np.isfinite(camera).all() and camera[0] > 0 and camera[1] > 0 and 0 <= near < far):
            raise InputError(
                _SRC,
                "intrinsics",
                f"expected positive focal lengths and 0 ≤ near < far, got {intrinsics}",
            )
        tt = float(t)
        if not math.isfinite(tt):
            raise InputError(_SRC, "t", f"must be a finite time, got {t!r}")
        cw: NDArray[np.float64] = np.linalg.inv(T).astype(np.float64, copy=False)
        cfg = self.config
        H, W = z.shape
        code = np.empty((H, W), dtype=np.float32)
        tiles = np.empty((*tile_levels(H, W), 3))
        zv, mv = z.view(), mask.view()  # read-only views: the caller's arrays keep their flags
        zv.flags.writeable = False
        mv.flags.writeable = False
        dmax = prepare_frame(zv, scale, mv, near, far, code, tiles)
        rules = np.array([cfg.surface_band, cfg.shadow_depth, tt, cfg.free_hold_s, dmax])
        for a in (code, tiles, camera, cw, T, rules):
            a.setflags(write=False)
        return PreparedFrame(code, tiles, camera, cw, T, rules, tt)

    def project(self, frame: PreparedFrame) -> None:
        """The second pass of :meth:`integrate`: the frame's free and shadow marks."""
        project_frame(
            self.state,
            self._freed_voxel,
            self._freed_block,
            self._held,
            frame.code,
            frame.tiles,
            frame.camera,
            frame.world_to_camera,
            self._grid,
            frame.rules,
        )

    def mark(self, frame: PreparedFrame) -> None:
        """The third pass of :meth:`integrate`: the voxels of the frame's points marked
        occupied; the memory's :attr:`stamp` is the frame's from then on."""
        mark_points(
            self.state,
            self.seen_at,
            self._held,
            frame.code,
            frame.camera,
            frame.camera_to_world,
            self._grid,
            frame.t,
        )
        self._stamp = max(self._stamp, frame.t)

    def obstacles(
        self, t: float | None = None, *, body: Sequence[ArrayLike] = ()
    ) -> NDArray[np.float64]:
        """The centres (``(k, 3)``, m, world) of the occupied and shadow voxels at time
        ``t`` (default: the newest frame's), after occupied voxels older than
        ``memory_s`` faded to shadow, leaving out the voxels of the robot's ``body``
        (module docstring): each item is one convex piece of it now, its ``(m, 4)``
        world half-spaces ``n · x ≤ d`` (rows ``nx, ny, nz, d``, unit normals)."""
        return self._collect(t, body)[0]

    def obstacle_cloud(
        self, t: float | None = None, *, body: Sequence[ArrayLike] = (), name: str = ""
    ) -> PointCloud | None:
        """:meth:`obstacles` as a cloud whose distance index is built already and kept
        in :data:`~reachwise.distance.index.INDICES`: the centres come in the Morton
        order of their voxels, so the tree is built over that order without a sort
        (:func:`~reachwise.distance.index.index_of_ordered`), and a scene that takes
        the cloud (``Scene.replace_cloud``) swaps it in without building anything.
        None while there are no occupied or shadow voxels (a cloud has a point)."""
        pts, codes = self._collect(t, body)
        if len(pts) == 0:
            return None
        index = index_of_ordered(pts, codes, pts.mean(axis=0))
        # the cloud and its index share the points: a read-only view for the cloud
        cloud = PointCloud.of_checked(pts.view(), name=name)
        INDICES.put(cloud, index)
        return cloud

    def _collect(
        self, t: float | None, body: Sequence[ArrayLike]
    ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """The occupied and shadow voxels' centres at time ``t`` without the ``body``
        (:meth:`obstacles`), and their Morton codes, in increasing code."""
        tt = self._stamp if t is None else float(t)
        pieces = [_halfspaces(h, i) for i, h in enumerate(body)]
        bricks, voxels = self._order
        cap = self._capacity
        while True:
            out = np.empty((cap, 3))
            codes = np.empty(cap, dtype=np.int64)
            n = collect_ordered(
                self.state, self.seen_at, self._held, self._grid, tt, self.config.memory_s,
                bricks, voxels, out, codes,
            )  # fmt: skip
            if n <= cap:
                break
            cap = n  # the fading is done: the second pass only collects
        self._capacity = max(1024, n + n // 4)
        centres, codes = out[:n], codes[:n]
        if pieces and n:
            keep = ~self._in_body(centres, pieces)
            centres, codes = centres[keep], codes[keep]
        return centres, codes

    def _in_body(
        self, centres: NDArray[np.float64], pieces: list[NDArray[np.float64]]
    ) -> NDArray[np.bool_]:
        """Which ``centres`` lie within :attr:`inflation` of a convex piece
        (:func:`~reachwise.geometry.body_pieces.near_pieces`: a lower bound of the
        distance to the piece, so every voxel that the piece reaches into is among
        them)."""
        return near_pieces(centres, pieces, self.inflation)

    def counts(self) -> MemoryCounts:
        """How many voxels hold each state now."""
        c = np.bincount(self.state.reshape(-1), minlength=4)
        return MemoryCounts(int(c[UNKNOWN]), int(c[FREE]), int(c[OCCUPIED]), int(c[SHADOW]))

    def clear(self) -> None:
        """Forget everything: every voxel unknown, no frame fused."""
        self.state.fill(UNKNOWN)
        self.seen_at.fill(-np.inf)
        self._freed_voxel.fill(-np.inf)
        self._freed_block.fill(-np.inf)
        self._held.fill(0)
        self._stamp = -math.inf

    def snapshot(self) -> MemorySnapshot:
        """A copy of the memory now, for :meth:`restore` (a replay that seeks back)."""
        return MemorySnapshot(
            self.state.copy(), self.seen_at.copy(), self.freed_at.copy(), self._stamp
        )

    def restore(self, snapshot: MemorySnapshot) -> None:
        """Return to ``snapshot`` (taken from a memory of the same grid)."""
        if snapshot.state.shape != self.shape:
            raise InputError(
                _SRC, "snapshot", f"a {snapshot.state.shape} grid, this memory is {self.shape}"
            )
        np.copyto(self.state, snapshot.state)
        np.copyto(self.seen_at, snapshot.seen_at)
        np.copyto(self._freed_voxel, to_blocks(snapshot.freed_at))
        self._freed_block.fill(-np.inf)
        self._held.fill(HELD_OBSTACLE)  # any brick may hold an obstacle: the next collection sees
        self._stamp = snapshot.stamp

    def voxel_of(self, point: ArrayLike) -> tuple[int, int, int] | None:
        """The index of the voxel holding ``point`` (m, world), or None outside the grid."""
        p = _vector(point, "point")
        idx = np.floor((p - self.origin) / self.config.voxel).astype(np.int64)
        if np.any(idx < 0) or np.any(idx >= self.shape):
            return None
        return (int(idx[0]), int(idx[1]), int(idx[2]))

    def centre(self, index: tuple[int, int, int]) -> NDArray[np.float64]:
        """The centre (m, world) of the voxel ``index``."""
        return self.origin + (np.asarray(index, dtype=np.float64) + 0.5) * self.config.voxel


def _vector(value: ArrayLike, name: str) -> NDArray[np.float64]:
    try:
        v = np.array(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise InputError(_SRC, name, f"expected three numbers, got {value!r}") from None
    if v.shape != (3,) or not np.isfinite(v).all():
        raise InputError(_SRC, name, f"expected three finite numbers, got {value!r}")
    return v


def _halfspaces(value: ArrayLike, i: int) -> NDArray[np.float64]:
    try:
        h = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(_SRC, f"body[{i}]", "expected (m, 4) half-space rows") from None
    if h.ndim != 2 or h.shape[1] != 4 or len(h) < 4 or not np.isfinite(h).all():
        raise InputError(_SRC, f"body[{i}]", f"expected (m ≥ 4, 4) finite rows, got {h.shape}")
    if not np.allclose(np.linalg.norm(h[:, :3], axis=1), 1.0, atol=1e-6):
        raise InputError(_SRC, f"body[{i}]", "the normals n of its rows must be unit vectors")
    return h


def _pose(pose: ArrayLike) -> NDArray[np.float64]:
    try:
        T = np.array(pose, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(_SRC, "pose", "expected a numeric 4 × 4 matrix") from None
    if T.shape != (4, 4) or not np.isfinite(T).all():
        raise InputError(_SRC, "pose", f"expected a finite 4 × 4 matrix, got shape {T.shape}")
    R = T[:3, :3]
    if not np.allclose(R.T @ R, np.eye(3), atol=1e-6) or np.linalg.det(R) <= 0.0:
        raise InputError(_SRC, "pose", "its rotation part is not a proper rotation")
    return np.ascontiguousarray(T)
