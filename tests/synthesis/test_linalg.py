"""Block-structured DLS against dense linear algebra."""

from __future__ import annotations

import numpy as np
import pytest

from reachwise.synthesis.linalg import (
    BlockSystem,
    dense_dls,
    dls_step,
    null_space_project,
    smallest_singular_value,
    weighted,
)


def random_blocks(rng: np.random.Generator, K: int, p: int, nf: int):  # type: ignore[no-untyped-def]
    D = rng.normal(size=(K, 6, p))
    J = rng.normal(size=(K, 6, nf))
    active = np.ones((K, 6), dtype=bool)
    active[rng.integers(0, K, K // 2), 5] = False  # some 5-D points
    active[0, 3:] = False  # one 3-D point
    D[~active] = 0.0
    J[~active] = 0.0
    e = np.where(active, rng.normal(size=(K, 6)), 0.0)
    return D, J, active, e


def dense(D: np.ndarray, J: np.ndarray, active: np.ndarray) -> np.ndarray:
    K, _, p = D.shape
    nf = J.shape[2]
    rows = []
    for k in range(K):
        blk = np.zeros((6, p + K * nf))
        blk[:, :p] = D[k]
        blk[:, p + k * nf : p + (k + 1) * nf] = J[k]
        rows.append(blk[active[k]])
    return np.vstack(rows)


@pytest.mark.parametrize("lam2", [0.0, 1e-3, 0.5])
def test_block_solve_equals_dense_solve(lam2: float) -> None:
    rng = np.random.default_rng(3)
    for K, p, nf in [(1, 3, 7), (5, 10, 7), (12, 4, 8)]:
        D, J, active, e = random_blocks(rng, K, p, nf)
        wd = rng.uniform(0, 1, p)
        wq = rng.uniform(0, 1, (K, nf))
        wd[0] = 0.0
        sd, sq, _ = dls_step(D, J, active, e, wd, wq, lam2)
        Phi = dense(D, J, active)
        w = np.concatenate([wd, wq.ravel()])
        ref = dense_dls(Phi, e[active], w, max(lam2, 1e-10))
        np.testing.assert_allclose(np.concatenate([sd, sq.ravel()]), ref, atol=1e-8)


def test_null_space_projection_leaves_the_task_unchanged() -> None:
    rng = np.random.default_rng(4)
    D, J, active, _ = random_blocks(rng, 8, 6, 8)
    sys = BlockSystem.build(D, J, active, 1e-12)
    vd, vq = rng.normal(size=6), rng.normal(size=(8, 8))
    pd, pq = null_space_project(sys, vd, vq, active)
    assert np.abs(np.where(active, sys.apply(pd, pq), 0.0)).max() < 1e-8
    # projecting twice changes nothing (a projector)
    pd2, pq2 = null_space_project(sys, pd, pq, active)
    np.testing.assert_allclose(pd2, pd, atol=1e-8)
    np.testing.assert_allclose(pq2, pq, atol=1e-8)


def test_smallest_singular_value_estimate() -> None:
    rng = np.random.default_rng(5)
    D, J, active, _ = random_blocks(rng, 10, 5, 8)
    J[3] *= 1e-3  # one nearly singular point
    Dw, Jw = weighted(D, J, np.ones(5), np.ones((10, 8)))
    sys0 = BlockSystem.build(Dw, Jw, active, 1e-12)
    est = smallest_singular_value(sys0, active, 1e-12, iters=30)
    exact = np.linalg.svd(dense(D, J, active), compute_uv=False)[-1]
    assert est == pytest.approx(exact, rel=1e-3)
