"""The tunnel profile and envelope: exact signed distance against brute force, and its
gradient against finite differences."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from reachwise.errors import TaskError
from reachwise.tasks import TunnelEnvelope, TunnelProfile


def dense_boundary(p: TunnelProfile, step: float) -> np.ndarray:
    """The boundary polygon built from the profile's definition (not its code)."""
    hw, hwall, h = p.width / 2, p.height - p.arch_height, p.height
    n = lambda length: max(2, math.ceil(length / step) + 1)  # noqa: E731
    floor = np.column_stack([np.linspace(-hw, hw, n(p.width)), np.zeros(n(p.width))])
    right = np.column_stack([np.full(n(hwall), hw), np.linspace(0, hwall, n(hwall))])
    if p.arch_height > 1e-9 * p.width:
        a = p.arch_height
        r = (hw**2 + a**2) / (2 * a)
        vc = h - r
        t0 = math.atan2(hwall - vc, hw)
        th = np.linspace(t0, math.pi - t0, n(r * (math.pi - 2 * t0)))
        roof = np.column_stack([r * np.cos(th), vc + r * np.sin(th)])
    else:
        roof = np.column_stack([np.linspace(hw, -hw, n(p.width)), np.full(n(p.width), h)])
    left = np.column_stack([np.full(n(hwall), -hw), np.linspace(hwall, 0, n(hwall))])
    uv = np.concatenate([floor, right, roof, left])
    return uv + np.array([p.y_center, p.floor_z])


def point_in_polygon(q: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Even-odd ray casting, vectorized over the query points."""
    x, y = q[:, 0:1], q[:, 1:2]
    x0, y0 = poly[:, 0], poly[:, 1]
    x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
    cross = (y0 > y) != (y1 > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xi = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
    return np.asarray(np.sum(cross & (x < xi), axis=1) % 2 == 1)


def brute_signed_distance(p: TunnelProfile, q: np.ndarray, step: float = 2e-3) -> np.ndarray:
    poly = dense_boundary(p, step)
    d = np.min(np.linalg.norm(q[:, None, :] - poly[None, :, :], axis=2), axis=1)
    return np.where(point_in_polygon(q, poly), d, -d)


PROFILES = [
    TunnelProfile(6.0, 5.5, 1.8),
    TunnelProfile(4.5, 4.8, 2.25, y_center=0.4, floor_z=-1.2),  # semicircular roof
    TunnelProfile(8.0, 4.0, 0.0),  # flat roof
    TunnelProfile(11.5, 9.3, 3.0),
]


@pytest.mark.parametrize("profile", PROFILES)
def test_signed_distance_2d_matches_brute_force(profile: TunnelProfile) -> None:
    rng = np.random.default_rng(1)
    lo = np.array([profile.y_center - profile.width, profile.floor_z - 2])
    hi = np.array([profile.y_center + profile.width, profile.floor_z + profile.height + 2])
    q = rng.uniform(lo, hi, (400, 2))
    s = profile.signed_distance_2d(q)
    ref = brute_signed_distance(profile, q)
    assert np.abs(s - ref).max() < 2e-3
    assert (np.sign(s) == np.sign(ref))[np.abs(ref) > 2e-3].all()


profiles = st.builds(
    lambda w, hr, ar, yc, fz: TunnelProfile(w, hr * w, min(ar * w / 2, hr * w), yc, fz),
    st.floats(2.0, 14.0),
    st.floats(0.5, 1.5),
    st.floats(0.0, 1.0),
    st.floats(-2.0, 2.0),
    st.floats(-2.0, 2.0),
)


@settings(max_examples=40, deadline=None)
@given(profiles, st.integers(0, 2**31 - 1))
def test_signed_distance_property(profile: TunnelProfile, seed: int) -> None:
    rng = np.random.default_rng(seed)
    c = np.array([profile.y_center, profile.floor_z + profile.height / 2])
    q = c + rng.uniform(-1, 1, (60, 2)) * [profile.width, profile.height]
    s = profile.signed_distance_2d(q)
    ref = brute_signed_distance(profile, q, step=4e-3)
    assert np.abs(s - ref).max() < 4e-3


def test_boundary_points_have_zero_distance_and_area_matches_polygon() -> None:
    for p in PROFILES:
        b = p.boundary(0.01)
        assert np.abs(p.signed_distance_2d(b)).max() < 1e-12
        poly = dense_boundary(p, 1e-3)
        x, y = poly[:, 0], poly[:, 1]
        shoelace = 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
        assert p.area == pytest.approx(shoelace, rel=1e-5)
    semi = TunnelProfile(4.0, 5.0, 2.0)
    assert semi.area == pytest.approx(4.0 * 3.0 + math.pi * 4 / 2)
    assert semi.arch_radius == pytest.approx(2.0)
    assert semi.perimeter == pytest.approx(4 + 2 * 3 + math.pi * 2)


def fd_gradient(f, q: np.ndarray, h: float = 1e-6) -> np.ndarray:  # type: ignore[no-untyped-def]
    g = np.zeros_like(q)
    for j in range(q.shape[1]):
        e = np.zeros(q.shape[1])
        e[j] = h
        g[:, j] = (f(q + e) - f(q - e)) / (2 * h)
    return g


@pytest.mark.parametrize("profile", PROFILES)
def test_gradient_2d_matches_finite_differences(profile: TunnelProfile) -> None:
    rng = np.random.default_rng(2)
    q = rng.uniform(
        [profile.y_center - profile.width, profile.floor_z - 2],
        [profile.y_center + profile.width, profile.floor_z + profile.height + 2],
        (500, 2),
    )
    _, g, c = profile.closest_2d(q)
    assert np.allclose(np.linalg.norm(g, axis=1), 1.0)
    fd = fd_gradient(profile.signed_distance_2d, q)
    smooth = np.abs(np.linalg.norm(fd, axis=1) - 1) < 1e-6  # off the medial axis
    assert smooth.mean() > 0.95
    assert np.allclose(g[smooth], fd[smooth], atol=1e-5)
    # the closest point is on the boundary at the reported distance
    s = profile.signed_distance_2d(q)
    assert np.abs(profile.signed_distance_2d(c)).max() < 1e-9
    assert np.allclose(np.linalg.norm(q - c, axis=1), np.abs(s))


def test_gradient_on_the_boundary_is_the_inward_normal() -> None:
    p = TunnelProfile(6.0, 5.5, 1.8)
    _, g, _ = p.closest_2d(np.array([[0.0, 0.0], [3.0, 1.0], [-3.0, 1.0], [0.0, 5.5]]))
    assert np.allclose(g, [[0, 1], [-1, 0], [1, 0], [0, -1]])


def brute_envelope(env: TunnelEnvelope, q: np.ndarray, step: float = 0.05) -> np.ndarray:
    """3-D brute force: distance to samples of the lateral surface and both end caps."""
    p = env.profile
    x0, x1 = env.x_range[0], env.x_end
    curve = dense_boundary(p, step)
    xs = np.arange(x0, x1 + step / 2, step)
    lateral = np.column_stack([np.repeat(xs, len(curve)), np.tile(curve, (len(xs), 1))])
    gy, gz = np.meshgrid(
        np.arange(p.y_center - p.width / 2, p.y_center + p.width / 2 + step / 2, step),
        np.arange(p.floor_z, p.floor_z + p.height + step / 2, step),
    )
    g2 = np.column_stack([gy.ravel(), gz.ravel()])
    g2 = g2[point_in_polygon(g2, curve)]
    caps = [np.column_stack([np.full(len(g2), x), g2]) for x in (x0, x1)]
    surf = np.concatenate([lateral, *caps])
    d = np.array([np.min(np.linalg.norm(surf - qi, axis=1)) for qi in q])
    inside = point_in_polygon(q[:, 1:], curve) & (q[:, 0] >= x0) & (q[:, 0] <= x1)
    return np.where(inside, d, -d)


def test_envelope_signed_distance_matches_3d_brute_force() -> None:
    env = TunnelEnvelope(TunnelProfile(4.0, 4.0, 1.2, 0.3), x_range=(0.0, 3.0))
    rng = np.random.default_rng(3)
    q = rng.uniform([-1.5, -2.5, -1.0], [4.5, 3.0, 5.0], (150, 3))
    s = env.signed_distance(q)
    ref = brute_envelope(env, q)
    assert np.abs(s - ref).max() < 0.04


def test_envelope_face_and_open_ends() -> None:
    p = TunnelProfile(6.0, 5.5, 1.8)
    open_env = TunnelEnvelope(p)
    q = np.array([[100.0, 0.0, 2.0], [-50.0, 2.5, 1.0], [0.0, 4.0, 1.0]])
    assert np.allclose(open_env.signed_distance(q), p.signed_distance_2d(q[:, 1:]))
    face = TunnelEnvelope(p, face_x=7.0)
    assert face.x_end == 7.0
    s, g = face.signed_distance_and_gradient(np.array([[6.5, 0.0, 2.5], [7.5, 0.0, 2.5]]))
    assert np.allclose(s, [0.5, -0.5]) and np.allclose(g, [[-1, 0, 0], [-1, 0, 0]])
    # outside both the wall and the face: the distance to the edge
    s = face.signed_distance(np.array([[7.3, 3.4, 1.0]]))
    assert s[0] == pytest.approx(-0.5)
    assert face.contains(np.array([[6.5, 0.0, 2.5]]), margin=0.4).all()
    assert not face.contains(np.array([[6.5, 0.0, 2.5]]), margin=0.6).any()


def test_envelope_gradient_matches_finite_differences() -> None:
    env = TunnelEnvelope(TunnelProfile(6.0, 5.5, 1.8, -0.5, 0.2), x_range=(-3.0, 9.0), face_x=8.0)
    rng = np.random.default_rng(4)
    q = rng.uniform([-5, -5, -2], [10, 4, 8], (600, 3))
    _, g = env.signed_distance_and_gradient(q)
    assert np.allclose(np.linalg.norm(g, axis=1), 1.0)
    fd = fd_gradient(env.signed_distance, q)
    smooth = np.abs(np.linalg.norm(fd, axis=1) - 1) < 1e-6
    assert smooth.mean() > 0.9
    assert np.allclose(g[smooth], fd[smooth], atol=1e-5)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"width": -1.0, "height": 4.0, "arch_height": 1.0}, "width"),
        ({"width": 4.0, "height": 0.0, "arch_height": 0.0}, "height"),
        ({"width": 4.0, "height": 4.0, "arch_height": 2.5}, "arch_height"),
        ({"width": 6.0, "height": 2.0, "arch_height": 2.5}, "arch_height"),
        ({"width": 6.0, "height": 5.0, "arch_height": -0.1}, "arch_height"),
        ({"width": np.nan, "height": 5.0, "arch_height": 1.0}, "width"),
    ],
)
def test_invalid_profiles(kwargs: dict, field: str) -> None:
    with pytest.raises(TaskError) as info:
        TunnelProfile(**kwargs)
    assert info.value.field == field


def test_profile_from_arch_radius_and_envelope_errors() -> None:
    p = TunnelProfile.from_arch_radius(6.0, 5.5, 4.0)
    assert p.arch_radius == pytest.approx(4.0)
    with pytest.raises(TaskError, match="half the width"):
        TunnelProfile.from_arch_radius(6.0, 5.5, 2.0)
    with pytest.raises(TaskError, match="x_min < x_max"):
        TunnelEnvelope(p, x_range=(3.0, 1.0))
    with pytest.raises(TaskError, match="behind"):
        TunnelEnvelope(p, x_range=(3.0, 10.0), face_x=2.0)
    with pytest.raises(TaskError, match="shape"):
        TunnelEnvelope(p).signed_distance(np.zeros((4, 2)))
