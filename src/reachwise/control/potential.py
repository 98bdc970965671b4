"""Khatib's repulsive potential (thesis Eq. 3.16–3.17, P-V Eq. 4–5) and the velocity
damper that keeps a pair from closing in faster than it can still stop.

Thesis Eq. 3.16: ``U = ½ μ (1/ρ − 1/ρ_O)²`` for ``ρ ≤ ρ_O``, 0 beyond (P-V Eq. 4
prints the same potential without the square; its gradient, P-V Eq. 5, is the one of
the squared form). Its negative gradient along the collision line (thesis Eq. 3.17,
P-V Eq. 5) is the repulsive speed of the avoidance point,
``v = μ (1/ρ − 1/ρ_O) / ρ²``, directed from the obstacle's closest point to the
robot's (the distance query's ``direction``).

The velocity damper (Faverjon & Tournassoud 1987, not in the thesis) bounds the rate
at which the distance may shrink: ``ρ̇ ≥ −ξ (ρ − ρ_s) / (ρ_O − ρ_s)``; at the margin
the pair may approach at ``ξ``, at the stop distance ``ρ_s`` not at all (a pair whose
margin is not beyond twice the stop distance uses half its margin,
:func:`stop_within`). The
controller uses it as a guard on top of Eq. 3.18 (see ``controller``).

Each formula is written once, as a compiled scalar function that the controller's
tick calls (:func:`khatib_speed`, :func:`damper_bound`, :func:`moving_damper_bound`);
:func:`repulsive_speed` and :func:`approach_bound` apply the same functions to
arrays, so a test of either checks the code the controller runs.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "RHO_FLOOR",
    "approach_bound",
    "damper_bound",
    "khatib_speed",
    "moving_damper_bound",
    "repulsive_potential",
    "repulsive_speed",
    "stop_within",
]

#: Smallest distance (m) the repulsive speed is evaluated at: a touching or
#: overlapping pair (``ρ ≤ 1 µm``) repels at the speed of ``ρ = 1 µm`` (in practice
#: the cap), a finite number however small the gain.
RHO_FLOOR = 1e-6

#: Smallest span ``ρ_O − ρ_s`` (m) of the velocity damper (a margin at or inside the
#: stop distance would divide by zero).
_SPAN_FLOOR = 1e-9


@njit(cache=True)
def khatib_speed(rho, rho0, mu, v_max):  # type: ignore[no-untyped-def]
    """Repulsive speed ``min(μ (1/ρ − 1/ρ_O) / ρ², v_max)`` (m/s) of one avoidance
    point at distance ``ρ`` (m) inside the margin ``ρ_O`` (m), 0 beyond or for a NaN
    distance (thesis Eq. 3.17, P-V Eq. 5: the magnitude of ``−∇U`` of Eq. 3.16 along
    the collision line). ``μ`` (m⁴/s) is Khatib's coefficient; ``ρ`` is floored at
    :data:`RHO_FLOOR`, so touching gives a finite speed (the cap ``v_max``)."""
    if not (rho <= rho0):
        return 0.0
    r = max(rho, RHO_FLOOR)
    v = mu * (1.0 / r - 1.0 / rho0) / (r * r)
    return min(v, v_max)


@njit(cache=True)
def stop_within(rho0, rho_stop):  # type: ignore[no-untyped-def]
    """The stop distance the damper of a pair with margin ``ρ_O`` uses:
    ``min(ρ_s, ρ_O / 2)``. A margin at or inside the configured stop distance (a self
    pair's 2 cm margin against a 3 cm stop distance) would otherwise forbid any
    approach anywhere within the margin, so a pair that starts inside it holds the
    whole arm still instead of being pushed out by its repulsion."""
    return min(rho_stop, 0.5 * rho0)


@njit(cache=True)
def damper_bound(rho, rho0, rho_stop, xi):  # type: ignore[no-untyped-def]
    """Lowest allowed distance rate ``ρ̇_min = −ξ (ρ − ρ_s)/(ρ_O − ρ_s)`` (m/s, ≤ 0) of
    the velocity damper: ``−ξ`` at the margin ``ρ_O``, 0 at and below the stop
    distance ``ρ_s``; ``−inf`` (no bound) beyond the margin. ``ξ`` (m/s) is the
    approach speed allowed at the margin."""
    if rho > rho0:
        return -np.inf
    rs = stop_within(rho0, rho_stop)
    span = max(rho0 - rs, _SPAN_FLOOR)
    frac = min(max((rho - rs) / span, 0.0), 1.0)
    return -xi * frac


@njit(cache=True)
def moving_damper_bound(rho, rho0, rho_stop, xi, u):  # type: ignore[no-untyped-def]
    """Lowest rate ``n_iᵀ J_Oi q̇`` (m/s) allowed against an obstacle approaching at
    ``u`` (m/s) along the collision line: the velocity damper on the true distance
    rate, ``u − ξ (ρ − ρ_s)/(ρ_O − ρ_s)``, continued below ``ρ_s`` (down to ``u + ξ`` at
    ``2ρ_s − ρ_O``) so that a point the obstacle pushed inside ``ρ_s`` must open the
    gap again, not only hold it."""
    rs = stop_within(rho0, rho_stop)
    span = max(rho0 - rs, _SPAN_FLOOR)
    frac = min(max((rho - rs) / span, -1.0), 1.0)
    return u - xi * frac


@njit(cache=True)
def _khatib_speeds(rho, rho0, mu, v_max, out):  # type: ignore[no-untyped-def]
    for i in range(rho.shape[0]):
        out[i] = khatib_speed(rho[i], rho0[i], mu, v_max)


@njit(cache=True)
def _damper_bounds(rho, rho0, rho_stop, xi, out):  # type: ignore[no-untyped-def]
    for i in range(rho.shape[0]):
        out[i] = damper_bound(rho[i], rho0[i], rho_stop, xi)


def _flat_pair(rho: ArrayLike, rho0: ArrayLike) -> tuple[NDArray[np.float64], ...]:
    """``ρ`` and ``ρ_O`` broadcast together, as contiguous 1-D float arrays, and an
    output array of their broadcast shape."""
    r, r0 = np.broadcast_arrays(np.asarray(rho, dtype=float), np.asarray(rho0, dtype=float))
    return np.ascontiguousarray(r).ravel(), np.ascontiguousarray(r0).ravel(), np.empty(r.shape)


def repulsive_potential(rho: ArrayLike, rho0: ArrayLike, mu: float) -> NDArray[np.float64]:
    """``U(ρ) = ½ μ (1/ρ − 1/ρ_O)²`` inside the margin ``ρ_O``, 0 beyond (Eq. 3.16).

    ``ρ`` (m) may be an array; ``inf`` (a "no risk" answer) gives 0, ``ρ ≤ 0`` gives
    ``inf``.
    """
    r = np.asarray(rho, dtype=float)
    r0 = np.asarray(rho0, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = 0.5 * mu * (1.0 / r - 1.0 / r0) ** 2
    u = np.where(r > r0, 0.0, u)
    return np.asarray(np.where(r <= 0.0, np.inf, u), dtype=float)


def repulsive_speed(
    rho: ArrayLike, rho0: ArrayLike, mu: float, vmax: float = np.inf
) -> NDArray[np.float64]:
    """:func:`khatib_speed` (Eq. 3.17) of every distance ``ρ`` (m) against the
    margins ``ρ_O`` (broadcast together), capped at ``vmax`` (m/s); a NaN distance
    gives NaN."""
    r, r0, out = _flat_pair(rho, rho0)
    flat = out.reshape(-1)
    _khatib_speeds(r, r0, float(mu), float(vmax), flat)
    flat[np.isnan(r) | np.isnan(r0)] = np.nan
    return out


def approach_bound(
    rho: ArrayLike, rho0: ArrayLike, rho_stop: float, xi: float
) -> NDArray[np.float64]:
    """:func:`damper_bound` of every distance ``ρ`` (m) against the margins ``ρ_O``
    (broadcast together): the lowest allowed distance rate (m/s, ≤ 0), ``−inf``
    beyond the margin; a NaN distance gives NaN."""
    r, r0, out = _flat_pair(rho, rho0)
    flat = out.reshape(-1)
    _damper_bounds(r, r0, float(rho_stop), float(xi), flat)
    flat[np.isnan(r) | np.isnan(r0)] = np.nan
    return out
