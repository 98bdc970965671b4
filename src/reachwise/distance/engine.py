"""Exact shortest distance between two placed point clouds (thesis §3.1, P-V Table 1).

Three strategies answer the same question and must agree with each other exactly:

- ``"default"`` (:func:`default_closest`): dual-tree branch and bound. Each cloud has a
  tree of AABBs built once in its own frame (its
  :class:`~reachwise.distance.index.CloudIndex`, kept by the distance layer). Per
  query the smaller cloud's boxes and points are mapped into the larger cloud's frame
  by the relative pose (lazily: only the nodes the search reaches), node pairs are
  expanded depth first, nearer child pair first, while their box distance is below the
  best distance so far; once the smaller cloud's side is a leaf, each of its points
  descends the other tree on its own (point-to-box bounds), nearest points first. The
  best distance starts at the margin ("no risk" as soon as nothing can be within it)
  or at the last closest pair's current distance (warm start, :class:`PairQuery`). One
  compiled (numba) kernel, one core, no BLAS, no allocation beyond a few scratch
  arrays per query.
- ``"thesis"``: the Table 1 pipeline of P-III/P-V — EOBBs, separating-axis test,
  overlap volume, points inside it, exact minimum (:mod:`reachwise.distance.thesis`).
- ``"brute"``: every pair, chunked numpy (:mod:`reachwise.distance.brute`) — the
  reference.

Result convention (distance 0, beyond the margin): see :class:`DistanceResult` and
:mod:`reachwise.distance._common`. Poses are 4x4 rigid transforms mapping each cloud's
frame to world (``None`` = identity).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Literal, get_args

import numpy as np
from numpy.typing import ArrayLike, NDArray

import reachwise.distance._kernels as K
from reachwise.distance._common import (
    NO_RISK,
    DistanceResult,
    as_cloud,
    check_margin,
    check_pose,
    pose_array,
)
from reachwise.distance.brute import brute_closest
from reachwise.distance.index import CloudIndex, cloud_index
from reachwise.distance.thesis import thesis_closest
from reachwise.errors import check_choice
from reachwise.geometry.cloud import PointCloud

#: A distance strategy, all exact: ``default`` (dual-tree branch and bound with warm
#: starts), ``thesis`` (the P-III/P-V Table 1 pipeline), ``brute`` (every pair).
StrategyName = Literal["default", "thesis", "brute"]
STRATEGIES: tuple[StrategyName, ...] = get_args(StrategyName)

Strategy = Callable[
    [PointCloud, PointCloud, NDArray[np.float64], NDArray[np.float64], float], DistanceResult
]


def _fast_pose(pose: ArrayLike | None, name: str) -> NDArray[np.float64]:
    """``check_pose`` with a compiled fast path for poses that are rigid to 1e-12."""
    P = pose_array(pose, name)
    if K.pose_status(P) == 0:
        return P
    return check_pose(P, name)


def _run_default(
    ta: CloudIndex,
    tb: CloudIndex,
    pose_a: NDArray[np.float64],
    pose_b: NDArray[np.float64],
    margin: float,
    warm: tuple[int, int],
) -> tuple[DistanceResult, tuple[int, int]]:
    """One dual-tree query; ``warm`` and the pair returned to warm-start the next one are
    tree-order indices into ``ta`` and ``tb`` (-1: none)."""
    swap = ta.points.shape[0] > tb.points.shape[0]  # map the smaller cloud into the larger's frame
    wa, wb = warm
    out = np.empty(10)
    idx = np.empty(4, np.int64)
    if swap:
        status = K.dual_tree_query(
            tb.points, tb.boxes, tb.info, tb.perm, tb.centroid,
            ta.points, ta.boxes, ta.info, ta.perm, ta.centroid,
            pose_b, pose_a, margin, wb, wa, True, out, idx,
        )  # fmt: skip
        ib, ia, tb_k, ta_k = idx.tolist()
    else:
        status = K.dual_tree_query(
            ta.points, ta.boxes, ta.info, ta.perm, ta.centroid,
            tb.points, tb.boxes, tb.info, tb.perm, tb.centroid,
            pose_a, pose_b, margin, wa, wb, False, out, idx,
        )  # fmt: skip
        ia, ib, ta_k, tb_k = idx.tolist()
    if status != 0:
        return NO_RISK, (-1, -1)
    out.setflags(write=False)
    res = DistanceResult(float(out[0]), out[1:4], out[4:7], out[7:10], ia, ib, False)
    return res, (ta_k, tb_k)


def default_closest(
    a: PointCloud,
    b: PointCloud,
    pose_a: NDArray[np.float64],
    pose_b: NDArray[np.float64],
    margin: float,
) -> DistanceResult:
    """Exact closest pair by dual-tree branch and bound (validated inputs)."""
    return _run_default(cloud_index(a), cloud_index(b), pose_a, pose_b, margin, (-1, -1))[0]


_STRATEGY_FUNCS: dict[StrategyName, Strategy] = {
    "default": default_closest,
    "thesis": thesis_closest,
    "brute": brute_closest,
}


def _check_strategy(strategy: object) -> Strategy:
    fn = _STRATEGY_FUNCS.get(strategy) if type(strategy) is str else None  # type: ignore[call-overload]
    if fn is not None:
        return fn
    return _STRATEGY_FUNCS[check_choice(strategy, STRATEGIES, source="strategy", kind="strategy")]


def closest_points(
    a: PointCloud | ArrayLike,
    b: PointCloud | ArrayLike,
    pose_a: ArrayLike | None = None,
    pose_b: ArrayLike | None = None,
    margin: float = math.inf,
    *,
    strategy: StrategyName = "default",
) -> DistanceResult:
    """Exact shortest distance between clouds ``a`` and ``b`` placed by their poses.

    ``a``, ``b``: :class:`~reachwise.geometry.cloud.PointCloud` (its spatial index is
    built on first use and kept, so repeated queries do not rebuild it) or (N, 3)
    arrays (indexed anew on every call). ``pose_a``, ``pose_b``: 4x4 rigid transforms
    from each cloud's frame to world, ``None`` for identity. ``margin`` (m): beyond it
    the answer is "no risk" (``no_risk=True``, ``distance=inf``, NaN points). Returns a
    :class:`DistanceResult` in world coordinates. ``strategy``: ``"default"``,
    ``"thesis"`` or ``"brute"`` — all exact. Stateless; for a pair queried repeatedly
    use :class:`PairQuery`, which warm-starts from the previous closest pair.

    Raises :class:`~reachwise.errors.CloudError` for bad clouds and
    :class:`~reachwise.errors.InputError` for bad poses or margin, and
    :class:`~reachwise.errors.UnknownName` for an unknown strategy.
    """
    fn = _check_strategy(strategy)
    ca = as_cloud(a, "cloud a")
    cb = as_cloud(b, "cloud b")
    m = check_margin(margin)
    if fn is default_closest:
        Pa = _fast_pose(pose_a, "pose_a")
        Pb = _fast_pose(pose_b, "pose_b")
    else:
        Pa = check_pose(pose_a, "pose_a")
        Pb = check_pose(pose_b, "pose_b")
    return fn(ca, cb, Pa, Pb, m)


class PairQuery:
    """Repeated exact queries of one pair of clouds, e.g. at 100 Hz in a control loop.

    The indices are built at construction (Table 1's initialization phase). With the
    default strategy each query starts its bound from the previous closest pair's
    distance under the new poses (warm start): when the poses change a little between
    queries, that bound is already (nearly) the answer and most of both trees is pruned
    at once. The answer stays exact: the warm pair only tightens the initial bound.
    """

    def __init__(
        self,
        a: PointCloud | ArrayLike,
        b: PointCloud | ArrayLike,
        *,
        margin: float = math.inf,
        strategy: StrategyName = "default",
    ) -> None:
        self._fn = _check_strategy(strategy)
        self.strategy = strategy
        self.a = as_cloud(a, "cloud a")
        self.b = as_cloud(b, "cloud b")
        self.margin = check_margin(margin)
        self._ta = cloud_index(self.a)
        self._tb = cloud_index(self.b)
        self._warm: tuple[int, int] = (-1, -1)

    def reset(self) -> None:
        """Forget the warm-start pair."""
        self._warm = (-1, -1)

    def __call__(
        self,
        pose_a: ArrayLike | None = None,
        pose_b: ArrayLike | None = None,
        margin: float | None = None,
    ) -> DistanceResult:
        """Query with the current poses; ``margin`` overrides the pair's margin."""
        m = self.margin if margin is None else check_margin(margin)
        if self._fn is not default_closest:
            return self._fn(
                self.a, self.b, check_pose(pose_a, "pose_a"), check_pose(pose_b, "pose_b"), m
            )
        Pa = _fast_pose(pose_a, "pose_a")
        Pb = _fast_pose(pose_b, "pose_b")
        res, pair = _run_default(self._ta, self._tb, Pa, Pb, m, self._warm)
        if pair[0] >= 0:
            self._warm = pair
        return res

    query = __call__
