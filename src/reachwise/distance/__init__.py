"""Exact shortest distance between point clouds and the scene of watched pairs.

Thesis §3.1, P-III §2, P-V §II and Table 1. Public entry:
``closest_points(a, b, pose_a=None, pose_b=None, margin=inf, *, strategy="default")
-> DistanceResult(distance, point_a, point_b, direction, index_a, index_b, no_risk)``.
Importing this package compiles (or loads from numba's cache) the distance kernels, so
no query ever compiles.
"""

from reachwise.distance._common import NO_RISK, DistanceResult
from reachwise.distance.engine import STRATEGIES, PairQuery, closest_points
from reachwise.distance.scene import PairResult, RobotLike, Scene, SceneResult, WatchedPair

__all__ = [
    "NO_RISK",
    "STRATEGIES",
    "DistanceResult",
    "PairQuery",
    "PairResult",
    "RobotLike",
    "Scene",
    "SceneResult",
    "WatchedPair",
    "closest_points",
]
