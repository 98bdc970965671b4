"""Tunnel-face drilling patterns and the tunnel-87 stand-in: the geometry each zone
must have, determinism, and the 10 plans → 87 points combination (P-I §4)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from reachwise.errors import TaskError
from reachwise.tasks import (
    TUNNEL_87_LARGEST,
    ZONES,
    ContourLayout,
    CutLayout,
    DrillLayout,
    LifterLayout,
    Task,
    TunnelProfile,
    combine_plans,
    drilling_pattern,
    farthest_point_selection,
    plan_extremes,
    tunnel_87,
    tunnel_plans,
)

PROFILE = TunnelProfile(8.0, 7.0, 2.2, y_center=0.3)
LOOKOUT = math.radians(3.0)


@pytest.fixture(scope="module")
def plan() -> Task:
    return drilling_pattern(PROFILE, face_x=7.5, lookout_angle=LOOKOUT, contour_spacing=0.7)


def zone(task: Task, name: str) -> np.ndarray:
    return task.group_indices()[name]


def angle_from_x(axes: np.ndarray) -> np.ndarray:
    return np.arccos(np.clip(axes[:, 0], -1, 1))


def spread(axes: np.ndarray) -> float:
    return float(np.arccos(np.clip((axes @ axes.T).min(), -1, 1)))


def test_every_collar_is_on_the_face_and_inside_the_profile(plan: Task) -> None:
    assert np.allclose(plan.positions[:, 0], 7.5)
    assert (PROFILE.signed_distance_2d(plan.positions[:, 1:]) > 0.1).all()
    assert plan.envelope is not None and plan.envelope.profile == PROFILE
    assert (plan.dims == 5).all() and set(plan.groups) == set(ZONES)
    assert len(set(plan.names)) == len(plan) and plan.names[0] == "P01/cut01"
    assert (plan.axes[:, 0] > 0.8).all()  # every hole drills into the face


def test_zone_counts_of_an_8m_face(plan: Task) -> None:
    counts = {g: len(ix) for g, ix in plan.group_indices().items()}
    assert counts["cut"] == 16  # 4 rows × 2 pairs × 2 sides
    assert counts["lifter"] == 9  # 7.7 m of floor at ≈1 m
    assert 22 <= counts["contour"] <= 28  # ≈17 m of walls and roof at ≤ 0.7 m
    assert 15 <= counts["stoping"] <= 40
    assert 55 <= len(plan) <= 110  # ≈1.1–2 holes per m² on a 51 m² face


def test_contour_spacing_offset_and_lookout(plan: Task) -> None:
    ix = zone(plan, "contour")
    yz = plan.positions[ix, 1:]
    gaps = np.linalg.norm(np.diff(yz, axis=0), axis=1)
    assert 0.5 <= gaps.min() and gaps.max() <= 1.0
    assert np.allclose(PROFILE.signed_distance_2d(yz), 0.15, atol=1e-9)
    A = plan.axes[ix]
    assert np.allclose(angle_from_x(A), LOOKOUT, atol=1e-9)
    # outward: stepping along the hole leaves the profile (distance decreases); the
    # look-out is normal to the wall or roof, at the two corners it bisects them
    _, g_in, _ = PROFILE.closest_2d(yz)
    out = -np.sum(A[:, 1:] * g_in, axis=1) / math.sin(LOOKOUT)
    assert (out > 0.7).all() and np.isclose(out, 1.0).sum() == len(ix) - 2
    # the contour runs along the walls and the roof, not the floor
    assert yz[:, 1].min() > 0.8 and 6.8 < yz[:, 1].max() <= 7.0 - 0.15


def test_lifters_along_the_floor_angled_down(plan: Task) -> None:
    ix = zone(plan, "lifter")
    P, A = plan.positions[ix], plan.axes[ix]
    assert np.allclose(P[:, 2], 0.25)
    assert P[:, 1].min() == pytest.approx(0.3 - 3.85) and P[:, 1].max() == pytest.approx(0.3 + 3.85)
    assert np.allclose(np.arcsin(-A[1:-1, 2]), LOOKOUT)  # down by the look-out
    assert A[0, 1] < 0 < A[-1, 1]  # corner lifters also outward


def test_cut_is_central_with_the_widest_angle_spread(plan: Task) -> None:
    ix = zone(plan, "cut")
    P = plan.positions[ix]
    center = np.array([0.3, 0.4 * 7.0])
    assert np.allclose(P[:, 1:].mean(axis=0), center)
    assert np.linalg.norm(P[:, 1:] - center, axis=1).max() < 3.0
    spreads = {g: spread(plan.axes[i]) for g, i in plan.group_indices().items()}
    assert spreads["cut"] == max(spreads.values())
    assert spreads["cut"] > math.radians(45)  # V pairs at ±30° and the vertical tilt
    assert angle_from_x(plan.axes[ix]).max() == pytest.approx(
        math.atan(math.hypot(math.tan(math.radians(30)), math.tan(math.radians(6)))), abs=1e-9
    )
    # the V converges: holes left of the cut's plane point right and vice versa
    du = P[:, 1] - center[0]
    assert (np.sign(plan.axes[ix, 1]) == -np.sign(du)).all()


def test_stoping_holes_are_parallel_and_clear_of_contour_and_cut(plan: Task) -> None:
    ix = zone(plan, "stoping")
    assert np.allclose(plan.axes[ix], [1, 0, 0])
    yz = plan.positions[ix, 1:]
    assert (PROFILE.signed_distance_2d(yz) >= 0.95 - 1e-9).all()
    cut = plan.positions[zone(plan, "cut"), 1:]
    d = np.linalg.norm(yz[:, None] - cut[None], axis=2)
    assert d.min() > 0.5


def test_parallel_cut() -> None:
    t = drilling_pattern(PROFILE, cut_type="parallel", cut_center=(-0.5, 2.0))
    ix = zone(t, "cut")
    assert len(ix) == 18
    assert np.allclose(t.axes[ix], [1, 0, 0])
    P = t.positions[ix, 1:]
    assert np.allclose(P.mean(axis=0), [0.3 - 0.5, 2.0])
    assert np.linalg.norm(P - [-0.2, 2.0], axis=1).max() == pytest.approx(1.2)


def test_six_d_adds_the_feed_roll(plan: Task) -> None:
    t = drilling_pattern(PROFILE, face_x=7.5, lookout_angle=LOOKOUT, dims=6)
    assert (t.dims == 6).all()
    assert np.allclose(t.axes, plan.axes) and np.allclose(t.positions, plan.positions)
    R = t.rotations
    assert np.allclose(np.einsum("kij,kil->kjl", R, R), np.eye(3), atol=1e-12)
    assert np.allclose(np.linalg.det(R), 1.0)
    # tool x points toward the interior: the inward normal of the nearest wall, roof or
    # floor, made normal to the hole
    _, g_in, _ = PROFILE.closest_2d(t.positions[:, 1:])
    g = np.column_stack([np.zeros(len(t)), g_in])
    x = g - np.sum(g * t.axes, axis=1, keepdims=True) * t.axes
    assert np.allclose(R[:, :, 0], x / np.linalg.norm(x, axis=1, keepdims=True))


def test_determinism_and_the_seed() -> None:
    a = drilling_pattern(PROFILE, jitter=0.02, seed=5)
    b = drilling_pattern(PROFILE, jitter=0.02, seed=5)
    c = drilling_pattern(PROFILE, jitter=0.02, seed=6)
    assert np.array_equal(a.poses, b.poses) and a.names == b.names
    assert not np.allclose(a.positions, c.positions)
    assert np.abs(a.positions - drilling_pattern(PROFILE).positions).max() <= 0.04 + 1e-12
    assert np.array_equal(drilling_pattern(PROFILE, seed=1).poses, drilling_pattern(PROFILE).poses)


@pytest.mark.parametrize(
    "profile",
    [TunnelProfile(4.4, 4.8, 1.3), TunnelProfile(6.0, 5.0, 0.0), TunnelProfile(7.0, 6.0, 3.5)],
    ids=["narrow", "flat-roof", "semicircle"],
)
def test_other_shapes(profile: TunnelProfile) -> None:
    t = drilling_pattern(profile, face_x=6.0)
    assert (profile.signed_distance_2d(t.positions[:, 1:]) > 0.1).all()
    ix = zone(t, "contour")
    gaps = np.linalg.norm(np.diff(t.positions[ix, 1:], axis=0), axis=1)
    assert 0.5 <= gaps.min() and gaps.max() <= 1.0
    assert spread(t.axes[zone(t, "cut")]) == max(
        spread(t.axes[i]) for i in t.group_indices().values()
    )


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"lookout_angle": math.radians(20)}, "lookout_angle"),
        ({"hole_depth": 0.0}, "hole_depth"),
        ({"contour_spacing": -0.7}, "contour_spacing"),
        ({"cut_type": "burn"}, "cut_type"),
        ({"cut_center": (3.9, 2.0)}, "cut_center"),
        ({"dims": 3}, "dims"),
        ({"face_x": math.nan}, "face_x"),
        ({"jitter": 0.5}, "jitter"),
    ],
)
def test_invalid_pattern_arguments(kwargs: dict, field: str) -> None:
    with pytest.raises(TaskError) as info:
        drilling_pattern(PROFILE, **kwargs)
    assert info.value.field == field


def test_too_narrow_a_tunnel_is_an_error() -> None:
    with pytest.raises(TaskError, match="too narrow"):
        drilling_pattern(TunnelProfile(1.5, 3.0, 0.5))


def test_farthest_point_selection() -> None:
    F = np.array([[0.0], [1.0], [10.0], [4.0], [6.0]])
    assert farthest_point_selection(F, 2).tolist() == [0, 2]
    assert farthest_point_selection(F, 3).tolist() == [0, 2, 3]  # 4 and 6 tie: lowest index
    assert farthest_point_selection(F, 3, keep=[1]).tolist() == [1, 2, 4]
    with pytest.raises(TaskError):
        farthest_point_selection(F, 1, keep=[0, 1])


@pytest.fixture(scope="module")
def plans() -> tuple[Task, ...]:
    return tunnel_plans()


def test_tunnel_plans_family(plans: tuple[Task, ...]) -> None:
    assert len(plans) == 10
    areas = [t.envelope.profile.area for t in plans if t.envelope is not None]
    assert areas[0] == pytest.approx(20, abs=1)
    assert areas[-1] == pytest.approx(TUNNEL_87_LARGEST.area)
    assert np.all(np.diff(areas) > 0)
    big = plans[-1].envelope
    assert big is not None and big.profile == TUNNEL_87_LARGEST
    for t in plans:
        x = t.positions[0, 0]
        assert 5.5 <= x <= 8.5 and np.allclose(t.positions[:, 0], x)
        assert (big.signed_distance(t.positions) > 0.1).all()
        assert set(t.groups) == set(ZONES) and (t.dims == 6).all()


def test_tunnel_87(plans: tuple[Task, ...]) -> None:
    t = tunnel_87()
    assert len(t) == 87 and t.name == "tunnel-87" and (t.dims == 6).all()
    assert np.array_equal(t.poses, tunnel_87().poses)  # deterministic
    assert set(t.groups) == set(ZONES)
    plan_ids = {n.split("/")[0] for n in t.names}
    assert len(plan_ids) == 10  # every plan contributes
    # covers several plan sizes: points from faces under 40 m² and over 80 m²
    area = {f"P{k + 1:02d}": p.envelope.profile.area for k, p in enumerate(plans) if p.envelope}
    used = [area[n.split("/")[0]] for n in t.names]
    assert min(used) < 30 and max(used) > 0.95 * TUNNEL_87_LARGEST.area
    # every plan's extremes are kept
    names = set(t.names)
    for p in plans:
        assert {p.names[i] for i in plan_extremes(p)} <= names
    # the task's envelope (the largest face) contains every point; faces 5.5–8.5 m ahead
    assert t.envelope is not None and (t.envelope.signed_distance(t.positions) > 0.1).all()
    assert 5.5 <= t.positions[:, 0].min() and t.positions[:, 0].max() <= 8.5
    # the cut holes keep the widest range of directions
    spreads = {g: spread(t.axes[i]) for g, i in t.group_indices().items()}
    assert spreads["cut"] == max(spreads.values())


def test_combine_plans_pools_or_selects(plans: tuple[Task, ...]) -> None:
    pool = combine_plans(plans[:3])
    assert len(pool) == sum(len(p) for p in plans[:3])
    sel = combine_plans(plans[:3], 30, name="three")
    assert len(sel) == 30 and sel.name == "three"
    assert set(sel.names) <= set(pool.names)
    with pytest.raises(TaskError, match="empty task"):
        combine_plans([])
    other = tunnel_87(seed=1)
    assert len(other) == 87 and not np.allclose(other.positions, tunnel_87().positions)


def test_a_layout_and_the_same_keywords_give_the_same_plan() -> None:
    layout = DrillLayout(
        face_x=6.5,
        cut=CutLayout(type="parallel", center=(-0.5, 2.0)),
        contour=ContourLayout(spacing=0.8, lookout_angle=math.radians(2.0)),
        lifters=LifterLayout(angle=0.1),
        jitter=0.02,
    )
    a = drilling_pattern(PROFILE, layout, seed=3, dims=6)
    b = drilling_pattern(
        PROFILE,
        face_x=6.5,
        cut_type="parallel",
        cut_center=(-0.5, 2.0),
        contour_spacing=0.8,
        lookout_angle=math.radians(2.0),
        lifter_angle=0.1,
        jitter=0.02,
        seed=3,
        dims=6,
    )
    assert np.array_equal(a.poses, b.poses) and a.names == b.names
    # a keyword replaces one field of a given layout, the rest stays
    c = drilling_pattern(PROFILE, layout, seed=3, dims=6, face_x=8.0)
    np.testing.assert_allclose(c.positions[:, 0], 8.0)
    np.testing.assert_array_equal(c.positions[:, 1:], a.positions[:, 1:])
    assert drilling_pattern(PROFILE, DrillLayout()).poses.tobytes() == (
        drilling_pattern(PROFILE).poses.tobytes()
    )


def test_layout_groups_check_their_fields() -> None:
    with pytest.raises(TaskError) as info:
        ContourLayout(spacing=0.0)
    assert info.value.field == "contour_spacing"
    with pytest.raises(TaskError) as info:
        CutLayout(angle=math.radians(70))
    assert info.value.field == "cut_angle"
    with pytest.raises(TaskError) as info:
        DrillLayout(contour=ContourLayout(offset=0.1), jitter=0.03)  # > offset / 4
    assert info.value.field == "jitter"
    with pytest.raises(TypeError, match="cut_kind"):
        drilling_pattern(PROFILE, cut_kind="v")  # type: ignore[call-arg]
