"""Compiled kernels of the scene memory (:mod:`reachwise.distance.scene_memory`).

Two passes per depth frame and one per hand-over, each over flat arrays:

- :func:`project_frame` — the projective update (nvblox's method, on the CPU): every
  voxel of the grid that a brick test cannot rule out is projected into the depth image
  through its centre; against the depth ``d`` measured at that pixel, a centre at depth
  ``z`` (along the optical axis) is *free* when ``z < d − band`` and *at or behind the
  surface* when ``d − band ≤ z ≤ d + shadow`` (occupied shadow, unless another frame saw
  it free within ``hold`` s); pixels without a return change nothing, and a pixel that
  sees the robot (``body``, its depth the robot's) only frees what lies in front of the
  robot: the robot's own shadow keeps what was seen there before.
- :func:`mark_points` — every returned pixel back-projected to its point, whose voxel
  is marked occupied at time ``t``: a voxel that holds an observed point is occupied,
  whatever its centre's pixel saw (depth edges).
- :func:`decay_and_collect` — occupied voxels not re-observed for ``memory`` s fade to
  shadow (never to free); the centres of the occupied and shadow voxels are returned.

The loops are long by design: one pass over millions of voxels, with the camera
coordinates of each centre updated by three additions along the innermost axis.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types

UNKNOWN = np.uint8(0)
FREE = np.uint8(1)
OCCUPIED = np.uint8(2)
SHADOW = np.uint8(3)

#: Edge of a brick (voxels) and of a pixel tile for the brick tests of
#: :func:`project_frame`.
BRICK = 8
TILE = 8

_W_U1_3D = types.Array(types.uint8, 3, "C")
_W_F8_3D = types.Array(types.float64, 3, "C")
_RO_F8_2D = types.Array(types.float64, 2, "C", readonly=True)
_RO_B1_2D = types.Array(types.boolean, 2, "C", readonly=True)
_RO_F8_1D = types.Array(types.float64, 1, "C", readonly=True)
_W_F8_2D = types.Array(types.float64, 2, "C")

# camera = [fx, fy, cx, cy, near, far]; grid = [ox, oy, oz, voxel];
# rules = [band, shadow, t, hold]; pose_cw: world -> camera (4 x 4)
_SIG_PROJECT = types.int64(
    _W_U1_3D, _W_F8_3D, _RO_F8_2D, _RO_B1_2D, _RO_F8_1D, _RO_F8_2D, _RO_F8_1D, _RO_F8_1D
)


@njit(_SIG_PROJECT, cache=True, nogil=True)
def project_frame(state, freed_at, depth, body, camera, pose_cw, grid, rules):  # type: ignore[no-untyped-def]
    """Free and shadow marks of one frame (module docstring); returns the number of
    voxels whose centre projected onto a pixel with a return."""
    fx, fy, cx, cy, near = camera[0], camera[1], camera[2], camera[3], camera[4]
    ox, oy, oz, vox = grid[0], grid[1], grid[2], grid[3]
    band, shadow, t, hold = rules[0], rules[1], rules[2], rules[3]
    H, W = depth.shape
    nx, ny, nz = state.shape
    # per tile of TILE x TILE pixels: the nearest and farthest return, and whether a
    # pixel without a return (or on the robot) lies in it
    nty = (H + TILE - 1) // TILE
    ntx = (W + TILE - 1) // TILE
    tmin = np.full((nty, ntx), np.inf)
    tmax = np.full((nty, ntx), -np.inf)
    tbad = np.zeros((nty, ntx), dtype=np.bool_)
    dmax = 0.0
    for r in range(H):
        for c in range(W):
            d = depth[r, c]
            ty = r // TILE
            tx = c // TILE
            if d == d:
                if d > dmax:
                    dmax = d
                if d < tmin[ty, tx]:
                    tmin[ty, tx] = d
                if d > tmax[ty, tx]:
                    tmax[ty, tx] = d
            if d != d or body[r, c]:
                tbad[ty, tx] = True
    if dmax <= 0.0:
        return 0
    reach = dmax + shadow
    R = pose_cw[:3, :3]
    tc = pose_cw[:3, 3]
    # camera coordinates of the voxel (0, 0, 0) centre and of one step along each axis
    c0 = np.empty(3)
    dx = np.empty(3)
    dy = np.empty(3)
    dz = np.empty(3)
    for a in range(3):
        c0[a] = (
            R[a, 0] * (ox + 0.5 * vox)
            + R[a, 1] * (oy + 0.5 * vox)
            + R[a, 2] * (oz + 0.5 * vox)
            + tc[a]
        )
        dx[a] = R[a, 0] * vox
        dy[a] = R[a, 1] * vox
        dz[a] = R[a, 2] * vox
    seen = 0
    for bi in range(0, nx, BRICK):
        for bj in range(0, ny, BRICK):
            for bk in range(0, nz, BRICK):
                # the brick's bounding sphere in camera coordinates: skip it when it lies
                # wholly before the near plane, beyond every return's shadow, or outside
                # the image's frustum
                ei = min(BRICK, nx - bi)
                ej = min(BRICK, ny - bj)
                ek = min(BRICK, nz - bk)
                mi = bi + 0.5 * (ei - 1)
                mj = bj + 0.5 * (ej - 1)
                mk = bk + 0.5 * (ek - 1)
                x = c0[0] + mi * dx[0] + mj * dy[0] + mk * dz[0]
                y = c0[1] + mi * dx[1] + mj * dy[1] + mk * dz[1]
                z = c0[2] + mi * dx[2] + mj * dy[2] + mk * dz[2]
                rad = 0.5 * vox * math.sqrt((ei - 1) ** 2 + (ej - 1) ** 2 + (ek - 1) ** 2) + 1e-9
                if z + rad <= near or z - rad > reach:
                    continue
                if z - rad > near:
                    # the frustum's four side planes, through the optical centre
                    # (pixels round to the nearest, so the image spans u in
                    # [-0.5, W - 0.5) and v in [-0.5, H - 0.5))
                    a0 = cx + 0.5
                    a1 = W - 0.5 - cx
                    b0 = cy + 0.5
                    b1 = H - 0.5 - cy
                    if (fx * x + a0 * z) / math.sqrt(fx * fx + a0 * a0) < -rad:
                        continue
                    if (-fx * x + a1 * z) / math.sqrt(fx * fx + a1 * a1) < -rad:
                        continue
                    if (fy * y + b0 * z) / math.sqrt(fy * fy + b0 * b0) < -rad:
                        continue
                    if (-fy * y + b1 * z) / math.sqrt(fy * fy + b1 * b1) < -rad:
                        continue
                    # the pixels every centre of the brick projects into (the corners'
                    # projections bound them): a brick wholly behind its pixels' shadow
                    # is skipped; one wholly in front of them, all seen, is free at once
                    umin = vmin = zmin = np.inf
                    umax = vmax = zmax = -np.inf
                    for ci in (bi, bi + ei - 1):
                        for cj in (bj, bj + ej - 1):
                            for ck in (bk, bk + ek - 1):
                                qx = c0[0] + ci * dx[0] + cj * dy[0] + ck * dz[0]
                                qy = c0[1] + ci * dx[1] + cj * dy[1] + ck * dz[1]
                                qz = c0[2] + ci * dx[2] + cj * dy[2] + ck * dz[2]
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
                    inside = (
                        umin + 0.5 >= 0.0
                        and umax + 0.5 < W
                        and vmin + 0.5 >= 0.0
                        and vmax + 0.5 < H
                    )
                    if pu0 <= pu1 and pv0 <= pv1:
                        lo = np.inf
                        hi = -np.inf
                        bad = False
                        for ty in range(pv0 // TILE, pv1 // TILE + 1):
                            for tx in range(pu0 // TILE, pu1 // TILE + 1):
                                lo = min(lo, tmin[ty, tx])
                                hi = max(hi, tmax[ty, tx])
                                bad = bad or tbad[ty, tx]
                        if zmin > hi + shadow:
                            continue
                        if inside and not bad and zmax < lo - band:
                            for i in range(bi, bi + ei):
                                for j in range(bj, bj + ej):
                                    for k in range(bk, bk + ek):
                                        state[i, j, k] = FREE
                                        freed_at[i, j, k] = t
                            seen += ei * ej * ek
                            continue
                for i in range(bi, bi + ei):
                    for j in range(bj, bj + ej):
                        px = c0[0] + i * dx[0] + j * dy[0] + bk * dz[0]
                        py = c0[1] + i * dx[1] + j * dy[1] + bk * dz[1]
                        pz = c0[2] + i * dx[2] + j * dy[2] + bk * dz[2]
                        for k in range(bk, bk + ek):
                            if pz > near and pz <= reach:
                                inv = 1.0 / pz
                                u = math.floor(fx * px * inv + cx + 0.5)
                                v = math.floor(fy * py * inv + cy + 0.5)
                                if 0 <= u < W and 0 <= v < H:
                                    d = depth[v, u]
                                    if d == d:
                                        seen += 1
                                        if pz < d - band:
                                            state[i, j, k] = FREE
                                            freed_at[i, j, k] = t
                                        elif pz <= d + shadow and not body[v, u]:
                                            s = state[i, j, k]
                                            if s != OCCUPIED and t - freed_at[i, j, k] > hold:
                                                state[i, j, k] = SHADOW
                            px += dz[0]
                            py += dz[1]
                            pz += dz[2]
    return seen


_SIG_MARK = types.int64(
    _W_U1_3D, _W_F8_3D, _RO_F8_2D, _RO_B1_2D, _RO_F8_1D, _RO_F8_2D, _RO_F8_1D, types.float64
)


@njit(_SIG_MARK, cache=True, nogil=True)
def mark_points(state, seen_at, depth, body, camera, pose_wc, grid, t):  # type: ignore[no-untyped-def]
    """Mark the voxel of every returned pixel's point occupied at time ``t``; returns
    the number of points that fell inside the grid."""
    fx, fy, cx, cy = camera[0], camera[1], camera[2], camera[3]
    ox, oy, oz, vox = grid[0], grid[1], grid[2], grid[3]
    inv_vox = 1.0 / vox
    H, W = depth.shape
    nx, ny, nz = state.shape
    R = pose_wc[:3, :3]
    tw = pose_wc[:3, 3]
    marked = 0
    for r in range(H):
        for c in range(W):
            d = depth[r, c]
            if d != d or body[r, c]:
                continue
            xc = (c - cx) / fx * d
            yc = (r - cy) / fy * d
            x = R[0, 0] * xc + R[0, 1] * yc + R[0, 2] * d + tw[0]
            y = R[1, 0] * xc + R[1, 1] * yc + R[1, 2] * d + tw[1]
            z = R[2, 0] * xc + R[2, 1] * yc + R[2, 2] * d + tw[2]
            i = math.floor((x - ox) * inv_vox)
            j = math.floor((y - oy) * inv_vox)
            k = math.floor((z - oz) * inv_vox)
            if 0 <= i < nx and 0 <= j < ny and 0 <= k < nz:
                state[i, j, k] = OCCUPIED
                seen_at[i, j, k] = t
                marked += 1
    return marked


_SIG_COLLECT = types.int64(_W_U1_3D, _W_F8_3D, _RO_F8_1D, types.float64, types.float64, _W_F8_2D)


@njit(_SIG_COLLECT, cache=True, nogil=True)
def decay_and_collect(state, seen_at, grid, t, memory, out):  # type: ignore[no-untyped-def]
    """Fade occupied voxels older than ``memory`` s to shadow, then write the centres of
    the occupied and shadow voxels into ``out`` (as many rows as fit); returns their
    count (call again with a larger ``out`` when it exceeds ``len(out)``)."""
    ox, oy, oz, vox = grid[0], grid[1], grid[2], grid[3]
    nx, ny, nz = state.shape
    cap = out.shape[0]
    n = 0
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                s = state[i, j, k]
                if s == OCCUPIED and t - seen_at[i, j, k] > memory:
                    state[i, j, k] = SHADOW
                    s = SHADOW
                if s == OCCUPIED or s == SHADOW:
                    if n < cap:
                        out[n, 0] = ox + (i + 0.5) * vox
                        out[n, 1] = oy + (j + 0.5) * vox
                        out[n, 2] = oz + (k + 0.5) * vox
                    n += 1
    return n
