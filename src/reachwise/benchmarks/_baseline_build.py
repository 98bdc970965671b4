"""The ingestion path this issue started from (commit 9be9138), kept for
``reachwise bench realtime`` only: the baseline its build figures are compared with.

A frame became a :class:`~reachwise.geometry.cloud.PointCloud` (a copy and a NaN check
in numpy), then ``build_index`` copied the points again, built the tree with a
two-pass 15-bit radix sort (a pass for the bounds, a separate gather), made the
inverse permutation and took the mean in numpy. :func:`ingest_baseline` does exactly
that; the tree kernel is the one of that commit, copied (its split and box helpers are
unchanged in :mod:`reachwise.distance._build`).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from reachwise.distance._build import MORTON_BITS, _split, _spread
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
    cap = 2 * (n // max(1, leaf_size // 2)) + 3
    info = np.empty((cap, 3), np.int64)
    st_s = np.empty(512, np.int64)
    st_e = np.empty(512, np.int64)
    st_p = np.empty(512, np.int64)
    st_s[0] = 0
    st_e[0] = n
    st_p[0] = -1
    sp = 1
    count = 0
    while sp > 0:
        sp -= 1
        s = st_s[sp]
        e = st_e[sp]
        parent = st_p[sp]
        if count == info.shape[0]:
            grown = np.empty((2 * count, 3), np.int64)
            grown[:count] = info
            info = grown
        node = count
        count += 1
        if parent >= 0:
            info[parent, 2] = node
        info[node, 0] = s
        info[node, 1] = e
        info[node, 2] = -1
        if e - s <= leaf_size:
            continue
        m = _split(pts, idx, codes, s, e)
        st_s[sp] = m  # right child: pushed first, built after the whole left subtree
        st_e[sp] = e
        st_p[sp] = node
        sp += 1
        st_s[sp] = s  # left child: built next, so it gets id node + 1
        st_e[sp] = m
        st_p[sp] = -1
        sp += 1
    boxes = np.empty((count, 6))
    for k in range(count - 1, -1, -1):
        r = info[k, 2]
        if r < 0:
            lx = ly = lz = np.inf
            hx = hy = hz = -np.inf
            for i in range(info[k, 0], info[k, 1]):
                x = pts[i, 0]
                y = pts[i, 1]
                z = pts[i, 2]
                lx = min(lx, x)
                hx = max(hx, x)
                ly = min(ly, y)
                hy = max(hy, y)
                lz = min(lz, z)
                hz = max(hz, z)
            boxes[k, 0] = lx
            boxes[k, 1] = ly
            boxes[k, 2] = lz
            boxes[k, 3] = hx
            boxes[k, 4] = hy
            boxes[k, 5] = hz
        else:
            left = k + 1
            for c in range(3):
                boxes[k, c] = min(boxes[left, c], boxes[r, c])
                boxes[k, c + 3] = max(boxes[left, c + 3], boxes[r, c + 3])
    return pts, idx, boxes, info[:count].copy()


def ingest_baseline(points: NDArray[np.float64], leaf_size: int = 8) -> tuple[object, ...]:
    """What ingesting ``points`` cost at commit 9be9138: the cloud, then its index."""
    cloud = PointCloud(points)
    pts = np.array(cloud.points, dtype=np.float64, order="C", copy=True)
    tp, perm, boxes, info = build_tree(pts, leaf_size)
    inverse = np.empty_like(perm)
    inverse[perm] = np.arange(perm.shape[0])
    centroid = np.ascontiguousarray(pts.mean(axis=0))
    return cloud, tp, perm, inverse, boxes, info, centroid
