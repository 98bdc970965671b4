"""The descriptive subset of a task (P-II §2; thesis §6.3.1 future work, done).

P-II §2 runs the first round of dimensional synthesis over every candidate topology on
"a subset of the task (most important task points that define the limits of the
required reach, as well as some typical operating points)", to speed the process up;
the thesis leaves choosing them to future work (§6.3.1). ``descriptive_subset`` does it
automatically and deterministically:

1. **Reach limits** — the points with the smallest and the largest coordinate along each
   world axis (x, y, z: the extent of the required reach) and, among 5-/6-D points, with
   the smallest and largest component of the tool axis along each world axis (the most
   tilted holes in every direction: the limits of the orientation range). Duplicates
   collapse; if there are more extremes than ``size``, farthest-point sampling keeps the
   ``size`` most different of them.
2. **Typical points** — the remaining ``size − (extremes)`` points are cluster
   representatives: k-means (``scipy.cluster.vq.kmeans2``, started from a farthest-point
   selection, so no randomness) in the feature space ``[p / L, axis]``, where ``L`` is
   the RMS distance of the positions from their centroid (a 1 rad change of direction
   weighs like a move of ``L``); each cluster gives its medoid (the member nearest to
   the centroid, lowest index on ties), largest clusters first. Farthest-point sampling
   fills any shortfall (empty clusters, medoids already chosen).

Result: sorted indices into the task (``Task.subset`` builds the subset task). Same task
and size, same indices. Pure: numpy in, numpy out.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import TaskError
from reachwise.tasks.drilling import farthest_point_selection
from reachwise.tasks.task import Task

_SRC = "descriptive subset"


def task_features(task: Task) -> NDArray[np.float64]:
    """``(m, 6)`` features ``[p / L, axis]`` (axis 0 for 3-D points); see module doc."""
    P = task.positions
    c = P.mean(axis=0)
    L = float(np.sqrt(np.mean(np.sum((P - c) ** 2, axis=1))))
    L = L if L > 1e-12 else 1.0
    A = np.where((task.dims >= 5)[:, None], task.axes, 0.0)
    return np.hstack([(P - c) / L, A])


def reach_extremes(task: Task) -> NDArray[np.intp]:
    """Indices of the extreme points (step 1 of the module docstring), in the order
    x min, x max, y min, y max, z min, z max, then axis-x min, max, …; duplicates
    dropped (first occurrence kept)."""
    P = task.positions
    idx: list[int] = []
    for k in range(3):
        idx += [int(np.argmin(P[:, k])), int(np.argmax(P[:, k]))]
    oriented = np.flatnonzero(task.dims >= 5)
    if oriented.size:
        A = task.axes[oriented]
        for k in range(3):
            idx += [int(oriented[np.argmin(A[:, k])]), int(oriented[np.argmax(A[:, k])])]
    return np.array(list(dict.fromkeys(idx)), dtype=np.intp)


def descriptive_subset(task: Task, size: int, extremes: bool = True) -> NDArray[np.intp]:
    """``size`` indices of ``task``: its reach limits plus typical points (module doc).

    ``size >= len(task)`` returns every index. ``extremes=False`` skips step 1 (only
    cluster representatives).
    """
    m = len(task)
    if isinstance(size, bool) or not isinstance(size, int | np.integer) or size < 1:
        raise TaskError(_SRC, "size", f"must be a positive integer, got {size!r}")
    if size >= m:
        return np.arange(m, dtype=np.intp)
    F = task_features(task)
    chosen: list[int] = []
    if extremes:
        ext = reach_extremes(task)
        if ext.size > size:
            ext = ext[farthest_point_selection(F[ext], size, keep=[0])]
        chosen = [int(i) for i in ext]
    k = size - len(chosen)
    if k > 0:
        chosen += _medoids(F, k, chosen)
    if len(chosen) < size:
        chosen = [int(i) for i in farthest_point_selection(F, size, keep=chosen)]
    return np.sort(np.array(chosen[:size], dtype=np.intp))


def _medoids(F: NDArray[np.float64], k: int, taken: list[int]) -> list[int]:
    """Medoids of a deterministic k-means of the rows of ``F`` not in ``taken``."""
    from scipy.cluster.vq import ClusterError, kmeans2

    free = np.array([i for i in range(len(F)) if i not in set(taken)], dtype=np.intp)
    if free.size <= k:
        return [int(i) for i in free]
    X = F[free]
    start = farthest_point_selection(X, k)
    try:
        centroids, labels = kmeans2(X, X[start].copy(), iter=50, minit="matrix", missing="raise")
    except ClusterError:  # an empty cluster: keep the farthest-point start itself
        return [int(free[i]) for i in start]
    sizes = np.bincount(labels, minlength=k)
    order = sorted(range(k), key=lambda c: (-int(sizes[c]), c))
    out: list[int] = []
    for c in order:
        members = np.flatnonzero(labels == c)
        if members.size == 0:
            continue
        d = np.linalg.norm(X[members] - centroids[c], axis=1)
        out.append(int(free[members[int(np.argmin(d))]]))
    return out
