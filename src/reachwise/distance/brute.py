"""The ``brute`` strategy: every pair of points, in chunks (the reference all must equal).

Plain numpy, independent of the trees and kernels of the other strategies: both clouds
are mapped to world by their poses and the squared distance of every pair is formed
from coordinate differences (not the ``|a|² + |b|² - 2a·b`` expansion, whose
cancellation would cost accuracy near contact), a block of at most
:data:`CHUNK_PAIRS` pairs at a time, so memory stays bounded (≈ 50 MB) for clouds of
any size. Ties go to the first pair in row-major order within a block.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from reachwise.distance._common import DistanceResult, result_from_pair, world
from reachwise.geometry.cloud import PointCloud

#: Pairs per block (each block holds a few float64 arrays of this many entries).
CHUNK_PAIRS = 1 << 20


def brute_min_pair(wa: NDArray[np.float64], wb: NDArray[np.float64]) -> tuple[float, int, int]:
    """Smallest squared distance between rows of ``wa`` (N, 3) and ``wb`` (M, 3) and the
    row indices of that pair."""
    na, nb = wa.shape[0], wb.shape[0]
    cb = min(nb, CHUNK_PAIRS)
    ca = max(1, CHUNK_PAIRS // cb)
    best = np.inf
    bi = bj = -1
    for j0 in range(0, nb, cb):
        xb = wb[j0 : j0 + cb]
        bx, by, bz = xb[:, 0], xb[:, 1], xb[:, 2]
        for i0 in range(0, na, ca):
            xa = wa[i0 : i0 + ca]
            d = np.subtract.outer(xa[:, 0], bx)
            d2 = d * d
            np.subtract.outer(xa[:, 1], by, out=d)
            d *= d
            d2 += d
            np.subtract.outer(xa[:, 2], bz, out=d)
            d *= d
            d2 += d
            k = int(np.argmin(d2))
            i, j = divmod(k, d2.shape[1])
            v = float(d2[i, j])
            if v < best:
                best, bi, bj = v, i0 + i, j0 + j
    return best, bi, bj


def brute_closest(
    a: PointCloud,
    b: PointCloud,
    pose_a: NDArray[np.float64],
    pose_b: NDArray[np.float64],
    margin: float,
) -> DistanceResult:
    """Exact closest pair by exhaustive search (validated inputs; see ``closest_points``)."""
    _, i, j = brute_min_pair(world(a.points, pose_a), world(b.points, pose_b))
    return result_from_pair(a, b, pose_a, pose_b, i, j, margin)
