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

The beams are cast by :mod:`reachwise.geometry.raycast`; the occlusion fill behind the
returns is :mod:`reachwise.geometry.occlusion`; cropping and downsampling a scan of a
scene is :mod:`reachwise.geometry.scan_scene`.

This module is pure math: meshes and a random Generator in, arrays out.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.errors import CloudError, InputError
from reachwise.geometry.checks import finite_number, interval
from reachwise.geometry.cloud import DEFAULT_VOXEL, PointCloud
from reachwise.geometry.occlusion import shadow_points
from reachwise.geometry.raycast import Engine, cast_rays

if TYPE_CHECKING:
    from reachwise.geometry.raycast import MeshLike

__all__ = ["LaserScanner", "Scan"]

_SRC = "scanner"


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
        res = finite_number(self.angular_resolution, _SRC, "angular_resolution", positive=True)
        finite_number(self.scan_rate, _SRC, "scan_rate", positive=True)
        finite_number(self.tilt_rate, _SRC, "tilt_rate", positive=True)
        az = interval(self.azimuth_range, _SRC, "azimuth_range")
        if az[1] - az[0] >= 2 * math.pi:
            raise InputError(_SRC, "azimuth_range", "must span less than 360°")
        object.__setattr__(self, "azimuth_range", az)
        object.__setattr__(self, "tilt_range", interval(self.tilt_range, _SRC, "tilt_range"))
        lo = finite_number(self.min_range, _SRC, "min_range", nonneg=True)
        hi = finite_number(self.max_range, _SRC, "max_range", positive=True)
        if lo >= hi:
            raise InputError(_SRC, "min_range", f"must be below max_range {hi!r}, got {lo!r}")
        finite_number(self.range_noise, _SRC, "range_noise", nonneg=True)
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
        f = finite_number(factor, _SRC, "factor", positive=True)
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
