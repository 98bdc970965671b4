"""Indices an improvement keeps: never worse than at the reach-only design.

Improving one index may sacrifice another: on the hard SB60-like family, raising the
GCI (the mean LCI, P-II Eq. 38) by 43 % lowered the KCI (the worst LCI, P-II Eq. 39) by
15 %. A *kept* index is a constraint of the improvement (``improve``), not a term of its
cost: with ``f⁰`` the index at the reach-only design the improvement starts from, every
accepted iterate has ``f ≥ f⁰`` (an index to maximize; ``≤`` for one to minimize). An
index that is a minimum is kept item by item, which is the same constraint and smooth
in each item:

* ``kci`` — the LCI of every task pose ``≥ KCI⁰`` (the minimum of the LCIs ``≥ KCI⁰``
  exactly when every LCI is);
* ``clearance`` — every clearance term of every pose (``clearance.ClearanceModel``)
  ``≥`` the smallest clearance at the start;
* any other objective (``gci``, ``size``, ``limits``, ``bounds``) — its value
  (``objectives``), one item.

The improvement checks the constraint on the true values at every trial (a trial that
breaks it is rejected, as one that leaves the tunnel is) and, so that its steps do not
run into the constraint blindly, adds the barrier ``Σ max(0, w − s)² / w²`` over the
items' slacks ``s = ±(f − f⁰)`` to its cost (``w``: 5 % of ``|f⁰|``; 0.05 m for the
clearance, the width of the bodies' barrier in ``clearance_rows``). The barrier is 1 at
the start's worst item and pushes it inside before the objective pulls elsewhere. Pure
maths.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import InputError, UnknownName
from reachwise.kinematics.conditioning import lci_gradient
from reachwise.kinematics.robot import OBJECTIVES
from reachwise.synthesis.clearance import ClearanceModel
from reachwise.synthesis.clearance_rows import MOTION_BAND
from reachwise.synthesis.objectives import evaluate_terms
from reachwise.synthesis.problem import SynthesisProblem

Array = NDArray[np.float64]
#: The barrier's width as a fraction of the kept index's start value.
KEEP_BAND = 0.05


def check_keep(names: Sequence[str] | None, source: str = "keep") -> tuple[str, ...]:
    """Validated names of kept indices (``OBJECTIVES``), duplicates removed."""
    out: list[str] = []
    for n in names or ():
        n = str(n).strip()
        if n not in OBJECTIVES:
            raise UnknownName(source, "index", n, OBJECTIVES)
        if n not in out:
            out.append(n)
    return tuple(out)


def parse_keep(text: str, source: str = "--keep") -> tuple[str, ...]:
    """``"kci,clearance"`` → ``("kci", "clearance")``; ``""`` or ``"none"`` → ``()``."""
    parts = [p.strip() for p in text.split(",") if p.strip()]
    if parts == ["none"]:
        return ()
    return check_keep(parts, source)


def default_keep(weights: Mapping[str, float]) -> tuple[str, ...]:
    """What an improvement keeps when not told: the KCI when the GCI is weighted (a
    better mean must not hide a worse worst pose), else nothing."""
    return ("kci",) if weights.get("gci", 0.0) > 0 else ()


def _items(
    problem: SynthesisProblem,
    z: Array,
    name: str,
    bodies: ClearanceModel | None,
    margin: float,
) -> tuple[Array, Array | None, Array | None, Array | None]:
    """The items of one kept index at ``z``: values ``(K, m)`` with design and joint
    gradients ``(K, m, p)``, ``(K, m, n_f)`` (per-pose items), or a value ``(1, 1)`` with
    a full gradient ``(size,)`` as the last entry (a scalar index)."""
    if name == "kci":
        design, Q = problem.split(z)
        robot = problem.robot_at(design)
        lcis, dl = lci_gradient(robot, Q, problem.template.design.free)
        n = robot.n
        return lcis[:, None], dl[:, None, n:], dl[:, None, problem.free_joints], None
    if name == "clearance":
        if bodies is None:
            raise InputError(
                problem.template.name,
                "design.bodies",
                "keeping the clearance needs the template's bodies (design.bodies)",
            )
        t = bodies.terms(problem, z)
        return t.distance, t.grad_design, t.grad_joints, None
    terms = evaluate_terms(problem, z, (name,), margin)
    return np.array([[terms.values[name]]]), None, None, terms.gradients[name]


def kept_floors(
    problem: SynthesisProblem,
    z: Array,
    names: Sequence[str],
    bodies: ClearanceModel | None = None,
    margin: float = 0.05,
) -> dict[str, float]:
    """Each kept index's value at ``z`` (the KCI and the clearance as true minima): the
    bound the improvement keeps."""
    out = {}
    for n in names:
        v = _items(problem, z, n, bodies, margin)[0]
        out[n] = float(v.min()) if OBJECTIVES[n] > 0 else float(v.max())
    return out


def keep_barrier(
    problem: SynthesisProblem,
    z: Array,
    floors: Mapping[str, float],
    bodies: ClearanceModel | None = None,
    margin: float = 0.05,
    band: float = KEEP_BAND,
) -> tuple[float, Array, bool]:
    """The barrier of the module docstring at ``z``, its gradient w.r.t. ``z`` and
    whether every kept index is at least as good as its floor."""
    value, g, ok = 0.0, np.zeros(problem.size), True
    p = problem.p
    for name, f0 in floors.items():
        sense = float(OBJECTIVES[name])
        v, gd, gq, full = _items(problem, z, name, bodies, margin)
        slack = sense * (v - f0)
        ok = ok and bool(np.all(slack >= 0.0))
        if name == "clearance":
            width = MOTION_BAND
        else:
            width = band * (abs(f0) if abs(f0) > 1e-12 else 1.0)
        depth = np.maximum(width - slack, 0.0)
        if not np.any(depth > 0):
            continue
        value += float(np.sum(depth * depth)) / width**2
        c = -2.0 * sense * depth / width**2  # d value / d item
        if full is not None:
            g += float(c[0, 0]) * full
        else:
            assert gd is not None and gq is not None
            g[:p] += np.einsum("km,kma->a", c, gd)
            g[p:] += np.einsum("km,kma->ka", c, gq).ravel()
    return value, g, ok
