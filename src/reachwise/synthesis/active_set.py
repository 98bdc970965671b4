"""The bounded DLS step: which variables at a bound may move (P-II Eq. 25–28).

P-II bounds every design parameter, base coordinate and joint value with dynamic
weighting: a variable's column weight is 1 inside its range and drops to 0 at a bound,
so the damped least-squares step ``Δz = W Φ_wᵀ (Φ_w Φ_wᵀ + λ² I)⁻¹ e`` (Eq. 27–28)
leaves it there. *Which* variables at a bound get weight 0 decides whether the iteration
can leave a corner of the box.

Fixing every variable whose unconstrained Gauss–Newton step points outward (the first
implementation) creates false stationary points: with two coupled variables at bounds,
the step may push both outward while the gradient of the cost pulls one of them back
inside. Both are fixed, the rest converges, and the iteration stalls at a point that is
not a constrained minimum (tunnel-87 seeds 4 and 8: ``a2`` at its lower and ``d4`` at its
upper bound with inward gradients; ``a1`` and ``a4`` at their upper bounds).

The rule here is the working-set rule of bound-constrained least squares. Within an
iteration, a variable at a bound whose step points outward is fixed (weight 0) and the
step solved again — the fast rule above, kept. When the iteration stalls on its working
set (no more decrease), the KKT conditions are checked: a fixed variable stays fixed only
if the steepest-descent direction ``g = Φᵀ W_x² e`` pushes it outward (its Lagrange
multiplier has the right sign). Of the others, the one with the largest scaled
violation ``|g_i| s_i`` is released. At the optimum of the working set the released
variable's step ``(Φᵀ Φ + λ² I)⁻¹ g`` has the sign of ``g_i``, so it moves inside; a point
where nothing can be released is a constrained stationary point.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from reachwise.synthesis.linalg import dls_step

Array = NDArray[np.float64]


@dataclass(frozen=True)
class VariableBox:
    """The variables of a step and their box, each a ``(design (p,), joints (K, n_f))``
    pair: the values ``z``, the ``lower`` and ``upper`` bounds and the ``scale`` that
    puts multipliers of different units on one footing (e.g. the step caps)."""

    z: tuple[Array, Array]
    lower: tuple[Array, Array]
    upper: tuple[Array, Array]
    scale: tuple[Array, Array]


@dataclass(frozen=True)
class BoundedStep:
    """A step and the column weights it was solved with (0 = fixed at its bound)."""

    design: Array  # (p,)
    joints: Array  # (K, n_f)
    weight_design: Array  # (p,)
    weight_joints: Array  # (K, n_f)


def descent_direction(D: Array, J: Array, e: Array) -> tuple[Array, Array]:
    """``Φᵀ e`` split into design ``(p,)`` and joint ``(K, n_f)`` parts (row-weighted
    blocks and residual): minus the gradient of ``½‖e‖²``."""
    return np.einsum("kia,ki->a", D, e), np.einsum("kia,ki->ka", J, e)


def bounded_step(
    D: Array,
    J: Array,
    active: NDArray[np.bool_],
    e: Array,
    lam2: float,
    box: VariableBox,
    release: bool = False,
    passes: int = 4,
) -> BoundedStep:
    """The weighted DLS step (P-II Eq. 27–28) with the working set of the bounds.

    ``D (K, 6, p)``, ``J (K, 6, n_f)`` and ``e (K, 6)`` are row-weighted; ``box`` holds
    the variables, their bounds and scales.
    ``release`` (when the iteration has stalled on its working set) frees the one fixed
    variable whose multiplier has the wrong sign by the most (module docstring).
    """
    zd, zq = box.z
    lo_d, hi_d = zd <= box.lower[0], zd >= box.upper[0]
    lo_q, hi_q = zq <= box.lower[1], zq >= box.upper[1]
    scale = box.scale
    wd, wq = np.ones(zd.shape), np.ones(zq.shape)

    def outward(sd: Array, sq: Array) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
        od = ((lo_d & (sd < 0)) | (hi_d & (sd > 0))) & (wd > 0)
        oq = ((lo_q & (sq < 0)) | (hi_q & (sq > 0))) & (wq > 0)
        return od, oq

    sd, sq, _ = dls_step(D, J, active, e, wd, wq, lam2)
    for _ in range(passes):
        out_d, out_q = outward(sd, sq)
        if not (out_d.any() or out_q.any()):
            break
        wd[out_d] = 0.0
        wq[out_q] = 0.0
        sd, sq, _ = dls_step(D, J, active, e, wd, wq, lam2)
    if release:
        gd, gq = descent_direction(D, J, np.where(active, e, 0.0))
        vd = np.where((wd == 0) & ((lo_d & (gd > 0)) | (hi_d & (gd < 0))), np.abs(gd) * scale[0], 0)
        vq = np.where((wq == 0) & ((lo_q & (gq > 0)) | (hi_q & (gq < 0))), np.abs(gq) * scale[1], 0)
        i, k = int(np.argmax(vd)), np.unravel_index(int(np.argmax(vq)), vq.shape)
        if max(vd[i], vq[k]) > 0:
            w = wd if vd[i] >= vq[k] else wq
            at = i if vd[i] >= vq[k] else k
            w[at] = 1.0
            td, tq, _ = dls_step(D, J, active, e, wd, wq, lam2)
            od, oq = outward(td, tq)
            if od.any() or oq.any():  # the subproblem was not at its optimum yet
                w[at] = 0.0
            else:
                sd, sq = td, tq
    return BoundedStep(sd, sq, wd, wq)
