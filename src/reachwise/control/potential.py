"""Khatib's repulsive potential (thesis Eq. 3.16–3.17, P-V Eq. 4–5) and the velocity
damper that keeps a pair from closing in faster than it can still stop.

Thesis Eq. 3.16: ``U = ½ μ (1/ρ − 1/ρ_O)²`` for ``ρ ≤ ρ_O``, 0 beyond. Its negative
gradient along the collision line (Eq. 3.17) is the repulsive speed of the avoidance
point, ``v = μ (1/ρ − 1/ρ_O) / ρ²``, directed from the obstacle's closest point to the
robot's (the distance query's ``direction``).

The velocity damper (Faverjon & Tournassoud 1987, not in the thesis) bounds the rate
at which the distance may shrink: ``ρ̇ ≥ −ξ (ρ − ρ_s) / (ρ_O − ρ_s)``; at the margin
the pair may approach at ``ξ``, at the stop distance ``ρ_s`` not at all. The
controller uses it as a guard on top of Eq. 3.18 (see ``controller``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["approach_bound", "repulsive_potential", "repulsive_speed"]


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
    """Repulsive speed ``μ (1/ρ − 1/ρ_O) / ρ²`` (m/s) inside the margin, 0 beyond
    (Eq. 3.17, the magnitude of ``−∇U`` along the collision line), capped at ``vmax``.

    ``ρ ≤ 0`` (touching) gives ``vmax`` (``inf`` without a cap).
    """
    r = np.asarray(rho, dtype=float)
    r0 = np.asarray(rho0, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        v = mu * (1.0 / r - 1.0 / r0) / (r * r)
    v = np.where(r > r0, 0.0, v)
    v = np.where(r <= 0.0, np.inf, v)
    return np.asarray(np.minimum(v, vmax), dtype=float)


def approach_bound(
    rho: ArrayLike, rho0: ArrayLike, rho_stop: float, xi: float
) -> NDArray[np.float64]:
    """Lowest allowed distance rate ``ρ̇_min = −ξ (ρ − ρ_s)/(ρ_O − ρ_s)`` (m/s, ≤ 0).

    ``−ξ`` at the margin ``ρ_O``, 0 at and below the stop distance ``ρ_s``; ``−inf``
    (no bound) beyond the margin.
    """
    r = np.asarray(rho, dtype=float)
    r0 = np.asarray(rho0, dtype=float)
    span = np.maximum(r0 - rho_stop, 1e-9)
    b = -xi * np.clip((r - rho_stop) / span, 0.0, 1.0)
    return np.asarray(np.where(r > r0, -np.inf, b), dtype=float)
