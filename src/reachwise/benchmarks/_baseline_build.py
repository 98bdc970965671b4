"""The ingestion path of commit 9be9138 (before the ingestion worker), kept for
``reachwise bench realtime`` only: the baseline its build figures are compared with.

A frame became a :class:`~reachwise.geometry.cloud.PointCloud` (a copy and a NaN check
in numpy), then ``build_index`` copied the points again, built the tree with a
two-pass 15-bit radix sort (a pass for the bounds, a separate gather), made the
inverse permutation and took the mean in numpy. :func:`ingest_baseline` does exactly
that: its sort and copies are the ones of that commit, copied here; the splits and
boxes after the sort are unchanged since, so they are
:func:`reachwise.distance._build.tree_of_sorted`.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from reachwise.distance._build import tree_of_sorted
from reachwise.distance._morton import MORTON_BITS, _spread
from reachwise.geometry.cloud import PointCloud

_RADIX = 1 << 15
_MASK15 = np.uint64(_RADIX - 1)
_LOW32 = np.uint64(0xFFFFFFFF)


@njit(cache=True, nogil=True)
def _morton_order(points):  # type: ignore[no-untyped-def]
    """``(order, codes)``: the rows of ``points`` sorted by Morton code, and the codes
    in that order (two-pass LSD radix sort of ``code << 32 | row``; stable)."""
    n = points.shape[0]
    lo0 = lo1 = lo2 = np.inf
    hi0 = hi1 = hi2 = -np.inf
    for i in range(n):
        x = points[i, 0]
        y = points[i, 1]
        z = points[i, 2]
        lo0 = min(lo0, x)
        hi0 = max(hi0, x)
        lo1 = min(lo1, y)
        hi1 = max(hi1, y)
        lo2 = min(lo2, z)
        hi2 = max(hi2, z)
    span = max(hi0 - lo0, hi1 - lo1, hi2 - lo2)
    # cells of a cube (not of the box): splits halve the longest side first
    scale = ((1 << MORTON_BITS) - 1e-3) / span if span > 0.0 else 0.0
    keys = np.empty(n, np.uint64)
    tmp = np.empty(n, np.uint64)
    count_lo = np.zeros(_RADIX, np.int64)
    count_hi = np.zeros(_RADIX, np.int64)
    for i in range(n):
        cx = np.uint32((points[i, 0] - lo0) * scale)
        cy = np.uint32((points[i, 1] - lo1) * scale)
        cz = np.uint32((points[i, 2] - lo2) * scale)
        code = (_spread(cx) << 2) | (_spread(cy) << 1) | _spread(cz)
        keys[i] = (np.uint64(code) << np.uint64(32)) | np.uint64(i)
        count_lo[code & (_RADIX - 1)] += 1
        count_hi[code >> 15] += 1
    run_lo = 0
    run_hi = 0
    for b in range(_RADIX):
        c = count_lo[b]
        count_lo[b] = run_lo
        run_lo += c
        c = count_hi[b]
        count_hi[b] = run_hi
        run_hi += c
    for i in range(n):
        k = keys[i]
        b = (k >> np.uint64(32)) & _MASK15
        j = count_lo[b]
        count_lo[b] = j + 1
        tmp[j] = k
    for i in range(n):
        k = tmp[i]
        b = k >> np.uint64(47)
        j = count_hi[b]
        count_hi[b] = j + 1
        keys[j] = k
    order = np.empty(n, np.int64)
    codes = np.empty(n, np.int64)
    for i in range(n):
        order[i] = np.int64(keys[i] & _LOW32)
        codes[i] = np.int64(keys[i] >> np.uint64(32))
    return order, codes


_SIG = (
    "Tuple((float64[:, ::1], int64[::1], float64[:, ::1], int64[:, ::1]))(float64[:, ::1], int64)"
)


@njit(_SIG, cache=True, nogil=True)
def build_tree(points, leaf_size):  # type: ignore[no-untyped-def]
    """Tree of (N, 3) ``points`` (N ≥ 1): returns (points in tree order, tree → input
    row, node boxes (M, 6) as lo xyz, hi xyz, node info (M, 3) as start, end, right
    child). See the module docstring."""
    n = points.shape[0]
    idx, codes = _morton_order(points)
    pts = np.empty((n, 3))
    for i in range(n):
        r = idx[i]
        pts[i, 0] = points[r, 0]
        pts[i, 1] = points[r, 1]
        pts[i, 2] = points[r, 2]
    return tree_of_sorted(pts, idx, codes, leaf_size, False)


def ingest_baseline(points: NDArray[np.float64], leaf_size: int = 8) -> tuple[object, ...]:
    """What ingesting ``points`` cost at commit 9be9138: the cloud, then its index."""
    cloud = PointCloud(points)
    pts = np.array(cloud.points, dtype=np.float64, order="C", copy=True)
    tp, perm, boxes, info = build_tree(pts, leaf_size)
    inverse = np.empty_like(perm)
    inverse[perm] = np.arange(perm.shape[0])
    centroid = np.ascontiguousarray(pts.mean(axis=0))
    return cloud, tp, perm, inverse, boxes, info, centroid
