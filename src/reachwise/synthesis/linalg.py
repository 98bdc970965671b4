"""Block-structured damped least squares for the synthesis Jacobian (P-I Eq. 22, P-II Eq. 27–28).

The stacked Jacobian ``Φ`` has one row block per task point: shared design columns
``D_k (6 × p)`` and own joint columns ``J_k (6 × n_f)``. With column weights ``w``
(dynamic weighting, P-II Eq. 25–28) and damping ``λ``::

    A = Φ_w Φ_wᵀ + λ² I = blockdiag(J_k J_kᵀ + λ² I) + D Dᵀ     (D stacks the D_k)

is a block-diagonal matrix plus a rank-``p`` update, so the Woodbury identity solves it
in ``O(K (6³ + 6² p) + p³)``: linear in the number of task points ``K`` instead of cubic
in the ``6K`` rows. Inactive (padding) rows get a unit diagonal and zero residual. A
block may carry more than six rows (the clearance rows of ``clearance_rows``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


@dataclass(frozen=True)
class BlockSystem:
    """Factorized ``A = blockdiag(B_k) + D Dᵀ`` of the weighted, damped normal equations."""

    D: Array  # (K, 6, p) weighted design blocks
    J: Array  # (K, 6, nf) weighted joint blocks
    Binv: Array  # (K, 6, 6)
    BinvD: Array  # (K, 6, p)
    S: Array  # (p, p) capacitance matrix I + Σ D_kᵀ B_k⁻¹ D_k

    @classmethod
    def build(cls, D: Array, J: Array, active: NDArray[np.bool_], lam2: float) -> BlockSystem:
        B = np.einsum("kia,kja->kij", J, J)
        pad = (~active).astype(np.float64) + max(lam2, 1e-10)
        rows = np.arange(B.shape[1])  # 6 task rows, plus any clearance rows
        B[:, rows, rows] += pad
        Binv = np.linalg.inv(B)
        BinvD = Binv @ D
        S = np.eye(D.shape[2]) + np.einsum("kia,kib->ab", D, BinvD)
        return cls(D, J, Binv, BinvD, S)

    def solve(self, e: Array) -> Array:
        """``A⁻¹ e`` for a padded residual ``e`` of shape (K, 6)."""
        Be = np.einsum("kij,kj->ki", self.Binv, e)
        t = np.einsum("kia,ki->a", self.D, Be)
        s = np.linalg.solve(self.S, t)
        return np.asarray(Be - self.BinvD @ s)

    def transpose_apply(self, y: Array) -> tuple[Array, Array]:
        """``Φ_wᵀ y``: design part (p,) and joint part (K, nf)."""
        return np.einsum("kia,ki->a", self.D, y), np.einsum("kia,ki->ka", self.J, y)

    def apply(self, vd: Array, vq: Array) -> Array:
        """``Φ_w v`` for design part ``vd`` (p,) and joint part ``vq`` (K, nf) → (K, 6)."""
        return np.asarray(self.D @ vd + np.einsum("kia,ka->ki", self.J, vq))


def weighted(D: Array, J: Array, wd: Array, wq: Array) -> tuple[Array, Array]:
    """Column-weighted blocks ``D W_d`` and ``J_k W_k``."""
    return D * wd[None, None, :], J * wq[:, None, :]


def dls_step(
    D: Array, J: Array, active: NDArray[np.bool_], e: Array, wd: Array, wq: Array, lam2: float
) -> tuple[Array, Array, BlockSystem]:
    """Weighted DLS step ``Δz = W Φ_wᵀ (Φ_w Φ_wᵀ + λ² I)⁻¹ e`` (P-II Eq. 27–28)."""
    Dw, Jw = weighted(D, J, wd, wq)
    sys = BlockSystem.build(Dw, Jw, active, lam2)
    y = sys.solve(np.where(active, e, 0.0))
    gd, gq = sys.transpose_apply(y)
    return wd * gd, wq * gq, sys


def null_space_project(
    sys: BlockSystem, vd: Array, vq: Array, active: NDArray[np.bool_]
) -> tuple[Array, Array]:
    """``(I − Φ_w⁺ Φ_w) v`` with ``Φ_w⁺ = Φ_wᵀ (Φ_w Φ_wᵀ)⁻¹`` evaluated by the factorized
    system (built with a negligible damping): motion that leaves the task unchanged."""
    r = np.where(active, sys.apply(vd, vq), 0.0)
    y = sys.solve(r)
    gd, gq = sys.transpose_apply(y)
    return vd - gd, vq - gq


def smallest_singular_value(
    sys0: BlockSystem, active: NDArray[np.bool_], mu: float, iters: int = 12
) -> float:
    """Estimate ``σ_min(Φ_w)`` by inverse iteration on ``Φ_w Φ_wᵀ + μ I`` (factorized in
    ``sys0`` with ``λ² = μ``); the Rayleigh quotient bounds ``σ_min²`` from above.

    Used for the damping schedule of P-I Eq. 14 on the stacked matrix, whose full SVD
    would cost ``O(K³)``. Padding rows (eigenvalue ``1 + μ``) are excluded.
    """
    rng = np.random.default_rng(12345)
    x = np.where(active, rng.standard_normal(active.shape), 0.0)
    for _ in range(iters):
        x = np.where(active, sys0.solve(x), 0.0)
        nrm = np.linalg.norm(x)
        if not np.isfinite(nrm) or nrm == 0.0:
            return 0.0
        x /= nrm
    gd, gq = sys0.transpose_apply(x)
    rq = float(gd @ gd + np.sum(gq * gq))  # xᵀ Φ Φᵀ x
    return float(np.sqrt(max(rq, 0.0)))


def dense_dls(Phi: Array, e: Array, w: Array, lam2: float) -> Array:
    """Reference: ``W Φ_wᵀ (Φ_w Φ_wᵀ + λ² I)⁻¹ e`` with dense linear algebra."""
    Pw = Phi * w[None, :]
    A = Pw @ Pw.T + lam2 * np.eye(Phi.shape[0])
    return np.asarray(w * (Pw.T @ np.linalg.solve(A, e)))
