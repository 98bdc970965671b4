"""Pruning rules: which chains add nothing a kept chain lacks (P-II §2, thesis §4.2).

**Enumeration** (``enumerate_topologies``, rules in ``EnumerationRules``): every chain of
``min_joints``…``max_joints`` movable joints of the allowed ``types`` with at most
``max_prismatic`` prismatic joints, twists from ``twists`` (default {0, ±π/2}), the first
joint's type and axis as allowed (``first_axis`` ``vertical``: α₀ = 0; ``horizontal``:
α₀ = ±π/2), optionally only the type patterns in ``patterns``. Pruned (each rule is a
proof that the chain adds nothing a kept chain lacks):

1. *Parallel prismatic pair* — two consecutive prismatic joints with parallel axes
   (twist 0 or π between them) slide along one line: one of them is redundant.
2. *Coincident revolute pair* — two consecutive revolute joints with parallel axes and
   a locked ``a = 0`` between them share one axis: only the sum of the angles matters.
   (The enumerator frees every ``a``, so this only prunes specs given with locked links.)
3. *Planar redundancy* — more than ``max_parallel_revolute`` (3) consecutive revolute
   joints with parallel axes: a planar 3R chain already spans all planar motions.
4. *Rotational mobility* — the tool orientation changes only through revolute joints,
   and a run of revolute joints with parallel axes (prismatic or fixed rows between
   them included) contributes one rotation axis. Fewer such axes than
   ``min_rotation_axes`` (3 for 6-D task points, 2 for 5-D) cannot orient the tool.
5. *Axis-reversal (mirror) equivalence* — reversing the axis of a revolute (or fixed)
   row ``k`` other than the last maps the chain onto one with ``alpha_k`` and
   ``alpha_{k+1}`` each changed by π (so ±π/2 swap sign), ``theta_k`` and ``d_k``
   negated and ``q_k → −q_k``: the same set of tool poses when the revolute range and
   the length bounds are symmetric about 0. Of each class of equivalent sign patterns
   only one is kept: the one whose twists, read base to tool, prefer +π/2, then 0, then
   −π/2, then π. (Not applied to prismatic rows, whose stroke [0, 3] m is not
   symmetric, nor to the last row, which carries the tool frame.)

Pure: no files, no clocks, no printing.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from numpy.typing import NDArray

from reachwise.synthesis.topology.rules import _TWIST_CODES, EnumerationRules, _twist_masks
from reachwise.synthesis.topology.spec import JointSpec, TopologySpec, _parallel, _wrap, as_spec
from reachwise.synthesis.topology.template import TemplateOptions, free_parameters


def _rx(a: float) -> NDArray[np.float64]:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])


def _rz(t: float) -> NDArray[np.float64]:
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def rotation_axes(spec: TopologySpec) -> int:
    """Number of distinct rotation axes: runs of revolute joints whose axes stay parallel
    (rows between two revolutes are fixed rotations ``Rx(alpha) Rz(theta)``; rule 4)."""
    count = 0
    R: NDArray[np.float64] | None = None  # fixed rotation since the last revolute
    for j in spec.joints:
        if R is not None:
            R = R @ _rx(j.alpha)
        if j.kind == "R":
            if R is None or abs(abs(float(R[2, 2])) - 1.0) > 1e-9:
                count += 1
            R = np.eye(3)
        elif R is not None:
            R = R @ _rz(j.theta)
    return count


def violations(
    spec: TopologySpec | str,
    rules: EnumerationRules | None = None,
    options: TemplateOptions | None = None,
) -> list[str]:
    """The pruning rules (1–5 of the module docstring) ``spec`` breaks; empty if none."""
    sp = as_spec(spec)
    ru = rules or EnumerationRules()
    free = free_parameters(sp, options)
    out: list[str] = []
    js = sp.joints
    run = 1
    worst = 1 if js[0].kind == "R" else 0
    for i in range(1, len(js)):
        prev, cur = js[i - 1], js[i]
        par = _parallel(cur.alpha)
        if prev.kind == "P" and cur.kind == "P" and par:
            out.append(f"1 parallel prismatic pair at rows {i}-{i + 1}")
        if prev.kind == "R" and cur.kind == "R" and par and "a" not in free[i]:
            out.append(f"2 coincident revolute axes at rows {i}-{i + 1}")
        run = run + 1 if (prev.kind == "R" and cur.kind == "R" and par) else 1
        if cur.kind == "R":
            worst = max(worst, run)
    if worst > ru.max_parallel_revolute:
        out.append(f"3 {worst} consecutive parallel revolute joints")
    axes = rotation_axes(sp)
    if axes < ru.min_rotation_axes:
        out.append(f"4 {axes} rotation axes < {ru.min_rotation_axes}")
    if ru.mirror and (options or TemplateOptions()).symmetric:
        canon = canonical(sp, ru)
        if str(canon) != str(sp):
            out.append(f"5 mirror-equivalent to {canon}")
    return out


def canonical(spec: TopologySpec | str, rules: EnumerationRules | None = None) -> TopologySpec:
    """The representative of ``spec``'s axis-reversal class (rule 5): every subset of the
    reversible rows (revolute or fixed, not the last) is reversed and, among the results
    whose twists the ``rules`` allow (all results without rules; ``spec`` itself always
    counts), the one whose twists read best base to tool (+π/2 < 0 < −π/2 < π, offsets
    as tie-break) wins."""
    sp = as_spec(spec)
    js = sp.joints
    n = len(js)
    flippable = [k for k in range(n - 1) if js[k].kind in ("R", "F")]
    allowed = None if rules is None else _twist_masks(rules, n)
    best: tuple[tuple[float, ...], TopologySpec] | None = None
    for mask in itertools.product((False, True), repeat=len(flippable)):
        alpha = [j.alpha for j in js]
        theta = [j.theta for j in js]
        for k, f in zip(flippable, mask, strict=True):
            if f:
                alpha[k] += math.pi
                alpha[k + 1] -= math.pi
                theta[k] = -theta[k]
        cand = TopologySpec(
            tuple(JointSpec(j.kind, a, t, j.free) for j, a, t in zip(js, alpha, theta, strict=True))
        )
        if any(mask) and allowed is not None and not _allowed(cand, allowed):
            continue
        key = tuple(
            v for j in cand.joints for v in (_twist_rank(j.alpha), round(math.degrees(j.theta), 6))
        )
        if best is None or key < best[0]:
            best = (key, cand)
    if best is None:  # pragma: no cover - the empty product has one element
        return sp
    return best[1]


def _allowed(spec: TopologySpec, allowed: NDArray[np.bool_]) -> bool:
    for k, j in enumerate(spec.joints):
        r = _twist_rank(j.alpha)
        if r >= len(_TWIST_CODES) or not allowed[k, int(r)]:
            return False
    return True


def _twist_rank(alpha: float) -> float:
    for c, v in enumerate(_TWIST_CODES):
        if abs(_wrap(alpha - v)) < 1e-9:
            return float(c)
    return 10.0 + round(math.degrees(_wrap(alpha)), 6)
