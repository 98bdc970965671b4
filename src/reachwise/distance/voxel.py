"""Voxel thinning of a handed-over cloud, compiled, for ingestion at camera rate.

:func:`reachwise.geometry.cloud.voxel_downsample` keeps one point per occupied voxel —
the input point nearest to the centroid of the voxel's points, ties to the smallest
``(x, y, z)``, in voxel order (P-V §IV's "points within 3 cm"). It is numpy code that
sorts with ``np.unique`` and ``np.lexsort`` and holds the GIL in between: fine for a
scan file, too slow for a 300 000-point frame 30 times a second. :func:`voxel_thin` is
the same rule in one numba pass that releases the GIL (a radix sort by voxel, the
points of each voxel in ``(x, y, z)`` order, their centroid summed in that order, the
nearest point kept) and keeps the same voxels in the same order; for grids too large
for its 63-bit sort keys it calls ``voxel_downsample`` itself. Where two points of a
voxel are equally near the centroid up to rounding, the two may keep different ones
(numpy's ``einsum`` and this loop round the squared distances differently).

A scene thinning its handed-over clouds (``Scene(voxel=...)``) swaps in the thinned
cloud: its answers are exact on that cloud — the cloud :attr:`Scene.objects` reports
— not on the dropped points, which lie within one voxel diagonal of a kept one.
"""

from __future__ import annotations

import numbers

import numpy as np
from numba import njit, types
from numpy.typing import ArrayLike, NDArray

from reachwise.errors import CloudError
from reachwise.geometry.cloud import PointCloud, voxel_downsample

__all__ = ["voxel_thin"]

_BITS = 11  # radix digit
_LIMIT = 2.0**62  # voxel numbers and grid cells must stay below this


@njit(cache=True, nogil=True)
def _radix_order(keys, bits):  # type: ignore[no-untyped-def]
    """Stable order of non-negative int64 ``keys`` < 2**bits: an LSD radix sort (11 bits
    a pass) of ``key << r | row`` (``r`` bits for the row), the row carried with its
    key so that every pass reads and writes in sequence. Needs ``bits + r <= 63``."""
    n = keys.shape[0]
    r = 1
    while (np.int64(1) << r) < n:
        r += 1
    low = (np.int64(1) << r) - 1
    radix = 1 << _BITS
    passes = (bits + _BITS - 1) // _BITS
    a = np.empty(n, np.int64)
    b = np.empty(n, np.int64)
    count = np.zeros((max(passes, 1), radix), np.int64)
    for i in range(n):
        k = keys[i]
        a[i] = (k << r) | i
        for p in range(passes):
            count[p, (k >> (p * _BITS)) & (radix - 1)] += 1
    for p in range(passes):
        run = 0
        for d in range(radix):
            c = count[p, d]
            count[p, d] = run
            run += c
        shift = r + p * _BITS
        for i in range(n):
            v = a[i]
            d = (v >> shift) & (radix - 1)
            b[count[p, d]] = v
            count[p, d] += 1
        a, b = b, a
    for i in range(n):
        b[i] = a[i] & low
    return b


@njit(cache=True, nogil=True, inline="always")
def _before(pts, i, j):  # type: ignore[no-untyped-def]
    """Row i comes before row j in (x, y, z) order (ties: the earlier row first)."""
    for c in range(3):
        if pts[i, c] != pts[j, c]:
            return pts[i, c] < pts[j, c]
    return i < j


@njit(cache=True, nogil=True)
def _sort_group(pts, order, s, e, tmp):  # type: ignore[no-untyped-def]
    """Sort ``order[s:e]`` by the (x, y, z) of its rows: insertion sort for a few rows,
    bottom-up merge sort for many."""
    if e - s <= 32:
        for i in range(s + 1, e):
            r = order[i]
            k = i
            while k > s and _before(pts, r, order[k - 1]):
                order[k] = order[k - 1]
                k -= 1
            order[k] = r
        return
    width = 1
    n = e - s
    while width < n:
        for lo in range(s, e, 2 * width):
            mid = min(lo + width, e)
            hi = min(lo + 2 * width, e)
            i = lo
            j = mid
            k = lo
            while i < mid and j < hi:
                if _before(pts, order[j], order[i]):
                    tmp[k] = order[j]
                    j += 1
                else:
                    tmp[k] = order[i]
                    i += 1
                k += 1
            while i < mid:
                tmp[k] = order[i]
                i += 1
                k += 1
            while j < hi:
                tmp[k] = order[j]
                j += 1
                k += 1
        for k in range(s, e):
            order[k] = tmp[k]
        width *= 2


_SIG = [
    types.Tuple((types.float64[:, ::1], types.int64))(t, types.float64)
    for dtype in (types.float64, types.float32)
    for layout in ("C", "A")
    for t in (types.Array(dtype, 2, layout), types.Array(dtype, 2, layout, readonly=True))
]


@njit(_SIG, cache=True, nogil=True)
def _thin(points, voxel):  # type: ignore[no-untyped-def]
    """``(kept points, status)``: status 0 done, 1 a coordinate is not finite, 2 the
    grid is too fine for 62-bit voxel numbers (the caller falls back). One compiled
    function on purpose: its three passes (each point's cell and the grid's bounds;
    the voxel numbers and their order; each voxel's point nearest its centroid) share
    the buffers allocated once for the cloud, which helpers would pass around; the
    sorts it calls are compiled helpers of their own."""
    n = points.shape[0]
    pts = np.empty((n, 3))
    cell = np.empty((n, 3), np.int64)
    big = np.iinfo(np.int64).max
    lo0 = lo1 = lo2 = big
    hi0 = hi1 = hi2 = -big
    for i in range(n):
        x = np.float64(points[i, 0])
        y = np.float64(points[i, 1])
        z = np.float64(points[i, 2])
        if not (np.isfinite(x) and np.isfinite(y) and np.isfinite(z)):
            return np.empty((0, 3)), 1
        pts[i, 0] = x
        pts[i, 1] = y
        pts[i, 2] = z
        fx = np.floor(x / voxel)
        fy = np.floor(y / voxel)
        fz = np.floor(z / voxel)
        if not (abs(fx) < _LIMIT and abs(fy) < _LIMIT and abs(fz) < _LIMIT):
            return np.empty((0, 3)), 2
        kx = np.int64(fx)
        ky = np.int64(fy)
        kz = np.int64(fz)
        cell[i, 0] = kx
        cell[i, 1] = ky
        cell[i, 2] = kz
        lo0 = min(lo0, kx)
        lo1 = min(lo1, ky)
        lo2 = min(lo2, kz)
        hi0 = max(hi0, kx)
        hi1 = max(hi1, ky)
        hi2 = max(hi2, kz)
    # one voxel number per point, in lexicographic (i, j, k) order
    s0 = hi0 - lo0 + 1
    s1 = hi1 - lo1 + 1
    s2 = hi2 - lo2 + 1
    total = float(s0) * float(s1) * float(s2)
    r = 1
    while (np.int64(1) << r) < n:
        r += 1
    if not total * 2.0**r < _LIMIT:  # voxel number and row must share 63 bits
        return np.empty((0, 3)), 2
    keys = np.empty(n, np.int64)
    for i in range(n):
        keys[i] = ((cell[i, 0] - lo0) * s1 + (cell[i, 1] - lo1)) * s2 + (cell[i, 2] - lo2)
    bits = 1
    while (np.int64(1) << bits) < np.int64(total):
        bits += 1
    order = _radix_order(keys, bits)
    sorted_keys = np.empty(n, np.int64)
    for i in range(n):
        sorted_keys[i] = keys[order[i]]
    tmp = np.empty(n, np.int64)
    out = np.empty((n, 3))
    m = 0
    s = 0
    while s < n:
        e = s + 1
        while e < n and sorted_keys[e] == sorted_keys[s]:
            e += 1
        if e - s > 1:
            _sort_group(pts, order, s, e, tmp)
        # centroid summed in (x, y, z) order, then the point nearest to it (first wins)
        sx = sy = sz = 0.0
        for k in range(s, e):
            r = order[k]
            sx += pts[r, 0]
            sy += pts[r, 1]
            sz += pts[r, 2]
        cnt = e - s
        cx = sx / cnt
        cy = sy / cnt
        cz = sz / cnt
        best = np.inf
        pick = order[s]
        for k in range(s, e):
            r = order[k]
            dx = pts[r, 0] - cx
            dy = pts[r, 1] - cy
            dz = pts[r, 2] - cz
            d2 = dx * dx + dy * dy + dz * dz
            if d2 < best:
                best = d2
                pick = r
        out[m, 0] = pts[pick, 0]
        out[m, 1] = pts[pick, 1]
        out[m, 2] = pts[pick, 2]
        m += 1
        s = e
    return out[:m].copy(), 0


def voxel_thin(cloud: PointCloud | ArrayLike, voxel: float, *, name: str = "") -> PointCloud:
    """One point per occupied voxel of edge ``voxel`` metres (grid anchored at the
    frame origin): the same points, in the same order, as
    :func:`reachwise.geometry.cloud.voxel_downsample` ``(cloud, voxel)``, compiled and
    without the GIL (see the module docstring). Frame and name kept (``name`` names an
    array). Raises :class:`~reachwise.errors.CloudError` for bad points or voxel."""
    src = cloud.name if isinstance(cloud, PointCloud) and cloud.name else name
    where = src or "point cloud"
    if isinstance(voxel, bool) or not isinstance(voxel, numbers.Real):
        raise CloudError(where, "voxel", f"expected a number in metres, got {voxel!r}")
    size = float(voxel)
    if not np.isfinite(size) or size <= 0.0:
        raise CloudError(where, "voxel", f"must be a finite length > 0 m, got {size!r}")
    frame = cloud.frame if isinstance(cloud, PointCloud) else "world"
    pts = cloud.points if isinstance(cloud, PointCloud) else _points(cloud, src)
    kept, status = _thin(pts, size)
    if status == 1:
        PointCloud(pts, name=src)  # raises the CloudError naming the bad points
    if status == 2:
        return voxel_downsample(PointCloud(pts, frame=frame, name=src), size)
    return PointCloud.of_checked(kept, frame=frame, name=src)


def _points(data: ArrayLike, source: str) -> NDArray[np.floating]:
    arr = np.asarray(data)
    if arr.dtype not in (np.float64, np.float32):
        try:
            arr = arr.astype(np.float64)
        except (TypeError, ValueError) as exc:
            raise CloudError(source or "point cloud", "points", f"not numeric: {exc}") from None
    if arr.ndim == 1 and arr.shape[0] == 3:
        arr = arr.reshape(1, 3)
    if arr.ndim != 2 or arr.shape[1] != 3 or arr.shape[0] == 0:
        raise CloudError(
            source or "point cloud", "points", f"expected shape (N, 3), N >= 1, got {arr.shape}"
        )
    return arr
