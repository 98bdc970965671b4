"""numba kernel that builds a cloud's tree of boxes: a linear BVH in Morton order (small
clouds: a k-d tree).

The tree is the one every query kernel of :mod:`reachwise.distance._kernels` walks: nodes
in depth-first order (node ``k``'s left child is ``k + 1``, its right child
``info[k, 2]``, ``-1`` for a leaf), each covering the contiguous range
``info[k, 0]:info[k, 1]`` of the tree-ordered points and holding their tight
axis-aligned box ``boxes[k]`` (lo xyz, hi xyz); a leaf holds at most ``leaf_size``
points.

How it is built, in time linear in the number of points (a camera frame of 300 000
points or a room scan of a million must be indexed between two 30 Hz frames):

1. Each point gets the 30-bit Morton code of its cell in a 1024³ grid over the cloud's
   bounding cube (x, y, z bits interleaved), and the points are sorted by it with a
   radix sort — three LSD passes of 10 bits (small count tables that stay in cache),
   the last one gathering the points themselves; from
   :data:`~reachwise.distance._morton.MSD_FROM` points on, a first pass by the top 10
   bits that carries the points, then each of those cells sorted and gathered within
   the cache (a shuffled million-point scan gathered in one go spends most of the
   build waiting for memory) —, so points close in space are close in the order
   (:mod:`reachwise.distance._morton`). The bounds come with the points
   (:func:`summary`, or :func:`checked_copy`, which also copies and checks a
   handed-over frame in the same read): no separate pass finds them.
2. A range of points is split where the highest bit in which its first and last codes
   differ changes (found by bisection): the two halves are the two halves of a cell of
   an implicit octree, split along one axis at its midpoint (the linear BVH of Karras,
   2012, built top down). A range whose points share one cell (duplicates, or a few
   far outliers that make the cells coarse) is split instead at the median of its
   box's widest axis, as a k-d tree would be, so such clouds stay well indexed.
   Clouds of up to :data:`MEDIAN_UP_TO` points (robot link clouds, laser scans, thinned
   camera frames) are split at the median of the widest axis throughout instead, as a
   k-d tree: their queries prune better (a 1000-point part against a 5500-point scan:
   11 % faster than on the Morton tree, measured side by side) and the O(n log n)
   build still takes only milliseconds there; the linear build is for the large clouds
   the 30 Hz budget is about.
3. Boxes are computed bottom-up: each leaf's from its points, each inner node's as the
   union of its children's (children always come after their parent in the order).

The boxes are the tight bounds of exactly the points below each node, as any tree of
this layout must hold, so every query stays exact; the build only changes how well the
boxes prune.
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
from numba import njit, types

from reachwise.distance._morton import morton_sort

#: Clouds of up to this many points are split at medians throughout (a k-d tree).
MEDIAN_UP_TO = 1 << 15


@njit(cache=True, nogil=True, inline="always")
def _finish_summary(points, n, lo, hi, sums):  # type: ignore[no-untyped-def]
    """(bad rows, bounds, centroid) from one pass's running bounds ``lo``, ``hi`` and
    coordinate ``sums`` (3-tuples: the pass keeps them as scalars, in registers)."""
    lo0, lo1, lo2 = lo
    hi0, hi1, hi2 = hi
    s0, s1, s2 = sums
    bad = 0
    # a NaN or inf coordinate makes a sum non-finite (NaN propagates, +inf + -inf is
    # NaN): only then are the rows counted one by one
    if not (np.isfinite(s0) and np.isfinite(s1) and np.isfinite(s2)):
        for i in range(n):
            x = points[i, 0]
            y = points[i, 1]
            z = points[i, 2]
            if not (np.isfinite(x) and np.isfinite(y) and np.isfinite(z)):
                bad += 1
        if bad == 0:  # finite points whose sum overflows: take the mean of scaled rows
            s0 = s1 = s2 = 0.0
            for i in range(n):
                s0 += points[i, 0] / n
                s1 += points[i, 1] / n
                s2 += points[i, 2] / n
            s0 *= n
            s1 *= n
            s2 *= n
    bounds = np.empty(6)
    bounds[0] = lo0
    bounds[1] = lo1
    bounds[2] = lo2
    bounds[3] = hi0
    bounds[4] = hi1
    bounds[5] = hi2
    centroid = np.empty(3)
    centroid[0] = s0 / n
    centroid[1] = s1 / n
    centroid[2] = s2 / n
    return bad, bounds, centroid


def _points_types(dtype: Any, layout: Literal["C", "A"]) -> tuple[Any, Any]:
    """The (N, 3) points array type, writable and read-only (a PointCloud's points)."""
    return types.Array(dtype, 2, layout), types.Array(dtype, 2, layout, readonly=True)


_F8 = types.float64[::1]
_SIG_SUMMARY = [types.Tuple((types.int64, _F8, _F8))(t) for t in _points_types(types.float64, "C")]


@njit(_SIG_SUMMARY, cache=True, nogil=True)
def summary(points):  # type: ignore[no-untyped-def]
    """``(bad, bounds, centroid)`` of (N, 3) ``points`` in one pass: how many rows hold
    a NaN or inf, the bounds (lo xyz, hi xyz) and the mean point (summed row by row, as
    ``points.mean(axis=0)`` does)."""
    n = points.shape[0]
    lo0 = lo1 = lo2 = np.inf
    hi0 = hi1 = hi2 = -np.inf
    s0 = s1 = s2 = 0.0
    for i in range(n):
        x = points[i, 0]
        y = points[i, 1]
        z = points[i, 2]
        s0 += x
        s1 += y
        s2 += z
        lo0 = min(lo0, x)
        hi0 = max(hi0, x)
        lo1 = min(lo1, y)
        hi1 = max(hi1, y)
        lo2 = min(lo2, z)
        hi2 = max(hi2, z)
    return _finish_summary(points, n, (lo0, lo1, lo2), (hi0, hi1, hi2), (s0, s1, s2))


_SIG_COPY = [
    types.Tuple((types.float64[:, ::1], types.int64, _F8, _F8))(t)
    for dtype in (types.float64, types.float32)
    for layout in ("C", "A")
    for t in _points_types(dtype, layout)
]


@njit(_SIG_COPY, cache=True, nogil=True)
def checked_copy(points):  # type: ignore[no-untyped-def]
    """``(copy, bad, bounds, centroid)``: a float64 C-ordered copy of (N, 3) ``points``
    (float64 or float32, any strides) and, from the same pass, what :func:`summary`
    returns. One read of the input for what a cloud's ingestion needs before its tree
    (a camera frame handed over as it came off the sensor)."""
    n = points.shape[0]
    out = np.empty((n, 3))
    lo0 = lo1 = lo2 = np.inf
    hi0 = hi1 = hi2 = -np.inf
    s0 = s1 = s2 = 0.0
    for i in range(n):
        x = np.float64(points[i, 0])
        y = np.float64(points[i, 1])
        z = np.float64(points[i, 2])
        out[i, 0] = x
        out[i, 1] = y
        out[i, 2] = z
        s0 += x
        s1 += y
        s2 += z
        lo0 = min(lo0, x)
        hi0 = max(hi0, x)
        lo1 = min(lo1, y)
        hi1 = max(hi1, y)
        lo2 = min(lo2, z)
        hi2 = max(hi2, z)
    bad, bounds, centroid = _finish_summary(out, n, (lo0, lo1, lo2), (hi0, hi1, hi2), (s0, s1, s2))
    return out, bad, bounds, centroid


@njit(cache=True, nogil=True)
def morton_order(points):  # type: ignore[no-untyped-def]
    """``(order, codes)``: the rows of ``points`` sorted by Morton code, and the codes
    in that order (stable)."""
    _, bounds, _ = summary(points)
    _, order, codes = morton_sort(points, bounds)
    return order, codes


@njit(cache=True, nogil=True)
def _swap(pts, idx, i, j):  # type: ignore[no-untyped-def]
    for c in range(3):
        t = pts[i, c]
        pts[i, c] = pts[j, c]
        pts[j, c] = t
    k = idx[i]
    idx[i] = idx[j]
    idx[j] = k


@njit(cache=True, nogil=True)
def _select(pts, idx, axis, s, e, k):  # type: ignore[no-untyped-def]
    """Reorder rows s:e so that row k holds the k-th smallest coordinate ``axis``, rows
    before it are <= and rows after it >= (Hoare selection; robust to duplicates)."""
    lo = s
    hi = e - 1
    while hi > lo:
        a = pts[lo, axis]
        b = pts[(lo + hi) // 2, axis]
        c = pts[hi, axis]
        if a > b:
            a, b = b, a
        if b > c:
            b = c
        pivot = max(a, b)
        i = lo
        j = hi
        while i <= j:
            while pts[i, axis] < pivot:
                i += 1
            while pts[j, axis] > pivot:
                j -= 1
            if i <= j:
                _swap(pts, idx, i, j)
                i += 1
                j -= 1
        if k <= j:
            hi = j
        elif k >= i:
            lo = i
        else:
            break


@njit(cache=True, nogil=True)
def _widest_axis(pts, s, e):  # type: ignore[no-untyped-def]
    lx = ly = lz = np.inf
    hx = hy = hz = -np.inf
    for i in range(s, e):
        x = pts[i, 0]
        y = pts[i, 1]
        z = pts[i, 2]
        lx = min(lx, x)
        hx = max(hx, x)
        ly = min(ly, y)
        hy = max(hy, y)
        lz = min(lz, z)
        hz = max(hz, z)
    ex = hx - lx
    ey = hy - ly
    ez = hz - lz
    if ey > ex and ey >= ez:
        return 1
    if ez > ex and ez > ey:
        return 2
    return 0


@njit(cache=True, nogil=True)
def _split(pts, idx, codes, s, e, median):  # type: ignore[no-untyped-def]
    """Where range s:e splits: at the highest differing Morton bit, or (one cell, or
    ``median``) at the median of the widest axis, reordering s:e for it."""
    cs = codes[s]
    ce = codes[e - 1]
    if not median and cs != ce:
        x = cs ^ ce
        bit = 1
        while x > 1:
            x >>= 1
            bit <<= 1
        lo = s
        hi = e - 1
        while lo < hi:
            mid = (lo + hi) // 2
            if codes[mid] & bit:
                hi = mid
            else:
                lo = mid + 1
        return lo
    m = (s + e) // 2
    _select(pts, idx, _widest_axis(pts, s, e), s, e, m)
    return m


_SIG_BUILD = (
    "Tuple((float64[:, ::1], int64[::1], float64[:, ::1], int64[:, ::1]))(float64[:, ::1], int64)"
)
_TREE = types.Tuple(
    (types.float64[:, ::1], types.int64[::1], types.float64[:, ::1], types.int64[:, ::1])
)
_SIG_BUILD_IN = [_TREE(t, _F8, types.int64) for t in _points_types(types.float64, "C")]
_SIG_BUILD_AS = [
    _TREE(t, _F8, types.int64, types.boolean) for t in _points_types(types.float64, "C")
]


@njit(cache=True, nogil=True)
def tree_of_sorted(pts, idx, codes, leaf_size, median):  # type: ignore[no-untyped-def]
    """The tree over ``pts`` (already gathered in the order ``idx`` of their Morton
    ``codes``; any order for ``median``): ranges split top-down by :func:`_split`
    (reordering ``pts`` and ``idx`` in place), then the boxes bottom-up. Returns what
    :func:`build_tree` does."""
    n = pts.shape[0]
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
        m = _split(pts, idx, codes, s, e, median)
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


@njit(_SIG_BUILD_AS, cache=True, nogil=True)
def build_tree_as(points, bounds, leaf_size, median):  # type: ignore[no-untyped-def]
    """The tree of ``points`` with one split rule: Morton cells (``median`` False; a
    range within one cell still splits at its median) or the median of the widest axis
    of every range (``median`` True: a k-d tree; the points are not Morton-sorted)."""
    n = points.shape[0]
    if median:
        pts = points.copy()
        idx = np.arange(n)
        codes = np.zeros(n, np.int64)  # one cell: every range splits at its median
    else:
        pts, idx, codes = morton_sort(points, bounds)
    return tree_of_sorted(pts, idx, codes, leaf_size, median)


@njit(_SIG_BUILD_IN, cache=True, nogil=True)
def build_tree_in(points, bounds, leaf_size):  # type: ignore[no-untyped-def]
    """:func:`build_tree` with the points' ``bounds`` (lo xyz, hi xyz) known already
    (from :func:`summary` or :func:`checked_copy`): no pass to find them. Clouds of up
    to :data:`MEDIAN_UP_TO` points get median splits throughout (module docstring)."""
    return build_tree_as(points, bounds, leaf_size, points.shape[0] <= MEDIAN_UP_TO)


@njit(_SIG_BUILD, cache=True, nogil=True)
def build_tree(points, leaf_size):  # type: ignore[no-untyped-def]
    """Tree of (N, 3) ``points`` (N ≥ 1): returns (points in tree order, tree → input
    row, node boxes (M, 6) as lo xyz, hi xyz, node info (M, 3) as start, end, right
    child). See the module docstring."""
    _, bounds, _ = summary(points)
    return build_tree_in(points, bounds, leaf_size)
