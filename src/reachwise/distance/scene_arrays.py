"""The arrays a :class:`~reachwise.distance.scene.Scene` answers its queries from.

The scene speaks of named objects, robots and pairs; a query at 1 kHz must not touch a
Python object per pair. :class:`SceneArrays` keeps the same state as arrays the one
compiled call of :mod:`reachwise.distance._batch` reads: one slot per object (its index
arrays in a typed list, its pose source), the stacked forward-kinematics frames of
every robot, and the watched pairs (object slots, margins, warm starts). Everything is
(re)built when the scene's contents change — an object or robot added, a pair watched,
a cloud swapped in — never per query; a query writes into preallocated arrays and
allocates only its answer rows.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

import reachwise.distance._batch as B
from reachwise.distance.index import CloudIndex

__all__ = ["SceneArrays"]


class SceneArrays:
    """Slots of objects, frames of robots and the pair table (see the module docstring).

    Per object slot: ``src`` -1 for a pose of its own (``fixed``: a fixed or run-time
    world pose), else the row of its link in :attr:`frames` (``fixed`` then holds the
    link offset, ``identity`` whether it is the identity).
    """

    def __init__(self) -> None:
        self.objects = B.new_object_list()
        self.indices: list[CloudIndex] = []
        self.fixed = np.zeros((0, 4, 4))
        self.src = np.zeros(0, np.int64)
        self.identity = np.zeros(0, np.bool_)
        self.needed = np.zeros(0, np.bool_)
        self.poses = np.zeros((0, 4, 4))
        self.frames = np.zeros((0, 4, 4))
        # pair table
        self.pair_a = np.zeros(0, np.int64)
        self.pair_b = np.zeros(0, np.int64)
        self.margin = np.zeros(0)
        self.warm = np.zeros((0, 2), np.int64)
        self.scratch = B.scratch_for(1, 1)
        self._scratch_size = (1, 1)

    # ------------------------------------------------------------------ contents
    def add_frames(self, count: int) -> int:
        """Room for ``count`` more frames (a robot's ``fk_all``); returns its first row."""
        first = self.frames.shape[0]
        grown = np.zeros((first + count, 4, 4))
        grown[:first] = self.frames
        grown[first:] = np.eye(4)
        self.frames = grown
        return first

    def add_object(self, index: CloudIndex, pose: NDArray[np.float64], frame_row: int = -1) -> int:
        """A new slot for an object indexed by ``index``: its own pose ``pose``, or (with
        ``frame_row`` >= 0) the link at that row of :attr:`frames` with offset ``pose``.
        Returns the slot."""
        slot = len(self.indices)
        self.indices.append(index)
        B.put_object(
            self.objects, slot, index.points, index.boxes, index.info, index.perm, index.centroid
        )
        self.fixed = np.concatenate([self.fixed, pose[None]])
        self.src = np.append(self.src, np.int64(frame_row))
        self.identity = np.append(self.identity, bool(np.array_equal(pose, np.eye(4))))
        self.needed = np.append(self.needed, False)
        self.poses = np.concatenate([self.poses, np.eye(4)[None]])
        return slot

    def set_index(self, slot: int, index: CloudIndex) -> CloudIndex:
        """Swap slot ``slot``'s index for ``index`` (between two queries) and drop the
        warm starts of its pairs; returns the index it replaced."""
        old = self.indices[slot]
        self.indices[slot] = index
        B.put_object(
            self.objects, slot, index.points, index.boxes, index.info, index.perm, index.centroid
        )
        touched = (self.pair_a == slot) | (self.pair_b == slot)
        self.warm[touched] = -1
        self._size_scratch()
        return old

    def set_pose(self, slot: int, pose: NDArray[np.float64]) -> None:
        """The world pose of an object with a pose of its own."""
        self.fixed[slot] = pose

    # ------------------------------------------------------------------ pairs
    def set_pairs(
        self,
        pair_a: NDArray[np.int64],
        pair_b: NDArray[np.int64],
        margin: NDArray[np.float64],
        warm: NDArray[np.int64],
    ) -> None:
        """The pair table (object slots, margins, warm starts; P rows each)."""
        self.pair_a = np.ascontiguousarray(pair_a, np.int64)
        self.pair_b = np.ascontiguousarray(pair_b, np.int64)
        self.margin = np.ascontiguousarray(margin, np.float64)
        self.warm = np.ascontiguousarray(warm, np.int64).reshape(-1, 2)
        self.needed[:] = False
        self.needed[self.pair_a] = True
        self.needed[self.pair_b] = True
        self._size_scratch()

    def _size_scratch(self) -> None:
        """Grow the query scratch to the largest smaller-cloud of any pair."""
        nodes = points = 1
        for a, b in zip(self.pair_a.tolist(), self.pair_b.tolist(), strict=True):
            ia, ib = self.indices[a], self.indices[b]
            small = ia if len(ia) <= len(ib) else ib
            nodes = max(nodes, small.boxes.shape[0])
            points = max(points, len(small))
        have_nodes, have_points = self._scratch_size
        if nodes > have_nodes or points > have_points:
            size = (max(nodes, 2 * have_nodes), max(points, 2 * have_points))
            self.scratch = B.scratch_for(*size)
            self._scratch_size = size

    # ------------------------------------------------------------------ queries
    def place(self) -> NDArray[np.float64]:
        """World poses of the needed objects from :attr:`frames` (filled by the
        caller) and the objects' own poses; returns :attr:`poses`."""
        B.place_objects(self.frames, self.fixed, self.src, self.identity, self.needed, self.poses)
        return self.poses

    def query(self, rows: NDArray[np.float64]) -> int:
        """Place the objects and answer every pair into ``rows`` (P, 13); returns how
        many pairs are within their margin."""
        return int(B.query_pairs(rows, *self.arguments()))

    def arguments(self) -> tuple[object, ...]:
        """What :func:`~reachwise.distance._batch.query_pairs` takes after the rows
        (the same arrays until the contents change: keep the tuple between queries)."""
        return (
            self.objects, self.frames, self.fixed, self.src, self.identity, self.needed,
            self.poses, self.pair_a, self.pair_b, self.margin, self.warm, *self.scratch,
        )  # fmt: skip
