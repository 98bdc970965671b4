"""The tunnel as a workspace constraint: profile geometry and an exact signed distance.

P-I §4.2 and P-II §4.2 ("workspace constraints"): the manipulator works inside an
underground tunnel, "walls, a floor and a ceiling around the manipulator which is unable
to go through or collide with" them; the synthesis pushes sampled link points away
from them in the null space (P-I Eq. 27–31, P-II Eq. 29–33). That motion needs, for any
point, the distance to the tunnel surface and the direction in which it grows; this
module provides both, exactly, for the usual horseshoe-like profile.

Frames (the machine frame of the whole ``reachwise.tasks`` package): x forward along
the tunnel axis toward the face, y to the left, z up. A profile lives in the y–z
plane: lateral coordinate ``u = y - y_center``, height ``v = z - floor_z``.

The profile (public stand-in for the thesis's proprietary customer tunnels): a flat
floor ``v = 0`` of width ``w``, vertical walls ``u = ±w/2`` up to the wall height
``h_w = h - a``, and a circular arched roof through both wall tops with rise ``a``
(``a = w/2`` is a semicircle, ``a = 0`` a flat roof). The region is convex.

Pure math: numpy in, numpy out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.errors import TaskError

FloatArray = NDArray[np.float64]

# boundary pieces, in the order ties are resolved
FLOOR, RIGHT_WALL, ROOF, LEFT_WALL = 0, 1, 2, 3
PIECE_NAMES: tuple[str, ...] = ("floor", "right wall", "roof", "left wall")
_ON_BOUNDARY = 1e-12
_FLAT_RISE = 1e-6


def _finite(source: str, field: str, value: float) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise TaskError(source, field, f"must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise TaskError(source, field, f"must be finite, got {v}")
    return v


@dataclass(frozen=True)
class TunnelProfile:
    """Cross-section of a tunnel: flat floor, vertical walls, circular arched roof.

    ``width`` (m) wall to wall, ``height`` (m) floor to the roof crown, ``arch_height``
    (m) the rise of the roof arc above the wall tops (``0 ≤ arch_height ≤
    min(width/2, height)``). ``y_center`` and ``floor_z`` place the profile in the
    machine frame: the tunnel centreline is at ``y = y_center`` and the floor at
    ``z = floor_z``. A public stand-in for the customer tunnels of P-I §4 (faces of
    roughly 20–100 m² drilled by 10–15 m reach booms).
    """

    width: float
    height: float
    arch_height: float
    y_center: float = 0.0
    floor_z: float = 0.0

    def __post_init__(self) -> None:
        src = "tunnel profile"
        for f in ("width", "height", "arch_height", "y_center", "floor_z"):
            object.__setattr__(self, f, _finite(src, f, getattr(self, f)))
        if self.width <= 0:
            raise TaskError(src, "width", f"must be > 0, got {self.width}")
        if self.height <= 0:
            raise TaskError(src, "height", f"must be > 0, got {self.height}")
        if self.arch_height < 0:
            raise TaskError(src, "arch_height", f"must be ≥ 0, got {self.arch_height}")
        if self.arch_height > self.width / 2 + 1e-12:
            raise TaskError(
                src,
                "arch_height",
                f"{self.arch_height} exceeds half the width {self.width / 2} (a semicircle)",
            )
        if self.arch_height > self.height:
            raise TaskError(
                src, "arch_height", f"{self.arch_height} exceeds the height {self.height}"
            )

    @classmethod
    def from_arch_radius(
        cls,
        width: float,
        height: float,
        arch_radius: float,
        y_center: float = 0.0,
        floor_z: float = 0.0,
    ) -> TunnelProfile:
        """A profile whose roof is an arc of radius ``arch_radius`` (≥ ``width/2``) m."""
        r = _finite("tunnel profile", "arch_radius", arch_radius)
        hw = float(width) / 2
        if not r >= hw > 0:
            raise TaskError(
                "tunnel profile", "arch_radius", f"must be ≥ half the width {hw}, got {r}"
            )
        rise = r - math.sqrt(max(r * r - hw * hw, 0.0))
        return cls(width, height, min(rise, hw), y_center, floor_z)

    # -- derived geometry ------------------------------------------------------------
    @property
    def half_width(self) -> float:
        return self.width / 2

    @property
    def wall_height(self) -> float:
        """Height of the vertical walls above the floor, ``height - arch_height`` (m;
        ``height`` for a flat roof)."""
        return self.height - self.arch_height if self.is_arched else self.height

    @property
    def is_arched(self) -> bool:
        """False for a flat roof: a rise below ``1e-6·width`` (whose arc would deviate
        from the flat roof by less than that) is treated as flat, for numerical sanity."""
        return self.arch_height > _FLAT_RISE * self.width

    @property
    def arch_radius(self) -> float:
        """Radius of the roof arc, ``(w²/4 + a²) / (2a)``; ``inf`` for a flat roof."""
        a = self.arch_height
        if not self.is_arched:
            return math.inf
        return (self.half_width**2 + a * a) / (2 * a)

    @property
    def arch_center_v(self) -> float:
        """Height of the roof arc's centre above the floor (``-inf`` for a flat roof)."""
        return self.height - self.arch_radius

    @property
    def arch_half_angle(self) -> float:
        """Half the angle the roof arc subtends at its centre (rad); 0 for a flat roof."""
        if not self.is_arched:
            return 0.0
        return math.asin(min(self.half_width / self.arch_radius, 1.0))

    @property
    def area(self) -> float:
        """Cross-section area (m²): wall rectangle plus the circular segment of the roof."""
        rect = self.width * self.wall_height
        if not self.is_arched:
            return rect
        r, psi = self.arch_radius, self.arch_half_angle
        return rect + r * r * (psi - math.sin(psi) * math.cos(psi))

    @property
    def perimeter(self) -> float:
        """Length of the boundary (floor, walls, roof arc) (m)."""
        roof = self.width if not self.is_arched else 2 * self.arch_radius * self.arch_half_angle
        return self.width + 2 * self.wall_height + roof

    def translated(self, dy: float = 0.0, dz: float = 0.0) -> TunnelProfile:
        """The same profile moved by ``dy`` laterally and ``dz`` vertically (m)."""
        return TunnelProfile(
            self.width, self.height, self.arch_height, self.y_center + dy, self.floor_z + dz
        )

    def scaled(self, factor: float) -> TunnelProfile:
        """The profile scaled about its floor centre (same placement), area × factor²."""
        return TunnelProfile(
            self.width * factor,
            self.height * factor,
            self.arch_height * factor,
            self.y_center,
            self.floor_z,
        )

    # -- queries ---------------------------------------------------------------------
    def roof_v(self, u: ArrayLike) -> FloatArray:
        """Height of the ceiling above the floor at lateral offsets ``u`` (``|u| ≤ w/2``)."""
        uu = np.clip(np.asarray(u, dtype=float), -self.half_width, self.half_width)
        if not self.is_arched:
            return np.full_like(uu, self.height)
        r = self.arch_radius
        return np.asarray(self.arch_center_v + np.sqrt(np.maximum(r * r - uu * uu, 0.0)))

    def signed_distance_2d(self, yz: ArrayLike) -> FloatArray:
        """Signed distance (m) of points ``(k, 2)`` = (y, z) to the profile boundary.

        Positive inside the free cross-section, negative in the rock (outside the
        walls, below the floor, above the roof), exact.
        """
        s, _, _ = self.closest_2d(yz)
        return s

    def closest_2d(self, yz: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Signed distance ``(k,)``, its unit gradient ``(k, 2)`` and the closest boundary
        point ``(k, 2)`` (all in y, z) of points ``(k, 2)``; see ``signed_distance_2d``.

        The gradient points the way the signed distance grows: away from the nearest
        boundary point inside, toward it outside; on the boundary it is the inward
        normal of the piece (floor, wall or roof). Where two pieces are equally near
        (the medial axis, where the distance has a kink) the first of floor, right
        wall, roof, left wall is used.
        """
        s, g, c, _ = _profile_query(self, yz)
        return s, g, c

    def nearest_piece(self, yz: ArrayLike) -> NDArray[np.intp]:
        """Index (``FLOOR, RIGHT_WALL, ROOF, LEFT_WALL``) of the nearest boundary piece."""
        return _profile_query(self, yz)[3]

    def boundary(self, spacing: float = 0.1) -> FloatArray:
        """Points ``(k, 2)`` (y, z) along the closed boundary at most ``spacing`` m apart,
        counter-clockwise seen from the face (+x): floor, right wall, roof, left wall.
        """
        if not spacing > 0:
            raise TaskError("tunnel profile", "spacing", f"must be > 0, got {spacing}")
        hw, hwall = self.half_width, self.wall_height

        def seg(p0: tuple[float, float], p1: tuple[float, float]) -> FloatArray:
            n = max(1, math.ceil(math.hypot(p1[0] - p0[0], p1[1] - p0[1]) / spacing))
            t = np.arange(n) / n
            return np.column_stack([p0[0] + t * (p1[0] - p0[0]), p0[1] + t * (p1[1] - p0[1])])

        parts = [seg((-hw, 0.0), (hw, 0.0)), seg((hw, 0.0), (hw, hwall))]
        if self.is_arched:
            r, vc, psi = self.arch_radius, self.arch_center_v, self.arch_half_angle
            n = max(1, math.ceil(2 * psi * r / spacing))
            phi = np.pi / 2 - psi + 2 * psi * np.arange(n) / n
            parts.append(np.column_stack([r * np.cos(phi), vc + r * np.sin(phi)]))
        else:
            parts.append(seg((hw, self.height), (-hw, self.height)))
        parts.append(seg((-hw, hwall), (-hw, 0.0)))
        uv = np.concatenate(parts)
        return np.column_stack([uv[:, 0] + self.y_center, uv[:, 1] + self.floor_z])


def _as_points(points: ArrayLike, dim: int, name: str) -> FloatArray:
    P = np.asarray(points, dtype=float)
    if P.ndim == 1 and P.shape[0] == dim:
        P = P[None, :]
    if P.ndim != 2 or P.shape[1] != dim:
        raise TaskError(name, "", f"expected points of shape (k, {dim}), got {P.shape}")
    return P


def _profile_query(
    profile: TunnelProfile, yz: ArrayLike
) -> tuple[FloatArray, FloatArray, FloatArray, NDArray[np.intp]]:
    """Signed distance, gradient, closest point (y, z) and nearest piece, vectorized."""
    P = _as_points(yz, 2, "points")
    u = P[:, 0] - profile.y_center
    v = P[:, 1] - profile.floor_z
    k = u.shape[0]
    hw, hwall, h = profile.half_width, profile.wall_height, profile.height
    # closest point on each piece: (4, k) coordinates and inward normals (4, 2)
    cu = np.empty((4, k))
    cv = np.empty((4, k))
    cu[FLOOR], cv[FLOOR] = np.clip(u, -hw, hw), 0.0
    cu[RIGHT_WALL], cv[RIGHT_WALL] = hw, np.clip(v, 0.0, hwall)
    cu[LEFT_WALL], cv[LEFT_WALL] = -hw, np.clip(v, 0.0, hwall)
    n_in = np.zeros((4, k, 2))
    n_in[FLOOR, :, 1] = 1.0
    n_in[RIGHT_WALL, :, 0] = -1.0
    n_in[LEFT_WALL, :, 0] = 1.0
    dist = np.empty((4, k))
    if profile.is_arched:
        r, vc, psi = profile.arch_radius, profile.arch_center_v, profile.arch_half_angle
        du, dv = u, v - vc
        rho = np.hypot(du, dv)
        phi = np.arctan2(dv, du)
        # the arc spans angles [π/2 - ψ, π/2 + ψ] about its centre
        on_arc = np.abs(phi - np.pi / 2) <= psi
        safe = np.where(rho > 0, rho, 1.0)
        ru = np.where(rho > 0, du / safe, 0.0)
        rv = np.where(rho > 0, dv / safe, 1.0)
        cu[ROOF], cv[ROOF] = r * ru, vc + r * rv
        n_in[ROOF, :, 0], n_in[ROOF, :, 1] = -ru, -rv
        dist[ROOF] = np.where(on_arc, np.abs(rho - r), np.inf)
        inside_roof = (v <= hwall) | (rho <= r)
    else:
        cu[ROOF], cv[ROOF] = np.clip(u, -hw, hw), h
        n_in[ROOF, :, 1] = -1.0
        dist[ROOF] = np.hypot(u - cu[ROOF], v - h)
        inside_roof = v <= h
    for piece in (FLOOR, RIGHT_WALL, LEFT_WALL):
        dist[piece] = np.hypot(u - cu[piece], v - cv[piece])
    piece_idx = np.argmin(dist, axis=0)
    cols = np.arange(k)
    d = dist[piece_idx, cols]
    c = np.column_stack([cu[piece_idx, cols], cv[piece_idx, cols]])
    inside = (np.abs(u) <= hw) & (v >= 0.0) & inside_roof
    sign = np.where(inside, 1.0, -1.0)
    s = sign * d
    diff = np.column_stack([u, v]) - c
    safe_d = np.where(d > _ON_BOUNDARY, d, 1.0)
    g = np.where(
        (d > _ON_BOUNDARY)[:, None],
        sign[:, None] * diff / safe_d[:, None],
        n_in[piece_idx, cols],
    )
    closest = c + np.array([profile.y_center, profile.floor_z])
    return s, g, closest, piece_idx


@dataclass(frozen=True)
class TunnelEnvelope:
    """The free space of a tunnel: a profile extruded along x, optionally capped.

    ``profile`` gives the cross-section; ``x_range = (x_min, x_max)`` limits the stretch
    of tunnel described (finite ends act as boundaries; ``±inf`` leaves them open);
    ``face_x``, if given, adds the face plane ``x = face_x``: rock lies ahead of it. The
    effective far end is ``min(x_max, face_x)``.

    ``signed_distance`` is exact: with ``d₂`` the 2-D signed distance of (y, z) to the
    profile and ``dₓ = min(x - x_min, x_end - x)``, a point inside both has distance
    ``min(d₂, dₓ)`` and a point outside ``-sqrt(max(-d₂, 0)² + max(-dₓ, 0)²)`` (the
    free space is the product of the cross-section and an interval). This is the
    workspace constraint of P-I §4.2 / P-II §4.2 (walls, floor and roof around the
    manipulator), used by the synthesis's workspace-avoidance motion (P-II Eq. 29–33).
    """

    profile: TunnelProfile
    x_range: tuple[float, float] = (-math.inf, math.inf)
    face_x: float | None = None

    def __post_init__(self) -> None:
        src = "tunnel envelope"
        if not isinstance(self.profile, TunnelProfile):
            raise TaskError(src, "profile", "must be a TunnelProfile")
        try:
            lo, hi = (float(x) for x in self.x_range)
        except (TypeError, ValueError):
            raise TaskError(
                src, "x_range", f"expected (x_min, x_max), got {self.x_range!r}"
            ) from None
        if math.isnan(lo) or math.isnan(hi) or not lo < hi:
            raise TaskError(src, "x_range", f"need x_min < x_max, got ({lo}, {hi})")
        object.__setattr__(self, "x_range", (lo, hi))
        if self.face_x is not None:
            fx = _finite(src, "face_x", self.face_x)
            if not lo < fx:
                raise TaskError(src, "face_x", f"face at x = {fx} is behind x_min = {lo}")
            object.__setattr__(self, "face_x", fx)

    @property
    def x_end(self) -> float:
        """Far end of the free space along x: ``min(x_max, face_x)``."""
        hi = self.x_range[1]
        return hi if self.face_x is None else min(hi, self.face_x)

    def signed_distance(self, points: ArrayLike) -> FloatArray:
        """Signed distance (m) of points ``(k, 3)``: > 0 in free space, < 0 in rock."""
        return self.signed_distance_and_gradient(points)[0]

    def gradient(self, points: ArrayLike) -> FloatArray:
        """Unit direction ``(k, 3)`` in which the signed distance grows (see class doc)."""
        return self.signed_distance_and_gradient(points)[1]

    def contains(self, points: ArrayLike, margin: float = 0.0) -> NDArray[np.bool_]:
        """True where a point is at least ``margin`` m inside the free space."""
        return np.asarray(self.signed_distance(points) >= margin)

    def signed_distance_and_gradient(self, points: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Signed distance ``(k,)`` and its unit gradient ``(k, 3)`` in one pass.

        Inside, the gradient is that of the nearer of the cross-section boundary and the
        x caps; outside, it is the normalized sum of both outward excesses. On a kink
        (equal distances) the cross-section is preferred.
        """
        P = _as_points(points, 3, "points")
        s2, g2, _, _ = _profile_query(self.profile, P[:, 1:])
        x = P[:, 0]
        x_lo, x_hi = self.x_range[0], self.x_end
        with np.errstate(invalid="ignore"):
            to_lo = x - x_lo
            to_hi = x_hi - x
        dx = np.minimum(to_lo, to_hi)
        gx = np.where(to_lo <= to_hi, 1.0, -1.0)
        inside = (s2 >= 0) & (dx >= 0)
        o2 = np.maximum(-s2, 0.0)
        ox = np.maximum(-dx, 0.0)
        rho = np.hypot(o2, ox)
        s = np.where(inside, np.minimum(s2, dx), -rho)
        use_2d = s2 <= dx
        g_in = np.where(use_2d[:, None], np.column_stack([np.zeros_like(x), g2]), 0.0)
        g_in[~use_2d, 0] = gx[~use_2d]
        safe = np.where(rho > 0, rho, 1.0)
        g_out = np.column_stack([gx * ox / safe, g2 * (o2 / safe)[:, None]])
        g = np.where(inside[:, None], g_in, g_out)
        return np.asarray(s, dtype=float), np.asarray(g, dtype=float)


__all__ = [
    "FLOOR",
    "LEFT_WALL",
    "PIECE_NAMES",
    "RIGHT_WALL",
    "ROOF",
    "TunnelEnvelope",
    "TunnelProfile",
]
