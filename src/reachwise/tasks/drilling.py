"""Tunnel-face drilling patterns: the task of a face-drilling boom (P-I §4, P-II §5).

The thesis designs its boom for "87 task points; 10 real drill plans were chosen from
actual customer cases and combined into a single set of task points" (P-I §4, Figs.
4–5; P-II §5, Fig. 3). Those plans are proprietary. This module builds an honest
**public stand-in** from the field's common practice (mission, "Public stand-ins"):

* a face is drilled in zones — the **cut** near the centre, opening the first free
  face (a V-cut of angled holes or a parallel cut of holes along the tunnel axis
  around empty relief holes), **stoping** holes breaking horizontally into the cut
  beside it and downward above it, **contour** (trimmer) holes along walls and roof
  at 0.5–1 m spacing angled outward by a small look-out angle so the next round keeps
  the profile, and **lifters** along the floor angled slightly down;
* each hole is a task point: the collar on the face plane plus the hole direction as
  the tool z axis (5-D, P-II §5), optionally with the feed's roll as the sixth
  coordinate (6-D, as the thesis uses near the walls);
* faces of roughly 20–100 m², 5–10 m ahead of the machine, for booms reaching
  10–15 m (P-I §1: "a long-reach manipulator (10–15 m) due to the desired tunnel size").

The thesis stresses the structure this reproduces: "the drilling pattern near the
center of the tunnel is more dense and requires a wide range of orientation angles …
near the boundaries of the tunnel (walls, ceiling, and ground) … a lower range of
orientation angles" (thesis §2.3, P-II §1).

Machine frame: x forward along the tunnel axis toward the face, y to the left, z up;
the origin is on the tunnel floor below the boom-base area (a boom base sits ≈1.2 m
above it). Profile coordinates ``(u, v) = (y - y_center, z - floor_z)``.

Pure math: numpy in, numpy out; deterministic for a given seed.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.errors import TaskError
from reachwise.tasks.task import (
    DEFAULT_TOL_ORIENTATION,
    DEFAULT_TOL_POSITION,
    Task,
    TaskPoint,
)
from reachwise.tasks.workspace import TunnelEnvelope, TunnelProfile

FloatArray = NDArray[np.float64]
CutType = Literal["v", "parallel"]
ZONES: tuple[str, ...] = ("cut", "stoping", "contour", "lifter")
TUNNEL_87_SEED = 2017
TUNNEL_87_POINTS = 87
TUNNEL_87_PLANS = 10
#: The largest face of the tunnel-87 family (≈97 m²); its envelope is the task's.
# The largest of the 10 stand-in plans: a ≈56 m² face. The thesis's 87 points are all
# reached by one SB60 boom; one boom of a two- or three-boom jumbo covers a face share
# of this size, so the combined plans stay within it (faces of 20–56 m²).
TUNNEL_87_LARGEST = TunnelProfile(width=8.5, height=7.2, arch_height=2.2)
_SRC = "drilling pattern"


@dataclass(frozen=True)
class _Holes:
    """Collars ``(k, 2)`` in profile coordinates (u, v) and unit directions ``(k, 3)``."""

    uv: FloatArray
    axis: FloatArray

    @staticmethod
    def empty() -> _Holes:
        return _Holes(np.zeros((0, 2)), np.zeros((0, 3)))


def _direction(tan_y: ArrayLike, tan_z: ArrayLike) -> FloatArray:
    """Unit vectors ``normalize(x̂ + tan_y ŷ + tan_z ẑ)``."""
    ty, tz = np.broadcast_arrays(np.asarray(tan_y, float), np.asarray(tan_z, float))
    d = np.column_stack([np.ones(ty.size), ty.ravel(), tz.ravel()])
    return np.asarray(d / np.linalg.norm(d, axis=1, keepdims=True))


def _lookout(normal_uv: FloatArray, angle: float) -> FloatArray:
    """Directions ``cos(L) x̂ + sin(L) n`` for outward unit normals ``n`` in (u, v)."""
    n = normal_uv / np.linalg.norm(normal_uv, axis=1, keepdims=True)
    return np.column_stack(
        [np.full(n.shape[0], math.cos(angle)), math.sin(angle) * n[:, 0], math.sin(angle) * n[:, 1]]
    )


def _inner_offset(profile: TunnelProfile, delta: float) -> tuple[float, float, float]:
    """The profile offset inward by ``delta``: (half width, junction height of wall and
    roof, roof radius) — the roof keeps its centre (``inf`` radius for a flat roof)."""
    hw = profile.half_width - delta
    if not profile.is_arched:
        return hw, profile.height - delta, math.inf
    r = profile.arch_radius - delta
    vj = profile.arch_center_v + math.sqrt(max(r * r - hw * hw, 0.0))
    return hw, vj, r


def _row_half_width(profile: TunnelProfile, delta: float, v: float) -> float:
    """Half width at height ``v`` of the region at least ``delta`` inside the profile."""
    hw, vj, r = _inner_offset(profile, delta)
    if v < delta or hw <= 0:
        return -1.0
    if v <= vj:
        return hw
    if math.isinf(r):
        return -1.0
    s = r * r - (v - profile.arch_center_v) ** 2
    return math.sqrt(s) if s >= 0 else -1.0


def _even(lo: float, hi: float, spacing: float) -> FloatArray:
    """Points from ``lo`` to ``hi`` inclusive, evenly, about ``spacing`` apart."""
    n = max(1, round(abs(hi - lo) / spacing))
    return np.asarray(lo + (hi - lo) * np.arange(n + 1) / n)


def _contour(
    profile: TunnelProfile, offset: float, v_start: float, spacing: float, lookout: float
) -> _Holes:
    """Contour holes on the profile offset inward by ``offset``: up one wall, over the
    roof, down the other wall; a hole at each wall-roof corner, even spacing between."""
    hw, vj, r = _inner_offset(profile, offset)
    uv: list[FloatArray] = []
    nrm: list[FloatArray] = []
    wall_len = vj - v_start
    wall = _even(v_start, vj, spacing)[:-1] if wall_len > 0.25 * spacing else np.zeros(0)
    # +u wall, bottom to corner (corner excluded)
    uv.append(np.column_stack([np.full(wall.size, hw), wall]))
    nrm.append(np.tile([1.0, 0.0], (wall.size, 1)))
    if math.isinf(r):
        us = _even(hw, -hw, spacing)
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
    return _Holes(U, _lookout(N, lookout))


def _lifters(
    profile: TunnelProfile,
    offset: float,
    height: float,
    spacing: float,
    angle: float,
    lookout: float,
) -> _Holes:
    """Lifters along the floor, angled down by ``angle``; the corner ones also outward."""
    hw = profile.half_width - offset
    us = _even(-hw, hw, spacing)
    side = np.zeros(us.size)
    side[0], side[-1] = -1.0, 1.0
    uv = np.column_stack([us, np.full(us.size, height)])
    return _Holes(uv, _direction(side * math.tan(lookout), -math.tan(angle)))


def _v_cut(
    center: tuple[float, float],
    rows: int,
    pairs: int,
    row_pitch: float,
    angle: float,
    vertical_angle: float,
    depth: float,
    half_room: float,
) -> _Holes:
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
    return _Holes(np.array(uv, dtype=float), _direction(ty, tz))


def _parallel_cut(center: tuple[float, float]) -> _Holes:
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
    return _Holes(np.array(uv, dtype=float), _direction(np.zeros(n), np.zeros(n)))


def _stoping(
    profile: TunnelProfile,
    delta: float,
    v_lo: float,
    burden: float,
    spacing: float,
    keep_out: tuple[float, float, float, float],
) -> _Holes:
    """Stoping holes on rows ``burden`` apart from ``v_lo`` up to ``delta`` under the
    crown, ``spacing`` apart inside the region ``delta`` inside the profile, outside
    the cut's keep-out box ``(u0, u1, v0, v1)``; all along the tunnel axis."""
    v_hi = profile.height - delta
    if v_hi < v_lo:
        return _Holes.empty()
    rows = _even(v_lo, v_hi, burden) if v_hi - v_lo > 0.25 * burden else np.array([v_lo])
    uv: list[tuple[float, float]] = []
    u0, u1, v0, v1 = keep_out
    for v in rows:
        half = _row_half_width(profile, delta, float(v))
        if half < 0:
            continue
        us = np.array([0.0]) if half < spacing / 2 else _even(-half, half, spacing)
        for u in us:
            if not (u0 <= u <= u1 and v0 <= v <= v1):
                uv.append((float(u), float(v)))
    if not uv:
        return _Holes.empty()
    U = np.array(uv, dtype=float)
    return _Holes(U, _direction(np.zeros(len(U)), np.zeros(len(U))))


def _check_positive(field: str, value: float) -> float:
    v = float(value)
    if not (math.isfinite(v) and v > 0):
        raise TaskError(_SRC, field, f"must be finite and > 0, got {value}")
    return v


def roll_rotations(profile: TunnelProfile, collars_yz: ArrayLike, axes: ArrayLike) -> FloatArray:
    """6-D tool rotations ``(k, 3, 3)`` for holes: z along the hole, x toward the tunnel
    interior — away from the nearest wall, roof or floor, projected normal to the hole —
    the side the feed beam goes so the drill steel can get close to the profile (the
    thesis's reason for a sixth task coordinate near the walls, P-II §5)."""
    A = np.asarray(axes, dtype=float)
    _, g, _ = profile.closest_2d(collars_yz)
    inward = np.column_stack([np.zeros(len(g)), g])
    x = inward - np.sum(inward * A, axis=1, keepdims=True) * A
    x = x / np.linalg.norm(x, axis=1, keepdims=True)
    y = np.cross(A, x)
    return np.stack([x, y, A], axis=-1)


def drilling_pattern(
    profile: TunnelProfile,
    *,
    face_x: float = 7.0,
    hole_depth: float = 4.5,
    lookout_angle: float = math.radians(3.0),
    contour_spacing: float = 0.7,
    contour_offset: float = 0.15,
    contour_burden: float = 0.8,
    lifter_spacing: float = 1.0,
    lifter_height: float = 0.25,
    lifter_angle: float | None = None,
    stoping_burden: float = 0.9,
    stoping_spacing: float = 1.0,
    cut_type: CutType = "v",
    cut_center: tuple[float, float] | None = None,
    cut_angle: float = math.radians(30.0),
    cut_rows: int = 4,
    cut_pairs: int = 2,
    cut_row_pitch: float = 0.55,
    cut_vertical_angle: float = math.radians(6.0),
    jitter: float = 0.0,
    seed: int | np.random.Generator | None = 0,
    dims: int = 5,
    plan: str = "P01",
    name: str | None = None,
    tol_position: float = DEFAULT_TOL_POSITION,
    tol_orientation: float = DEFAULT_TOL_ORIENTATION,
) -> Task:
    """One tunnel-face drill plan as a task (public stand-in for P-I §4's customer plans).

    Every hole is collared on the face plane ``x = face_x`` (m ahead of the machine
    origin) inside ``profile``; its direction is the tool z axis. Zones (each point's
    ``group``; ``name`` is ``"{plan}/{zone}{k:02d}"``):

    * ``cut`` around ``cut_center`` = (u, v) in profile coordinates (default: the
      centreline, ``clip(0.4·height, 1.6, 3.0)`` m above the floor).
      ``cut_type="v"``: a horizontal V-cut, ``cut_rows`` × ``cut_pairs`` symmetric
      pairs angled up to ``cut_angle`` (rad) from the tunnel axis toward the cut's
      vertical plane, the outer rows also tilted up to ``cut_vertical_angle`` toward the
      centre row — the widest range of directions on the face. ``"parallel"``: a
      four-section burn cut of 18 holes along the tunnel axis (2 empty relief holes).
    * ``stoping``: rows ``stoping_burden`` apart, holes ``stoping_spacing`` apart, along
      the tunnel axis, at least ``contour_offset + contour_burden`` inside the profile
      and clear of the cut; those beside the cut break horizontally into it, those above
      it downward (firing order, not geometry).
    * ``contour``: along walls and roof, ``contour_offset`` inside the profile, about
      ``contour_spacing`` m apart (0.5–1 m is usual; corners get a hole bisecting wall
      and roof), each tilted outward by ``lookout_angle`` (rad) from the tunnel axis so
      the hole bottom reaches ``≈ hole_depth·tan(lookout)`` past the collar line.
    * ``lifter``: along the floor ``lifter_height`` m up, ``lifter_spacing`` apart,
      angled down by ``lifter_angle`` (default: the look-out), corner lifters also
      outward by the look-out.

    ``hole_depth`` (m) sets the V-cut depths (which shrink if the tunnel is too narrow
    for them). ``jitter`` (m) perturbs collars in the face plane (N(0, jitter) clipped
    to ±2σ, seeded by ``seed``) like a real plan's irregular holes. ``dims=6`` adds the
    feed roll (``roll_rotations``: tool x toward the tunnel interior).
    """
    if not isinstance(profile, TunnelProfile):
        raise TaskError(_SRC, "profile", "must be a TunnelProfile")
    fx = float(face_x)
    if not math.isfinite(fx):
        raise TaskError(_SRC, "face_x", f"must be finite, got {face_x}")
    hole_depth = _check_positive("hole_depth", hole_depth)
    contour_spacing = _check_positive("contour_spacing", contour_spacing)
    contour_offset = _check_positive("contour_offset", contour_offset)
    contour_burden = _check_positive("contour_burden", contour_burden)
    lifter_spacing = _check_positive("lifter_spacing", lifter_spacing)
    lifter_height = _check_positive("lifter_height", lifter_height)
    stoping_burden = _check_positive("stoping_burden", stoping_burden)
    stoping_spacing = _check_positive("stoping_spacing", stoping_spacing)
    cut_row_pitch = _check_positive("cut_row_pitch", cut_row_pitch)
    lookout = float(lookout_angle)
    if not 0 <= lookout <= math.radians(15):
        raise TaskError(_SRC, "lookout_angle", f"must be in [0, 15°] (rad), got {lookout_angle}")
    lift = lookout if lifter_angle is None else float(lifter_angle)
    if not 0 <= lift <= math.radians(15):
        raise TaskError(_SRC, "lifter_angle", f"must be in [0, 15°] (rad), got {lifter_angle}")
    if not 0 < cut_angle < math.radians(60):
        raise TaskError(_SRC, "cut_angle", f"must be in (0, 60°) (rad), got {cut_angle}")
    if not 0 <= cut_vertical_angle < math.radians(30):
        raise TaskError(
            _SRC, "cut_vertical_angle", f"must be in [0, 30°), got {cut_vertical_angle}"
        )
    if cut_type not in ("v", "parallel"):
        raise TaskError(_SRC, "cut_type", f"must be 'v' or 'parallel', got {cut_type!r}")
    if int(cut_rows) < 1 or int(cut_pairs) < 1:
        raise TaskError(_SRC, "cut_rows", "cut_rows and cut_pairs must be ≥ 1")
    if dims not in (5, 6):
        raise TaskError(_SRC, "dims", f"must be 5 or 6, got {dims}")
    if not (math.isfinite(jitter) and 0 <= jitter <= contour_offset / 4):
        raise TaskError(_SRC, "jitter", f"must be in [0, contour_offset/4], got {jitter}")
    if lifter_height >= profile.wall_height:
        raise TaskError(_SRC, "lifter_height", "lifters must be below the wall tops")
    if 2 * (contour_offset + contour_burden) >= profile.width:
        raise TaskError(_SRC, "profile", f"tunnel {profile.width} m wide is too narrow")

    if cut_center is None:
        cc = (0.0, min(max(0.4 * profile.height, 1.6), 3.0))
    else:
        cc = (float(cut_center[0]), float(cut_center[1]))
    room = _row_half_width(profile, contour_offset + contour_burden, cc[1])
    if room <= abs(cc[0]):
        raise TaskError(_SRC, "cut_center", f"{cc} is not inside the stoping region")
    if cut_type == "v":
        half_room = room - abs(cc[0])
        cut = _v_cut(
            cc,
            int(cut_rows),
            int(cut_pairs),
            cut_row_pitch,
            float(cut_angle),
            float(cut_vertical_angle),
            hole_depth,
            half_room,
        )
    else:
        cut = _parallel_cut(cc)
    s_cut = profile.signed_distance_2d(cut.uv + np.array([profile.y_center, profile.floor_z]))
    if (s_cut < contour_offset).any():
        raise TaskError(_SRC, "cut_center", f"the cut at {cc} does not fit inside the profile")
    clear = 0.5
    box = (
        float(cut.uv[:, 0].min()) - clear,
        float(cut.uv[:, 0].max()) + clear,
        float(cut.uv[:, 1].min()) - clear,
        float(cut.uv[:, 1].max()) + clear,
    )
    stoping = _stoping(
        profile,
        contour_offset + contour_burden,
        lifter_height + stoping_burden,
        stoping_burden,
        stoping_spacing,
        box,
    )
    contour = _contour(
        profile, contour_offset, lifter_height + contour_spacing, contour_spacing, lookout
    )
    lifters = _lifters(profile, contour_offset, lifter_height, lifter_spacing, lift, lookout)

    zones = {"cut": cut, "stoping": stoping, "contour": contour, "lifter": lifters}
    uv = np.concatenate([z.uv for z in zones.values()])
    axes = np.concatenate([z.axis for z in zones.values()])
    groups = [g for g, z in zones.items() for _ in range(len(z.uv))]
    names = [f"{plan}/{g}{k + 1:02d}" for g, z in zones.items() for k in range(len(z.uv))]
    if jitter > 0:
        rng = np.random.default_rng(seed)
        uv = uv + np.clip(rng.normal(0.0, jitter, uv.shape), -2 * jitter, 2 * jitter)
    yz = uv + np.array([profile.y_center, profile.floor_z])
    pos = np.column_stack([np.full(len(yz), fx), yz])
    rot = roll_rotations(profile, yz, axes) if dims == 6 else None
    task_name = (
        name if name is not None else (f"tunnel-{profile.width:g}x{profile.height:g}-{plan}")
    )
    return Task.from_arrays(
        task_name,
        pos,
        rotations=rot,
        axes=None if rot is not None else axes,
        dims=dims,
        tol_position=tol_position,
        tol_orientation=tol_orientation,
        names=names,
        groups=groups,
        envelope=TunnelEnvelope(profile),
        source=_SRC,
    )


def _feature_space(task: Task, direction_scale: float) -> FloatArray:
    return np.concatenate([task.positions, direction_scale * task.axes], axis=1)


def farthest_point_selection(
    features: ArrayLike, n: int, keep: Sequence[int] = ()
) -> NDArray[np.intp]:
    """Greedy farthest-point sampling: ``n`` row indices of ``features (N, d)``, starting
    from ``keep`` (or row 0), each next row the one farthest (Euclidean) from those
    chosen, ties to the lowest index. Deterministic; sorted result."""
    F = np.asarray(features, dtype=float)
    N = F.shape[0]
    if not 0 < n <= N:
        raise TaskError(_SRC, "n_points", f"must be in [1, {N}], got {n}")
    chosen = list(dict.fromkeys(int(i) for i in keep))
    if len(chosen) > n:
        raise TaskError(_SRC, "n_points", f"{n} is fewer than the {len(chosen)} kept points")
    if not chosen:
        chosen = [0]
    d = np.min(np.linalg.norm(F[:, None, :] - F[None, chosen, :], axis=2), axis=1)
    while len(chosen) < n:
        i = int(np.argmax(d))
        chosen.append(i)
        d = np.minimum(d, np.linalg.norm(F - F[i], axis=1))
    return np.sort(np.array(chosen, dtype=np.intp))


def plan_extremes(task: Task) -> NDArray[np.intp]:
    """Indices of a plan's extreme holes: leftmost, rightmost, highest collar and the
    hole steepest to the tunnel axis (the poses that bound what a boom must reach)."""
    P, A = task.positions, task.axes
    steep = np.arccos(np.clip(A[:, 0], -1.0, 1.0))
    ix = [
        int(np.argmax(P[:, 1])),
        int(np.argmin(P[:, 1])),
        int(np.argmax(P[:, 2])),
        int(np.argmax(steep)),
    ]
    return np.array(list(dict.fromkeys(ix)), dtype=np.intp)


def combine_plans(
    plans: Sequence[Task],
    n_points: int | None = None,
    *,
    keep_extremes: bool = True,
    direction_scale: float = 5.0,
    name: str = "combined",
    envelope: TunnelEnvelope | None = None,
) -> Task:
    """Several drill plans as one task, like the thesis's 10 plans → 87 points (P-I §4).

    All holes of all plans are pooled in the machine frame (names keep their plan id).
    With ``n_points``, the pool is down-selected deterministically: every plan's
    extremes (``plan_extremes``) are kept, then farthest-point sampling in the joint
    position + direction space ``[p, direction_scale · axis]`` (m; ``direction_scale``
    m per unit of axis difference ≈ per radian) adds the hole least like those already
    chosen until ``n_points`` — so the selection covers the union's extent and its
    range of directions with few near-duplicates. Points stay in pool order.
    """
    if not plans:
        raise TaskError(_SRC, "plans", "need at least one plan (empty task)")
    points: list[TaskPoint] = []
    keep: list[int] = []
    for t in plans:
        if keep_extremes:
            keep.extend(int(i) + len(points) for i in plan_extremes(t))
        points.extend(t.points)
    pool = Task(name, tuple(points), envelope)
    if n_points is None:
        return pool
    idx = farthest_point_selection(_feature_space(pool, direction_scale), n_points, keep)
    return pool.subset(idx)


def _inside(profile: TunnelProfile, envelope: TunnelEnvelope) -> bool:
    """True when the boundary of ``profile`` lies inside ``envelope``'s cross-section."""
    b = profile.boundary(0.2)
    return bool((envelope.profile.signed_distance_2d(b) >= -1e-9).all())


def _shape_area(aspect: float, arch_ratio: float) -> float:
    """Area of a unit-width profile with height ``aspect`` and arch rise ``arch_ratio``."""
    return TunnelProfile(1.0, aspect, arch_ratio).area


def tunnel_plans(
    n_plans: int = TUNNEL_87_PLANS,
    *,
    largest: TunnelProfile = TUNNEL_87_LARGEST,
    smallest_area: float = 20.0,
    seed: int = TUNNEL_87_SEED,
    dims: int = 6,
) -> tuple[Task, ...]:
    """A family of ``n_plans`` drill plans, faces from ``smallest_area`` m² up to
    ``largest`` (public stand-in for the thesis's 10 customer plans, P-I §4).

    Plan k (``"P01"`` … smallest first) has face area linearly spaced from
    ``smallest_area`` to ``largest.area``; its height/width ratio goes from 1.05 (small
    drifts are tall) to the largest's, its roof rise/width from 0.30 to the largest's;
    sizes round to 5 cm. The seed draws, per plan: the face distance ``face_x`` in
    5.5–8.5 m, a lateral offset of the tunnel from the machine (≤ 0.6 m, kept so the
    plan lies inside the largest profile, which sits on the centreline), the cut type
    (V or parallel) and its lateral position (±0.4 m), look-out 2–4°, hole depth
    3.5–5.2 m, contour spacing 0.55–0.85 m and 1 cm collar jitter. Every plan shares
    the largest's floor (the machine stands on it; ``floor_z = 0`` by default).
    """
    if int(n_plans) < 1:
        raise TaskError(_SRC, "n_plans", f"must be ≥ 1, got {n_plans}")
    if not 0 < smallest_area <= largest.area:
        raise TaskError(_SRC, "smallest_area", f"must be in (0, {largest.area:.1f}] m²")
    rng = np.random.default_rng(seed)
    n = int(n_plans)
    big_env = TunnelEnvelope(largest)
    plans = []
    for k in range(n):
        t = k / (n - 1) if n > 1 else 1.0
        if k == n - 1:
            prof = largest
        else:
            area = smallest_area + (largest.area - smallest_area) * t
            aspect = 1.05 + (largest.height / largest.width - 1.05) * t
            arch = 0.30 + (largest.arch_height / largest.width - 0.30) * t
            w = math.sqrt(area / _shape_area(aspect, arch))
            prof = TunnelProfile(
                round(w * 20) / 20,
                round(aspect * w * 20) / 20,
                round(arch * w * 20) / 20,
                largest.y_center,
                largest.floor_z,
            )
        face_x = round(float(rng.uniform(5.5, 8.5)), 1)
        shift = float(rng.uniform(-1.0, 1.0)) * min(0.6, max(largest.width - prof.width, 0) / 4)
        cut_v = bool(rng.random() < 0.5)
        cut_u = round(float(rng.uniform(-0.4, 0.4)), 2)
        lookout = math.radians(round(float(rng.uniform(2.0, 4.0)) * 2) / 2)
        depth = round(float(rng.uniform(3.5, 5.2)), 1)
        spacing = round(float(rng.uniform(0.55, 0.85)) * 20) / 20
        plan_seed = int(rng.integers(2**31))
        if k == n - 1:
            shift = 0.0
        # keep the plan inside the largest face: halve the offset until it fits
        p = prof.translated(dy=round(shift, 2))
        for _ in range(8):
            if _inside(p, big_env):
                break
            shift /= 2
            p = prof.translated(dy=round(shift, 2))
        else:
            p = prof
        cut_center = (cut_u, min(max(0.4 * p.height, 1.6), 3.0))
        plans.append(
            drilling_pattern(
                p,
                face_x=face_x,
                hole_depth=depth,
                lookout_angle=lookout,
                contour_spacing=spacing,
                cut_type="v" if cut_v else "parallel",
                cut_center=cut_center,
                jitter=0.01,
                seed=plan_seed,
                dims=dims,
                plan=f"P{k + 1:02d}",
            )
        )
    return tuple(plans)


def tunnel_87(seed: int = TUNNEL_87_SEED, dims: int = 6) -> Task:
    """The public stand-in for the thesis's tunnel task: 10 drill plans, 87 points.

    P-I §4: "The drilling pattern consisted of 87 task points; 10 real drill plans were
    chosen from actual customer cases and combined into a single set of task points",
    with six task-space coordinates (P-I §4, P-II §5); the plans are proprietary. Here:
    ``tunnel_plans(10, seed=seed, dims=dims)`` — faces from 20 to ≈56 m², 5.5–8.5 m
    ahead of the machine — combined by ``combine_plans(..., 87)`` (every plan's extremes
    plus farthest-point sampling in position + direction). The task's envelope is the
    largest face's tunnel (``TUNNEL_87_LARGEST`` on the centreline), which contains
    every plan. The built-in ``tunnel-87`` task file is this task.
    """
    plans = tunnel_plans(TUNNEL_87_PLANS, seed=seed, dims=dims)
    return combine_plans(
        plans,
        TUNNEL_87_POINTS,
        name="tunnel-87",
        envelope=TunnelEnvelope(TUNNEL_87_LARGEST),
    )


__all__ = [
    "TUNNEL_87_LARGEST",
    "TUNNEL_87_PLANS",
    "TUNNEL_87_POINTS",
    "TUNNEL_87_SEED",
    "ZONES",
    "CutType",
    "TunnelProfile",
    "combine_plans",
    "drilling_pattern",
    "farthest_point_selection",
    "plan_extremes",
    "roll_rotations",
    "tunnel_87",
    "tunnel_plans",
]
