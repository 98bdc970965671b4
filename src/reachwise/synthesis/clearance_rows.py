"""Clearance as rows of the synthesis's least squares: the active set of the bodies.

The damped least-squares step of the synthesis (P-I Eq. 22, P-II Eq. 27–28) solves
``Φ Δz ≈ e`` on the stacked task rows, one block per task pose. A clearance term
``d`` (``clearance``) of pose ``k`` depends on the design and on that pose's joints
only, so it fits into pose ``k``'s row block as one more row. Every term closer than
``clearance + band`` becomes an active row with residual ``clearance + band − d`` and
Jacobian ``∇d``: a one-sided constraint solved with the task. Terms farther away add no
row. The residual and its square are continuous where a term enters or leaves the set,
so the merit ``½‖e‖²`` of the solver stays C¹, and it is 0 exactly where every pose is
reached and every term keeps ``clearance + band``: with a small band (1 mm, the task's
usual tolerance) a reachable, clear design is a zero of the merit, not a compromise
between reach and clearance. Moving farther from the bodies' limits is the job of the
null-space motion (``clearance_motion``, as the tunnel wall's, P-II Eq. 29–33), which
leaves the task unchanged.

Rows are padded per pose to the largest number of active terms of any pose (inactive
padding rows have zero residual), which keeps the block solver's shapes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from reachwise.synthesis.clearance import ClearanceModel, ClearanceTerms
from reachwise.synthesis.problem import Evaluation, SynthesisProblem

Array = NDArray[np.float64]

#: Distance above the clearance (m) at which a term's row turns on.
CLEARANCE_BAND = 1e-3
#: Distance above the clearance (m) within which the null-space motion pushes a term.
MOTION_BAND = 0.05


@dataclass(frozen=True)
class Rows:
    """Row-weighted residual ``e (K, R)``, blocks ``D (K, R, p)``, ``J (K, R, n_f)``, which
    rows are active, the merit ``½‖e‖²`` and the clearance terms (None without bodies)."""

    e: Array
    D: Array
    J: Array
    active: NDArray[np.bool_]
    terms: ClearanceTerms | None

    @property
    def cost(self) -> float:
        return 0.5 * float(np.sum(self.e * self.e))

    def clear(self, clearance: float) -> bool:
        """Every term keeps at least ``clearance`` (True without bodies)."""
        return self.terms is None or bool(np.all(self.terms.distance >= clearance))


def clearance_excess(distance: Array, target: float) -> Array:
    """The residual of each clearance row: ``max(0, target − d)`` per term, 0 for a term
    at least ``target`` away (such a term adds no row)."""
    return np.maximum(target - distance, 0.0)


def stacked_rows(
    problem: SynthesisProblem,
    ev: Evaluation,
    wx: Array,
    z: Array,
    model: ClearanceModel | None,
    band: float = CLEARANCE_BAND,
) -> Rows:
    """The task rows of ``ev`` weighted by ``wx`` and, with ``model``, one row per
    clearance term within ``band`` of the clearance (module docstring)."""
    e = ev.e * wx
    D = ev.D * wx[:, :, None]
    J = ev.J * wx[:, :, None]
    active = problem.active_rows
    if model is None:
        return Rows(e, D, J, active, None)
    terms = model.terms(problem, z)
    excess = clearance_excess(terms.distance, model.clearance + band)  # (K, m)
    near = excess > 0.0
    r = int(near.sum(axis=1).max(initial=0))
    if r == 0:
        return Rows(e, D, J, active, terms)
    idx = np.argsort(~near, axis=1, kind="stable")[:, :r]  # the near terms first
    on = np.take_along_axis(near, idx, 1)
    ec = np.take_along_axis(excess, idx, 1)
    gd = np.take_along_axis(terms.grad_design, idx[:, :, None], 1)
    gq = np.take_along_axis(terms.grad_joints, idx[:, :, None], 1)
    Dc = np.where(on[:, :, None], gd, 0.0)
    Jc = np.where(on[:, :, None], gq, 0.0)
    return Rows(
        np.concatenate([e, ec], axis=1),
        np.concatenate([D, Dc], axis=1),
        np.concatenate([J, Jc], axis=1),
        np.concatenate([active, on], axis=1),
        terms,
    )


def _task_shares(ev: Evaluation, wx: Array) -> Array:
    """Each pose's share ``(K,)`` of the merit from its task rows alone."""
    e = ev.e * wx
    return np.asarray(0.5 * np.sum(e * e, axis=1))


def pose_merits(
    problem: SynthesisProblem,
    ev: Evaluation,
    wx: Array,
    z: Array,
    model: ClearanceModel | None,
    band: float = CLEARANCE_BAND,
) -> Array:
    """Each pose's share ``(K,)`` of ``stacked_rows(...).cost``, from the distances alone
    (without the gradients of the clearance terms): a pose's rows depend on the design
    and its own joints only, so given the design the poses' shares are independent."""
    out = _task_shares(ev, wx)
    if model is None:
        return out
    ec = clearance_excess(model.distances(problem, z), model.clearance + band)
    return np.asarray(out + 0.5 * np.sum(ec * ec, axis=1))


def merit(
    problem: SynthesisProblem,
    ev: Evaluation,
    wx: Array,
    z: Array,
    model: ClearanceModel | None,
    band: float = CLEARANCE_BAND,
    limit: float = math.inf,
) -> float:
    """``stacked_rows(...).cost`` without the gradients of the clearance terms: the
    merit of a trial step, which the solver keeps only if it lowers the merit (the
    rows of an accepted step are built once, by ``stacked_rows``).

    When the task rows' share alone exceeds ``limit`` (the most a trial may cost), that
    share is returned without the clearance terms: a lower bound of the merit that is
    above ``limit`` exactly when the merit is. Every pose's share only grows by its
    clearance rows (rounding is monotone, and both sums add the poses alike), so a trial
    rejected on its task rows is rejected as the full merit would reject it, without
    the distances of its bodies."""
    if model is None:  # the reach-only merit, summed as ``Rows.cost`` sums it
        e = ev.e * wx
        return 0.5 * float(np.sum(e * e))
    task = _task_shares(ev, wx)
    if float(np.sum(task)) > limit:
        return float(np.sum(task))
    return float(np.sum(pose_merits(problem, ev, wx, z, model, band)))


def clearance_motion(
    terms: ClearanceTerms, clearance: float, gain: float, band: float = MOTION_BAND
) -> tuple[Array, Array] | None:
    """``Σ k (clearance + band − d) ∇d`` over the terms closer than ``clearance + band``:
    design part ``(p,)`` and joint part ``(K, n_f)`` (the Khatib-style push of P-II
    Eq. 29–31 on the clearance terms), or None when every term is farther."""
    push = clearance_excess(terms.distance, clearance + band) * gain  # (K, m)
    if not np.any(push > 0):
        return None
    nd = np.einsum("km,kma->a", push, terms.grad_design)
    nq = np.einsum("km,kma->ka", push, terms.grad_joints)
    return nd, nq


def clearance_barrier(
    problem: SynthesisProblem, z: Array, model: ClearanceModel, band: float = MOTION_BAND
) -> tuple[float, Array, bool]:
    """Barrier ``Σ max(0, c + band − d)² / band²`` over the clearance terms, its gradient
    w.r.t. ``z`` and whether every term keeps the clearance ``c`` (the improvement's
    counterpart of the tunnel wall's barrier)."""
    terms = model.terms(problem, z)
    c = model.clearance
    ok = bool(np.all(terms.distance >= c))
    depth = clearance_excess(terms.distance, c + band)
    g = np.zeros(problem.size)
    if not np.any(depth > 0):
        return 0.0, g, ok
    value = float(np.sum(depth * depth)) / band**2
    w = -2.0 * depth / band**2  # d value / d distance
    g[: problem.p] = np.einsum("km,kma->a", w, terms.grad_design)
    g[problem.p :] = np.einsum("km,kma->ka", w, terms.grad_joints).ravel()
    return value, g, ok
