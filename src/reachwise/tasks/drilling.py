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
from typing import Unpack

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.errors import TaskError
from reachwise.tasks.drill_layout import (
    ContourLayout,
    CutLayout,
    CutType,
    DrillLayout,
    LayoutKeywords,
    LifterLayout,
    StopingLayout,
    layout_with,
)
from reachwise.tasks.drill_zones import (
    Holes,
    contour_holes,
    lifter_holes,
    parallel_cut,
    row_half_width,
    stoping_holes,
    v_cut,
)
from reachwise.tasks.task import (
    DEFAULT_TOL_ORIENTATION,
    DEFAULT_TOL_POSITION,
    Task,
    TaskPoint,
)
from reachwise.tasks.workspace import TunnelEnvelope, TunnelProfile

FloatArray = NDArray[np.float64]
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
    layout: DrillLayout | None = None,
    *,
    seed: int | np.random.Generator | None = 0,
    dims: int = 5,
    plan: str = "P01",
    name: str | None = None,
    tol_position: float = DEFAULT_TOL_POSITION,
    tol_orientation: float = DEFAULT_TOL_ORIENTATION,
    **keywords: Unpack[LayoutKeywords],
) -> Task:
    """One tunnel-face drill plan as a task (public stand-in for P-I §4's customer plans).

    ``layout`` (:class:`~reachwise.tasks.drill_layout.DrillLayout`, default: its
    defaults) holds the rules; flat ``keywords`` (``face_x=7.5``,
    ``contour_spacing=0.7``, ``cut_type="parallel"``, …; see
    ``LayoutKeywords``) replace single fields of it.
    Every hole is collared on the face plane ``x = face_x`` (m ahead of the machine
    origin) inside ``profile``; its direction is the tool z axis. Zones (each point's
    ``group``; ``name`` is ``"{plan}/{zone}{k:02d}"``):

    * ``cut`` around the cut centre (profile coordinates; default: the centreline,
      ``clip(0.4·height, 1.6, 3.0)`` m above the floor). A V-cut has the widest range
      of directions on the face; a parallel cut is 18 holes along the tunnel axis
      (2 empty relief holes).
    * ``stoping``: rows along the tunnel axis at least ``contour offset + contour
      burden`` inside the profile and clear of the cut; those beside the cut break
      horizontally into it, those above it downward (firing order, not geometry).
    * ``contour``: along walls and roof (0.5–1 m apart is usual; corners get a hole
      bisecting wall and roof), each tilted outward by the look-out angle so the hole
      bottom reaches ``≈ hole_depth·tan(lookout)`` past the collar line.
    * ``lifter``: along the floor, angled down (default: by the look-out), corner
      lifters also outward by the look-out.

    The hole depth sets the V-cut depths (which shrink if the tunnel is too narrow
    for them). The jitter (m) perturbs collars in the face plane (N(0, jitter) clipped
    to ±2σ, seeded by ``seed``) like a real plan's irregular holes. ``dims=6`` adds the
    feed roll (:func:`roll_rotations`: tool x toward the tunnel interior).
    """
    if not isinstance(profile, TunnelProfile):
        raise TaskError(_SRC, "profile", "must be a TunnelProfile")
    lay = layout_with(layout if layout is not None else DrillLayout(), **keywords)
    if dims not in (5, 6):
        raise TaskError(_SRC, "dims", f"must be 5 or 6, got {dims}")
    zones = _zones(profile, lay)
    uv = np.concatenate([z.uv for z in zones.values()])
    axes = np.concatenate([z.axis for z in zones.values()])
    groups = [g for g, z in zones.items() for _ in range(len(z.uv))]
    names = [f"{plan}/{g}{k + 1:02d}" for g, z in zones.items() for k in range(len(z.uv))]
    if lay.jitter > 0:
        rng = np.random.default_rng(seed)
        j = lay.jitter
        uv = uv + np.clip(rng.normal(0.0, j, uv.shape), -2 * j, 2 * j)
    yz = uv + np.array([profile.y_center, profile.floor_z])
    pos = np.column_stack([np.full(len(yz), lay.face_x), yz])
    rot = roll_rotations(profile, yz, axes) if dims == 6 else None
    task_name = name if name is not None else f"tunnel-{profile.width:g}x{profile.height:g}-{plan}"
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


def _cut(profile: TunnelProfile, lay: DrillLayout) -> Holes:
    """The cut's holes, checked to lie inside the stoping region and the profile."""
    cut, contour = lay.cut, lay.contour
    if cut.center is None:
        cc = (0.0, min(max(0.4 * profile.height, 1.6), 3.0))
    else:
        cc = cut.center
    room = row_half_width(profile, contour.offset + contour.burden, cc[1])
    if room <= abs(cc[0]):
        raise TaskError(_SRC, "cut_center", f"{cc} is not inside the stoping region")
    if cut.type == "v":
        holes = v_cut(
            cc,
            cut.rows,
            cut.pairs,
            cut.row_pitch,
            cut.angle,
            cut.vertical_angle,
            lay.hole_depth,
            room - abs(cc[0]),
        )
    else:
        holes = parallel_cut(cc)
    s_cut = profile.signed_distance_2d(holes.uv + np.array([profile.y_center, profile.floor_z]))
    if (s_cut < contour.offset).any():
        raise TaskError(_SRC, "cut_center", f"the cut at {cc} does not fit inside the profile")
    return holes


def _zones(profile: TunnelProfile, lay: DrillLayout) -> dict[str, Holes]:
    """The holes of every zone (:data:`ZONES` order) for ``lay`` on ``profile``."""
    contour, lifters, stoping = lay.contour, lay.lifters, lay.stoping
    if lifters.height >= profile.wall_height:
        raise TaskError(_SRC, "lifter_height", "lifters must be below the wall tops")
    if 2 * (contour.offset + contour.burden) >= profile.width:
        raise TaskError(_SRC, "profile", f"tunnel {profile.width} m wide is too narrow")
    cut = _cut(profile, lay)
    clear = 0.5
    box = (
        float(cut.uv[:, 0].min()) - clear,
        float(cut.uv[:, 0].max()) + clear,
        float(cut.uv[:, 1].min()) - clear,
        float(cut.uv[:, 1].max()) + clear,
    )
    return {
        "cut": cut,
        "stoping": stoping_holes(
            profile,
            contour.offset + contour.burden,
            lifters.height + stoping.burden,
            stoping.burden,
            stoping.spacing,
            box,
        ),
        "contour": contour_holes(
            profile,
            contour.offset,
            lifters.height + contour.spacing,
            contour.spacing,
            contour.lookout_angle,
        ),
        "lifter": lifter_holes(
            profile,
            contour.offset,
            lifters.height,
            lifters.spacing,
            lay.lifter_angle,
            contour.lookout_angle,
        ),
    }


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


def _plan_profile(k: int, n: int, largest: TunnelProfile, smallest_area: float) -> TunnelProfile:
    """The face of plan ``k`` of ``n`` (see :func:`tunnel_plans`): its area linearly
    spaced from ``smallest_area`` (m²) to the largest's, its height/width from 1.05 to
    the largest's, its roof rise/width from 0.30 to the largest's; sizes round to 5 cm.
    The last plan's face is ``largest`` itself."""
    if k == n - 1:
        return largest
    t = k / (n - 1)
    area = smallest_area + (largest.area - smallest_area) * t
    aspect = 1.05 + (largest.height / largest.width - 1.05) * t
    arch = 0.30 + (largest.arch_height / largest.width - 0.30) * t
    w = math.sqrt(area / _shape_area(aspect, arch))
    return TunnelProfile(
        round(w * 20) / 20,
        round(aspect * w * 20) / 20,
        round(arch * w * 20) / 20,
        largest.y_center,
        largest.floor_z,
    )


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
        prof = _plan_profile(k, n, largest, smallest_area)
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
                DrillLayout(
                    face_x=face_x,
                    hole_depth=depth,
                    cut=CutLayout(type="v" if cut_v else "parallel", center=cut_center),
                    contour=ContourLayout(spacing=spacing, lookout_angle=lookout),
                    jitter=0.01,
                ),
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
    "ContourLayout",
    "CutLayout",
    "CutType",
    "DrillLayout",
    "LayoutKeywords",
    "LifterLayout",
    "StopingLayout",
    "TunnelProfile",
    "combine_plans",
    "drilling_pattern",
    "farthest_point_selection",
    "plan_extremes",
    "roll_rotations",
    "tunnel_87",
    "tunnel_plans",
]
