"""Restoring a vector onto the reaching set: damped Gauss–Newton steps on the task's
residual, the joints first, the design only if the joints cannot restore the poses.

The null-space step of the improvement (``improve``) keeps the task poses to first
order only; each trial is restored here before it is judged.

Pure maths: numpy in and out.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from reachwise.synthesis.active_set import VariableBox, bounded_step
from reachwise.synthesis.problem import Evaluation, SynthesisProblem
from reachwise.synthesis.solver_options import row_weights

Array = NDArray[np.float64]


def variable_spans(problem: SynthesisProblem) -> Array:
    """Each variable's range ``hi − lo`` (0 for a fixed one)."""
    lo, hi = problem.bounds
    return np.asarray(np.maximum(hi - lo, 0.0))


def _reached(problem: SynthesisProblem, ev: Evaluation, fraction: float = 1.0) -> bool:
    task = problem.task
    pos = ev.position_error <= fraction * task.tol_position
    ori = (ev.orientation_error <= fraction * task.tol_orientation) | (task.dims == 3)
    return bool(pos.all() and ori.all())


def _worst(problem: SynthesisProblem, ev: Evaluation) -> float:
    """The largest error over the task in units of its tolerance."""
    task = problem.task
    ori = np.where(task.dims == 3, 0.0, ev.orientation_error / task.tol_orientation)
    return float(max(np.max(ev.position_error / task.tol_position), np.max(ori)))


#: Damping ``λ²`` (m², the rows' units) of the restoration's steps, tried in turn until
#: one lowers the residual: the first is Gauss–Newton's (``λ → 0``).
RESTORE_DAMPING = (1e-12, 1e-9, 1e-7, 1e-5, 1e-3)


def _residual(ev: Evaluation, wx: Array) -> float:
    """``½‖W_x e‖²``, the task residual the restoration lowers."""
    e = ev.e * wx
    return 0.5 * float(np.sum(e * e))


def restore(
    problem: SynthesisProblem, z: Array, iterations: int = 6, fraction: float = 0.25
) -> tuple[Array, Evaluation]:
    """Gauss–Newton steps (bounded DLS, ``λ → 0``) from ``z`` until every pose is within
    ``fraction`` of its tolerance (or ``iterations`` are spent). The joints alone are
    moved first — the design stays what the improvement chose — and the design too
    only if the joints cannot restore the poses. Returns the last iterate.

    A step is taken only if it lowers the residual ``½‖W_x e‖²``; otherwise it is damped
    (Levenberg–Marquardt, ``RESTORE_DAMPING``), and the restoration stops when no damping
    lowers it. Near a singular posture the undamped step is huge: on the sb60 in the
    tunnel a residual of 0.06 mm moved joints by 1 rad to another posture of the same
    pose, through the bodies' clearance, and so every trial of the improvement failed."""
    lo, hi = problem.bounds
    p, K, nf = problem.p, problem.K, problem.n_free_joints
    wx = row_weights(problem)
    span = variable_spans(problem)
    ev = problem.evaluate(z)
    joints_only = iterations
    worst = np.inf
    for i in range(2 * iterations):
        if _reached(problem, ev, fraction):
            break
        now = _worst(problem, ev)
        if i < joints_only and now > 0.5 * worst:
            joints_only = i  # the joints alone stall (one at a limit): move the design too
        worst = now
        D, J = ev.D * wx[:, :, None], ev.J * wx[:, :, None]
        if i < joints_only:
            D = np.zeros_like(D)
        box = VariableBox(
            (z[:p], z[p:].reshape(K, nf)), (lo[:p], lo[p:].reshape(K, nf)),
            (hi[:p], hi[p:].reshape(K, nf)), (span[:p], span[p:].reshape(K, nf)),
        )  # fmt: skip
        before = _residual(ev, wx)
        for lam2 in RESTORE_DAMPING:
            bs = bounded_step(D, J, problem.active_rows, ev.e * wx, lam2, box)
            z_try = np.clip(z + np.concatenate([bs.design, bs.joints.ravel()]), lo, hi)
            ev_try = problem.evaluate(z_try)
            if _residual(ev_try, wx) < before:
                break
        else:
            break  # no step lowers the residual
        z, ev = z_try, ev_try
    return z, ev
