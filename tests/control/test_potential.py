"""The repulsive speed (thesis Eq. 3.16–3.17), the velocity damper and the joint
velocity interval, checked against independent truth (finite differences of the
potential, the closed forms) through the very functions the compiled tick runs."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import reachwise
from reachwise.control import limits, potential
from reachwise.control.limits import (
    joint_velocity_interval,
    limit_scale,
    scale_into,
    velocity_bounds,
)
from reachwise.control.potential import (
    approach_bound,
    damper_bound,
    khatib_speed,
    moving_damper_bound,
    repulsive_potential,
    repulsive_speed,
)
from reachwise.control.tick import guard, joints, points
from reachwise.control.tick.points import active_points
from reachwise.control.tick.types import AvoidanceRows, AvoidanceSettings, Gains
from reachwise.kinematics._kernels import frames, tool_jacobian

Q = np.array([0.1, 0.3, 0.8, 0.3, 0.1, 0.4, 0.5, 0.8])


def test_the_tick_calls_the_documented_functions() -> None:
    """The compiled tick's modules hold the very functions tested here, not copies."""
    assert points.khatib_speed is potential.khatib_speed
    assert guard.damper_bound is potential.damper_bound
    assert guard.moving_damper_bound is potential.moving_damper_bound
    assert joints.joint_velocity_interval is limits.joint_velocity_interval
    assert joints.scale_into is limits.scale_into


@settings(max_examples=60, deadline=None)
@given(
    rho0=st.floats(0.05, 2.0),
    frac=st.floats(0.02, 0.98),
    mu=st.floats(1e-6, 1e-2),
)
def test_khatib_speed_is_the_negative_gradient_of_the_potential(
    rho0: float, frac: float, mu: float
) -> None:
    """Eq. 3.17 = −dU/dρ of Eq. 3.16, by central differences, inside the margin."""
    rho = frac * rho0
    h = 1e-7 * rho0
    dU = (repulsive_potential(rho + h, rho0, mu) - repulsive_potential(rho - h, rho0, mu)) / (2 * h)
    assert khatib_speed(rho, rho0, mu, np.inf) == pytest.approx(-float(dU), rel=1e-5)


def test_khatib_speed_edges() -> None:
    mu, r0, cap = 2e-4, 0.3, 1.0
    assert khatib_speed(0.31, r0, mu, cap) == 0.0  # beyond the margin
    assert khatib_speed(r0, r0, mu, cap) == 0.0  # at the margin the potential is flat
    assert khatib_speed(np.inf, r0, mu, cap) == 0.0  # "no risk"
    assert khatib_speed(np.nan, r0, mu, cap) == 0.0
    assert khatib_speed(0.0, r0, mu, cap) == cap  # touching: the cap
    assert khatib_speed(-0.01, r0, mu, cap) == cap  # overlapping: the cap
    assert khatib_speed(0.0, r0, 0.0, cap) == 0.0  # no potential, no speed
    # uncapped, touching is still finite (the speed at RHO_FLOOR)
    assert np.isfinite(khatib_speed(0.0, r0, mu, np.inf))
    # the cap is reached exactly where μ(1/ρ − 1/ρ_O)/ρ² = cap
    rho = 0.01
    assert khatib_speed(rho, r0, mu, cap) == pytest.approx(
        min(mu * (1 / rho - 1 / r0) / rho**2, cap)
    )


def test_array_form_is_the_scalar_form() -> None:
    rho = np.array([[0.02, 0.1], [0.29, 0.5]])
    want = np.array([[khatib_speed(r, 0.3, 1e-3, 2.0) for r in row] for row in rho])
    np.testing.assert_array_equal(repulsive_speed(rho, 0.3, 1e-3, 2.0), want)
    assert repulsive_speed(rho, 0.3, 1e-3).shape == (2, 2)
    assert np.isnan(repulsive_speed(np.nan, 0.3, 1e-3))  # array form: NaN stays visible
    b = approach_bound([0.04, 0.17, 0.3, 0.5, np.nan], 0.3, 0.04, 0.26)
    np.testing.assert_allclose(b[:3], [0.0, -0.13, -0.26])
    assert b[3] == -np.inf and np.isnan(b[4])


def test_damper_bounds_closed_form() -> None:
    r0, rs, xi = 0.3, 0.04, 0.26
    assert damper_bound(0.3, r0, rs, xi) == pytest.approx(-xi)
    assert damper_bound(0.17, r0, rs, xi) == pytest.approx(-xi * 0.5)
    assert damper_bound(0.02, r0, rs, xi) == 0.0  # inside the stop distance: hold
    assert damper_bound(0.31, r0, rs, xi) == -np.inf
    u = 0.1  # an obstacle approaching at 0.1 m/s
    assert moving_damper_bound(0.3, r0, rs, xi, u) == pytest.approx(u - xi)
    assert moving_damper_bound(rs, r0, rs, xi, u) == pytest.approx(u)
    # below ρ_s the bound keeps rising (the gap must open again), up to u + ξ
    assert moving_damper_bound(rs - 0.13, r0, rs, xi, u) == pytest.approx(u + 0.5 * xi)
    assert moving_damper_bound(-1.0, r0, rs, xi, u) == pytest.approx(u + xi)
    # a margin inside the stop distance does not divide by zero
    assert np.isfinite(damper_bound(0.03, 0.04, 0.04, xi))


def test_a_margin_inside_the_stop_distance_stops_at_half_the_margin() -> None:
    """A 2 cm margin against a 3 cm stop distance: the damper stops at 1 cm (half the
    margin), so a pair inside the margin may still approach (slower the closer it
    is) instead of being held everywhere within it; margins beyond twice the stop
    distance keep it."""
    xi = 0.15
    assert potential.stop_within(0.02, 0.03) == pytest.approx(0.01)
    assert potential.stop_within(0.3, 0.04) == 0.04
    assert damper_bound(0.02, 0.02, 0.03, xi) == pytest.approx(-xi)
    assert damper_bound(0.015, 0.02, 0.03, xi) == pytest.approx(-0.5 * xi)
    assert damper_bound(0.01, 0.02, 0.03, xi) == 0.0
    assert damper_bound(0.005, 0.02, 0.03, xi) == 0.0
    assert moving_damper_bound(0.01, 0.02, 0.03, xi, 0.1) == pytest.approx(0.1)


def test_push_out_keeps_every_bound_or_leaves_the_velocity_alone() -> None:
    """The guard's fallback instead of a freeze: cyclic projections onto the half-spaces
    ``g_i q̇ ≥ lo_i`` end with every active bound kept, the velocity changed only along
    the rows; the inactive row is ignored; an infeasible set (two opposite rows that
    must both open) leaves the velocity as it was and says so."""
    rng = np.random.default_rng(4)
    for _ in range(50):
        g = rng.normal(size=(3, 7))
        lo = np.array([0.0, 0.0, -0.05])
        qd = rng.normal(size=7)
        before = qd.copy()
        active = np.array([True, True, False])
        assert guard.push_out(qd, g, lo, active)
        assert np.all(g[:2] @ qd >= lo[:2] - 1e-12)
        # the change lies in the span of the active rows
        coef, *_ = np.linalg.lstsq(g[:2].T, qd - before, rcond=None)
        np.testing.assert_allclose(g[:2].T @ coef, qd - before, atol=1e-12)
    g = np.array([[1.0, 0.0], [-1.0, 0.0]])
    qd = np.array([0.3, 0.2])
    assert not guard.push_out(qd, g, np.array([0.1, 0.1]), np.array([True, True]))
    np.testing.assert_array_equal(qd, [0.3, 0.2])


def test_joint_velocity_interval() -> None:
    lo, hi = velocity_bounds([0.0, 0.95, -2.0, 2.0], -1.0, 1.0, 0.5, 2.0)
    np.testing.assert_allclose(hi, [0.5, 0.1, 0.5, 0.0])
    np.testing.assert_allclose(lo, [-0.5, -0.5, 0.0, -0.5])
    assert joint_velocity_interval(-0.98, -1.0, 1.0, 0.5, 2.0) == pytest.approx((-0.04, 0.5))


def test_scale_into_brings_the_scaled_velocity_onto_the_bound() -> None:
    lo, hi = -0.5, 0.1
    for top in (1.0, 0.6):
        for qd in (0.4, -2.0, 0.05, 0.0):
            a = scale_into(top * qd, lo, hi, top)
            assert 0.0 <= a <= top
            assert lo - 1e-12 <= a * qd <= hi + 1e-12
            if not lo <= top * qd <= hi:  # the largest factor: on the bound it crossed
                assert a * qd == pytest.approx(hi if qd > 0 else lo)
            else:
                assert a == top
    assert limit_scale([1.0, 0.05, 0.0], [-0.5, -0.5, 0.0], [0.5, 0.1, 0.5]) == pytest.approx(0.5)


@pytest.fixture(scope="module")
def sb60() -> reachwise.Robot:
    return reachwise.load_robot("sb60")


def test_the_ticks_avoidance_points_repel_at_the_khatib_speed(sb60: reachwise.Robot) -> None:
    """``active_points`` (what the controller runs) against Eq. 3.17 written out here."""
    chain = sb60.arrays
    N = chain.kind.shape[0]
    F = np.empty((N + 2, 4, 4))
    frames(chain.kind, chain.qidx, chain.dh, chain.classic, chain.base, chain.tool, Q, F)
    Jg = np.empty((6, sb60.n))
    tool_jacobian(chain.kind, chain.qidx, chain.classic, F, sb60.n, Jg)
    k = sb60.link_index("link_5")
    dist = np.array([0.0, 0.02, 0.1, 0.29, 0.3, 0.4])
    m = dist.size
    rows = AvoidanceRows(
        a_link=np.full(m, k),
        a_point=np.repeat(F[k, :3, 3][None], m, axis=0),
        b_link=np.full(m, -1),
        b_point=np.full((m, 3), np.nan),
        normal=np.repeat(np.array([[0.0, 0.0, 1.0]]), m, axis=0),
        obstacle_velocity=np.zeros((m, 3)),
        distance=dist,
        margin=np.full(m, 0.3),
        task_space=np.zeros(m, np.bool_),
    )
    mu, cap = 2e-4, 1.0
    gains = Gains(1.0, 1.0, 0.5, 0.3, 0.05, 0.05, mu, cap, 2.0)
    settings_ = AvoidanceSettings(True, True, 0.04, 0.5, 0.0, True)
    pts = active_points(
        chain, np.zeros(sb60.n, np.bool_), F, Jg, rows, np.zeros(m, np.bool_), m, gains, settings_
    )
    with np.errstate(divide="ignore"):
        want = np.where(dist <= 0.3, mu * (1 / dist - 1 / 0.3) / dist**2, 0.0)
    want = np.minimum(np.where(dist <= 0.0, np.inf, want), cap)
    np.testing.assert_allclose(pts.vrep, want, rtol=1e-12)
    np.testing.assert_array_equal(pts.active, dist <= 0.3)
