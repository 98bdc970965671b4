"""``enumerate_topologies``: every chain the rules allow, pruned (``pruning``, rules 1–5).

Vectorized over the twists of one type pattern (``theta = 0``, every ``a`` and ``d``
free). Pure: no files, no clocks, no printing.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator

import numpy as np
from numpy.typing import NDArray

from reachwise.synthesis.topology.rules import _TWIST_CODES, EnumerationRules, _twist_masks
from reachwise.synthesis.topology.spec import JointSpec, TopologySpec
from reachwise.synthesis.topology.template import TemplateOptions


def _type_patterns(rules: EnumerationRules) -> Iterator[str]:
    if rules.patterns:
        yield from (p for p in rules.patterns if rules.min_joints <= len(p) <= rules.max_joints)
        return
    for n in range(rules.min_joints, rules.max_joints + 1):
        for combo in itertools.product(rules.types, repeat=n):
            yield "".join(combo)


def _pattern_ok(p: str, rules: EnumerationRules) -> bool:
    k = p.count("P")
    return (
        rules.min_prismatic <= k <= rules.max_prismatic
        and p[0] in rules.first_types
        and set(p) <= set(rules.types)
        and rules.min_joints <= len(p) <= rules.max_joints
    )


def _pattern_keep(
    pattern: str, rules: EnumerationRules, options: TemplateOptions
) -> NDArray[np.int64]:
    """Twist codes ``(m, n)`` of every kept chain of one type pattern (rules 1, 3–5)."""
    n = len(pattern)
    allowed = _twist_masks(rules, n)
    choices = [np.flatnonzero(allowed[k]) for k in range(n)]
    C = np.array(list(itertools.product(*choices)), dtype=np.int64).reshape(-1, n)
    keep = np.ones(len(C), dtype=np.bool_)
    par = (C == 1) | (C == 3)  # twist 0 or π: axis parallel to the previous one
    isR = np.array([c == "R" for c in pattern])
    isP = ~isR
    for k in range(1, n):
        if isP[k - 1] and isP[k]:
            keep &= ~par[:, k]  # rule 1
    run = np.full(len(C), 1 if isR[0] else 0)
    worst = run.copy()
    for k in range(1, n):
        if isR[k]:
            run = np.where(isR[k - 1] & par[:, k], run + 1, 1)
            worst = np.maximum(worst, run)
        else:
            run = np.zeros(len(C), dtype=np.int64)
    keep &= worst <= rules.max_parallel_revolute  # rule 3
    # rule 4: with theta = 0 the fixed rotation between two revolutes is Rx(sum of twists)
    deg = np.array([90, 0, -90, 180], dtype=np.int64)[C]
    axes = np.zeros(len(C), dtype=np.int64)
    acc: NDArray[np.int64] | None = None
    for k in range(n):
        if acc is not None:
            acc = acc + deg[:, k]
        if isR[k]:
            axes += 1 if acc is None else (acc % 180 != 0).astype(np.int64)
            acc = np.zeros(len(C), dtype=np.int64)
    keep &= axes >= rules.min_rotation_axes
    if rules.mirror and options.symmetric:  # rule 5
        flippable = [k for k in range(n - 1) if isR[k]]
        weights = 4 ** np.arange(n - 1, -1, -1, dtype=np.int64)
        own = C @ weights
        best = own.copy()
        for mask in itertools.product((0, 1), repeat=len(flippable)):
            if not any(mask):
                continue
            t = np.zeros(n, dtype=np.int64)
            for k, f in zip(flippable, mask, strict=True):
                if f:
                    t[k] ^= 1
                    t[k + 1] ^= 1
            Cf = (C + 2 * t) % 4
            valid = allowed[np.arange(n), Cf].all(axis=1)
            key = Cf @ weights
            best = np.where(valid & (key < best), key, best)
        keep &= own == best
    return C[keep]


def enumerate_topologies(
    rules: EnumerationRules | None = None, options: TemplateOptions | None = None
) -> list[TopologySpec]:
    """Every topology the rules allow, pruned by rules 1–5, in a fixed order (joint
    count, then type pattern R before P base to tool, then twists +π/2, 0, −π/2, π).
    All ``a`` and ``d`` free, ``theta = 0``. With ``rules.sample`` an evenly spaced
    deterministic selection of that many."""
    ru = rules or EnumerationRules()
    opt = options or TemplateOptions()
    out: list[TopologySpec] = []
    seen: set[str] = set()
    for pattern in _type_patterns(ru):
        if pattern in seen or not _pattern_ok(pattern, ru):
            continue
        seen.add(pattern)
        for row in _pattern_keep(pattern, ru, opt):
            out.append(
                TopologySpec(
                    tuple(
                        JointSpec(c, _TWIST_CODES[int(k)])
                        for c, k in zip(pattern, row, strict=True)
                    )
                )
            )
    if ru.sample is not None and ru.sample < len(out):
        idx = np.unique(np.round(np.linspace(0, len(out) - 1, ru.sample)).astype(np.int64))
        out = [out[int(i)] for i in idx]
    return out
