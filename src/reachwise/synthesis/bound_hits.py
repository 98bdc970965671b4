"""Which design parameters ended at a bound (what a designer must be told).

A design parameter at its bound is a decision the synthesis did not make: the task
wanted it further, and the bound (or ``design.min_length``) stopped it. P-I Table 3's
optimum sits inside its bounds; ours is flagged wherever it does not. A parameter is
flagged when it lies at, or within ``tolerance`` (1 % by default) of its range from, a
bound the solver keeps: the declared ``lower``/``upper`` bound, or the ``min_length``
that keeps a link buildable. Pure math.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from reachwise.synthesis.problem import SynthesisProblem

Side = Literal["lower", "upper", "min_length"]


@dataclass(frozen=True)
class BoundHit:
    """A design parameter at (or within ``tolerance`` of) a bound."""

    parameter: str
    value: float
    side: Side
    bound: float
    normalized: float  # the value on P-I Table 3's scale (0 and 1 are the declared bounds)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def bound_hits(
    problem: SynthesisProblem, design: NDArray[np.float64], tolerance: float = 0.01
) -> list[BoundHit]:
    """The parameters of ``design`` within ``tolerance`` × range of a kept bound."""
    lo_decl, hi_decl = problem.declared_bounds
    lo, hi = problem.design_bounds
    out: list[BoundHit] = []
    for i, name in enumerate(problem.design_names):
        span = hi_decl[i] - lo_decl[i]
        if span <= 0:
            continue  # a fixed parameter is not a decision
        x = float(design[i])
        u = (x - lo_decl[i]) / span
        tol = tolerance * span
        for side, b, tight in (("lower", lo[i], lo[i] > lo_decl[i]),
                               ("upper", hi[i], hi[i] < hi_decl[i])):  # fmt: skip
            if abs(x - b) <= tol:
                out.append(BoundHit(name, x, "min_length" if tight else side, float(b), u))  # type: ignore[arg-type]
                break
    return out
