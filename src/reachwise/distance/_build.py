"""numba kernel that builds a cloud's tree of boxes: a linear BVH in Morton order.

The tree is the one every query kernel of :mod:`reachwise.distance._kernels` walks: nodes
in depth-first order (node ``k``'s left child is ``k + 1``, its right child
``info[k, 2]``, ``-1`` for a leaf), each covering the contiguous range
``info[k, 0]:info[k, 1]`` of the tree-ordered points and holding their tight
axis-aligned box ``boxes[k]`` (lo xyz, hi xyz); a leaf holds at most ``leaf_size``
points.

How it is built, in time linear in the number of points (a camera frame of 300 000
points or a room scan of a million must be indexed between two 30 Hz frames, issue 17):

1. Each point gets the 30-bit Morton code of its cell in a 1024³ grid over the cloud's
   bounding cube (x, y, z bits interleaved), and the points are sorted by it with a
   two-pass LSD radix sort (15 bits a pass), so points close in space are close in
   the order.
2. A range of points is split where the highest bit in which its first and last codes
   differ changes (found by bisection): the two halves are the two halves of a cell of
   an implicit octree, split along one axis at its midpoint (the linear BVH of Karras,
   2012, built top down). A range whose points share one cell (duplicates, or a few
   far outliers that make the cells coarse) is split instead at the median of its
   box's widest axis, as a k-d tree would be, so such clouds stay well indexed.
3. Boxes are computed bottom-up: each leaf's from its points, each inner node's as the
   union of its children's (children always come after their parent in the order).

The boxes are the tight bounds of exactly the points below each node, as any tree of
this layout must hold, so every query stays exact; the build only changes how well the
boxes prune.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: Bits of the Morton code per axis (a 1024³ grid over the cloud's bounding cube).
MORTON_BITS = 10
_RADIX = 1 << 15
_MASK15 = np.uint64(_RADIX - 1)
_LOW32 = np.uint64(0xFFFFFFFF)


@njit(cache=True, nogil=True, inline="always")
def _spread(v):  # type: ignore[no-untyped-def]
    """The 10 low bits of ``v`` spread to every third bit (bit i → bit 3i)."""
    v = (v | (v << 16)) & 0x030000FF
    v = (v | (v << 8)) & 0x0300F00F
    v = (v | (v << 4)) & 0x030C30C3
    v = (v | (v << 2)) & 0x09249249
    return v


@njit(cache=True, nogil=True)
def morton_order(points):  # type: ignore[no-untyped-def]
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
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    for i in range(s, e):
        for c in range(3):
            lo[c] = min(lo[c], pts[i, c])
            hi[c] = max(hi[c], pts[i, c])
    ext = hi - lo
    if ext[1] > ext[0] and ext[1] >= ext[2]:
        return 1
    if ext[2] > ext[0] and ext[2] > ext[1]:
        return 2
    return 0


@njit(cache=True, nogil=True)
def _split(pts, idx, codes, s, e):  # type: ignore[no-untyped-def]
    """Where range s:e splits: at the highest differing Morton bit, or (one cell) at the
    median of the widest axis, reordering s:e for it."""
    cs = codes[s]
    ce = codes[e - 1]
    if cs != ce:
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


@njit(_SIG_BUILD, cache=True, nogil=True)
def build_tree(points, leaf_size):  # type: ignore[no-untyped-def]
    """Tree of (N, 3) ``points`` (N ≥ 1): returns (points in tree order, tree → input
    row, node boxes (M, 6) as lo xyz, hi xyz, node info (M, 3) as start, end, right
    child). See the module docstring."""
    n = points.shape[0]
    idx, codes = morton_order(points)
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
