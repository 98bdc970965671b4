"""The ``trf`` solver of the synthesis problem: the baseline of ``dls``.

``scipy.optimize.least_squares`` (trust-region reflective) with bounds, the exact
sparse Jacobian and the same workspace penalty as extra residuals.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from reachwise.synthesis.problem import Evaluation, SynthesisProblem
from reachwise.synthesis.solver_options import (
    SolveOutcome,
    SolverOptions,
    Workspace,
    converged,
    row_weights,
)
from reachwise.synthesis.workspace_motion import workspace_clear
from reachwise.synthesis.workspace_points import link_points

Array = NDArray[np.float64]


def solve_trf(
    problem: SynthesisProblem,
    z0: Array,
    workspace: Workspace | None = None,
    options: SolverOptions | None = None,
    max_nfev: int | None = None,
) -> SolveOutcome:
    """``scipy.optimize.least_squares(method="trf")`` with bounds, the exact sparse
    Jacobian and, with a workspace, one penalty residual ``max(0, margin − distance)``
    per sampled link point."""
    from scipy.optimize import least_squares
    from scipy.sparse import csr_matrix

    opt = options or SolverOptions()
    lo, hi = problem.bounds
    wx = row_weights(problem)
    act = problem.active_rows
    p, K, nf = problem.p, problem.K, problem.n_free_joints
    rows_idx = np.flatnonzero(act.ravel())
    cols = np.empty((K, 6, p + nf), dtype=np.int64)
    cols[:, :, :p] = np.arange(p)
    cols[:, :, p:] = p + np.arange(K)[:, None, None] * nf + np.arange(nf)
    cols_flat = cols.reshape(K * 6, p + nf)[rows_idx]
    rr = np.repeat(np.arange(rows_idx.size), p + nf)

    def blocks(z: Array) -> tuple[Evaluation, Array]:
        ev = problem.evaluate(np.clip(z, lo, hi))
        return ev, -(ev.e * wx).ravel()[rows_idx]

    def ws_terms(z: Array) -> tuple[Array, Array, NDArray[np.int64]]:
        if workspace is None:
            return np.zeros(0), np.zeros((0, p + nf)), np.zeros(0, int)
        pts, Jd, Jq, owner = link_points(problem, np.clip(z, lo, hi), opt.samples_per_link)
        flat = pts.reshape(-1, 3)
        sd = workspace.signed_distance(flat)
        pen = np.maximum(0.0, opt.workspace_margin - sd)
        g = workspace.gradient(flat)
        Jall = np.concatenate([Jd.reshape(-1, 3, p), Jq.reshape(-1, 3, nf)], axis=2)
        # d pen / dz = −gᵀ J where violated, 0 otherwise
        dpen = -np.einsum("ki,kia->ka", g, Jall) * (pen > 0)[:, None]
        return pen, dpen, owner.reshape(-1)

    def fun(z: Array) -> Array:
        _, r = blocks(z)
        pen, _, _ = ws_terms(z)
        return np.concatenate([r, pen])

    def jac(z: Array) -> csr_matrix:
        ev, _ = blocks(z)
        D = (ev.D * wx[:, :, None]).reshape(K * 6, p)[rows_idx]
        J = (ev.J * wx[:, :, None]).reshape(K * 6, nf)[rows_idx]
        vals = np.concatenate([D, J], axis=1).ravel()
        m = rows_idx.size
        pen, dpen, owner = ws_terms(z)
        if pen.size:
            wcols = np.empty((pen.size, p + nf), dtype=np.int64)
            wcols[:, :p] = np.arange(p)
            wcols[:, p:] = p + owner[:, None] * nf + np.arange(nf)
            r2 = m + np.repeat(np.arange(pen.size), p + nf)
            data = np.concatenate([vals, dpen.ravel()])
            ri = np.concatenate([rr, r2])
            ci = np.concatenate([cols_flat.ravel(), wcols.ravel()])
            return csr_matrix((data, (ri, ci)), shape=(m + pen.size, problem.size))
        return csr_matrix((vals, (rr, cols_flat.ravel())), shape=(m, problem.size))

    z_init = np.clip(z0, lo, hi)
    # least_squares needs strictly feasible starts and lo < hi
    span = hi - lo
    fixed = span <= 0
    lo_s = np.where(fixed, lo - 1e-12, lo)
    hi_s = np.where(fixed, hi + 1e-12, hi)
    res = least_squares(
        fun, z_init, jac=jac, bounds=(lo_s, hi_s), method="trf", tr_solver="lsmr",
        x_scale="jac", max_nfev=max_nfev or 200, xtol=1e-12, ftol=1e-12, gtol=1e-12,
    )  # fmt: skip
    z = np.clip(res.x, lo, hi)
    ev = problem.evaluate(z)
    done = converged(problem, ev) and workspace_clear(problem, z, workspace, opt)
    return SolveOutcome(z, ev, int(res.nfev), done, [float(res.cost)])
