"""The ``thesis`` strategy: P-V Table 1 (= P-III Table 1) as written, kept exact.

Initialization phase (per cloud, once: its :class:`~reachwise.distance.index.CloudIndex`):

1. input: the point cloud (in its own frame);
2. a spatial index of the cloud — the thesis uses an octree; we use the same compact
   k-d tree the default strategy uses (:mod:`reachwise.distance._kernels`), which
   answers the same box range query;
3. the tight AABB of the cloud in its frame, to be enlarged by δx.

Calculation phase (per query, :func:`thesis_closest`):

4. input: the two poses;
5. the EOBBs: each AABB enlarged by δx and placed by its pose
   (:func:`reachwise.geometry.boxes.eobb`);
6. separating-axis test of the EOBBs (:func:`~reachwise.geometry.boxes.obb_overlap`):
   disjoint → no risk;
7. the overlap volume of the EOBBs, and 8. its AABB in each cloud's frame (the inverse
   pose; :func:`~reachwise.geometry.boxes.overlap_box`);
9. the points of each cloud inside its AABB (tree range query): none → no risk;
10. those points mapped to world by the poses;
11. the shortest distance among them (every pair; a compiled loop).

δx and exactness. The thesis fixes δx at initialization; a query's margin may change,
so we enlarge by δx = margin at query time (δx = margin is the smallest value that
keeps the exits of steps 6 and 9 exact). Why it is exact: if the two clouds have a
pair p ∈ A, q ∈ B with ‖p − q‖ <= margin, then p lies within ``margin`` of B's tight
box in every coordinate of B's frame, so p ∈ EOBB_B; trivially p ∈ EOBB_A; so p is in
the overlap volume, and likewise q. Hence when the true distance is within the margin
the closest pair survives steps 6–9 and step 11 returns it; otherwise every surviving
pair (if any) is beyond the margin and the answer is "no risk". The boxes are padded
for rounding and the SAT is conservative, so rounding never loses such a pair. With
``margin = inf`` the boxes are unbounded: every point is kept (steps 5–9 are skipped).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

import reachwise.distance._thesis_kernels as TK
from reachwise.distance._common import NO_RISK, DistanceResult, result_from_pair, world
from reachwise.distance.index import cloud_index
from reachwise.geometry.boxes import eobb, obb_overlap, overlap_box
from reachwise.geometry.cloud import PointCloud


def thesis_candidates(
    a: PointCloud,
    b: PointCloud,
    pose_a: NDArray[np.float64],
    pose_b: NDArray[np.float64],
    margin: float,
) -> tuple[NDArray[np.int64], NDArray[np.int64]] | None:
    """Table 1 steps 5–9: the input rows of a and of b inside the overlap volume of the
    EOBBs (δx = margin), or None for "no risk"."""
    ta, tb = cloud_index(a), cloud_index(b)
    if math.isinf(margin):
        return ta.perm, tb.perm
    ea = eobb(ta.aabb, pose_a, margin)  # step 3's tight AABBs are the trees' root boxes
    eb = eobb(tb.aabb, pose_b, margin)
    if not obb_overlap(ea, eb):
        return None
    va = overlap_box(ea, eb)
    vb = overlap_box(eb, ea)
    if va is None or vb is None:
        return None
    sa = TK.range_query(ta.points, ta.boxes, ta.info, np.array(va.lo), np.array(va.hi))
    if sa.shape[0] == 0:
        return None
    sb = TK.range_query(tb.points, tb.boxes, tb.info, np.array(vb.lo), np.array(vb.hi))
    if sb.shape[0] == 0:
        return None
    return ta.perm[sa], tb.perm[sb]


def thesis_closest(
    a: PointCloud,
    b: PointCloud,
    pose_a: NDArray[np.float64],
    pose_b: NDArray[np.float64],
    margin: float,
) -> DistanceResult:
    """Exact closest pair by the Table 1 pipeline (validated inputs; see
    ``closest_points``)."""
    cand = thesis_candidates(a, b, pose_a, pose_b, margin)
    if cand is None:
        return NO_RISK
    ia, ib = cand
    wa = np.ascontiguousarray(world(a.points[ia], pose_a))  # step 10
    wb = np.ascontiguousarray(world(b.points[ib], pose_b))
    _, i, j = TK.min_pair(wa, wb)  # step 11
    return result_from_pair(a, b, pose_a, pose_b, int(ia[i]), int(ib[j]), margin)
