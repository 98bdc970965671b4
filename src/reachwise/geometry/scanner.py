"""A simulated nodding 2-D laser scanner, after the obstacle-detection rig of P-V §IV.

P-V §IV: a SICK LMS511 2-D laser scanner, "mounted in an upright position", was turned
about one horizontal axis by a DC motor with an absolute encoder. Its angular
resolution of 0.25° set the horizontal resolution of the cloud; it sent a scan line at
25 Hz while turning at about 5°/s, which gave a vertical resolution of 0.2°. Range and
angles gave Cartesian points; points outside the working area were removed and the
cloud was downsampled to 3 cm, leaving about 5500 points of a floor and an obstacle,
with a small area behind the obstacle that the scanner could not see (P-V Fig. 3).

The model (scanner frame: x forward, y left, z up, at zero tilt):

- Every beam starts at the optical centre, placed on the tilt axis (the scanner's y
  axis through the frame origin); the real rig's small lever arm is neglected.
- A scan line is a fan of beams in the scanner's x-y plane, at azimuths
  ``a = a_min, a_min + res, ...`` up to ``a_max`` (``res`` = 0.25°).
- The fan is tilted about the y axis by ``phi``; positive ``phi`` looks down. Beam
  direction in the scanner frame: ``Ry(phi) (cos a, sin a, 0) =
  (cos phi cos a, sin a, -sin phi cos a)``.
- Line ``k`` starts at ``t_k = k / f`` (``f`` = 25 Hz). We assume the mirror turns
  once per line (as the LMS511's does at its listed scan frequencies), so the beam
  at azimuth ``a`` fires at ``t = t_k + (a - a_min) / (2 pi f)`` and the tilt keeps
  turning meanwhile: ``phi(t) = phi_start + omega t`` (``omega`` = 5°/s).
  Lines are taken until the line-start tilt passes ``phi_end``.
- Each beam returns its first hit (so surfaces behind others are in shadow), unless
  that hit is nearer than ``min_range`` or farther than ``max_range`` (no return).
  Optional Gaussian range noise (standard deviation ``range_noise``) is added along
  the beam.

Ray casting uses trimesh: Embree when it is installed, the pure-Python
``ray_triangle`` backend (numpy + rtree) otherwise (or on request). Either backend only picks the
triangle; the hit distance is then recomputed in float64 from that triangle's plane,
so both give the same points to rounding.

**Occlusion-aware clouds** (beyond P-V; P-V Fig. 5: the missing points behind the
obstacle made the return path wrong). A beam that hits a surface observes the free
space in front of the hit, nothing behind it: everything farther along the beam is
unknown. :func:`shadow_points` fills that unknown space with *virtual* points: each
return ``h = o + r d`` is extended along its own beam to ``o + (r + s) d`` for
``s = spacing, 2 spacing, … ≤ depth``, stopping at the ground (nothing enters the
ground) — so the occluded space up to ``depth`` behind every observed surface counts
as occupied. ``depth`` is the thickness the caller is willing to assume for unseen
objects (a longer depth is more conservative). The virtual points never lie in front
of any surface a beam observed: each lies on its own beam, behind its own hit.
:class:`OcclusionFill` holds the settings; :func:`scan_scene` and
:meth:`ScanScene.process` take one.

This module is pure math: meshes and a random Generator in, arrays out.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Literal, get_args

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.errors import CloudError, InputError, MissingDependency, UnknownName
from reachwise.geometry.cloud import (
    DEFAULT_VOXEL,
    PointCloud,
    crop,
    crop_mask,
    voxel_downsample,
    voxel_keys,
)

if TYPE_CHECKING:
    from typing import TypeAlias

    import trimesh

    #: A mesh: a ``trimesh.Trimesh`` or a ``(vertices (V, 3), faces (F, 3))`` pair.
    MeshLike: TypeAlias = trimesh.Trimesh | tuple[ArrayLike, ArrayLike]

__all__ = [
    "SCENES",
    "LaserScanner",
    "OcclusionFill",
    "Scan",
    "ScanScene",
    "cast_rays",
    "get_scene",
    "p5_floor_obstacle",
    "p5_occlusion",
    "scan_scene",
    "shadow_points",
]

Engine = Literal["auto", "embree", "triangle"]

_SRC = "scanner"


def _finite(
    value: object, field_name: str, *, positive: bool = False, nonneg: bool = False
) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InputError(_SRC, field_name, f"expected a number, got {value!r}")
    out = float(value)
    if not math.isfinite(out):
        raise InputError(_SRC, field_name, f"must be finite, got {out!r}")
    if positive and out <= 0.0:
        raise InputError(_SRC, field_name, f"must be > 0, got {out!r}")
    if nonneg and out < 0.0:
        raise InputError(_SRC, field_name, f"must be >= 0, got {out!r}")
    return out


def _interval(value: object, field_name: str) -> tuple[float, float]:
    if not isinstance(value, Sequence | np.ndarray) or len(value) != 2:
        raise InputError(_SRC, field_name, f"expected (min, max), got {value!r}")
    out = (_finite(value[0], field_name), _finite(value[1], field_name))
    if out[0] > out[1]:
        raise InputError(_SRC, field_name, f"min {out[0]!r} exceeds max {out[1]!r}")
    return out


@dataclass(frozen=True, eq=False)
class LaserScanner:
    """A 2-D line scanner nodding about its horizontal y axis (P-V §IV defaults).

    Angles in radians, rates in Hz and rad/s, lengths in metres. ``pose`` is the 4x4
    world pose of the scanner frame at zero tilt; its origin is the optical centre on
    the tilt axis. ``azimuth_range`` bounds the beams kept from each line (the LMS511
    sees 190°, but only the working area matters); ``tilt_range`` is the tilt at the
    start of the first and (at most) of the last line. Defaults: 0.25° beam spacing,
    25 Hz lines, 5°/s tilt rate (0.2° between lines), 80 m maximum range (the LMS511's
    nominal reach), no range noise.
    """

    pose: NDArray[np.float64] = field(default_factory=lambda: np.eye(4))
    angular_resolution: float = math.radians(0.25)
    scan_rate: float = 25.0
    tilt_rate: float = math.radians(5.0)
    azimuth_range: tuple[float, float] = (math.radians(-45.0), math.radians(45.0))
    tilt_range: tuple[float, float] = (math.radians(10.0), math.radians(60.0))
    min_range: float = 0.0
    max_range: float = 80.0
    range_noise: float = 0.0

    def __post_init__(self) -> None:
        try:
            pose = np.array(self.pose, dtype=np.float64, copy=True)
        except (TypeError, ValueError) as exc:
            raise InputError(_SRC, "pose", f"not numeric: {exc}") from None
        if pose.shape != (4, 4) or not np.isfinite(pose).all():
            raise InputError(_SRC, "pose", f"expected a finite 4x4 matrix, got shape {pose.shape}")
        R = pose[:3, :3]
        if (
            not np.allclose(R @ R.T, np.eye(3), atol=1e-9)
            or not np.linalg.det(R) > 0
            or not np.allclose(pose[3], [0, 0, 0, 1])
        ):
            raise InputError(_SRC, "pose", "not a rigid transform (rotation part not orthonormal)")
        pose.setflags(write=False)
        object.__setattr__(self, "pose", pose)
        res = _finite(self.angular_resolution, "angular_resolution", positive=True)
        _finite(self.scan_rate, "scan_rate", positive=True)
        _finite(self.tilt_rate, "tilt_rate", positive=True)
        az = _interval(self.azimuth_range, "azimuth_range")
        if az[1] - az[0] >= 2 * math.pi:
            raise InputError(_SRC, "azimuth_range", "must span less than 360°")
        object.__setattr__(self, "azimuth_range", az)
        object.__setattr__(self, "tilt_range", _interval(self.tilt_range, "tilt_range"))
        lo = _finite(self.min_range, "min_range", nonneg=True)
        hi = _finite(self.max_range, "max_range", positive=True)
        if lo >= hi:
            raise InputError(_SRC, "min_range", f"must be below max_range {hi!r}, got {lo!r}")
        _finite(self.range_noise, "range_noise", nonneg=True)
        if self.n_rays > 20_000_000:
            raise InputError(
                _SRC, "angular_resolution", f"{self.n_rays} rays per scan is too many ({res!r})"
            )

    # ------------------------------------------------------------------ geometry

    @property
    def origin(self) -> NDArray[np.float64]:
        """World position of the optical centre (every beam starts here), shape (3,)."""
        return np.array(self.pose[:3, 3])

    @property
    def line_spacing(self) -> float:
        """Tilt between consecutive lines, ``tilt_rate / scan_rate`` (0.2° in P-V)."""
        return self.tilt_rate / self.scan_rate

    @property
    def n_beams(self) -> int:
        """Beams per scan line."""
        lo, hi = self.azimuth_range
        return math.floor((hi - lo) / self.angular_resolution + 1e-9) + 1

    @property
    def n_lines(self) -> int:
        """Scan lines in one sweep of ``tilt_range``."""
        lo, hi = self.tilt_range
        return math.floor((hi - lo) / self.line_spacing + 1e-9) + 1

    @property
    def n_rays(self) -> int:
        """Beams fired in one sweep."""
        return self.n_beams * self.n_lines

    @property
    def duration(self) -> float:
        """Seconds from the first beam of the sweep to the start of its last line."""
        return (self.n_lines - 1) / self.scan_rate

    def coarsened(self, factor: float) -> LaserScanner:
        """The same scanner with ``factor`` times coarser beam and line spacing.

        For quick previews and tests: the angular resolution and the tilt rate are
        multiplied by ``factor`` (so about ``factor**2`` fewer rays).
        """
        f = _finite(factor, "factor", positive=True)
        return replace(
            self, angular_resolution=self.angular_resolution * f, tilt_rate=self.tilt_rate * f
        )

    def beams(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Firing time (s), tilt and azimuth (rad) of every beam, each shape (n_rays,).

        Ordered line by line, each line by increasing azimuth.
        """
        a0 = self.azimuth_range[0]
        az = a0 + self.angular_resolution * np.arange(self.n_beams)
        t_line = np.arange(self.n_lines) / self.scan_rate
        t = t_line[:, None] + ((az - a0) / (2.0 * math.pi * self.scan_rate))[None, :]
        tilt = self.tilt_range[0] + self.tilt_rate * t
        return t.reshape(-1), tilt.reshape(-1), np.broadcast_to(az, t.shape).reshape(-1)

    def directions(
        self, tilt: ArrayLike | None = None, azimuth: ArrayLike | None = None
    ) -> NDArray[np.float64]:
        """Unit beam directions in the world frame, shape (M, 3).

        Without arguments: every beam of the sweep (see :meth:`beams`).
        """
        if tilt is None or azimuth is None:
            _, tilt, azimuth = self.beams()
        phi = np.asarray(tilt, dtype=np.float64).reshape(-1)
        a = np.asarray(azimuth, dtype=np.float64).reshape(-1)
        local = np.stack([np.cos(phi) * np.cos(a), np.sin(a), -np.sin(phi) * np.cos(a)], axis=1)
        d = local @ self.pose[:3, :3].T
        out: NDArray[np.float64] = d / np.linalg.norm(d, axis=1, keepdims=True)
        return out

    # ---------------------------------------------------------------------- scan

    def scan(
        self,
        meshes: MeshLike | Sequence[MeshLike],
        rng: np.random.Generator | int | None = None,
        *,
        engine: Engine = "auto",
        name: str = "scan",
    ) -> Scan:
        """Sweep once over ``meshes`` (world frame) and return the measured points.

        ``meshes``: a ``trimesh.Trimesh``, a ``(vertices, faces)`` pair, or a list of
        either; they are cast against as one scene (the first hit of each beam counts).

        ``rng`` (a Generator or a seed) drives the range noise; it is required when
        ``range_noise > 0`` so that a noisy scan is always reproducible.
        """
        generator: np.random.Generator | None
        if rng is None:
            generator = None
        elif isinstance(rng, np.random.Generator):
            generator = rng
        elif isinstance(rng, numbers.Integral) and not isinstance(rng, bool):
            generator = np.random.default_rng(int(rng))
        else:
            raise InputError(_SRC, "rng", f"expected a numpy Generator or an int seed, got {rng!r}")
        if self.range_noise > 0 and generator is None:
            raise InputError(_SRC, "rng", "range_noise > 0 needs a Generator or a seed")
        t, tilt, az = self.beams()
        d = self.directions(tilt, az)
        o = np.broadcast_to(self.origin, d.shape)
        hit, true_range = cast_rays(meshes, o, d, engine=engine)
        ok = hit & (true_range >= self.min_range) & (true_range <= self.max_range)
        if not ok.any():
            raise CloudError(name, "points", f"none of {len(d)} beams hit a surface in range")
        r = true_range[ok]
        if generator is not None and self.range_noise > 0:
            r = r + generator.normal(0.0, self.range_noise, size=r.shape)
        pts = self.origin + r[:, None] * d[ok]
        return Scan(
            cloud=PointCloud(pts, frame="world", name=name),
            origin=self.origin,
            ranges=r,
            directions=d[ok],
            times=t[ok],
            tilt=tilt[ok],
            azimuth=az[ok],
            n_rays=len(d),
        )


@dataclass(frozen=True, eq=False)
class Scan:
    """One sweep: the points (world frame) and, per point, its beam's data.

    ``ranges`` are the measured ranges (noise included), ``directions`` the unit beam
    directions, ``times`` the firing times from the start of the sweep, ``tilt`` and
    ``azimuth`` the beam angles. ``n_rays`` counts every beam fired, returns or not.
    """

    cloud: PointCloud
    origin: NDArray[np.float64]
    ranges: NDArray[np.float64]
    directions: NDArray[np.float64]
    times: NDArray[np.float64]
    tilt: NDArray[np.float64]
    azimuth: NDArray[np.float64]
    n_rays: int

    @property
    def points(self) -> NDArray[np.float64]:
        """The measured points, world frame, shape (M, 3)."""
        return self.cloud.points

    def shadow(
        self, depth: float, spacing: float = DEFAULT_VOXEL, ground: float | None = None
    ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """Virtual points filling the space behind every return (see
        :func:`shadow_points`): ``(points (V, 3), index of the return (V,))``."""
        return shadow_points(self.origin, self.points, depth, spacing, ground)


def shadow_points(
    origin: ArrayLike,
    hits: ArrayLike,
    depth: float,
    spacing: float = DEFAULT_VOXEL,
    ground: float | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Virtual points in the occluded space behind each hit, seen from ``origin``.

    Each hit ``h`` (range ``r = |h − o| > 0``, beam direction ``d = (h − o)/r``) gets
    the points ``h + s d`` for ``s = spacing, 2 spacing, …`` up to ``depth``: the beam
    observed the space in front of ``h`` to be free and nothing behind it, so the
    unknown space up to ``depth`` behind the surface is taken as occupied. With
    ``ground`` (world z, m), a point below it is dropped, and so is the rest of its
    beam (the ground is solid; nothing needs to be avoided under it); ``-inf`` or
    ``None`` keeps them all. Hits at the origin (no direction) give no point.

    Returns ``(points (V, 3), ray (V,))``: ``ray[k]`` is the index of the hit that
    point ``k`` extends. Every point lies on its hit's beam, farther than the hit.
    """
    o = np.asarray(origin, dtype=np.float64).reshape(-1)
    h = np.asarray(hits, dtype=np.float64)
    if o.shape != (3,) or not np.isfinite(o).all():
        raise InputError(_SRC, "origin", "expected 3 finite coordinates")
    if h.ndim != 2 or h.shape[1] != 3 or not np.isfinite(h).all():
        raise InputError(_SRC, "hits", f"expected finite (N, 3) points, got shape {h.shape}")
    D = _finite(depth, "depth", positive=True)
    step = _finite(spacing, "spacing", positive=True)
    if D / step > 10_000:
        raise InputError(_SRC, "spacing", f"depth/spacing = {D / step:.0f} samples per beam")
    v = h - o
    r = np.linalg.norm(v, axis=1)
    ok = r > 0.0
    d = np.zeros_like(v)
    d[ok] = v[ok] / r[ok, None]
    s_max = np.where(ok, D, 0.0)
    if ground is not None and ground != -math.inf:
        g = _finite(ground, "ground")
        down = d[:, 2] < 0.0
        with np.errstate(divide="ignore", invalid="ignore"):
            to_ground = np.where(down, (h[:, 2] - g) / -d[:, 2], np.inf)
        s_max = np.where(h[:, 2] >= g, np.minimum(s_max, to_ground), 0.0)
    count = np.floor(s_max / step + 1e-9).astype(np.int64)
    count = np.maximum(count, 0)
    ray = np.repeat(np.arange(len(h), dtype=np.int64), count)
    if ray.size == 0:
        return np.zeros((0, 3)), ray
    first = np.cumsum(count) - count
    k = np.arange(ray.size, dtype=np.int64) - np.repeat(first, count) + 1
    pts = h[ray] + (k * step)[:, None] * d[ray]
    return pts, ray


@dataclass(frozen=True)
class OcclusionFill:
    """Settings of the occlusion fill (:func:`shadow_points`): ``depth`` (m) behind
    each return; ``spacing`` (m) between virtual points along a beam (``None``: the
    scene's voxel, so the fill is as dense as the cloud); ``ground`` (world z, m)
    below which no virtual point is kept (``None``: the scene's ground, if any)."""

    depth: float = 1.0
    spacing: float | None = None
    ground: float | None = None

    def __post_init__(self) -> None:
        _finite(self.depth, "occlusion depth", positive=True)
        if self.spacing is not None:
            _finite(self.spacing, "occlusion spacing", positive=True)
        if self.ground is not None and self.ground != -math.inf:
            _finite(self.ground, "occlusion ground")


def _as_meshes(meshes: object) -> list[tuple[NDArray[np.float64], NDArray[np.int64]]]:
    """Validated ``(vertices, faces)`` of each mesh: Trimesh objects or array pairs."""
    import trimesh

    single = isinstance(meshes, trimesh.Trimesh) or (
        isinstance(meshes, tuple)
        and len(meshes) == 2
        and not isinstance(meshes[0], trimesh.Trimesh)
        and np.ndim(meshes[0]) == 2
    )
    items = [meshes] if single else meshes
    if not isinstance(items, Sequence) or isinstance(items, str) or len(items) == 0:
        raise InputError(
            _SRC, "meshes", "expected a trimesh.Trimesh, a (vertices, faces) pair, or a list"
        )
    out = []
    for i, m in enumerate(items):
        where = f"meshes[{i}]"
        if isinstance(m, trimesh.Trimesh):
            v_in, f_in = m.vertices, m.faces
        elif isinstance(m, tuple | list) and len(m) == 2:
            v_in, f_in = m
        else:
            raise InputError(
                _SRC, where, f"expected a Trimesh or (vertices, faces), got {type(m).__name__}"
            )
        try:
            v = np.asarray(v_in, dtype=np.float64)
            f = np.asarray(f_in)
        except (TypeError, ValueError) as exc:
            raise InputError(_SRC, where, f"not numeric: {exc}") from None
        if v.ndim != 2 or v.shape[1] != 3 or not np.isfinite(v).all():
            raise InputError(_SRC, where, f"vertices must be finite (V, 3), got {v.shape}")
        if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0 or not np.issubdtype(f.dtype, np.integer):
            raise InputError(_SRC, where, f"faces must be integer (F, 3), F >= 1, got {f.shape}")
        if f.min() < 0 or f.max() >= len(v):
            raise InputError(_SRC, where, f"face indices must lie in [0, {len(v) - 1}]")
        out.append((v, f.astype(np.int64)))
    return out


def cast_rays(
    meshes: MeshLike | Sequence[MeshLike],
    origins: ArrayLike,
    directions: ArrayLike,
    *,
    engine: Engine = "auto",
) -> tuple[NDArray[np.bool_], NDArray[np.float64]]:
    """First hit of each ray: ``(hit, distance)``, distance along the unit direction.

    ``engine`` picks trimesh's ray backend: ``"embree"`` (needs ``embreex``),
    ``"triangle"`` (pure numpy + rtree) or ``"auto"`` (Embree if installed). The backend
    only names the first triangle hit; the distance is recomputed in float64 from that
    triangle's plane. Rays that miss have ``hit`` False and distance ``inf``.
    """
    import trimesh
    from trimesh.ray import ray_triangle

    parts = _as_meshes(meshes)
    offsets = np.cumsum([0] + [len(v) for v, _ in parts[:-1]])
    mesh = trimesh.Trimesh(
        vertices=np.concatenate([v for v, _ in parts]),
        faces=np.concatenate([f + off for (_, f), off in zip(parts, offsets, strict=True)]),
        process=False,
    )
    o = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
    d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    if o.shape != d.shape:
        raise InputError(_SRC, "origins", f"shape {o.shape} differs from directions {d.shape}")
    norm = np.linalg.norm(d, axis=1)
    if not (np.isfinite(o).all() and np.isfinite(d).all() and (norm > 0).all()):
        raise InputError(_SRC, "directions", "rays need finite origins and non-zero directions")
    d = d / norm[:, None]
    if engine == "auto":
        engine = "embree" if trimesh.ray.has_embree else "triangle"
    if engine == "embree":
        if not trimesh.ray.has_embree:
            raise MissingDependency("embreex", "", "the Embree ray backend of the scanner")
        from trimesh.ray import ray_pyembree

        intersector: object = ray_pyembree.RayMeshIntersector(mesh)
    elif engine == "triangle":
        intersector = ray_triangle.RayMeshIntersector(mesh)
    else:
        raise UnknownName(_SRC, "ray engine", str(engine), get_args(Engine))
    try:
        tri = np.asarray(intersector.intersects_first(o, d), dtype=np.int64)  # type: ignore[attr-defined]
    except ImportError:  # ray_triangle needs rtree, which trimesh does not require
        raise MissingDependency("rtree", "", f"trimesh's {engine!r} ray backend") from None
    dist = np.full(len(o), np.inf)
    hit = tri >= 0
    if hit.any():
        v = np.asarray(mesh.vertices)[np.asarray(mesh.faces)[tri[hit]]]
        n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
        denom = np.einsum("ij,ij->i", n, d[hit])
        num = np.einsum("ij,ij->i", n, v[:, 0] - o[hit])
        with np.errstate(divide="ignore", invalid="ignore"):
            t = num / denom
        good = np.isfinite(t) & (t > 0)
        idx = np.flatnonzero(hit)
        dist[idx[good]] = t[good]
        hit[idx[~good]] = False
    return hit, dist


# --------------------------------------------------------------------------- scenes


@dataclass(frozen=True, eq=False)
class ScanScene:
    """A scene to scan: meshes (world frame), a scanner, and the post-processing box.

    ``crop_min``/``crop_max`` bound the working area kept (P-V §IV: "points located
    outside the working area were removed"); ``voxel`` is the downsampling voxel edge,
    anchored at ``crop_min``. ``obstacles`` lists the (2, 3) ``[min, max]`` corners of
    each box obstacle, for analysis and tests.
    """

    name: str
    meshes: tuple[trimesh.Trimesh, ...]
    scanner: LaserScanner
    crop_min: NDArray[np.float64]
    crop_max: NDArray[np.float64]
    voxel: float = DEFAULT_VOXEL
    obstacles: tuple[NDArray[np.float64], ...] = ()
    description: str = ""
    ground: float | None = None

    def process(self, cloud: PointCloud, virtual: NDArray[np.float64] | None = None) -> PointCloud:
        """Crop to the working area, then voxel-downsample (P-V §IV).

        ``virtual`` points (an occlusion fill) are cropped and downsampled on the same
        grid, and kept only in voxels that hold no measured point (a measured surface
        is never replaced by a virtual point) and that lie on the boundary of the
        occupied voxels (the inside of a filled shadow adds points but no distance).
        """
        measured = voxel_downsample(
            crop(cloud, self.crop_min, self.crop_max), self.voxel, self.crop_min
        )
        if virtual is None or len(virtual) == 0:
            return measured
        inside = crop_mask(virtual, self.crop_min, self.crop_max)
        if not inside.any():
            return measured
        virt = voxel_downsample(virtual[inside], self.voxel, self.crop_min)
        seen = {tuple(k) for k in voxel_keys(measured, self.voxel, self.crop_min).tolist()}
        keys = [tuple(k) for k in voxel_keys(virt, self.voxel, self.crop_min).tolist()]
        occupied = seen.union(keys)
        # keep the virtual voxels on the boundary of the occupied region: one whose six
        # face neighbours are all occupied is inside it and never the nearest point to
        # anything outside by more than a voxel
        steps = ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1))
        keep = np.array(
            [
                k not in seen
                and not all((k[0] + a, k[1] + b, k[2] + c) in occupied for a, b, c in steps)
                for k in keys
            ],
            dtype=bool,
        )
        if not keep.any():
            return measured
        pts = np.concatenate([measured.points, virt.points[keep]])
        return PointCloud(pts, frame=measured.frame, name=measured.name)

    def virtual_points(self, scan: Scan, fill: OcclusionFill) -> NDArray[np.float64]:
        """The occlusion fill of ``scan`` with this scene's voxel and ground as the
        defaults of ``fill``."""
        spacing = self.voxel if fill.spacing is None else fill.spacing
        ground = self.ground if fill.ground is None else fill.ground
        pts, _ = scan.shadow(fill.depth, spacing, ground)
        return pts


def p5_floor_obstacle(
    *,
    scanner: LaserScanner | None = None,
    obstacle_size: tuple[float, float, float] = (0.7, 0.8, 0.55),
    obstacle_center: tuple[float, float] = (2.7, 0.0),
) -> ScanScene:
    """A public stand-in for the P-V experiment's scan: a floor with one box obstacle.

    P-V's scan data is not public; P-V §IV and Fig. 3 give only the rig, the processing
    and the result (about 5500 points after cropping and 3 cm downsampling, denser near
    the scanner, a small unseen area behind the obstacle). This scene reproduces those
    facts with choices of ours, not measurements:

    - World frame: floor plane z = 0 (a 16 m x 16 m square of two triangles), x away
      from the scanner, z up.
    - Obstacle: a rock-sized box, 0.70 m (x) x 0.80 m (y) x 0.55 m (z), standing on
      the floor centred at (2.7, 0) m, i.e. 2.35–3.05 m ahead of the scanner.
    - Scanner: optical centre 2.5 m above the floor over the origin (a stand looking
      down at the work area), tilt axis along y, the P-V resolutions (0.25° beams,
      25 Hz lines, 5°/s, so 0.2° between lines), beams from -42° to +42° azimuth,
      tilt 28°–64° below horizontal: a 7.2 s sweep of 181 lines x 337 beams that
      covers the working area.
    - Working area (crop): x 1.5–4.0 m, y ±1.08 m, z -0.1–1.0 m; 3 cm voxels anchored
      at the crop's min corner, so neither the floor nor the box faces lie on a voxel
      plane.

    The scanner height and the working-area size were tuned so that the noise-free
    scan, cropped and downsampled, gives about 5500 points (5496, about 1150 of them
    on the box), and the shadow behind the box (0.86 m long on the centre line, from
    x = 3.05 m to 3.91 m) lies inside the working area, as in P-V Fig. 3. The
    arguments change the obstacle; ``scanner`` replaces the default scanner.
    """
    import trimesh

    sx, sy, sz = (_finite(v, "obstacle_size", positive=True) for v in obstacle_size)
    cx, cy = (_finite(v, "obstacle_center") for v in obstacle_center)
    half = 8.0
    floor = trimesh.Trimesh(
        vertices=[[-half, -half, 0.0], [half, -half, 0.0], [half, half, 0.0], [-half, half, 0.0]],
        faces=[[0, 1, 2], [0, 2, 3]],
        process=False,
    )
    box = trimesh.creation.box(extents=(sx, sy, sz))
    box.apply_translation((cx, cy, sz / 2.0))
    if scanner is None:
        pose = np.eye(4)
        pose[:3, 3] = (0.0, 0.0, 2.5)
        scanner = LaserScanner(
            pose=pose,
            azimuth_range=(math.radians(-42.0), math.radians(42.0)),
            tilt_range=(math.radians(28.0), math.radians(64.0)),
        )
    return ScanScene(
        name="p5-floor-obstacle",
        meshes=(floor, box),
        scanner=scanner,
        crop_min=np.array([1.5, -1.08, -0.1]),
        crop_max=np.array([4.0, 1.08, 1.0]),
        voxel=DEFAULT_VOXEL,
        obstacles=(np.array([[cx - sx / 2, cy - sy / 2, 0.0], [cx + sx / 2, cy + sy / 2, sz]]),),
        description="P-V stand-in: a floor with a box obstacle, nodding scanner 2.5 m up",
        ground=0.0,
    )


def p5_occlusion(
    *,
    scanner: LaserScanner | None = None,
    obstacle_size: tuple[float, float, float] = (0.7, 0.8, 1.0),
    obstacle_center: tuple[float, float] = (2.7, 0.0),
) -> ScanScene:
    """A variant of :func:`p5_floor_obstacle` whose scan misses the obstacle's far half.

    Our choice, for the occlusion study of issue 9 (P-V Fig. 5: the return path went
    wrong behind the obstacle, where the scan had no points): the same floor and a
    taller box, 0.70 (x) x 0.80 (y) x 1.00 (z) m centred at (2.7, 0) m, scanned by the
    P-V scanner (same resolutions) standing low in front of it, behind the crane,
    optical centre at (-1.0, 0, 0.8) m, below the box's top: every beam that reaches
    the box hits its front face (x = 2.35 m); its top, its sides, its back and the
    floor behind it are in shadow. Beams from -30° to +30° azimuth, tilt from 10°
    above to 30° below the horizon (an 8 s sweep). Working area (crop): x 1.5–4.0 m, y ±1.5 m,
    z -0.1–1.5 m, 3 cm voxels anchored at its min corner. So the cloud is the floor
    around the obstacle and one face of it: whatever passes behind that face sees
    nothing, which :func:`shadow_points` fills.
    """
    import trimesh

    sx, sy, sz = (_finite(v, "obstacle_size", positive=True) for v in obstacle_size)
    cx, cy = (_finite(v, "obstacle_center") for v in obstacle_center)
    half = 8.0
    floor = trimesh.Trimesh(
        vertices=[[-half, -half, 0.0], [half, -half, 0.0], [half, half, 0.0], [-half, half, 0.0]],
        faces=[[0, 1, 2], [0, 2, 3]],
        process=False,
    )
    box = trimesh.creation.box(extents=(sx, sy, sz))
    box.apply_translation((cx, cy, sz / 2.0))
    if scanner is None:
        pose = np.eye(4)
        pose[:3, 3] = (-1.0, 0.0, 0.8)
        scanner = LaserScanner(
            pose=pose,
            azimuth_range=(math.radians(-30.0), math.radians(30.0)),
            tilt_range=(math.radians(-10.0), math.radians(30.0)),
        )
    return ScanScene(
        name="p5-occlusion",
        meshes=(floor, box),
        scanner=scanner,
        crop_min=np.array([1.5, -1.5, -0.1]),
        crop_max=np.array([4.0, 1.5, 1.5]),
        voxel=DEFAULT_VOXEL,
        obstacles=(np.array([[cx - sx / 2, cy - sy / 2, 0.0], [cx + sx / 2, cy + sy / 2, sz]]),),
        description="P-V occlusion variant: a 1 m box seen only from the front, scanner 0.8 m up",
        ground=0.0,
    )


#: Built-in scenes by name.
SCENES: dict[str, Callable[[], ScanScene]] = {
    "p5-floor-obstacle": p5_floor_obstacle,
    "p5-occlusion": p5_occlusion,
}


def get_scene(name: str) -> ScanScene:
    """The built-in scene ``name`` (see :data:`SCENES`)."""
    if name not in SCENES:
        raise UnknownName("scene", "scene", name, SCENES)
    return SCENES[name]()


def scan_scene(
    scene: ScanScene | str,
    rng: np.random.Generator | int | None = None,
    *,
    noise: float | None = None,
    coarsen: float = 1.0,
    engine: Engine = "auto",
    occlusion: OcclusionFill | None = None,
) -> tuple[Scan, PointCloud]:
    """Scan ``scene`` once; return the raw scan and the cropped, downsampled cloud.

    ``noise`` overrides the scanner's range noise (m, standard deviation); ``coarsen``
    multiplies its beam and line spacing (see :meth:`LaserScanner.coarsened`);
    ``occlusion`` adds the occlusion fill (:func:`shadow_points`) to the processed
    cloud (the raw scan keeps the measured returns only).
    """
    sc = get_scene(scene) if isinstance(scene, str) else scene
    scanner = sc.scanner
    if noise is not None:
        scanner = replace(scanner, range_noise=noise)
    if coarsen != 1.0:
        scanner = scanner.coarsened(coarsen)
    raw = scanner.scan(list(sc.meshes), rng, engine=engine, name=sc.name)
    if occlusion is None:
        return raw, sc.process(raw.cloud)
    return raw, sc.process(raw.cloud, sc.virtual_points(raw, occlusion))
