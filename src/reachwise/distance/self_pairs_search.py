"""The local search of the ``never`` rule (:mod:`reachwise.distance.self_pairs`): a pair
that no random configuration brings within the margin is searched for closer ones from
its closest samples, since sampling alone misses pairs that come close only in a small
region of the joint space."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from reachwise.distance.engine import PairQuery
from reachwise.distance.self_pairs_types import ChainLike
from reachwise.geometry.cloud import PointCloud

__all__ = ["SEEDS", "LocalSearch"]

#: Local search: how many closest samples it starts from, perturbations per step, and its
#: step sizes (fraction of each joint's range).
SEEDS = 5
_BATCH = 16
_STEP0, _STEP_MIN = 0.05, 1e-3


class LocalSearch:
    """Descends the exact distance of one pair from its closest random samples: a few
    random perturbations per step inside the limits, the best kept, the step halved
    when none is better; stops as soon as the pair comes within the margin."""

    def __init__(
        self,
        robot: ChainLike,
        a: PointCloud,
        b: PointCloud,
        ia: int,
        ib: int,
        margin: float,
    ) -> None:
        self.robot, self.ia, self.ib, self.margin = robot, ia, ib, margin
        self.query = PairQuery(a, b, margin=max(4.0 * margin, 0.5))
        self.lo = np.asarray(robot.lower, float)
        self.hi = np.asarray(robot.upper, float)

    def run(
        self, Q: NDArray[np.float64], F: NDArray[np.float64], bounds: NDArray[np.float64], seed: int
    ) -> float:
        """The smallest distance found (``inf`` when every sample is far beyond)."""
        # the closest samples by exact distance: in order of their lower bound, until the
        # bound exceeds the k-th best distance (no later sample can be closer); each
        # query is bounded by that k-th best, so a farther sample costs little
        found: list[tuple[float, int]] = []
        cap = self.query.margin
        for s in np.argsort(bounds, kind="stable"):
            kth = found[SEEDS - 1][0] if len(found) >= SEEDS else cap
            if bounds[s] > kth:
                break
            r = self.query(F[s, self.ia], F[s, self.ib], margin=kth)
            if not r.no_risk:
                found.append((r.distance, int(s)))
                found.sort()
                del found[SEEDS:]
        best_d = found[0][0] if found else math.inf
        if not math.isfinite(best_d):
            return best_d
        rng = np.random.default_rng([int(seed), self.ia, self.ib])
        span = self.hi - self.lo
        for dq, s in found:
            q = Q[s].copy()
            step = _STEP0
            while step >= _STEP_MIN and dq > self.margin:
                trial = np.clip(q + rng.normal(0.0, 1.0, (_BATCH, len(q))) * step * span,
                                self.lo, self.hi)  # fmt: skip
                Ft = np.asarray(self.robot.fk_all(trial), dtype=float)
                dt = np.array(  # only a closer trial matters: bound each query by dq
                    [self.query(f[self.ia], f[self.ib], margin=dq).distance for f in Ft]
                )
                k = int(np.argmin(dt))
                if dt[k] < dq:
                    q, dq = trial[k], float(dt[k])
                else:
                    step *= 0.5
            best_d = min(best_d, dq)
            if best_d <= self.margin:
                break
        return best_d
