"""Morton (Z-order) sort of a cloud's points, the first step of the tree build
(:mod:`reachwise.distance._build`): each point gets the 30-bit Morton code of its cell in
a 1024³ grid over the cloud's bounding cube (x, y, z bits interleaved) and the points
are sorted by it with a radix sort — three LSD passes of 10 bits, or from
:data:`MSD_FROM` points on a first pass by the top 10 bits and each of those cells
sorted within the cache — so points close in space are close in the order.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["MORTON_BITS", "MSD_FROM", "morton_sort"]

#: Bits of the Morton code per axis (a 1024³ grid over the cloud's bounding cube).
MORTON_BITS = 10
_RADIX_BITS = 10
_PASSES = 3  # 3 x 10 bits: the 30-bit code
_RADIX = 1 << _RADIX_BITS
_MASK = np.uint64(_RADIX - 1)
_LOW32 = np.uint64(0xFFFFFFFF)
#: From this many points on, the sort goes top-down (:func:`_sorted_msd`).
MSD_FROM = 1 << 19


@njit(cache=True, nogil=True, inline="always")
def _spread(v):  # type: ignore[no-untyped-def]
    """The 10 low bits of ``v`` spread to every third bit (bit i → bit 3i)."""
    v = (v | (v << 16)) & 0x030000FF
    v = (v | (v << 8)) & 0x0300F00F
    v = (v | (v << 4)) & 0x030C30C3
    v = (v | (v << 2)) & 0x09249249
    return v


@njit(cache=True, nogil=True, inline="always")
def _scale(bounds):  # type: ignore[no-untyped-def]
    """Cells per metre of the Morton grid: a cube over the bounds (not the box), so
    that splits halve the longest side first."""
    span = max(bounds[3] - bounds[0], bounds[4] - bounds[1], bounds[5] - bounds[2])
    return ((1 << MORTON_BITS) - 1e-3) / span if span > 0.0 else 0.0


@njit(cache=True, nogil=True, inline="always")
def _code(points, i, lo0, lo1, lo2, scale):  # type: ignore[no-untyped-def]
    """The 30-bit Morton code of row ``i``."""
    cx = np.uint32((points[i, 0] - lo0) * scale)
    cy = np.uint32((points[i, 1] - lo1) * scale)
    cz = np.uint32((points[i, 2] - lo2) * scale)
    return np.uint64((_spread(cx) << 2) | (_spread(cy) << 1) | _spread(cz))


@njit(cache=True, nogil=True)
def morton_sort(points, bounds):  # type: ignore[no-untyped-def]
    """``(tree_points, order, codes)``: the rows of ``points`` sorted by Morton code
    and then by row (stable), and the points gathered in that order. ``bounds`` (lo
    xyz, hi xyz) bound the points. Two sorts give the same result: an LSD radix sort
    for up to :data:`MSD_FROM` points, a top-down one above (its gather stays in cache
    however the input is ordered)."""
    if points.shape[0] >= MSD_FROM:
        return _sorted_msd(points, bounds)
    return _sorted_lsd(points, bounds)


@njit(cache=True, nogil=True)
def _sorted_lsd(points, bounds):  # type: ignore[no-untyped-def]
    """:func:`morton_sort` by three 10-bit passes of an LSD radix sort of ``code << 32 |
    row``, the points gathered in the last pass (fast when the input's order is
    already local, as a camera's raster or a scanner's lines are; the gather's reads
    jump across all the points otherwise)."""
    n = points.shape[0]
    lo0 = bounds[0]
    lo1 = bounds[1]
    lo2 = bounds[2]
    scale = _scale(bounds)
    keys = np.empty(n, np.uint64)
    tmp = np.empty(n, np.uint64)
    counts = np.zeros((_PASSES, _RADIX), np.int64)
    for i in range(n):
        code = _code(points, i, lo0, lo1, lo2, scale)
        keys[i] = (code << np.uint64(32)) | np.uint64(i)
        for p in range(_PASSES):
            counts[p, (code >> np.uint64(p * _RADIX_BITS)) & _MASK] += 1
    for p in range(_PASSES):
        run = 0
        for b in range(_RADIX):
            c = counts[p, b]
            counts[p, b] = run
            run += c
    src = keys
    dst = tmp
    for p in range(_PASSES - 1):
        shift = np.uint64(32 + p * _RADIX_BITS)
        for i in range(n):
            k = src[i]
            b = (k >> shift) & _MASK
            j = counts[p, b]
            counts[p, b] = j + 1
            dst[j] = k
        src, dst = dst, src
    # last pass: scatter straight into the outputs, gathering each point with its key
    order = np.empty(n, np.int64)
    codes = np.empty(n, np.int64)
    pts = np.empty((n, 3))
    last = _PASSES - 1
    shift = np.uint64(32 + last * _RADIX_BITS)
    for i in range(n):
        k = src[i]
        b = (k >> shift) & _MASK
        j = counts[last, b]
        counts[last, b] = j + 1
        r = np.int64(k & _LOW32)
        order[j] = r
        codes[j] = np.int64(k >> np.uint64(32))
        pts[j, 0] = points[r, 0]
        pts[j, 1] = points[r, 1]
        pts[j, 2] = points[r, 2]
    return pts, order, codes


@njit(cache=True, nogil=True)
def _sorted_msd(points, bounds):  # type: ignore[no-untyped-def]
    """:func:`morton_sort` top-down: the points, their rows and codes are first scattered
    (stably) into the 1024 cells of the code's top 10 bits — one sequential read, 1024
    write streams —, then each cell is sorted on its low 20 bits by a two-pass LSD
    radix sort and gathered, all within the cell's few kilobytes (insertion sort for a
    cell of a few points). One compiled function on purpose: the passes share their
    count tables and buffers, allocated once for the cloud."""
    n = points.shape[0]
    lo0 = bounds[0]
    lo1 = bounds[1]
    lo2 = bounds[2]
    scale = _scale(bounds)
    code_of = np.empty(n, np.uint32)
    top = np.zeros(_RADIX + 1, np.int64)
    for i in range(n):
        code = _code(points, i, lo0, lo1, lo2, scale)
        code_of[i] = np.uint32(code)
        top[np.int64(code >> np.uint64(20)) + 1] += 1
    for b in range(_RADIX):
        top[b + 1] += top[b]
    at = top[:_RADIX].copy()
    keys = np.empty(n, np.uint64)  # code << 32 | row, bucketed by the top bits
    near = np.empty((n, 3))  # the points, bucketed alike
    for i in range(n):
        c = code_of[i]
        b = np.int64(c >> 20)
        j = at[b]
        at[b] = j + 1
        keys[j] = (np.uint64(c) << np.uint64(32)) | np.uint64(i)
        near[j, 0] = points[i, 0]
        near[j, 1] = points[i, 1]
        near[j, 2] = points[i, 2]
    order = np.empty(n, np.int64)
    codes = np.empty(n, np.int64)
    pts = np.empty((n, 3))
    local = np.empty(n, np.uint64)  # low 20 bits << 32 | position in keys
    tmp = np.empty(n, np.uint64)
    low_mask = np.uint64((1 << 20) - 1)
    count0 = np.empty(_RADIX, np.int64)
    count1 = np.empty(_RADIX, np.int64)
    for b in range(_RADIX):
        s = top[b]
        e = top[b + 1]
        if e == s:
            continue
        for i in range(s, e):
            local[i] = (((keys[i] >> np.uint64(32)) & low_mask) << np.uint64(32)) | np.uint64(i)
        if e - s <= 32:
            for i in range(s + 1, e):  # insertion sort: positions break ties stably
                k = local[i]
                j = i
                while j > s and local[j - 1] > k:
                    local[j] = local[j - 1]
                    j -= 1
                local[j] = k
            sorted_local = local
        else:
            count0[:] = 0
            count1[:] = 0
            for i in range(s, e):
                low = local[i] >> np.uint64(32)
                count0[np.int64(low & _MASK)] += 1
                count1[np.int64(low >> np.uint64(_RADIX_BITS))] += 1
            r0 = s
            r1 = s
            for d in range(_RADIX):
                c0 = count0[d]
                count0[d] = r0
                r0 += c0
                c1 = count1[d]
                count1[d] = r1
                r1 += c1
            for i in range(s, e):
                k = local[i]
                d = np.int64((k >> np.uint64(32)) & _MASK)
                j = count0[d]
                count0[d] = j + 1
                tmp[j] = k
            for i in range(s, e):
                k = tmp[i]
                d = np.int64(k >> np.uint64(32 + _RADIX_BITS))
                j = count1[d]
                count1[d] = j + 1
                local[j] = k
            sorted_local = local
        for j in range(s, e):
            src = np.int64(sorted_local[j] & _LOW32)
            full = keys[src]
            order[j] = np.int64(full & _LOW32)
            codes[j] = np.int64(full >> np.uint64(32))
            pts[j, 0] = near[src, 0]
            pts[j, 1] = near[src, 1]
            pts[j, 2] = near[src, 2]
    return pts, order, codes
