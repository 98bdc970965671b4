"""The hand-over kernel of the scene memory (:mod:`reachwise.distance.scene_memory`):
occupied voxels not re-observed for ``memory`` s fade to shadow (never to free), and the
centres of the occupied and shadow voxels are collected in Morton order of their voxel
indices, with their codes, so that their distance index is built without a sort
(``reachwise.distance.index.index_of_ordered``). Apart from the update's kernels
(:mod:`reachwise.distance._memory_kernel`): it runs once per hand-over, not per frame,
and reads only the bricks the update flagged in the per-brick summary ``held``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit, types
from numpy.typing import NDArray

from reachwise.distance._memory_kernel import BRICK, HELD_NONE, HELD_OBSTACLE, OCCUPIED, SHADOW

_W_U1_3D = types.Array(types.uint8, 3, "C")
_W_F8_3D = types.Array(types.float64, 3, "C")
_W_F8_2D = types.Array(types.float64, 2, "C")
_RO_F8_1D = types.Array(types.float64, 1, "C", readonly=True)

#: Bits per axis of a voxel's Morton code (:func:`collect_ordered`): codes stay below
#: 2**60, as the ordered tree build (``index_of_ordered``) needs.
MORTON_AXIS_BITS = 20
_LOCAL_BITS = 9  # the Morton code of a voxel within its BRICK**3 brick


def morton_codes(i: NDArray[np.int64], j: NDArray[np.int64], k: NDArray[np.int64]) -> Any:
    """The Morton codes of the voxel indices ``i``, ``j``, ``k`` (each below
    2**:data:`MORTON_AXIS_BITS`): their bits interleaved, ``i``'s highest."""
    out = np.zeros(np.broadcast(i, j, k).shape, dtype=np.int64)
    for b in range(MORTON_AXIS_BITS):
        for shift, axis in ((2, i), (1, j), (0, k)):
            out |= ((np.asarray(axis, dtype=np.int64) >> b) & 1) << (3 * b + shift)
    return out


def brick_order(shape: tuple[int, int, int]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """The traversal of :func:`collect_ordered` over a grid of ``shape``: the bricks
    (rows: first voxel's i, j, k and the Morton code of that voxel) and the voxels of a
    brick (rows: offsets i, j, k and their Morton code), each in increasing code. A
    brick's first index is a multiple of ``BRICK`` (a power of two), so a voxel's code
    is its brick's code plus its offset's: the two orders together visit the voxels in
    increasing Morton code."""
    nb = [(n + BRICK - 1) // BRICK for n in shape]
    b = np.indices(nb, dtype=np.int64).reshape(3, -1) * BRICK
    bricks = np.column_stack([*b, morton_codes(*b)])
    local = np.indices((BRICK,) * 3, dtype=np.int64).reshape(3, -1)
    voxels = np.column_stack([*local, morton_codes(*local)])
    return (
        np.ascontiguousarray(bricks[np.argsort(bricks[:, 3])]),
        np.ascontiguousarray(voxels[np.argsort(voxels[:, 3])]),
    )


_RO_I8_2D = types.Array(types.int64, 2, "C", readonly=True)
_W_I8_1D = types.Array(types.int64, 1, "C")
_SIG_COLLECT = types.int64(
    _W_U1_3D,
    _W_F8_3D,
    _W_U1_3D,
    _RO_F8_1D,
    types.float64,
    types.float64,
    _RO_I8_2D,
    _RO_I8_2D,
    _W_F8_2D,
    _W_I8_1D,
)


@njit(cache=True, nogil=True, inline="always")
def _spread3(x):  # type: ignore[no-untyped-def]
    """The three low bits of ``x`` spread to every third bit (bit b → bit 3b)."""
    return (x & 1) | ((x & 2) << 2) | ((x & 4) << 4)


@njit(_SIG_COLLECT, cache=True, nogil=True)
def collect_ordered(state, seen_at, held, grid, t, memory, bricks, voxels, out, codes):  # type: ignore[no-untyped-def]
    """Fade occupied voxels older than ``memory`` s to shadow, then write the centres of
    the occupied and shadow voxels into ``out`` and their Morton codes into ``codes``
    (as many rows as fit), in increasing code (the traversal ``bricks``, ``voxels`` of
    :func:`brick_order`); returns their count (call again with larger arrays when it
    exceeds ``len(out)``: the fading is done already). Points in Morton order of
    distinct codes are what the ordered tree build takes without a sort.

    ``held`` flags the bricks (``BRICK``³ voxels, indexed by ``i // BRICK`` …) that
    may hold an occupied or shadow voxel: every kernel that makes one flags its brick,
    and only flagged bricks are read here (in memory order: fading, and flagging their
    obstacle voxels by their code within the brick), a brick found without any
    unflagged. A brick with some is walked again, in code order over those flags."""
    ox, oy, oz, vox = grid[0], grid[1], grid[2], grid[3]
    nx, ny, nz = state.shape
    cap = out.shape[0]
    flags = np.zeros(voxels.shape[0], dtype=np.bool_)
    n = 0
    for b in range(bricks.shape[0]):
        bi, bj, bk, bcode = bricks[b, 0], bricks[b, 1], bricks[b, 2], bricks[b, 3]
        if held[bi // BRICK, bj // BRICK, bk // BRICK] != HELD_OBSTACLE:
            continue
        found = 0
        for i in range(bi, min(bi + BRICK, nx)):
            for j in range(bj, min(bj + BRICK, ny)):
                for k in range(bk, min(bk + BRICK, nz)):
                    s = state[i, j, k]
                    if s < OCCUPIED:
                        continue
                    if s == OCCUPIED and t - seen_at[i, j, k] > memory:
                        state[i, j, k] = SHADOW
                    flags[_spread3(i - bi) << 2 | _spread3(j - bj) << 1 | _spread3(k - bk)] = True
                    found += 1
        if found == 0:
            held[bi // BRICK, bj // BRICK, bk // BRICK] = HELD_NONE
            continue
        for v in range(voxels.shape[0]):
            if not flags[v]:
                continue
            flags[v] = False
            if n < cap:
                out[n, 0] = ox + (bi + voxels[v, 0] + 0.5) * vox
                out[n, 1] = oy + (bj + voxels[v, 1] + 0.5) * vox
                out[n, 2] = oz + (bk + voxels[v, 2] + 0.5) * vox
                codes[n] = bcode | v
            n += 1
    return n
