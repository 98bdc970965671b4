"""Damped least squares: the damping schedule and the damped pseudo-inverse, shared by the
inverse kinematics (``ik``), the synthesis solver and the controller (thesis Eq. 3.5–3.7,
P-I Eq. 12–14).

Damping schedule (P-I Eq. 14, after Chiaverini et al. 1994)::

    λ² = (1 − (σ_min/ε)²) λ_max²   if σ_min < ε,   else 0

``σ_min`` is the smallest singular value of the (weighted) Jacobian, ``ε`` (``epsilon``)
the width of the singular region in which damping applies and ``λ_max``
(``lambda_max``) the damping at a singularity.

Damped right pseudo-inverse (thesis Eq. 3.6)::

    Φ̃⁺ = Φᵀ (Φ Φᵀ + λ² I)⁻¹ = (Φᵀ Φ + λ² I)⁻¹ Φᵀ

computed from the eigen-decomposition of the smaller Gram matrix (``Φ Φᵀ`` when Φ has no
more rows than columns, else ``Φᵀ Φ``), whose smallest eigenvalue is ``σ_min²``; with it
the exact, rank-truncated projector ``Φ⁺ Φ`` that maps a secondary motion ``z`` into the
null space as ``(I − Φ⁺ Φ) z`` (thesis Eq. 3.7, 3.18). The projector is exact, not
damped, so the secondary motion never disturbs the task even while the primary solution
is damped.

Defaults (one set of names, ``epsilon`` and ``lambda_max``, everywhere):

- :data:`LAMBDA_MAX` ``= 0.05`` for all three users;
- :data:`EPSILON_SOLVER` ``= 0.02`` for the iterative solvers (IK and synthesis). They
  iterate to 1e-6 and fade the damping with the residual; a narrow singular region
  leaves their steps undamped everywhere but right at a singularity, so they keep
  converging quickly near (but not at) singular poses;
- :data:`EPSILON_CONTROL` ``= 0.05`` for the controller, whose output is a velocity
  command to a machine: a wider singular region starts damping earlier, before the
  joint speeds grow toward a singularity.

``damped_pinv`` returns the matrices (the controller applies them to many vectors),
``damped_solve`` applies the same decomposition to one task and one secondary motion
(the IK step). All are compiled (see ``reachwise.kinematics._jit``) and callable from
Python and from other kernels.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, types

from reachwise.kinematics._jit import RO_F8_1D, RO_F8_2D

__all__ = [
    "EPSILON_CONTROL",
    "EPSILON_SOLVER",
    "LAMBDA_MAX",
    "DampedInverse",
    "DampedSolution",
    "damped_pinv",
    "damped_solve",
    "damping_squared",
]

#: Damping at a singularity, ``λ_max`` (IK, synthesis and controller).
LAMBDA_MAX = 0.05
#: Width ``ε`` of the singular region for the iterative solvers (IK and synthesis).
EPSILON_SOLVER = 0.02
#: Width ``ε`` of the singular region for the controller.
EPSILON_CONTROL = 0.05


class DampedSolution(NamedTuple):
    """Result of :func:`damped_solve` for an ``(r, n)`` matrix Φ, a task ``e`` (r,) and a
    secondary motion ``z`` (n,): ``step`` ``Φ̃⁺ e`` and ``null_motion`` ``(I − Φ⁺ Φ) z``
    (n,), ``sigma_min`` and ``damping`` λ as in :class:`DampedInverse`."""

    step: np.ndarray
    null_motion: np.ndarray
    sigma_min: float
    damping: float


class DampedInverse(NamedTuple):
    """Result of :func:`damped_pinv` for an ``(r, n)`` matrix Φ.

    ``inverse`` ``(n, r)``: ``Φ̃⁺ = Φᵀ (Φ Φᵀ + λ² I)⁻¹`` (Eq. 3.6); ``projector``
    ``(n, n)``: the exact ``Φ⁺ Φ`` (``(0, 0)`` when not asked for); ``sigma_min``: the
    smallest singular value of Φ (of its ``min(r, n)`` ones); ``damping``: λ.
    """

    inverse: np.ndarray
    projector: np.ndarray
    sigma_min: float
    damping: float


@njit(types.float64(types.float64, types.float64, types.float64), cache=True)
def damping_squared(sigma_min, epsilon, lambda_max):  # type: ignore[no-untyped-def]
    """``λ² = (1 − (σ_min/ε)²) λ_max²`` inside the singular region ``σ_min < ε``, else 0
    (P-I Eq. 14)."""
    if sigma_min < epsilon:
        return (1.0 - (sigma_min / epsilon) ** 2) * lambda_max * lambda_max
    return 0.0


@njit(cache=True)
def _spectrum(Phi, epsilon, lambda_max):  # type: ignore[no-untyped-def]
    """Eigen-decomposition ``(ev, V)`` of the smaller Gram matrix (``wide``: ``Φ Φᵀ``,
    else ``Φᵀ Φ``), the damped inverse eigenvalues ``1/(e + λ²)``, the exact ones
    (0 below ``1e-12`` times the largest: rank truncation), ``σ_min`` and ``λ²``."""
    r, n = Phi.shape
    wide = r <= n
    G = Phi @ Phi.T if wide else Phi.T @ Phi
    ev, V = np.linalg.eigh(G)
    k = ev.shape[0]
    smin = math.sqrt(max(ev[0], 0.0))
    lam2 = damping_squared(smin, epsilon, lambda_max)
    damped = np.empty(k)
    exact = np.empty(k)
    cut = 1e-12 * max(ev[k - 1], 1e-300)
    for i in range(k):
        damped[i] = 1.0 / max(ev[i] + lam2, 1e-300)
        exact[i] = 1.0 / ev[i] if ev[i] > cut else 0.0
    return wide, ev, V, damped, exact, smin, lam2


@njit((RO_F8_2D, types.float64, types.float64, types.boolean), cache=True)
def damped_pinv(Phi, epsilon, lambda_max, projector):  # type: ignore[no-untyped-def]
    """Damped right pseudo-inverse of ``Phi`` (thesis Eq. 3.6) with the damping of
    P-I Eq. 14 and, if ``projector``, the exact null-space projector ``Φ⁺ Φ``, as
    matrices (for several right-hand sides; see :func:`damped_solve` for one).

    Returns a :class:`DampedInverse`.
    """
    r, n = Phi.shape
    wide, ev, V, damped, exact, smin, lam2 = _spectrum(Phi, epsilon, lambda_max)
    M = np.empty((n, r))
    if wide:
        # Φᵀ V diag(1/(e + λ²)) Vᵀ with V the eigenvectors of Φ Φᵀ
        PV = Phi.T @ V  # (n, r)
        for c in range(n):
            for j in range(r):
                acc = 0.0
                for i in range(r):
                    acc += PV[c, i] * damped[i] * V[j, i]
                M[c, j] = acc
    else:
        # V diag(1/(e + λ²)) Vᵀ Φᵀ with V the eigenvectors of Φᵀ Φ
        PV = Phi @ V  # (r, n)
        for c in range(n):
            for j in range(r):
                acc = 0.0
                for i in range(n):
                    acc += V[c, i] * damped[i] * PV[j, i]
                M[c, j] = acc
    if projector:
        P = np.empty((n, n))
        for c in range(n):
            for j in range(n):
                acc = 0.0
                if wide:
                    for i in range(r):
                        acc += PV[c, i] * exact[i] * PV[j, i]
                else:
                    for i in range(n):
                        acc += V[c, i] * (exact[i] * ev[i]) * V[j, i]
                P[c, j] = acc
    else:
        P = np.empty((0, 0))
    return DampedInverse(M, P, smin, math.sqrt(lam2))


@njit((RO_F8_2D, RO_F8_1D, RO_F8_1D, types.float64, types.float64), cache=True)
def damped_solve(Phi, e, z, epsilon, lambda_max):  # type: ignore[no-untyped-def]
    """The damped step ``Φ̃⁺ e`` (Eq. 3.6) and the null-space motion ``(I − Φ⁺ Φ) z``
    (Eq. 3.7) for one right-hand side, without forming the matrices of
    :func:`damped_pinv`. Returns a :class:`DampedSolution`."""
    wide, ev, V, damped, exact, smin, lam2 = _spectrum(Phi, epsilon, lambda_max)
    if wide:
        x = Phi.T @ (V @ (damped * (V.T @ e)))
        nz = z - Phi.T @ (V @ (exact * (V.T @ (Phi @ z))))
    else:
        x = V @ (damped * (V.T @ (Phi.T @ e)))
        nz = z - V @ ((exact * ev) * (V.T @ z))
    return DampedSolution(x, nz, smin, math.sqrt(lam2))
