"""Compiled kernels of the scene memory (:mod:`reachwise.distance.scene_memory`).

Three passes per depth frame, each over flat arrays:

- :func:`prepare_frame` — one pass over the pixels: the frame as one ``code`` image
  (the return's depth, minus it where the pixel saw the robot, NaN without a return)
  and, per tile of ``TILE`` × ``TILE`` pixels, the nearest and farthest return and
  whether a pixel without a return (or else one on the robot) lies in it, as a sparse table over
  squares of 2**level tiles so that any rectangle of tiles is bounded by a few reads.
- :func:`project_frame` — the projective update (nvblox's method, on the CPU): every
  voxel of the grid that a brick test cannot decide at once is projected into the depth
  image through its centre; against the depth ``d`` measured at that pixel, a centre at
  depth ``z`` (along the optical axis) is *free* when ``z < d − band`` and *at or behind
  the surface* when ``d − band ≤ z ≤ d + shadow`` (occupied shadow, unless another frame
  saw it free within ``hold`` s); pixels without a return change nothing, and a pixel
  that sees the robot (its depth the robot's) only frees what lies in front of the
  robot: the robot's own shadow keeps what was seen there before. Bricks of ``BRICK``³
  voxels, then of half that edge, are skipped, freed or shadowed whole when the tiles
  under their corners' projections decide every centre the same way.
- :func:`mark_points` — every returned pixel back-projected to its point, whose voxel
  is marked occupied at time ``t``: a voxel that holds an observed point is occupied,
  whatever its centre's pixel saw (depth edges).

The hand-over's collection (fading, Morton order) is in
:mod:`reachwise.distance._memory_collect`.

The loops are long by design: one pass over millions of voxels, with the camera
coordinates of each centre updated by three additions along the innermost axis. The
module holds the three passes and the brick test and its application they share (about
470 lines): they read one frame layout (``code``, ``tiles``) and one map layout
(``state``, the free stamps, the per-brick summary ``held``), which a split would
spread over several files.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types
from numpy.typing import NDArray

from reachwise.distance._prefetch import prefetch_for_write

UNKNOWN = np.uint8(0)
FREE = np.uint8(1)
OCCUPIED = np.uint8(2)
SHADOW = np.uint8(3)

#: Edge of a brick (voxels) and of a pixel tile for the brick tests of
#: :func:`project_frame`.
BRICK = 8
TILE = 8
#: Edge of a block (voxels): a half-brick, the unit of the free stamps ``freed_block``
#: of :func:`project_frame`, and the layout of the per-voxel stamps ``freed_at``: a
#: block's ``BLOCK``³ stamps lie side by side (:func:`to_blocks`).
BLOCK_BITS = 2
BLOCK = 1 << BLOCK_BITS
_IN_BLOCK = BLOCK - 1

#: What the per-brick summary ``held`` (one byte per brick of ``BRICK``³ voxels) knows
#: of its brick's voxels: nothing (``HELD_NONE``: no occupied or shadow voxel, others
#: unknown or free), that it may hold an occupied or shadow voxel (``HELD_OBSTACLE``:
#: every kernel that makes one sets it, and the hand-over's
#: :func:`~reachwise.distance._memory_collect.collect_ordered` reads only these), or
#: that every voxel is free (``HELD_FREE``: set when a frame frees the whole brick, so
#: the next frame that frees it whole writes no voxel, only the brick's stamp).
HELD_NONE = np.uint8(0)
HELD_OBSTACLE = np.uint8(1)
HELD_FREE = np.uint8(2)

#: The fast-math flags of every kernel here, which keep NaN and inf semantics (no
#: ``nnan``/``ninf``: NaN is a pixel without a return). The kernels also take numpy's
#: error model: a division by zero gives inf or NaN, as in numpy, instead of a check
#: before every division that keeps LLVM from vectorising a loop.
_FASTMATH = {"nsz", "arcp", "contract", "afn", "reassoc"}

_W_U1_3D = types.Array(types.uint8, 3, "C")
_W_F8_3D = types.Array(types.float64, 3, "C")
_W_F8_4D_BLOCKS = types.Array(types.float64, 4, "C")
_RO_F8_2D = types.Array(types.float64, 2, "C", readonly=True)
_RO_B1_2D = types.Array(types.boolean, 2, "C", readonly=True)
_RO_F8_1D = types.Array(types.float64, 1, "C", readonly=True)
_W_F8_2D = types.Array(types.float64, 2, "C")

_W_F4_2D = types.Array(types.float32, 2, "C")
_RO_F4_2D = types.Array(types.float32, 2, "C", readonly=True)
_W_F8_4D = types.Array(types.float64, 4, "C")
_RO_F8_4D = types.Array(types.float64, 4, "C", readonly=True)

#: The third channel of the tile table (:func:`prepare_frame`): the worst pixel under a
#: tile — every pixel a scene return (0.0), a robot's return among them (``_ROBOT``),
#: or a pixel without a return (``_NO_RETURN``); the maximum over tiles is the worst.
_ROBOT = 1.0
_NO_RETURN = 2.0

# code: the frame's pixels as one image (float32): NaN where there is no return, the
# depth (m) where the pixel saw the scene, minus the depth where it saw the robot.
# tiles[level, ty, tx] = [nearest, farthest return (the robot's too), the worst pixel:
# 0.0, _ROBOT or _NO_RETURN] over the 2**level x 2**level tiles of TILE x TILE pixels
# from tile (ty, tx) on (a sparse table: any rectangle of tiles is the union of a few
# such squares)
# depth: the sensor's image as it comes, float64 or float32 metres or uint16 units of
# ``scale`` metres (millimetres: 0.001), one compiled version each
_SIG_PREPARE = [
    types.float64(
        types.Array(pixel, 2, "C", readonly=True),
        types.float64,
        _RO_B1_2D,
        types.float64,
        types.float64,
        _W_F4_2D,
        _W_F8_4D,
    )
    for pixel in (types.float64, types.float32, types.uint16)
]


def tile_levels(height: int, width: int) -> tuple[int, int, int]:
    """The shape ``(levels, tile rows, tile columns)`` of the tile table of a
    ``height`` × ``width`` image (:func:`prepare_frame`)."""
    nty = (height + TILE - 1) // TILE
    ntx = (width + TILE - 1) // TILE
    return max(nty, ntx).bit_length(), nty, ntx


@njit(_SIG_PREPARE, cache=True, nogil=True, error_model="numpy", fastmath=_FASTMATH)
def prepare_frame(depth, scale, body, near, far, code, tiles):  # type: ignore[no-untyped-def]
    """One pass over the pixels: the ``code`` image (above) of the returns
    ``depth · scale`` (m) within ``[near, far]`` (and > 0), and the per-tile bounds the
    brick tests of :func:`project_frame` use; returns the farthest return (0.0 when
    there is none). ``depth`` is read in the sensor's own pixel type (float64, float32,
    uint16): no copy of the frame precedes this pass. Per image row, every pixel is
    read without a branch (selects the compiler vectorises) into its ``code`` and the
    row's per-pixel bounds, which then bound each tile once per row."""
    H, W = depth.shape
    L, nty, ntx = tiles.shape[0], tiles.shape[1], tiles.shape[2]
    for ty in range(nty):
        for tx in range(ntx):
            tiles[0, ty, tx, 0] = np.inf
            tiles[0, ty, tx, 1] = -np.inf
            tiles[0, ty, tx, 2] = 0.0
    dmax = 0.0
    row_lo = np.empty(ntx * TILE)
    row_hi = np.empty(ntx * TILE)
    row_worst = np.empty(ntx * TILE)
    row_lo[W:] = np.inf
    row_hi[W:] = -np.inf
    row_worst[W:] = 0.0
    for r in range(H):
        ty = r // TILE
        # branch-free per pixel (the compiler vectorises it), then per tile
        for c in range(W):
            d = np.float64(depth[r, c]) * scale
            ok = (d > 0.0) & (d >= near) & (d <= far)
            robot = body[r, c]
            v = d if ok else np.nan
            code[r, c] = np.float32(-v if robot else v)
            row_lo[c] = d if ok else np.inf
            row_hi[c] = d if ok else -np.inf
            row_worst[c] = (_ROBOT if robot else 0.0) if ok else _NO_RETURN
        for tx in range(ntx):
            lo = np.inf
            hi = -np.inf
            worst = 0.0
            for c in range(tx * TILE, tx * TILE + TILE):
                lo = min(lo, row_lo[c])
                hi = max(hi, row_hi[c])
                worst = max(worst, row_worst[c])
            dmax = max(dmax, hi)
            tiles[0, ty, tx, 0] = min(tiles[0, ty, tx, 0], lo)
            tiles[0, ty, tx, 1] = max(tiles[0, ty, tx, 1], hi)
            tiles[0, ty, tx, 2] = max(tiles[0, ty, tx, 2], worst)
    for lv in range(1, L):
        h = 1 << (lv - 1)
        for ty in range(nty - 2 * h + 1):
            for tx in range(ntx - 2 * h + 1):
                tiles[lv, ty, tx, 0] = min(
                    min(tiles[lv - 1, ty, tx, 0], tiles[lv - 1, ty + h, tx, 0]),
                    min(tiles[lv - 1, ty, tx + h, 0], tiles[lv - 1, ty + h, tx + h, 0]),
                )
                tiles[lv, ty, tx, 1] = max(
                    max(tiles[lv - 1, ty, tx, 1], tiles[lv - 1, ty + h, tx, 1]),
                    max(tiles[lv - 1, ty, tx + h, 1], tiles[lv - 1, ty + h, tx + h, 1]),
                )
                tiles[lv, ty, tx, 2] = max(
                    max(tiles[lv - 1, ty, tx, 2], tiles[lv - 1, ty + h, tx, 2]),
                    max(tiles[lv - 1, ty, tx + h, 2], tiles[lv - 1, ty + h, tx + h, 2]),
                )
    return dmax


def to_blocks(stamps: NDArray[np.float64]) -> NDArray[np.float64]:
    """The per-voxel stamps ``stamps`` (``(nx, ny, nz)``) in the block layout of
    :func:`project_frame`'s ``freed_at``: ``(blocks along x, y, z, BLOCK**3)``, each
    block's stamps side by side (x slowest, z fastest), the voxels past the grid's end
    ``-inf``. The voxels that update decides one by one — a half-brick, which is one
    block — then write and read ``BLOCK**3`` adjacent stamps (8 cache lines) instead
    of ``BLOCK**2`` runs of ``BLOCK`` spread over as many lines."""
    nx, ny, nz = stamps.shape
    a, b, c = -(-nx // BLOCK), -(-ny // BLOCK), -(-nz // BLOCK)
    padded = np.full((a * BLOCK, b * BLOCK, c * BLOCK), -np.inf)
    padded[:nx, :ny, :nz] = stamps
    split = padded.reshape(a, BLOCK, b, BLOCK, c, BLOCK).transpose(0, 2, 4, 1, 3, 5)
    return np.ascontiguousarray(split).reshape(a, b, c, BLOCK**3)


def from_blocks(blocks: NDArray[np.float64], shape: tuple[int, int, int]) -> NDArray[np.float64]:
    """The stamps of the block layout ``blocks`` (:func:`to_blocks`) as a
    ``shape`` grid, a new array."""
    a, b, c = blocks.shape[:3]
    split = blocks.reshape(a, b, c, BLOCK, BLOCK, BLOCK).transpose(0, 3, 1, 4, 2, 5)
    grid = split.reshape(a * BLOCK, b * BLOCK, c * BLOCK)
    return np.ascontiguousarray(grid[: shape[0], : shape[1], : shape[2]])


# camera = [fx, fy, cx, cy, near, far]; grid = [ox, oy, oz, voxel];
# rules = [band, shadow, t, hold, dmax]; pose_cw: world -> camera (4 x 4)
# freed_at: per block, its voxels' stamps side by side (to_blocks)
_SIG_PROJECT = types.int64(
    _W_U1_3D,
    _W_F8_4D_BLOCKS,
    _W_F8_3D,
    _W_U1_3D,
    _RO_F4_2D,
    _RO_F8_4D,
    _RO_F8_1D,
    _RO_F8_2D,
    _RO_F8_1D,
    _RO_F8_1D,
)

# what a brick test decides for every voxel of a brick
_SKIP = 0  # nothing to change: out of view, before the near plane or beyond the shadow
_ALL_FREE = 1  # every centre seen in front of its pixel's return
_ALL_SHADOW = 2  # every centre at or behind its pixel's surface, within the shadow
_EACH = 3  # decide voxel by voxel
_EACH_INSIDE = 4  # voxel by voxel, every centre beyond the near plane and inside the image


@njit(cache=True, nogil=True, error_model="numpy", fastmath=_FASTMATH)
def _brick_test(lo3, ext, view, tiles, rules, W, H):  # type: ignore[no-untyped-def]
    """Decide a brick of voxels ``lo3 .. lo3 + ext`` at once (``_SKIP``, ``_ALL_FREE``,
    ``_ALL_SHADOW``) or voxel by voxel (``_EACH``; ``_EACH_INSIDE`` when every centre
    lies beyond the near plane and projects inside the image, so that no voxel needs
    those checks). ``view`` rows: the camera
    coordinates of voxel (0, 0, 0)'s centre, one step along i, j, k, then [fx, fy, cx,
    cy, near, voxel]. The centres of a convex brick project inside the convex hull of
    its corners' projections (every centre in front of the camera), so the tiles under
    the corners' pixel rectangle bound every pixel a centre reads.

    One function (about 90 lines) of four stages, each of which may end the test: the
    bounding sphere against the near plane and the farthest reach, against the
    frustum's side planes, the corners' pixel rectangle, and the tile bounds over it.
    Every stage reads the centre, radius and corners of the one before, and the test
    runs about ten thousand times per frame inside :func:`project_frame`'s loop:
    compiled with numba, split, the stages would hand those back and forth through
    memory."""
    fx, fy, cx, cy, near, vox = (
        view[4, 0],
        view[4, 1],
        view[4, 2],
        view[4, 3],
        view[4, 4],
        view[4, 5],
    )
    band, shadow, reach = rules[0], rules[1], rules[4] + rules[1]
    bi, bj, bk = lo3[0], lo3[1], lo3[2]
    ei, ej, ek = ext[0], ext[1], ext[2]
    mi = bi + 0.5 * (ei - 1)
    mj = bj + 0.5 * (ej - 1)
    mk = bk + 0.5 * (ek - 1)
    x = view[0, 0] + mi * view[1, 0] + mj * view[2, 0] + mk * view[3, 0]
    y = view[0, 1] + mi * view[1, 1] + mj * view[2, 1] + mk * view[3, 1]
    z = view[0, 2] + mi * view[1, 2] + mj * view[2, 2] + mk * view[3, 2]
    rad = 0.5 * vox * math.sqrt((ei - 1) ** 2 + (ej - 1) ** 2 + (ek - 1) ** 2) + 1e-9
    if z + rad <= near or z - rad > reach:
        return _SKIP
    if z - rad <= near:
        return _EACH
    # the frustum's four side planes, through the optical centre (pixels round to the
    # nearest, so the image spans u in [-0.5, W - 0.5) and v in [-0.5, H - 0.5))
    a0 = cx + 0.5
    a1 = W - 0.5 - cx
    b0 = cy + 0.5
    b1 = H - 0.5 - cy
    if (fx * x + a0 * z) / math.sqrt(fx * fx + a0 * a0) < -rad:
        return _SKIP
    if (-fx * x + a1 * z) / math.sqrt(fx * fx + a1 * a1) < -rad:
        return _SKIP
    if (fy * y + b0 * z) / math.sqrt(fy * fy + b0 * b0) < -rad:
        return _SKIP
    if (-fy * y + b1 * z) / math.sqrt(fy * fy + b1 * b1) < -rad:
        return _SKIP
    umin = vmin = zmin = np.inf
    umax = vmax = zmax = -np.inf
    for ci in (bi, bi + ei - 1):
        for cj in (bj, bj + ej - 1):
            for ck in (bk, bk + ek - 1):
                qx = view[0, 0] + ci * view[1, 0] + cj * view[2, 0] + ck * view[3, 0]
                qy = view[0, 1] + ci * view[1, 1] + cj * view[2, 1] + ck * view[3, 1]
                qz = view[0, 2] + ci * view[1, 2] + cj * view[2, 2] + ck * view[3, 2]
                qu = fx * qx / qz + cx
                qv = fy * qy / qz + cy
                umin = min(umin, qu)
                umax = max(umax, qu)
                vmin = min(vmin, qv)
                vmax = max(vmax, qv)
                zmin = min(zmin, qz)
                zmax = max(zmax, qz)
    pu0 = max(0, math.floor(umin + 0.5))
    pu1 = min(W - 1, math.floor(umax + 0.5))
    pv0 = max(0, math.floor(vmin + 0.5))
    pv1 = min(H - 1, math.floor(vmax + 0.5))
    if pu0 > pu1 or pv0 > pv1:
        return _EACH
    inside = umin + 0.5 >= 0.0 and umax + 0.5 < W and vmin + 0.5 >= 0.0 and vmax + 0.5 < H
    # the tiles under the rectangle, as squares of 2**lv tiles from the sparse table
    ty0, ty1 = pv0 // TILE, pv1 // TILE
    tx0, tx1 = pu0 // TILE, pu1 // TILE
    lv = 0
    while (2 << lv) <= min(ty1 - ty0 + 1, tx1 - tx0 + 1):
        lv += 1
    side = 1 << lv
    lo = np.inf
    hi = -np.inf
    mixed = 0.0
    for y in range(ty0, ty1 + 1, side):
        yy = min(y, ty1 - side + 1)
        for x in range(tx0, tx1 + 1, side):
            xx = min(x, tx1 - side + 1)
            lo = min(lo, tiles[lv, yy, xx, 0])
            hi = max(hi, tiles[lv, yy, xx, 1])
            mixed = max(mixed, tiles[lv, yy, xx, 2])
    if zmin > hi + shadow:
        return _SKIP
    # a pixel without a return decides nothing: no whole-brick decision over one; a
    # robot's pixel frees in front of the robot's depth (within lo) as a scene pixel
    # does in front of its surface, but shadows nothing: no whole shadow over one
    if inside and mixed < _NO_RETURN:
        if zmax < lo - band:
            return _ALL_FREE
        if mixed == 0.0 and zmin >= hi - band and zmax <= lo + shadow:
            return _ALL_SHADOW
    # a pixel's width inside the image's edges: the centres' own projections, rounded
    # differently from the corners', stay inside
    if umin > 0.0 and umax < W - 1.0 and vmin > 0.0 and vmax < H - 1.0:
        return _EACH_INSIDE
    return _EACH


@njit(cache=True, nogil=True, error_model="numpy", fastmath=_FASTMATH)
def _apply(decision, whole, lo3, ext, state, freed_at, freed_block, held, code, view, rules, W, H):  # type: ignore[no-untyped-def]
    """Apply a brick test's ``decision`` to its voxels (voxel by voxel for ``_EACH``
    and ``_EACH_INSIDE``, the latter without the near-plane and image-edge checks);
    returns how many of them projected onto a pixel with a return. The voxels lie in
    one brick of ``BRICK``³, all of its voxels when ``whole``.

    When a voxel was last seen free is the later of its own stamp ``freed_at`` (kept
    block by block, :func:`to_blocks`) and its block's ``freed_block`` (blocks of
    ``BLOCK``³ voxels, half a brick's edge): bricks
    and half-bricks freed whole stamp their blocks, not their voxels (and a whole brick
    writes its voxels' states only if ``held`` does not say they are all free already),
    so a static free space costs one write per block and frame. The brick is flagged
    in ``held`` (:data:`HELD_OBSTACLE`) when a voxel turns shadow. Compiled with numba,
    which takes the grids, the view and the rules as arrays one by one, not as one
    object."""
    band, shadow, t, hold = rules[0], rules[1], rules[2], rules[3]
    bi, bj, bk = lo3[0], lo3[1], lo3[2]
    ei, ej, ek = ext[0], ext[1], ext[2]
    b0, b1, b2 = bi // BRICK, bj // BRICK, bk // BRICK
    if decision == _SKIP:
        return 0
    if decision == _ALL_FREE:
        for i in range(bi // BLOCK, (bi + ei - 1) // BLOCK + 1):
            for j in range(bj // BLOCK, (bj + ej - 1) // BLOCK + 1):
                for k in range(bk // BLOCK, (bk + ek - 1) // BLOCK + 1):
                    freed_block[i, j, k] = t
        if whole and held[b0, b1, b2] == HELD_FREE:
            return ei * ej * ek
        if whole:
            held[b0, b1, b2] = HELD_FREE
        for i in range(bi, bi + ei):
            for j in range(bj, bj + ej):
                for k in range(bk, bk + ek):
                    state[i, j, k] = FREE
        return ei * ej * ek
    if decision == _ALL_SHADOW:
        for i in range(bi, bi + ei):
            for j in range(bj, bj + ej):
                for k in range(bk, bk + ek):
                    slot = ((i & _IN_BLOCK) * BLOCK + (j & _IN_BLOCK)) * BLOCK + (k & _IN_BLOCK)
                    if (
                        state[i, j, k] != OCCUPIED
                        and t - freed_at[i >> BLOCK_BITS, j >> BLOCK_BITS, k >> BLOCK_BITS, slot]
                        > hold
                        and t - freed_block[i // BLOCK, j // BLOCK, k // BLOCK] > hold
                    ):
                        state[i, j, k] = SHADOW
                        held[b0, b1, b2] = HELD_OBSTACLE
        return ei * ej * ek
    # a voxel seen free within ``hold`` is not shadowed: none is when its block was
    # (the voxels of ``_EACH`` lie in one block)
    may_shadow = t - freed_block[bi // BLOCK, bj // BLOCK, bk // BLOCK] > hold
    # the block's own stamps, side by side (to_blocks): the voxels of ``_EACH`` are one
    # block (a half-brick), from its corner on
    stamps = freed_at[bi >> BLOCK_BITS, bj >> BLOCK_BITS, bk >> BLOCK_BITS]
    fx, fy, cx, cy, near = view[4, 0], view[4, 1], view[4, 2], view[4, 3], view[4, 4]
    reach = rules[4] + shadow
    sx, sy, sz = view[3, 0], view[3, 1], view[3, 2]
    seen = 0
    for i in range(bi, bi + ei):
        for j in range(bj, bj + ej):
            px = view[0, 0] + i * view[1, 0] + j * view[2, 0] + bk * sx
            py = view[0, 1] + i * view[1, 1] + j * view[2, 1] + bk * sy
            pz = view[0, 2] + i * view[1, 2] + j * view[2, 2] + bk * sz
            slot = ((i - bi) * BLOCK + (j - bj)) * BLOCK
            if decision == _EACH_INSIDE:
                # every centre beyond the near plane and inside the image: the rule
                # below is written out twice, as in the loop after this one (an
                # inlined function for it measured twice as slow)
                for k in range(bk, bk + ek):
                    if pz <= reach:
                        inv = 1.0 / pz
                        uf = fx * px * inv + cx + 0.5
                        vf = fy * py * inv + cy + 0.5
                        d = code[int(vf), int(uf)]
                        if d == d:
                            seen += 1
                            if d > 0.0:
                                if pz < d - band:
                                    state[i, j, k] = FREE
                                    stamps[slot] = t
                                elif pz <= d + shadow:
                                    if (
                                        may_shadow
                                        and state[i, j, k] != OCCUPIED
                                        and t - stamps[slot] > hold
                                    ):
                                        state[i, j, k] = SHADOW
                                        held[b0, b1, b2] = HELD_OBSTACLE
                            elif pz < -d - band:
                                state[i, j, k] = FREE
                                stamps[slot] = t
                    px += sx
                    py += sy
                    pz += sz
                    slot += 1
                continue
            for k in range(bk, bk + ek):
                if pz > near and pz <= reach:
                    inv = 1.0 / pz
                    uf = fx * px * inv + cx + 0.5
                    vf = fy * py * inv + cy + 0.5
                    if uf >= 0.0 and uf < W and vf >= 0.0 and vf < H:
                        d = code[int(vf), int(uf)]
                        if d == d:
                            seen += 1
                            if d > 0.0:
                                if pz < d - band:
                                    state[i, j, k] = FREE
                                    stamps[slot] = t
                                elif pz <= d + shadow:
                                    if (
                                        may_shadow
                                        and state[i, j, k] != OCCUPIED
                                        and t - stamps[slot] > hold
                                    ):
                                        state[i, j, k] = SHADOW
                                        held[b0, b1, b2] = HELD_OBSTACLE
                            elif pz < -d - band:
                                state[i, j, k] = FREE
                                stamps[slot] = t
                px += sx
                py += sy
                pz += sz
                slot += 1
    return seen


@njit(_SIG_PROJECT, cache=True, nogil=True, error_model="numpy", fastmath=_FASTMATH)
def project_frame(state, freed_at, freed_block, held, code, tiles, camera, pose_cw, grid, rules):  # type: ignore[no-untyped-def]
    """Free and shadow marks of one frame (module docstring) from its ``code`` image and
    ``tiles`` (:func:`prepare_frame`); ``rules`` = [band, shadow, t, hold, farthest
    return]. When a voxel was last seen free is the later of ``freed_at`` (per voxel,
    in the block layout of :func:`to_blocks`) and ``freed_block`` (per block of
    ``BLOCK``³ voxels: the block was freed whole then); ``held`` is the per-brick
    summary (:data:`HELD_OBSTACLE`, :data:`HELD_FREE`). Bricks of ``BRICK``³ voxels
    are decided at once where their corners allow (:func:`_brick_test`), else split
    into bricks of half the edge, then voxel by voxel.
    Returns the number of voxels whose centre projected onto a pixel with a return."""
    ox, oy, oz, vox = grid[0], grid[1], grid[2], grid[3]
    H, W = code.shape
    nx, ny, nz = state.shape
    if rules[4] <= 0.0:
        return 0
    R = pose_cw[:3, :3]
    tc = pose_cw[:3, 3]
    view = np.empty((5, 6))
    for a in range(3):
        view[0, a] = (
            R[a, 0] * (ox + 0.5 * vox)
            + R[a, 1] * (oy + 0.5 * vox)
            + R[a, 2] * (oz + 0.5 * vox)
            + tc[a]
        )
        view[1, a] = R[a, 0] * vox
        view[2, a] = R[a, 1] * vox
        view[3, a] = R[a, 2] * vox
    for a in range(5):
        view[4, a] = camera[a]
    view[4, 5] = vox
    half = BLOCK
    lo3 = np.empty(3, dtype=np.int64)
    ext = np.empty(3, dtype=np.int64)
    sub = np.empty(3, dtype=np.int64)
    sext = np.empty(3, dtype=np.int64)
    seen = 0
    for bi in range(0, nx, BRICK):
        for bj in range(0, ny, BRICK):
            for bk in range(0, nz, BRICK):
                lo3[0], lo3[1], lo3[2] = bi, bj, bk
                ext[0], ext[1], ext[2] = (
                    min(BRICK, nx - bi),
                    min(BRICK, ny - bj),
                    min(BRICK, nz - bk),
                )
                decision = _brick_test(lo3, ext, view, tiles, rules, W, H)
                # nothing to apply for _SKIP: no call (numba passes each array argument
                # field by field; leaving out these calls made the pass 5-8 % faster)
                if decision == _SKIP:
                    continue
                if decision < _EACH:
                    seen += _apply(
                        decision, True, lo3, ext, state, freed_at, freed_block, held,
                        code, view, rules, W, H,
                    )  # fmt: skip
                    continue
                for si in range(bi, bi + ext[0], half):
                    for sj in range(bj, bj + ext[1], half):
                        for sk in range(bk, bk + ext[2], half):
                            sub[0], sub[1], sub[2] = si, sj, sk
                            sext[0] = min(half, bi + ext[0] - si)
                            sext[1] = min(half, bj + ext[1] - sj)
                            sext[2] = min(half, bk + ext[2] - sk)
                            d = _brick_test(sub, sext, view, tiles, rules, W, H)
                            if d == _SKIP:
                                continue
                            seen += _apply(
                                d, False, sub, sext, state, freed_at, freed_block, held,
                                code, view, rules, W, H,
                            )  # fmt: skip
    return seen


_SIG_MARK = types.int64(
    _W_U1_3D, _W_F8_3D, _W_U1_3D, _RO_F4_2D, _RO_F8_1D, _RO_F8_2D, _RO_F8_1D, types.float64
)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _cell(f):  # type: ignore[no-untyped-def]
    """``floor(f)`` for ``f`` ≥ −1, −1 below (clamped to an int32: branch-free)."""
    return np.int32(min(max(f, -1.0), 2.0e9) + 1.0) - 1


@njit(_SIG_MARK, cache=True, nogil=True, error_model="numpy", fastmath=_FASTMATH)
def mark_points(state, seen_at, held, code, camera, pose_wc, grid, t):  # type: ignore[no-untyped-def]
    """Mark the voxel of every scene pixel's point (``code`` > 0, :func:`prepare_frame`)
    occupied at time ``t``, its brick flagged in ``held``
    (:func:`~reachwise.distance._memory_collect.collect_ordered`); returns the number
    of points that fell inside the grid. Per image row, the flat index of every pixel's
    voxel (−1 for a pixel without a scene point or outside the grid) and of its brick
    are found first in a branch-free pass (which the compiler vectorises), then the
    voxels marked: every scene pixel writes its voxel's three marks, though
    neighbouring pixels mostly share a voxel (the writes are the same; a test for a
    repeat mispredicts once per run and measured slower). The rows' indices run one
    row ahead of the marks: while a row is marked, the state and stamp lines of the
    next row's voxels are fetched (:func:`~reachwise.distance._prefetch.prefetch_for_write`),
    so a voxel first met in that row no longer stalls its writes on the memory (the
    pass measured 15-30 % faster)."""
    fx, fy, cx, cy = camera[0], camera[1], camera[2], camera[3]
    ox, oy, oz, vox = grid[0], grid[1], grid[2], grid[3]
    inv_vox = 1.0 / vox
    H, W = code.shape
    nx, ny, nz = state.shape
    hy, hz = held.shape[1], held.shape[2]
    R = pose_wc[:3, :3]
    tw = pose_wc[:3, 3]
    flat_state = state.reshape(-1)
    flat_seen = seen_at.reshape(-1)
    flat_held = held.reshape(-1)
    xs = np.empty(W)
    for c in range(W):
        xs[c] = (c - cx) / fx
    # two rows of indices: row r's (found at step r) and row r - 1's (marked at step r)
    voxels = np.empty((2, W), dtype=np.int64)
    bricks = np.empty((2, W), dtype=np.int64)
    marked = 0
    for r in range(H + 1):
        if r < H:
            voxel = voxels[r & 1]
            brick = bricks[r & 1]
            yr = (r - cy) / fy
            # world position of the ray's unit-depth point for this row, per column step
            bx = R[0, 1] * yr + R[0, 2]
            by = R[1, 1] * yr + R[1, 2]
            bz = R[2, 1] * yr + R[2, 2]
            for c in range(W):
                v = np.float64(code[r, c])
                d = max(v, 0.0)  # NaN or the robot's: any cell, not marked
                xc = xs[c]
                i = np.int64(_cell(((R[0, 0] * xc + bx) * d + tw[0] - ox) * inv_vox))
                j = np.int64(_cell(((R[1, 0] * xc + by) * d + tw[1] - oy) * inv_vox))
                k = np.int64(_cell(((R[2, 0] * xc + bz) * d + tw[2] - oz) * inv_vox))
                inside = (v > 0.0) & (i >= 0) & (i < nx) & (j >= 0) & (j < ny) & (k >= 0) & (k < nz)
                voxel[c] = ((i * ny + j) * nz + k) if inside else -1
                brick[c] = ((i // BRICK) * hy + j // BRICK) * hz + k // BRICK
        if r == 0:
            continue
        voxel = voxels[(r - 1) & 1]
        brick = bricks[(r - 1) & 1]
        ahead = voxels[r & 1]
        fetch = r < H
        for c in range(W):
            if fetch:
                g = max(ahead[c], 0)
                prefetch_for_write(flat_seen, g)
                prefetch_for_write(flat_state, g)
            f = voxel[c]
            if f < 0:
                continue
            marked += 1
            flat_state[f] = OCCUPIED
            flat_seen[f] = t
            flat_held[brick[c]] = HELD_OBSTACLE
    return marked
