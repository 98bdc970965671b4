"""A robot's body as convex pieces: what a scene memory leaves out of a depth frame and
of its obstacles, so the robot never enters its own map.

Each piece bounds a part of a link by its 26-DOP: the half-spaces ``n · x ≤ d`` normal
to the 26 directions of the cube's faces, edges and corners, each pushed out to the
part's farthest point (:func:`dop_offsets`). It is a convex superset of the part, at
most a few millimetres wider than a round link. A link's collision mesh gives one piece
per connected component of its surface (:func:`body_pieces`, the simulation's link
surfaces); a link's cloud gives one piece around all its points
(:func:`cloud_piece`, the link clouds of a distance scene).

:func:`near_pieces` tells which points lie within a reach of a placed piece: their
largest signed distance to its planes is at most the reach. That distance is a lower
bound of the Euclidean distance to the piece, so every point within the reach of the
piece is among them (and some a little farther, near its edges).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from itertools import product
from typing import NamedTuple, Protocol

import numpy as np
from numba import njit
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from reachwise.errors import InputError

__all__ = [
    "DOP26",
    "BodyPiece",
    "LinkSurface",
    "body_pieces",
    "body_pixels",
    "cloud_piece",
    "dop_bounds",
    "dop_offsets",
    "near_pieces",
    "place_halfspaces",
]

F64 = NDArray[np.float64]


class LinkSurface(Protocol):
    """A robot link's collision surface as :func:`body_pieces` reads it: its ``mesh``
    ``(vertices, faces)`` in the frame ``index`` of robot ``robot``."""

    @property
    def robot(self) -> str: ...

    @property
    def index(self) -> int: ...

    @property
    def mesh(self) -> tuple[F64, NDArray[np.int64]]: ...


def _dop_directions() -> F64:
    """The 26 unit directions of a 26-DOP, the three axes' six first."""
    dirs = [np.array(v, dtype=np.float64) for v in product((-1, 0, 1), repeat=3) if any(v)]
    dirs.sort(key=lambda v: int(np.count_nonzero(v)))
    return np.array([v / np.linalg.norm(v) for v in dirs])


#: The 26 unit normals of a 26-DOP, ``(26, 3)``: the six of the axes first (a box), so
#: the first six planes of a piece rule most far points out.
DOP26 = _dop_directions()
DOP26.setflags(write=False)
#: The rows of :data:`DOP26` along +x, +y, +z and along −x, −y, −z.
_AXIS_UP = np.array([int(np.flatnonzero(np.all(DOP26 == e, axis=1))[0]) for e in np.eye(3)])
_AXIS_DOWN = np.array([int(np.flatnonzero(np.all(DOP26 == -e, axis=1))[0]) for e in np.eye(3)])


class BodyPiece(NamedTuple):
    """One convex piece around a part of a robot link: the half-spaces ``n · x ≤ d``
    (``normals`` ``(m, 3)``, ``offsets`` ``(m,)``) in the frame ``frame`` of robot
    ``robot``'s ``fk_all``."""

    robot: str
    frame: int
    normals: F64
    offsets: F64

    def placed(self, pose: F64) -> F64:
        """The half-spaces in the world (rows ``nx, ny, nz, d``) at the frame's ``pose``."""
        return place_halfspaces(self.normals, self.offsets, pose)


def place_halfspaces(normals: F64, offsets: F64, pose: F64) -> F64:
    """The half-spaces ``n · x ≤ d`` of a frame moved to the world by ``pose`` (4 × 4),
    as rows ``nx, ny, nz, d``."""
    n = normals @ pose[:3, :3].T
    return np.column_stack([n, offsets + n @ pose[:3, 3]])


def dop_offsets(points: F64) -> F64:
    """The 26-DOP offsets ``d`` (one per row of :data:`DOP26`) of ``points`` ``(k ≥ 1, 3)``."""
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0 or not np.isfinite(pts).all():
        raise InputError("body piece", "points", f"expected (k ≥ 1, 3) finite, got {pts.shape}")
    return np.asarray((pts @ DOP26.T).max(axis=0))


def cloud_piece(robot: str, frame: int, points: F64) -> BodyPiece:
    """The 26-DOP of a link cloud's ``points`` (in the frame ``frame`` of ``robot``)."""
    return BodyPiece(robot, frame, DOP26, dop_offsets(points))


def body_pieces(bodies: Iterable[LinkSurface]) -> tuple[BodyPiece, ...]:
    """The 26-DOP of each connected piece of each link surface in ``bodies``."""
    out = []
    for b in bodies:
        v, f = b.mesh
        if len(f) == 0:
            continue
        edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]]])
        graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), (len(v), len(v)))
        _, label = connected_components(graph, directed=False)
        used = np.unique(f)
        for c in np.unique(label[used]):
            pts = v[used[label[used] == c]]
            out.append(BodyPiece(b.robot, b.index, DOP26, dop_offsets(pts)))
    return tuple(out)


def near_pieces(points: F64, pieces: Sequence[F64], reach: float) -> NDArray[np.bool_]:
    """Which ``points`` ``(k, 3)`` lie within ``reach`` (m) of one of the placed
    ``pieces`` (each ``(m, 4)`` world half-space rows ``nx, ny, nz, d``, unit normals):
    their largest signed distance to the piece's planes is at most ``reach``. Compiled
    (GIL released): a point leaves a piece at its first plane farther than ``reach``,
    and the six axis planes of a 26-DOP come first."""
    pts = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    out = np.zeros(len(pts), dtype=np.bool_)
    if pieces and len(pts):
        planes, starts = _stacked(pieces)
        _near_kernel(pts, planes, starts, float(reach), out)
    return out


def _stacked(pieces: Sequence[F64]) -> tuple[F64, NDArray[np.int64]]:
    """The pieces' rows one under the other, and where each piece starts (and the end)."""
    planes = np.ascontiguousarray(np.concatenate([np.asarray(h) for h in pieces]), np.float64)
    starts = np.concatenate([[0], np.cumsum([len(h) for h in pieces])]).astype(np.int64)
    return planes, starts


@njit(cache=True, nogil=True)
def _within(
    x: float, y: float, z: float, planes: F64, starts: NDArray[np.int64], reach: float
) -> bool:
    """Whether ``(x, y, z)`` lies within ``reach`` of one of the stacked pieces."""
    for p in range(starts.shape[0] - 1):
        inside = True
        for r in range(starts[p], starts[p + 1]):
            gap = planes[r, 0] * x + planes[r, 1] * y + planes[r, 2] * z - planes[r, 3]
            if gap > reach:
                inside = False
                break
        if inside:
            return True
    return False


@njit(cache=True, nogil=True)
def _near_kernel(
    points: F64, planes: F64, starts: NDArray[np.int64], reach: float, out: NDArray[np.bool_]
) -> None:
    for i in range(points.shape[0]):
        out[i] = _within(points[i, 0], points[i, 1], points[i, 2], planes, starts, reach)


def dop_bounds(offsets: F64, pose: F64) -> tuple[F64, F64]:
    """An axis-aligned world box (``lo``, ``hi``) holding the 26-DOP with ``offsets``
    (:func:`dop_offsets`) placed at ``pose``: the box of its six axis planes, turned."""
    hi = offsets[_AXIS_UP]
    lo = -offsets[_AXIS_DOWN]
    centre = pose[:3, :3] @ (0.5 * (lo + hi)) + pose[:3, 3]
    half = np.abs(pose[:3, :3]) @ (0.5 * (hi - lo))
    return centre - half, centre + half


def body_pixels(
    depth: F64,
    focal: tuple[float, float, float, float],
    pose: F64,
    pieces: Sequence[F64],
    reach: float,
    bounds: tuple[F64, F64],
) -> NDArray[np.bool_]:
    """Which pixels of a ``depth`` image (``(height, width)``, m along the optical axis;
    NaN or 0: no return) see a point within ``reach`` (m) of one of the placed
    ``pieces`` (:func:`near_pieces`): the image's self-filter for a body placed in the
    world. ``focal`` is the pinhole model ``(fx, fy, cx, cy)`` (pixel ``(u, v)`` looks
    along ``((u − cx)/fx, (v − cy)/fy, 1)``), ``pose`` the camera's (4 × 4, optical
    frame → world); ``bounds`` (``lo``, ``hi``, e.g. from :func:`dop_bounds`) a world
    box holding every piece: only the points within ``reach`` of it are tested plane
    by plane."""
    z = np.ascontiguousarray(depth, dtype=np.float64)
    out = np.zeros(z.shape, dtype=np.bool_)
    if not pieces or z.ndim != 2 or z.size == 0:
        return out
    planes, starts = _stacked(pieces)
    lo, hi = bounds
    box = np.concatenate([np.asarray(lo, np.float64) - reach, np.asarray(hi, np.float64) + reach])
    T = np.ascontiguousarray(pose, dtype=np.float64)
    camera = np.array([float(v) for v in focal], dtype=np.float64)
    _pixel_kernel(z, camera, T, box, planes, starts, float(reach), out)
    return out


@njit(cache=True, nogil=True)
def _pixel_kernel(
    depth: F64,
    camera: F64,
    pose: F64,
    box: F64,
    planes: F64,
    starts: NDArray[np.int64],
    reach: float,
    out: NDArray[np.bool_],
) -> None:
    """:func:`body_pixels` pixel by pixel: back-project, the box test, the pieces."""
    fx, fy, cx, cy = camera[0], camera[1], camera[2], camera[3]
    for v in range(depth.shape[0]):
        for u in range(depth.shape[1]):
            zc = depth[v, u]
            if not zc > 0.0:  # NaN too
                continue
            xc = (u - cx) / fx * zc
            yc = (v - cy) / fy * zc
            x = pose[0, 0] * xc + pose[0, 1] * yc + pose[0, 2] * zc + pose[0, 3]
            y = pose[1, 0] * xc + pose[1, 1] * yc + pose[1, 2] * zc + pose[1, 3]
            z = pose[2, 0] * xc + pose[2, 1] * yc + pose[2, 2] * zc + pose[2, 3]
            if x < box[0] or y < box[1] or z < box[2] or x > box[3] or y > box[4] or z > box[5]:
                continue
            out[v, u] = _within(x, y, z, planes, starts, reach)
