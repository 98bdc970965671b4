"""Fewest-points covers of a point set: every point within a radius of a kept one.

:func:`greedy_cover` visits the points in a seeded random order and keeps a point when
no point kept so far lies within ``radius`` of it. The kept points are then a maximal
set none of whose members is within ``radius`` of another, so every input point is
within ``radius`` of a kept one, and on a surface sampled much finer than ``radius``
about one point per ``radius²`` of area is kept (a disc packing of the surface).

The kept points are found through a hashed grid of cells of edge ``radius``: a point's
neighbours within ``radius`` lie in its own cell or the 26 around it; the cells hash
into a table of twice as many slots as points, each slot a linked list of kept points
(a collision only adds candidates, whose distance is checked anyway). Compiled with
numba: one pass, about 27 cell lookups per point, memory linear in the points.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from reachwise.errors import InputError

__all__ = ["greedy_cover"]


@njit(cache=True, nogil=True)
def _cover(points, order, radius):  # type: ignore[no-untyped-def]
    """Indices of the kept points (module docstring), in ``order``'s order."""
    n = points.shape[0]
    lo0, lo1, lo2 = points[:, 0].min(), points[:, 1].min(), points[:, 2].min()
    size = 2 * n + 1
    head = np.full(size, -1, np.int64)
    nxt = np.full(n, -1, np.int64)
    kept = np.empty(n, np.int64)
    count = 0
    r2 = radius * radius
    for k in range(n):
        i = order[k]
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        cx = np.int64((x - lo0) / radius)
        cy = np.int64((y - lo1) / radius)
        cz = np.int64((z - lo2) / radius)
        covered = False
        for dx in range(-1, 2):
            for dy in range(-1, 2):
                for dz in range(-1, 2):
                    h = ((cx + dx) * 73856093) ^ ((cy + dy) * 19349663) ^ ((cz + dz) * 83492791)
                    j = head[h % size]
                    while j >= 0:
                        ex = points[j, 0] - x
                        ey = points[j, 1] - y
                        ez = points[j, 2] - z
                        if ex * ex + ey * ey + ez * ez <= r2:
                            covered = True
                            break
                        j = nxt[j]
                    if covered:
                        break
                if covered:
                    break
            if covered:
                break
        if not covered:
            slot = ((cx * 73856093) ^ (cy * 19349663) ^ (cz * 83492791)) % size
            nxt[i] = head[slot]
            head[slot] = i
            kept[count] = i
            count += 1
    return kept[:count]


def greedy_cover(points: ArrayLike, radius: float, seed: int = 0) -> NDArray[np.intp]:
    """Indices (ascending) of points of ``points`` (N, 3) such that every point lies
    within ``radius`` (m) of a kept one and no two kept ones lie within ``radius`` of
    each other (module docstring); ``seed`` fixes the visiting order. ``radius`` 0
    keeps every point."""
    pts = np.ascontiguousarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3 or not np.isfinite(pts).all():
        raise InputError("greedy_cover", "points", f"expected finite (N, 3), got {pts.shape}")
    if isinstance(radius, bool) or not math.isfinite(radius) or radius < 0.0:
        raise InputError("greedy_cover", "radius", f"must be finite and >= 0, got {radius!r}")
    if radius == 0.0 or len(pts) < 2:
        return np.arange(len(pts), dtype=np.intp)
    order = np.random.default_rng(seed).permutation(len(pts)).astype(np.int64)
    return np.sort(_cover(pts, order, float(radius))).astype(np.intp)
