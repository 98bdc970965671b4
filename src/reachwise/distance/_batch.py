"""numba kernel that answers every watched pair of a scene in one call.

A 1 kHz control loop cannot spend ten microseconds of Python per pair: the scene keeps
what its queries need in arrays, and one compiled call places every object and runs
every pair's dual-tree query (:func:`reachwise.distance._kernels.query_core`, the same
search the per-pair :class:`~reachwise.distance.engine.PairQuery` runs, with the same
warm starts, so the answers are the same numbers).

What the kernel reads:

- ``objects``: a numba typed ``List`` with one
  :class:`~reachwise.distance._kernels.TreeArrays` per object slot, the arrays of its
  :class:`~reachwise.distance.index.CloudIndex` (:data:`OBJECT`). A swapped-in cloud
  replaces its slot's entry between two queries (:func:`put_object`, compiled: a
  microsecond).
- Poses: ``frames`` (F, 4, 4) the forward kinematics of every robot, stacked;
  per object ``src`` (-1: its world pose is ``fixed[o]``; else the row of its link in
  ``frames``, and its pose is ``frames[src[o]] @ fixed[o]``, ``fixed[o]`` then being the
  link offset, skipped when ``identity[o]``). ``poses`` (O, 4, 4) receives the world
  poses of the objects flagged in ``needed``.
- Pairs: object slots ``pair_a``, ``pair_b``, ``margin`` (m), and ``warm`` (P, 2), each
  pair's last closest pair as tree-order indices into its objects (-1: none), updated
  in place like :class:`~reachwise.distance.engine.PairQuery`'s.

What it writes: ``rows`` (P, :data:`ROW_COLUMNS`), one row per pair in the server's
wire layout — distance, point a xyz, point b xyz, direction xyz (world, b → a), input
rows of the two points, and 1.0 for "no risk" (then distance inf, NaN vectors, rows
-1), else 0.0. Scratch arrays (sized by the scene for its largest pair,
:func:`scratch_for`) are reused; the kernel allocates nothing."""

from __future__ import annotations

import numpy as np
from numba import njit, types
from numba.typed import List

from reachwise.distance._kernels import (
    TREE,
    QueryScratch,
    TreeArrays,
    new_scratch,
    query_core,
)

__all__ = [
    "OBJECT",
    "ROW_COLUMNS",
    "new_object_list",
    "place_objects",
    "put_object",
    "query_pairs",
    "scratch_for",
]

#: Columns of an answer row: distance, point a (3), point b (3), direction (3), input
#: row of point a, input row of point b, no-risk flag.
ROW_COLUMNS = 13

_F2 = types.float64[:, ::1]
_I2 = types.int64[:, ::1]
_F1 = types.float64[::1]
_I1 = types.int64[::1]
_B1 = types.boolean[::1]
_F3 = types.float64[:, :, ::1]
#: One object's index arrays, a :class:`~reachwise.distance._kernels.TreeArrays`.
OBJECT = TREE
_OBJECTS = types.ListType(OBJECT)


def new_object_list() -> List:  # type: ignore[type-arg]
    """An empty typed list of :data:`OBJECT` tuples."""
    return List.empty_list(OBJECT)


@njit(types.void(_OBJECTS, types.int64, _F2, _F2, _I2, _I1, _F1), cache=True)
def put_object(objects, slot, points, boxes, info, perm, centroid):  # type: ignore[no-untyped-def]
    """Set slot ``slot`` of ``objects`` (append when ``slot == len(objects)``)."""
    item = TreeArrays(points, boxes, info, perm, centroid)
    if slot == len(objects):
        objects.append(item)
    else:
        objects[slot] = item


@njit(cache=True, nogil=True, inline="always")
def _mul(A, B, out):  # type: ignore[no-untyped-def]
    """``out = A @ B`` for rigid 4x4 transforms."""
    for r in range(3):
        a0 = A[r, 0]
        a1 = A[r, 1]
        a2 = A[r, 2]
        for c in range(4):
            out[r, c] = a0 * B[0, c] + a1 * B[1, c] + a2 * B[2, c]
        out[r, 3] += A[r, 3]
    out[3, 0] = 0.0
    out[3, 1] = 0.0
    out[3, 2] = 0.0
    out[3, 3] = 1.0


@njit(types.void(_F3, _F3, _I1, _B1, _B1, _F3), cache=True, nogil=True)
def place_objects(frames, fixed, src, identity, needed, poses):  # type: ignore[no-untyped-def]
    """World pose of every object flagged in ``needed`` into ``poses`` (see the module
    docstring)."""
    for o in range(src.shape[0]):
        if not needed[o]:
            continue
        s = src[o]
        if s < 0:
            poses[o, :, :] = fixed[o]
        elif identity[o]:
            poses[o, :, :] = frames[s]
        else:
            _mul(frames[s], fixed[o], poses[o])


_SIG = types.int64(
    _F2,  # rows (out)
    _OBJECTS,  # objects
    _F3,  # frames
    _F3,  # fixed
    _I1,  # src
    _B1,  # identity
    _B1,  # needed
    _F3,  # poses (out)
    _I1,  # pair_a
    _I1,  # pair_b
    _F1,  # margin
    _I2,  # warm (in/out)
    _F2,  # tbox
    _B1,  # tdone
    _F2,  # tp
    _B1,  # done
    _I1,  # stack_i
    _F1,  # stack_g
    _F2,  # vec
    _F1,  # out10
)


@njit(_SIG, cache=True)
def query_pairs(  # type: ignore[no-untyped-def]
    rows, objects,
    frames, fixed, src, identity, needed, poses,
    pair_a, pair_b, margin, warm,
    tbox, tdone, tp, done, stack_i, stack_g, vec, out10,
):  # fmt: skip
    """Place the needed objects and answer every pair into ``rows`` (see the module
    docstring); returns how many pairs are within their margin.

    The arguments are flat arrays on purpose (the object placement, the pair table,
    then the :class:`~reachwise.distance._kernels.QueryScratch` fields and ``out10``,
    as :func:`scratch_for` makes them): this is the control loop's per-tick call, and
    numba types a named-tuple argument in Python at every call (≈ 2.5 µs each,
    measured), flat arrays through its C fast path. The scratch is grouped for
    :func:`~reachwise.distance._kernels.query_core` inside, at no cost.
    """
    place_objects(frames, fixed, src, identity, needed, poses)
    scratch = QueryScratch(tbox, tdone, tp, done, stack_i, stack_g, vec)
    within = 0
    for k in range(pair_a.shape[0]):
        a = pair_a[k]
        b = pair_b[k]
        A = objects[a]
        B = objects[b]
        if A.points.shape[0] > B.points.shape[0]:
            # map the smaller cloud into the larger's frame
            status, j, i = query_core(
                B, A, poses[b], poses[a], margin[k], warm[k, 1], warm[k, 0], True, out10, scratch
            )
        else:
            status, i, j = query_core(
                A, B, poses[a], poses[b], margin[k], warm[k, 0], warm[k, 1], False, out10, scratch
            )
        row = rows[k]
        if status == 0:
            for c in range(10):
                row[c] = out10[c]
            row[10] = A.perm[i]
            row[11] = B.perm[j]
            row[12] = 0.0
            warm[k, 0] = i
            warm[k, 1] = j
            within += 1
        else:
            row[0] = np.inf
            for c in range(1, 10):
                row[c] = np.nan
            row[10] = -1.0
            row[11] = -1.0
            row[12] = 1.0
    return within


def scratch_for(max_nodes: int, max_points: int) -> tuple[np.ndarray, ...]:
    """Scratch for pairs whose smaller cloud has at most ``max_nodes`` tree nodes and
    ``max_points`` points: the fields of a
    :class:`~reachwise.distance._kernels.QueryScratch` (``tbox, tdone, tp, done,
    stack_i, stack_g, vec``) and ``out10``, the last arguments of :func:`query_pairs`."""
    return (*new_scratch(max_nodes, max_points), np.empty(10))
