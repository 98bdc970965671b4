"""The shared damped least squares: the P-I Eq. 14 schedule and the Eq. 3.6 pseudo-inverse
against their formulas written out with numpy."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from reachwise.kinematics.dls import damped_pinv, damped_solve, damping_squared

EPS = 0.05
LAM = 0.1


def test_schedule_at_zero_at_the_edge_and_outside() -> None:
    assert damping_squared(0.0, EPS, LAM) == pytest.approx(LAM**2, rel=1e-15)
    assert damping_squared(EPS, EPS, LAM) == 0.0
    assert damping_squared(2 * EPS, EPS, LAM) == 0.0
    assert damping_squared(1e3, EPS, LAM) == 0.0


@settings(max_examples=200, deadline=None)
@given(s=st.floats(0.0, 0.2), eps=st.floats(1e-3, 0.1), lam=st.floats(0.0, 1.0))
def test_schedule_is_eq_14(s: float, eps: float, lam: float) -> None:
    expect = (1.0 - (s / eps) ** 2) * lam**2 if s < eps else 0.0
    assert damping_squared(s, eps, lam) == pytest.approx(expect, rel=1e-12, abs=1e-300)


def test_schedule_is_continuous_and_monotone() -> None:
    s = np.linspace(0.0, 2 * EPS, 2001)
    lam2 = np.array([damping_squared(x, EPS, LAM) for x in s])
    assert np.all(np.diff(lam2) <= 0.0)  # damping falls as σ_min grows
    # no jump anywhere, in particular not at σ_min = ε: steps bounded by the slope
    slope = 2 * LAM**2 / EPS
    assert np.max(np.abs(np.diff(lam2))) <= slope * (s[1] - s[0]) * 1.0001
    below = damping_squared(EPS * (1 - 1e-9), EPS, LAM)
    assert 0.0 < below < 1e-9 * 2 * LAM**2 * 1.01


def _matrices() -> list[np.ndarray]:
    rng = np.random.default_rng(7)
    out = [rng.standard_normal((r, n)) for r, n in [(3, 7), (6, 6), (6, 8), (6, 4), (3, 2)]]
    # a singular one: two equal rows (wide) and a rank-deficient tall one
    A = rng.standard_normal((3, 5))
    A[2] = A[1]
    B = rng.standard_normal((6, 3))
    B[:, 2] = B[:, 0]
    return [*out, A, B, 1e-3 * rng.standard_normal((6, 7))]


@pytest.mark.parametrize("Phi", _matrices())
def test_pinv_is_eq_3_6(Phi: np.ndarray) -> None:
    r, n = Phi.shape
    d = damped_pinv(Phi, EPS, LAM, True)
    s = np.linalg.svd(Phi, compute_uv=False)
    assert d.sigma_min == pytest.approx(s.min(), abs=1e-7)
    lam2 = (1 - (s.min() / EPS) ** 2) * LAM**2 if s.min() < EPS else 0.0
    assert d.damping == pytest.approx(np.sqrt(lam2), abs=1e-7)
    if d.damping > 0 or r <= n:
        ref = Phi.T @ np.linalg.inv(Phi @ Phi.T + d.damping**2 * np.eye(r))
        if r > n:  # Φ Φᵀ is singular: the push-through form of the same inverse
            ref = np.linalg.inv(Phi.T @ Phi + d.damping**2 * np.eye(n)) @ Phi.T
        np.testing.assert_allclose(d.inverse, ref, atol=1e-9 * max(1.0, np.abs(ref).max()))
    # the exact projector: Φ⁺Φ, symmetric, idempotent, and Φ (I − P) = 0
    P = d.projector
    np.testing.assert_allclose(P, np.linalg.pinv(Phi, rcond=1e-10) @ Phi, atol=1e-8)
    np.testing.assert_allclose(P @ P, P, atol=1e-8)
    np.testing.assert_allclose(Phi @ (np.eye(n) - P), 0.0, atol=1e-10)


@pytest.mark.parametrize("Phi", _matrices()[:5])
def test_pinv_without_damping_is_numpys_pinv(Phi: np.ndarray) -> None:
    d = damped_pinv(Phi, 0.0, LAM, False)  # ε = 0: never inside the singular region
    assert d.damping == 0.0
    assert d.projector.shape == (0, 0)
    np.testing.assert_allclose(d.inverse, np.linalg.pinv(Phi), atol=1e-10)


def test_pinv_damps_a_singularity() -> None:
    Phi = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])  # σ_min = 0
    d = damped_pinv(Phi, EPS, LAM, False)
    assert d.sigma_min == 0.0 and d.damping == pytest.approx(LAM)
    expect = np.array([[1.0 / (1.0 + LAM**2), 0.0], [0.0, 0.0], [0.0, 0.0]])
    np.testing.assert_allclose(d.inverse, expect, atol=1e-15)


def test_wrong_types_are_refused() -> None:
    with pytest.raises(TypeError):
        damped_pinv(np.ones((3, 4), dtype=np.int64), EPS, LAM, False)
    with pytest.raises(TypeError):
        damped_pinv(np.ones((4, 6))[:, ::2], EPS, LAM, False)  # not C-contiguous


@pytest.mark.parametrize("Phi", _matrices())
def test_solve_applies_the_same_inverse_and_projector(Phi: np.ndarray) -> None:
    """``damped_solve`` is ``damped_pinv`` applied to one task and one secondary motion,
    checked against numpy: ``Φ̃⁺ e`` and ``z − pinv(Φ) Φ z``."""
    r, n = Phi.shape
    rng = np.random.default_rng(r * 10 + n)
    e, z = rng.standard_normal(r), rng.standard_normal(n)
    s = damped_solve(Phi, e, z, EPS, LAM)
    d = damped_pinv(Phi, EPS, LAM, True)
    assert (s.sigma_min, s.damping) == (d.sigma_min, d.damping)
    lam2 = s.damping**2
    ref = (
        np.linalg.solve(Phi.T @ Phi + lam2 * np.eye(n), Phi.T @ e)
        if lam2 > 0 or r > n
        else (Phi.T @ np.linalg.solve(Phi @ Phi.T, e))
    )
    np.testing.assert_allclose(s.step, ref, atol=1e-8 * max(1.0, np.abs(ref).max()))
    np.testing.assert_allclose(s.step, d.inverse @ e, atol=1e-8 * max(1.0, np.abs(ref).max()))
    np.testing.assert_allclose(
        s.null_motion, z - np.linalg.pinv(Phi, rcond=1e-10) @ Phi @ z, atol=1e-8
    )
    np.testing.assert_allclose(Phi @ s.null_motion, 0.0, atol=1e-9)
