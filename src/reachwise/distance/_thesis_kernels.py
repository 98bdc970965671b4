"""numba kernels of the thesis's distance algorithm (P-V Table 1,
:mod:`reachwise.distance.thesis`): the points of a tree inside a box (step 5) and the
brute-force closest pair of two small point sets (step 11).

Compiled eagerly with explicit signatures, like every kernel of
:mod:`reachwise.distance._kernels`; the tree layout is the one described there.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["min_pair", "range_query"]


@njit(
    "int64[::1](float64[:, ::1], float64[:, ::1], int64[:, ::1], float64[::1], float64[::1])",
    cache=True,
    nogil=True,
)
def range_query(pts, boxes, info, lo, hi):  # type: ignore[no-untyped-def]
    """Tree-order indices of the points inside the closed box ``lo <= x <= hi``."""
    n = pts.shape[0]
    out = np.empty(n, np.int64)
    cnt = 0
    stack = np.empty(256, np.int64)
    stack[0] = 0
    sp = 1
    while sp > 0:
        sp -= 1
        k = stack[sp]
        inside = True
        for c in range(3):
            if boxes[k, c] > hi[c] or boxes[k, c + 3] < lo[c]:
                inside = False
                break
        if not inside:
            continue
        full = True
        for c in range(3):
            if boxes[k, c] < lo[c] or boxes[k, c + 3] > hi[c]:
                full = False
                break
        if full or info[k, 2] < 0:
            for p in range(info[k, 0], info[k, 1]):
                if full or (
                    lo[0] <= pts[p, 0] <= hi[0]
                    and lo[1] <= pts[p, 1] <= hi[1]
                    and lo[2] <= pts[p, 2] <= hi[2]
                ):
                    out[cnt] = p
                    cnt += 1
            continue
        stack[sp] = info[k, 2]
        sp += 1
        stack[sp] = k + 1
        sp += 1
    return out[:cnt].copy()


@njit(
    "Tuple((float64, int64, int64))(float64[:, ::1], float64[:, ::1])",
    cache=True,
    nogil=True,
)
def min_pair(P, Q):  # type: ignore[no-untyped-def]
    """Smallest squared distance between rows of P and rows of Q and its (first) pair."""
    best = np.inf
    bi = -1
    bj = -1
    for i in range(P.shape[0]):
        x = P[i, 0]
        y = P[i, 1]
        z = P[i, 2]
        for j in range(Q.shape[0]):
            dx = x - Q[j, 0]
            dy = y - Q[j, 1]
            dz = z - Q[j, 2]
            d2 = dx * dx + dy * dy + dz * dz
            if d2 < best:
                best = d2
                bi = i
                bj = j
    return best, bi, bj
