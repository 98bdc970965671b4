"""A simulated depth camera: a pinhole model that sees the scene's meshes as a cloud.

The robots our users drive see their cell through depth cameras (structured light,
stereo or time of flight) at about 30 frames/s and 640 × 480 pixels. The
model, in the camera frame of OpenCV and ROS optical frames (``z`` forward along the
optical axis, ``x`` right, ``y`` down in the image):

- Pixel ``(u, v)`` (column, row; centres at integer coordinates) looks along the ray
  ``((u − c_x)/f_x, (v − c_y)/f_y, 1)`` from the optical centre (:class:`Intrinsics`).
- Each ray returns its first hit on the meshes, so surfaces behind others are in
  shadow. The camera reports the hit's *depth* ``z`` (along the optical axis, not along
  the ray), as depth images do; a pixel whose depth lies outside
  ``[near, far]`` returns nothing.
- Depth noise is Gaussian with a standard deviation that grows with the square of the
  depth, ``σ(z) = noise · z²`` (``noise`` in 1/m: σ at 1 m, the usual model of
  structured-light and stereo sensors; 0 disables it), and a fraction ``dropout`` of
  the valid pixels, drawn at random, returns nothing (specular or dark surfaces).
- A returned pixel becomes the point ``z · ((u − c_x)/f_x, (v − c_y)/f_y, 1)`` in the
  camera frame; :meth:`DepthCamera.frame` maps it to world with the camera's pose.
- **Robot-body filter.** Meshes passed as ``body`` (the robot's own links) are rendered
  like any surface — they hide what lies behind them — but the pixels that see them
  first return nothing, as a real pipeline's robot self-filter removes the robot from
  its cloud, so the robot never avoids itself.

This module is pure math: meshes, a pose and a random Generator in, arrays out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.errors import InputError
from reachwise.geometry.checks import finite_number
from reachwise.geometry.raycast import Engine, first_hits

if TYPE_CHECKING:
    from collections.abc import Sequence

    from reachwise.geometry.raycast import MeshLike

__all__ = ["DepthCamera", "DepthFrame", "Intrinsics"]

_SRC = "depth camera"


def _pixels(value: object, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise InputError(_SRC, name, f"must be a positive whole number of pixels, got {value!r}")
    return int(value)


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics: image ``width`` × ``height`` (pixels), focal lengths ``fx``,
    ``fy`` and principal point ``cx``, ``cy`` (pixels)."""

    width: int = 640
    height: int = 480
    fx: float = 554.3
    fy: float = 554.3
    cx: float = 319.5
    cy: float = 239.5

    def __post_init__(self) -> None:
        object.__setattr__(self, "width", _pixels(self.width, "width"))
        object.__setattr__(self, "height", _pixels(self.height, "height"))
        for name in ("fx", "fy"):
            object.__setattr__(
                self, name, finite_number(getattr(self, name), _SRC, name, positive=True)
            )
        for name in ("cx", "cy"):
            object.__setattr__(self, name, finite_number(getattr(self, name), _SRC, name))

    @classmethod
    def from_fov(cls, width: int = 640, height: int = 480, fov: float = 1.0472) -> Intrinsics:
        """Square pixels, the principal point at the image centre and a horizontal field
        of view ``fov`` (rad; default 60°, which gives the default focal length)."""
        w = _pixels(width, "width")
        h = _pixels(height, "height")
        angle = finite_number(fov, _SRC, "fov", positive=True)
        if not angle < math.pi:
            raise InputError(_SRC, "fov", f"must be below π rad (180°), got {fov!r}")
        f = 0.5 * w / math.tan(0.5 * angle)
        return cls(w, h, f, f, 0.5 * (w - 1), 0.5 * (h - 1))

    def rays(self) -> NDArray[np.float64]:
        """``(height · width, 3)`` ray directions ``((u − cx)/fx, (v − cy)/fy, 1)`` in the
        camera frame, row by row (pixel ``(u, v)`` is row ``v · width + u``); their
        ``z`` is 1, so a hit at distance ``t`` along the unit ray has depth
        ``t / |ray|``."""
        u = (np.arange(self.width, dtype=np.float64) - self.cx) / self.fx
        v = (np.arange(self.height, dtype=np.float64) - self.cy) / self.fy
        out = np.empty((self.height, self.width, 3))
        out[:, :, 0] = u[None, :]
        out[:, :, 1] = v[:, None]
        out[:, :, 2] = 1.0
        return out.reshape(-1, 3)


@dataclass(frozen=True, eq=False)
class DepthFrame:
    """One frame: the ``depth`` image (``(height, width)``, metres along the optical
    axis, NaN where no return), the returned ``points`` in world (``(k, 3)``, row-major
    pixel order), the camera ``pose`` (4 × 4, camera → world) it was taken from and
    ``body``, the pixels that saw a ``body`` mesh first and were filtered out
    (``(height, width)`` bool), and ``body_depth``, those pixels' depth of the body
    (m, NaN elsewhere and outside ``[near, far]``; without noise or dropout): a
    self-filter knows how far the robot is, which frees the space in front of it."""

    depth: NDArray[np.float64]
    points: NDArray[np.float64]
    pose: NDArray[np.float64]
    body: NDArray[np.bool_] | None = None
    body_depth: NDArray[np.float64] | None = None


@dataclass(frozen=True, eq=False)
class DepthCamera:
    """A depth camera (see the module docstring): ``intrinsics``, range limits ``near``,
    ``far`` (m), depth ``noise`` (σ at 1 m; σ(z) = noise · z²) and pixel ``dropout``
    (a fraction in [0, 1))."""

    intrinsics: Intrinsics = field(default_factory=Intrinsics)
    near: float = 0.2
    far: float = 6.0
    noise: float = 0.0
    dropout: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.intrinsics, Intrinsics):
            raise InputError(_SRC, "intrinsics", "expected an Intrinsics")
        near = finite_number(self.near, _SRC, "near", nonneg=True)
        far = finite_number(self.far, _SRC, "far", positive=True)
        if not near < far:
            raise InputError(_SRC, "far", f"must exceed near ({near!r} m), got {far!r}")
        noise = finite_number(self.noise, _SRC, "noise", nonneg=True)
        dropout = finite_number(self.dropout, _SRC, "dropout", nonneg=True)
        if not dropout < 1.0:
            raise InputError(_SRC, "dropout", f"must be below 1, got {dropout!r}")
        object.__setattr__(self, "near", near)
        object.__setattr__(self, "far", far)
        object.__setattr__(self, "noise", noise)
        object.__setattr__(self, "dropout", dropout)

    @cached_property
    def _rays(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The pixel rays (:meth:`Intrinsics.rays`) and their lengths, computed once."""
        rays = self.intrinsics.rays()
        norm = np.linalg.norm(rays, axis=1)
        rays.setflags(write=False)
        norm.setflags(write=False)
        return rays, norm

    @property
    def shape(self) -> tuple[int, int]:
        """The depth image's shape, ``(height, width)``."""
        return (self.intrinsics.height, self.intrinsics.width)

    def depth(
        self,
        meshes: MeshLike | Sequence[MeshLike],
        pose: ArrayLike,
        rng: np.random.Generator | None = None,
        *,
        engine: Engine = "auto",
        body: Sequence[MeshLike] = (),
    ) -> NDArray[np.float64]:
        """The depth image (``(height, width)``, m, NaN where no return) of the world
        ``meshes`` seen from the camera at ``pose`` (4 × 4, camera → world); pixels that
        see a ``body`` mesh first return nothing (the robot-body filter). Noise and
        dropout need ``rng`` when they are on."""
        z, _, _ = self._render(meshes, body, _pose(pose), engine)
        return self.measure(z, rng)

    def _render(
        self,
        meshes: MeshLike | Sequence[MeshLike],
        body: Sequence[MeshLike],
        T: NDArray[np.float64],
        engine: Engine,
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.float64]]:
        """The true depth image (NaN: no surface, or a ``body`` pixel), the mask of
        the pixels that saw a ``body`` mesh first and their depth (NaN elsewhere)."""
        rays, norm = self._rays
        directions = rays @ T[:3, :3].T
        origins = np.broadcast_to(T[:3, 3], directions.shape)
        scene = _mesh_list(meshes)
        hit, t, which = first_hits([*scene, *body], origins, directions, engine=engine)
        on_body = which >= len(scene)
        seen = hit & ~on_body
        z = np.full(hit.shape, np.nan)
        z[seen] = t[seen] / norm[seen]
        zb = np.full(hit.shape, np.nan)
        zb[on_body] = t[on_body] / norm[on_body]
        with np.errstate(invalid="ignore"):
            zb[~((zb >= self.near) & (zb <= self.far))] = np.nan
        return z.reshape(self.shape), on_body.reshape(self.shape), zb.reshape(self.shape)

    def measure(
        self, depth: ArrayLike, rng: np.random.Generator | None = None
    ) -> NDArray[np.float64]:
        """What the sensor reports for the true ``depth`` image (NaN: no surface): range
        limits, then noise and dropout (random, from ``rng``)."""
        z = np.array(depth, dtype=np.float64, copy=True)
        if z.shape != self.shape:
            raise InputError(_SRC, "depth", f"expected shape {self.shape}, got {z.shape}")
        if (self.noise > 0.0 or self.dropout > 0.0) and rng is None:
            raise InputError(_SRC, "rng", "noise and dropout need a numpy random Generator")
        with np.errstate(invalid="ignore"):
            valid = (z >= self.near) & (z <= self.far)
        z[~valid] = np.nan
        if self.noise > 0.0 and rng is not None:
            zv = z[valid]
            z[valid] = zv + rng.normal(size=zv.shape) * self.noise * zv * zv
        if self.dropout > 0.0 and rng is not None:
            z[valid & (rng.random(z.shape) < self.dropout)] = np.nan
        return z

    def points(self, depth: ArrayLike, pose: ArrayLike | None = None) -> NDArray[np.float64]:
        """The returned pixels of a ``depth`` image as points, ``(k, 3)``, row-major pixel
        order: in the camera frame, or in world with ``pose`` (camera → world)."""
        z = np.asarray(depth, dtype=np.float64).reshape(-1)
        if z.shape[0] != self.shape[0] * self.shape[1]:
            raise InputError(_SRC, "depth", f"expected {self.shape} pixels, got {np.shape(depth)}")
        keep = np.isfinite(z)
        pts = self._rays[0][keep] * z[keep, None]
        if pose is None:
            return pts
        T = _pose(pose)
        return np.asarray(pts @ T[:3, :3].T + T[:3, 3])

    def frame(
        self,
        meshes: MeshLike | Sequence[MeshLike],
        pose: ArrayLike,
        rng: np.random.Generator | None = None,
        *,
        engine: Engine = "auto",
        body: Sequence[MeshLike] = (),
    ) -> DepthFrame:
        """One frame of the world ``meshes`` from ``pose``: depth image and world points,
        with the pixels that saw a ``body`` mesh filtered out (see :meth:`depth`)."""
        T = _pose(pose)
        true, on_body, body_z = self._render(meshes, body, T, engine)
        z = self.measure(true, rng)
        pts = self.points(z, T)
        for a in (z, pts, T, on_body, body_z):
            a.setflags(write=False)
        return DepthFrame(z, pts, T, on_body, body_z)

    def pixel_spacing(self, depth: float) -> float:
        """The diagonal distance (m) between the points of two diagonally neighbouring
        pixels on a surface facing the camera at ``depth`` (m, along the optical axis):
        ``depth · √(1/f_x² + 1/f_y²)``. Every point of such a surface lies within half
        of it from a returned point (without dropout); a surface seen at an angle
        ``θ`` is sampled ``1/cos θ`` more sparsely along its slope."""
        d = finite_number(depth, _SRC, "depth", positive=True)
        i = self.intrinsics
        return float(d * math.hypot(1.0 / i.fx, 1.0 / i.fy))


def _mesh_list(meshes: object) -> list[MeshLike]:
    """``meshes`` as a list (one mesh, a ``(vertices, faces)`` pair, or a sequence)."""
    import trimesh

    one = isinstance(meshes, trimesh.Trimesh) or (
        isinstance(meshes, tuple)
        and len(meshes) == 2
        and not isinstance(meshes[0], trimesh.Trimesh)
        and np.ndim(meshes[0]) == 2
    )
    return [meshes] if one else list(meshes)  # type: ignore[list-item, call-overload]


def _pose(pose: ArrayLike) -> NDArray[np.float64]:
    try:
        T = np.array(pose, dtype=np.float64, copy=True)
    except (TypeError, ValueError) as exc:
        raise InputError(_SRC, "pose", f"not a numeric 4x4 matrix: {exc}") from None
    if T.shape != (4, 4) or not np.isfinite(T).all():
        raise InputError(_SRC, "pose", f"expected a finite 4x4 matrix, got shape {T.shape}")
    R = T[:3, :3]
    if not np.allclose(R.T @ R, np.eye(3), atol=1e-6) or np.linalg.det(R) <= 0.0:
        raise InputError(_SRC, "pose", "its rotation part is not a proper rotation")
    if not np.array_equal(T[3], [0.0, 0.0, 0.0, 1.0]):
        raise InputError(_SRC, "pose", f"bottom row must be [0, 0, 0, 1], got {T[3].tolist()}")
    return T
