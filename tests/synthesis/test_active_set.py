"""The bounded DLS step's working set against scipy's bounded linear least squares.

On a linear, block-structured least-squares problem with bounds (the synthesis Jacobian's
shape: shared design columns, one block of joint columns per task point), iterating the
bounded step — releasing one multiplier of the wrong sign whenever the iteration stalls —
must reach the optimum ``scipy.optimize.lsq_linear`` finds. The rule it replaced (fix
every variable whose step points outward, never release) stalls above that optimum on
most of the same problems: the check can tell the two apart.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import lsq_linear

from reachwise.synthesis.active_set import VariableBox, bounded_step

K, P, NF = 4, 3, 2


def problem(rng: np.random.Generator) -> tuple[np.ndarray, ...]:
    D = rng.normal(size=(K, 6, P))
    J = rng.normal(size=(K, 6, NF))
    b = 3.0 * rng.normal(size=(K, 6))
    lo, hi = np.full(P + K * NF, -0.3), np.full(P + K * NF, 0.3)
    return D, J, b, lo, hi


def dense(D: np.ndarray, J: np.ndarray) -> np.ndarray:
    A = np.zeros((K * 6, P + K * NF))
    for k in range(K):
        A[6 * k : 6 * k + 6, :P] = D[k]
        A[6 * k : 6 * k + 6, P + NF * k : P + NF * (k + 1)] = J[k]
    return A


def iterate(D: np.ndarray, J: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray,
            release: bool, iterations: int = 200) -> float:  # fmt: skip
    A = dense(D, J)
    z = np.zeros(P + K * NF)
    cost = 0.5 * float(np.sum((b.ravel() - A @ z) ** 2))
    stalled = False
    for _ in range(iterations):
        e = (b.ravel() - A @ z).reshape(K, 6)
        bs = bounded_step(
            D, J, np.ones((K, 6), bool), e, 1e-12,
            VariableBox(
                (z[:P], z[P:].reshape(K, NF)), (lo[:P], lo[P:].reshape(K, NF)),
                (hi[:P], hi[P:].reshape(K, NF)), (np.ones(P), np.ones((K, NF))),
            ),
            release=release and stalled,
        )  # fmt: skip
        zn = np.clip(z + np.concatenate([bs.design, bs.joints.ravel()]), lo, hi)
        cn = 0.5 * float(np.sum((b.ravel() - A @ zn) ** 2))
        stalled = cn > cost * (1 - 1e-9)
        if cn < cost:
            z, cost = zn, cn
    return cost


def test_working_set_reaches_the_bounded_least_squares_optimum() -> None:
    rng = np.random.default_rng(3)
    old_stalls = 0
    for _ in range(12):
        D, J, b, lo, hi = problem(rng)
        ref = lsq_linear(dense(D, J), b.ravel(), bounds=(lo, hi), tol=1e-12).cost
        assert iterate(D, J, b, lo, hi, release=True) <= ref * (1 + 1e-9)
        old_stalls += iterate(D, J, b, lo, hi, release=False) > ref * (1 + 1e-6)
    assert old_stalls >= 6  # the old rule's false stationary points are common


def test_a_variable_at_a_bound_with_an_outward_gradient_stays() -> None:
    """One unknown, target beyond its upper bound: it stays at the bound, step 0."""
    D = np.zeros((1, 6, 1))
    D[0, 0, 0] = 1.0
    J = np.zeros((1, 6, 1))
    J[0, 1, 0] = 1.0
    e = np.zeros((1, 6))
    e[0, 0] = 2.0  # wants the design variable up by 2
    bs = bounded_step(
        D, J, np.ones((1, 6), bool), e, 1e-12,
        VariableBox(
            (np.array([1.0]), np.zeros((1, 1))), (np.array([-1.0]), -np.ones((1, 1))),
            (np.array([1.0]), np.ones((1, 1))), (np.ones(1), np.ones((1, 1))),
        ),
        release=True,
    )  # fmt: skip
    assert bs.weight_design[0] == 0.0 and bs.design[0] == 0.0
