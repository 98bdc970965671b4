"""A cloud's spatial index, kept by the distance layer (P-V Table 1, initialization phase).

A :class:`~reachwise.geometry.cloud.PointCloud` holds its points and nothing else. What
the distance strategies derive from the points — the tree of AABBs in the cloud's own
frame (:mod:`reachwise.distance._build`), the centroid and the tight AABB — is a
:class:`CloudIndex`, built once per cloud and looked up by the cloud:

- :func:`build_index` is a pure function of the points: no shared state, no lock, and
  the tree kernel releases the GIL (numba ``nogil``). So an index may be built on any
  thread — a worker that ingests a new scan while the control loop keeps querying the
  old one — and handed over whole; a :class:`CloudIndex` is immutable, so swapping one
  reference for another is atomic.
- :class:`IndexRegistry` keeps the index of every cloud in use, keyed weakly by the
  cloud (its identity, confirmed by a weak reference): an entry lives as long as its
  cloud, and repeated queries of the same cloud find it instead of rebuilding it
  (:attr:`IndexRegistry.builds` counts the builds). :data:`INDICES` is the one the
  strategies and the scene use; :func:`cloud_index` looks a cloud up in it.

Each index carries a ``version``, set by whoever builds it (0 by default): a scene that
replaces an object's cloud can number the clouds it swaps in and report, with every
answer, which one it used.
"""

from __future__ import annotations

import threading
import weakref
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray

import reachwise.distance._kernels as K
from reachwise.distance._build import build_tree_in, summary, tree_of_sorted
from reachwise.errors import InputError
from reachwise.geometry.boxes import AABB
from reachwise.geometry.cloud import PointCloud

__all__ = [
    "INDICES",
    "LEAF_SIZE",
    "CloudIndex",
    "IndexRegistry",
    "build_index",
    "cloud_centroid",
    "cloud_index",
    "index_of_checked",
    "index_of_ordered",
]

#: Leaf size of the per-cloud tree (points per leaf at most).
LEAF_SIZE = 8


@dataclass(frozen=True, eq=False)
class CloudIndex:
    """Everything the distance strategies derive from a cloud's points, in its frame.

    The tree (:func:`reachwise.distance._build.build_tree`): ``points`` in tree
    order, ``perm[k]`` the input row of tree point ``k`` (:attr:`inverse` the reverse
    map, made on first use: the queries keep their warm starts in tree order and never
    need it), ``boxes`` (M, 6) node AABBs (lo, hi; node 0 is the root), ``info`` (M, 3)
    start, end, right child. ``centroid`` the mean point (the direction rule at
    distance 0), ``aabb`` the tight bounds (Table 1 step 3), ``version`` the cloud
    version it indexes (see the module docstring).
    """

    points: NDArray[np.float64]
    perm: NDArray[np.int64]
    boxes: NDArray[np.float64]
    info: NDArray[np.int64]
    centroid: NDArray[np.float64]
    aabb: AABB
    version: int = 0

    def __len__(self) -> int:
        return int(self.points.shape[0])

    @cached_property
    def inverse(self) -> NDArray[np.int64]:
        """``inverse[row]``: the tree position of input row ``row`` (``perm``'s reverse)."""
        inv = np.empty_like(self.perm)
        inv[self.perm] = np.arange(self.perm.shape[0])
        inv.setflags(write=False)
        return inv


def build_index(points: ArrayLike, *, version: int = 0, leaf_size: int = LEAF_SIZE) -> CloudIndex:
    """The index of (N, 3) ``points`` (a pure function: safe on any thread).

    ``points`` are taken as given (a :class:`PointCloud`'s are validated already); one
    compiled pass finds their bounds and centroid, the tree kernel copies them into
    tree order (both release the GIL).
    """
    _check_leaf_size(leaf_size)
    pts = np.ascontiguousarray(points, dtype=np.float64)
    _, bounds, centroid = summary(pts)
    return index_of_checked(pts, bounds, centroid, version=version, leaf_size=leaf_size)


def index_of_checked(
    points: NDArray[np.float64],
    bounds: NDArray[np.float64],
    centroid: NDArray[np.float64],
    *,
    version: int = 0,
    leaf_size: int = LEAF_SIZE,
) -> CloudIndex:
    """The index of C-ordered float64 (N, 3) ``points`` whose ``bounds`` (lo xyz, hi
    xyz) and ``centroid`` are known already (:func:`reachwise.distance._build.checked_copy`
    found them while copying a handed-over frame): only the tree is built here."""
    _check_leaf_size(leaf_size)
    tp, perm, boxes, info = build_tree_in(points, bounds, leaf_size)
    return _index(tp, perm, boxes, info, centroid, version)


def index_of_ordered(
    points: NDArray[np.float64],
    codes: NDArray[np.int64],
    centroid: NDArray[np.float64],
    *,
    version: int = 0,
    leaf_size: int = LEAF_SIZE,
) -> CloudIndex:
    """The index of C-ordered, finite float64 (N, 3) ``points`` that come sorted by
    distinct cell ``codes`` of some Morton (Z-order) grid (N, increasing, each below
    2**62), with their ``centroid``: no sort, the tree is built over the given order.

    A depth camera's returned pixels taken in the Z-order of their pixel coordinates
    are such points: a range of them splits where its first and last codes' highest
    differing bit changes (:func:`reachwise.distance._build.tree_of_sorted`), i.e. into
    the two halves of a block of the image, so each node holds the points of a block of
    neighbouring pixels. The boxes are the tight bounds of the points below each node,
    as in :func:`build_index`, so every query on this index is as exact as on that one;
    only how well the boxes prune differs (a block that straddles a depth edge gets a
    deep box). The points are kept as they are (not copied) and ``perm`` is the
    identity.
    """
    _check_leaf_size(leaf_size)
    n = points.shape[0]
    if codes.shape != (n,) or n == 0:
        raise InputError("index", "codes", f"expected {n} codes for {n} points, got {codes.shape}")
    perm = np.arange(n, dtype=np.int64)
    tp, perm, boxes, info = tree_of_sorted(points, perm, codes, leaf_size, False)
    return _index(tp, perm, boxes, info, centroid, version)


def _index(
    tp: NDArray[np.float64],
    perm: NDArray[np.int64],
    boxes: NDArray[np.float64],
    info: NDArray[np.int64],
    centroid: NDArray[np.float64],
    version: int,
) -> CloudIndex:
    """A built tree as an index, its bounding box the root's (exact min, max)."""
    aabb = AABB(boxes[0, :3].copy(), boxes[0, 3:].copy())
    return CloudIndex(tp, perm, boxes, info, centroid, aabb, int(version))


def _check_leaf_size(leaf_size: int) -> None:
    if not 1 <= leaf_size <= K.LEAF_MAX:
        raise InputError("leaf_size", "", f"must be in 1..{K.LEAF_MAX}, got {leaf_size}")


class IndexRegistry:
    """The indices of the clouds in use, keyed weakly by the cloud (thread-safe).

    :meth:`get` returns a cloud's index, building and keeping it on first use;
    :meth:`put` installs one built elsewhere (e.g. on a worker thread); :meth:`peek`
    looks without building. :attr:`builds` counts the indices :meth:`get` built.

    Entries are keyed by the cloud's identity (``id``) next to a weak reference that
    confirms it and removes the entry when the cloud is freed: a lookup is one dict
    read and one dereference, no weak reference made per call (every single-pair
    query makes two).
    """

    def __init__(self) -> None:
        self._entries: dict[int, tuple[weakref.ref[PointCloud], CloudIndex]] = {}
        self._lock = threading.Lock()
        self._builds = 0

    @property
    def builds(self) -> int:
        """How many indices this registry has built."""
        return self._builds

    def peek(self, cloud: PointCloud) -> CloudIndex | None:
        """The index kept for ``cloud``, or None (nothing is built)."""
        entry = self._entries.get(id(cloud))
        if entry is not None and entry[0]() is cloud:
            return entry[1]
        return None

    def get(self, cloud: PointCloud) -> CloudIndex:
        """The index of ``cloud``: the one kept, else built now (outside the lock, so
        other lookups go on meanwhile) and kept for as long as the cloud lives."""
        entry = self._entries.get(id(cloud))
        if entry is not None and entry[0]() is cloud:
            return entry[1]
        built = build_index(cloud.points)
        with self._lock:
            kept = self.peek(cloud)
            if kept is not None:  # another thread was first
                return kept
            self._builds += 1
            self._keep(cloud, built)
        return built

    def put(self, cloud: PointCloud, index: CloudIndex) -> None:
        """Keep ``index`` (built elsewhere from ``cloud``'s points) as ``cloud``'s."""
        if len(index) != len(cloud):
            raise InputError(
                cloud.name or "point cloud",
                "index",
                f"built from {len(index)} points, the cloud has {len(cloud)}",
            )
        with self._lock:
            self._keep(cloud, index)

    def _keep(self, cloud: PointCloud, index: CloudIndex) -> None:
        """Store the entry (call under the lock)."""
        key = id(cloud)
        entries = self._entries

        def forget(ref: weakref.ref[PointCloud]) -> None:
            # the cloud is freed: drop its entry unless a newer cloud took its id. No
            # lock: a collection may run this while the lock is held; a lookup never
            # trusts an entry whose reference does not give back its cloud anyway
            entry = entries.get(key)
            if entry is not None and entry[0] is ref:
                entries.pop(key, None)

        entries[key] = (weakref.ref(cloud, forget), index)


#: The registry the distance strategies and the scene use.
INDICES = IndexRegistry()


def cloud_index(cloud: PointCloud) -> CloudIndex:
    """The index of ``cloud`` in :data:`INDICES` (built on first use, then kept)."""
    return INDICES.get(cloud)


def cloud_centroid(cloud: PointCloud) -> NDArray[np.float64]:
    """Mean point of ``cloud`` in its frame: its index's, or computed now if it has none
    (a strategy that needs no tree builds none)."""
    index = INDICES.peek(cloud)
    if index is not None:
        return index.centroid
    return np.ascontiguousarray(cloud.points.mean(axis=0))
