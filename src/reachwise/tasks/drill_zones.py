"""The zones of a tunnel-face drill plan as hole sets (collars in profile coordinates
and hole directions): the V-cut and the parallel cut, stoping rows, the contour along
walls and roof, the lifters along the floor. ``reachwise.tasks.drilling`` assembles
them into a task; the field practice they follow is described there.

Profile coordinates ``(u, v) = (y − y_center, z − floor_z)`` (m); directions in the
machine frame (x along the tunnel axis toward the face). Pure math.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.tasks.workspace import TunnelProfile

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Holes:
    """Collars ``(k, 2)`` in profile coordinates (u, v) and unit directions ``(k, 3)``."""

    uv: FloatArray
    axis: FloatArray

    @staticmethod
    def empty() -> Holes:
        return Holes(np.zeros((0, 2)), np.zeros((0, 3)))


def hole_directions(tan_y: ArrayLike, tan_z: ArrayLike) -> FloatArray:
    """Unit vectors ``normalize(x̂ + tan_y ŷ + tan_z ẑ)``."""
    ty, tz = np.broadcast_arrays(np.asarray(tan_y, float), np.asarray(tan_z, float))
    d = np.column_stack([np.ones(ty.size), ty.ravel(), tz.ravel()])
    return np.asarray(d / np.linalg.norm(d, axis=1, keepdims=True))


def lookout_directions(normal_uv: FloatArray, angle: float) -> FloatArray:
    """Directions ``cos(L) x̂ + sin(L) n`` for outward unit normals ``n`` in (u, v)."""
    n = normal_uv / np.linalg.norm(normal_uv, axis=1, keepdims=True)
    return np.column_stack(
        [np.full(n.shape[0], math.cos(angle)), math.sin(angle) * n[:, 0], math.sin(angle) * n[:, 1]]
    )


def inner_offset(profile: TunnelProfile, delta: float) -> tuple[float, float, float]:
    """The profile offset inward by ``delta``: (half width, junction height of wall and
    roof, roof radius) — the roof keeps its centre (``inf`` radius for a flat roof)."""
    hw = profile.half_width - delta
    if not profile.is_arched:
        return hw, profile.height - delta, math.inf
    r = profile.arch_radius - delta
    vj = profile.arch_center_v + math.sqrt(max(r * r - hw * hw, 0.0))
    return hw, vj, r


def row_half_width(profile: TunnelProfile, delta: float, v: float) -> float:
    """Half width at height ``v`` of the region at least ``delta`` inside the profile."""
    hw, vj, r = inner_offset(profile, delta)
    if v < delta or hw <= 0:
        return -1.0
    if v <= vj:
        return hw
    if math.isinf(r):
        return -1.0
    s = r * r - (v - profile.arch_center_v) ** 2
    return math.sqrt(s) if s >= 0 else -1.0


def evenly(lo: float, hi: float, spacing: float) -> FloatArray:
    """Points from ``lo`` to ``hi`` inclusive, evenly, about ``spacing`` apart."""
    n = max(1, round(abs(hi - lo) / spacing))
    return np.asarray(lo + (hi - lo) * np.arange(n + 1) / n)


def contour_holes(
    profile: TunnelProfile, offset: float, v_start: float, spacing: float, lookout: float
) -> Holes:
    """Contour holes on the profile offset inward by ``offset``: up one wall, over the
    roof, down the other wall; a hole at each wall-roof corner, even spacing between."""
    hw, vj, r = inner_offset(profile, offset)
    uv: list[FloatArray] = []
    nrm: list[FloatArray] = []
    wall_len = vj - v_start
    wall = evenly(v_start, vj, spacing)[:-1] if wall_len > 0.25 * spacing else np.zeros(0)
    # +u wall, bottom to corner (corner excluded)
    uv.append(np.column_stack([np.full(wall.size, hw), wall]))
    nrm.append(np.tile([1.0, 0.0], (wall.size, 1)))
    if math.isinf(r):
        us = evenly(hw, -hw, spacing)
        roof_uv = np.column_stack([us, np.full(us.size, vj)])
        roof_n = np.tile([0.0, 1.0], (us.size, 1))
        corner_n = np.array([[1.0, 1.0], [-1.0, 1.0]])
    else:
        psi = math.asin(min(hw / r, 1.0))
        n_arc = max(1, round(2 * psi * r / spacing))
        th = np.pi / 2 - psi + 2 * psi * np.arange(n_arc + 1) / n_arc
        roof_uv = np.column_stack([r * np.cos(th), profile.arch_center_v + r * np.sin(th)])
        roof_n = np.column_stack([np.cos(th), np.sin(th)])
        corner_n = np.array(
            [[1.0 + math.cos(th[0]), math.sin(th[0])], [-1.0 + math.cos(th[-1]), math.sin(th[-1])]]
        )
    roof_n = roof_n.copy()
    roof_n[0], roof_n[-1] = corner_n[0], corner_n[1]  # corner holes bisect wall and roof
    uv.append(roof_uv)
    nrm.append(roof_n)
    wall_down = wall[::-1]
    uv.append(np.column_stack([np.full(wall_down.size, -hw), wall_down]))
    nrm.append(np.tile([-1.0, 0.0], (wall_down.size, 1)))
    U = np.concatenate(uv)
    N = np.concatenate(nrm)
    return Holes(U, lookout_directions(N, lookout))


def lifter_holes(
    profile: TunnelProfile,
    offset: float,
    height: float,
    spacing: float,
    angle: float,
    lookout: float,
) -> Holes:
    """Lifters along the floor, angled down by ``angle``; the corner ones also outward."""
    hw = profile.half_width - offset
    us = evenly(-hw, hw, spacing)
    side = np.zeros(us.size)
    side[0], side[-1] = -1.0, 1.0
    uv = np.column_stack([us, np.full(us.size, height)])
    return Holes(uv, hole_directions(side * math.tan(lookout), -math.tan(angle)))


def v_cut(
    center: tuple[float, float],
    rows: int,
    pairs: int,
    row_pitch: float,
    angle: float,
    vertical_angle: float,
    depth: float,
    half_room: float,
) -> Holes:
    """A horizontal V-cut: ``rows`` rows of ``pairs`` symmetric pairs converging on the
    vertical plane ``u = center u``. Pair k (1 = inner "baby" V) is angled ``α_k`` from
    the tunnel axis, ``α₁ = angle`` decreasing to ``0.65·angle`` outermost; its tip is
    ``0.1 + 0.25 (k-1)`` m off the plane at a V depth growing from ``0.45·depth`` to
    ``depth``, which fixes the collar offset. If the outer collars do not fit in
    ``half_room`` the V depths shrink (a V-cut's advance is limited by the tunnel
    width, a well-known property of angled cuts). Outer rows also converge vertically
    on the cut centre by up to ``vertical_angle``."""
    uc, vc = center
    k = np.arange(1, pairs + 1, dtype=float)
    frac = (k - 1) / max(pairs - 1, 1)
    alpha = angle * (1 - 0.35 * frac)
    tip = 0.1 + 0.25 * (k - 1)
    vdepth = depth * (0.45 + 0.55 * frac)
    off = tip + vdepth * np.tan(alpha)
    if off[-1] > half_room:
        scale = max((half_room - tip[-1]) / (vdepth[-1] * math.tan(alpha[-1])), 0.0)
        off = tip + scale * vdepth * np.tan(alpha)
    row_off = (np.arange(rows) - (rows - 1) / 2) * row_pitch
    max_row = max(float(np.abs(row_off).max()), 1e-12)
    uv, ty, tz = [], [], []
    for ro in row_off:
        beta = vertical_angle * abs(ro) / max_row
        for side in (1.0, -1.0):
            for j in range(pairs):
                uv.append((uc + side * off[j], vc + ro))
                ty.append(-side * math.tan(alpha[j]))
                tz.append(-math.copysign(math.tan(beta), ro) if ro != 0 else 0.0)
    return Holes(np.array(uv, dtype=float), hole_directions(ty, tz))


def parallel_cut(center: tuple[float, float]) -> Holes:
    """A four-section parallel (burn) cut: two empty relief holes 0.2 m apart at the
    centre and four sections of four charged holes at 0.2, 0.4, 0.75 and 1.2 m,
    alternately on the diagonals and the axes; every hole along the tunnel axis."""
    uc, vc = center
    uv = [(uc, vc - 0.1), (uc, vc + 0.1)]
    for radius, start in ((0.2, 45.0), (0.4, 0.0), (0.75, 45.0), (1.2, 0.0)):
        for q in range(4):
            a = math.radians(start + 90.0 * q)
            uv.append((uc + radius * math.cos(a), vc + radius * math.sin(a)))
    n = len(uv)
    return Holes(np.array(uv, dtype=float), hole_directions(np.zeros(n), np.zeros(n)))


def stoping_holes(
    profile: TunnelProfile,
    delta: float,
    v_lo: float,
    burden: float,
    spacing: float,
    keep_out: tuple[float, float, float, float],
) -> Holes:
    """Stoping holes on rows ``burden`` apart from ``v_lo`` up to ``delta`` under the
    crown, ``spacing`` apart inside the region ``delta`` inside the profile, outside
    the cut's keep-out box ``(u0, u1, v0, v1)``; all along the tunnel axis."""
    v_hi = profile.height - delta
    if v_hi < v_lo:
        return Holes.empty()
    rows = evenly(v_lo, v_hi, burden) if v_hi - v_lo > 0.25 * burden else np.array([v_lo])
    uv: list[tuple[float, float]] = []
    u0, u1, v0, v1 = keep_out
    for v in rows:
        half = row_half_width(profile, delta, float(v))
        if half < 0:
            continue
        us = np.array([0.0]) if half < spacing / 2 else evenly(-half, half, spacing)
        for u in us:
            if not (u0 <= u <= u1 and v0 <= v <= v1):
                uv.append((float(u), float(v)))
    if not uv:
        return Holes.empty()
    U = np.array(uv, dtype=float)
    return Holes(U, hole_directions(np.zeros(len(U)), np.zeros(len(U))))
