"""Compiled kinematics kernels (numba): frames, tool/point/parameter Jacobians.

Everything here works on the packed chain ``Chain`` (``Robot.arrays``), its six fields
passed one by one. Rigid transforms are multiplied as ``[R p; 0 1]`` blocks. The
functions Python calls carry explicit signatures and are compiled at import (or loaded
from numba's disk cache); the others compile into their callers (``_jit``).

Joint transform (P-I Eq. 2–3, modified DH, Craig)::

    A_i = Rx(alpha) Tx(a) Rz(theta) Tz(d)
        = [[ ct,    -st,     0,   a     ],
           [ st*ca,  ct*ca, -sa, -sa*d ],
           [ st*sa,  ct*sa,  ca,  ca*d ],
           [ 0,      0,      0,   1     ]]

Classic DH: ``A_i = Rz(theta) Tz(d) Tx(a) Rx(alpha)``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types

from reachwise.kinematics._jit import RO_F8_1D, RO_F8_2D, RO_F8_3D, RO_I8_1D, W_F8_2D, W_F8_3D

#: The chain's six fields (``Chain``) in the signatures below.
_CHAIN = (RO_I8_1D, RO_I8_1D, RO_F8_2D, types.boolean, RO_F8_2D, RO_F8_2D)


@njit(cache=True, fastmath=False)
def joint_transform(kind, classic, a, alpha, d, theta, qv, out):  # type: ignore[no-untyped-def]
    """Fill ``out`` (4x4) with the transform of one joint at joint value ``qv``."""
    if kind == 0:
        theta = theta + qv
    elif kind == 1:
        d = d + qv
    ct = math.cos(theta)
    st = math.sin(theta)
    ca = math.cos(alpha)
    sa = math.sin(alpha)
    if classic:
        out[0, 0] = ct
        out[0, 1] = -st * ca
        out[0, 2] = st * sa
        out[0, 3] = a * ct
        out[1, 0] = st
        out[1, 1] = ct * ca
        out[1, 2] = -ct * sa
        out[1, 3] = a * st
        out[2, 0] = 0.0
        out[2, 1] = sa
        out[2, 2] = ca
        out[2, 3] = d
    else:
        out[0, 0] = ct
        out[0, 1] = -st
        out[0, 2] = 0.0
        out[0, 3] = a
        out[1, 0] = st * ca
        out[1, 1] = ct * ca
        out[1, 2] = -sa
        out[1, 3] = -sa * d
        out[2, 0] = st * sa
        out[2, 1] = ct * sa
        out[2, 2] = ca
        out[2, 3] = ca * d
    out[3, 0] = 0.0
    out[3, 1] = 0.0
    out[3, 2] = 0.0
    out[3, 3] = 1.0


@njit(cache=True)
def rigid_mul(A, B, out):  # type: ignore[no-untyped-def]
    """``out = A @ B`` for rigid 4x4 transforms (``out`` must not alias ``A`` or ``B``)."""
    for r in range(3):
        a0 = A[r, 0]
        a1 = A[r, 1]
        a2 = A[r, 2]
        for c in range(3):
            out[r, c] = a0 * B[0, c] + a1 * B[1, c] + a2 * B[2, c]
        out[r, 3] = a0 * B[0, 3] + a1 * B[1, 3] + a2 * B[2, 3] + A[r, 3]
    out[3, 0] = 0.0
    out[3, 1] = 0.0
    out[3, 2] = 0.0
    out[3, 3] = 1.0


@njit((*_CHAIN, RO_F8_1D, W_F8_3D), cache=True)
def frames(kind, qidx, dh, classic, base, tool, q, F):  # type: ignore[no-untyped-def]
    """World pose of every frame into ``F`` (N+2, 4, 4): base, link 1..N, tool."""
    N = kind.shape[0]
    A = np.empty((4, 4))
    F[0, :, :] = base
    for i in range(N):
        k = qidx[i]
        qv = q[k] if k >= 0 else 0.0
        joint_transform(kind[i], classic, dh[i, 0], dh[i, 1], dh[i, 2], dh[i, 3], qv, A)
        rigid_mul(F[i], A, F[i + 1])
    rigid_mul(F[N], tool, F[N + 1])


@njit((*_CHAIN, RO_F8_2D), cache=True)
def fk_batch(kind, qidx, dh, classic, base, tool, Q):  # type: ignore[no-untyped-def]
    """Tool poses ``(m, 4, 4)`` for a batch of configurations ``Q`` (m, n)."""
    m = Q.shape[0]
    N = kind.shape[0]
    out = np.empty((m, 4, 4))
    A = np.empty((4, 4))
    cur = np.empty((4, 4))
    nxt = np.empty((4, 4))
    for s in range(m):
        cur[:, :] = base
        for i in range(N):
            k = qidx[i]
            qv = Q[s, k] if k >= 0 else 0.0
            joint_transform(kind[i], classic, dh[i, 0], dh[i, 1], dh[i, 2], dh[i, 3], qv, A)
            rigid_mul(cur, A, nxt)
            cur[:, :] = nxt
        rigid_mul(cur, tool, out[s])
    return out


@njit((*_CHAIN, RO_F8_2D), cache=True)
def fk_all_batch(kind, qidx, dh, classic, base, tool, Q):  # type: ignore[no-untyped-def]
    """Every frame for a batch: ``(m, N+2, 4, 4)``."""
    m = Q.shape[0]
    N = kind.shape[0]
    out = np.empty((m, N + 2, 4, 4))
    for s in range(m):
        frames(kind, qidx, dh, classic, base, tool, Q[s], out[s])
    return out


@njit(cache=True)
def _axis_frame(i, classic):  # type: ignore[no-untyped-def]
    """Frame whose z axis is joint ``i``'s axis: frame i+1 (modified) or i (classic)."""
    return i if classic else i + 1


@njit(cache=True)
def _screw(J, col, revolute, ax, ay, az, ox, oy, oz, px, py, pz):  # type: ignore[no-untyped-def]
    """Column ``col`` of ``J``: the unit screw of a rotation about axis a through o (at
    point p), or of a translation along a (a geometric Jacobian column). Compiled and
    called per joint inside the loop: numba passes the vectors' components as scalars,
    which keeps the innermost call free of array allocation."""
    if revolute:
        rx = px - ox
        ry = py - oy
        rz = pz - oz
        J[0, col] = ay * rz - az * ry
        J[1, col] = az * rx - ax * rz
        J[2, col] = ax * ry - ay * rx
        J[3, col] = ax
        J[4, col] = ay
        J[5, col] = az
    else:
        J[0, col] = ax
        J[1, col] = ay
        J[2, col] = az
        J[3, col] = 0.0
        J[4, col] = 0.0
        J[5, col] = 0.0


@njit(cache=True)
def tool_jacobian(kind, qidx, classic, F, n, J):  # type: ignore[no-untyped-def]
    """Geometric tool Jacobian ``J`` (6, n) from frames ``F`` (thesis Eq. 3.1).

    Revolute column ``[z × (p_tool − p_i); z]``, prismatic ``[z; 0]``.
    """
    N = kind.shape[0]
    point_jacobian_rows(
        kind, qidx, classic, F, N + 1, F[N + 1, 0, 3], F[N + 1, 1, 3], F[N + 1, 2, 3], J
    )


@njit(
    (RO_I8_1D, RO_I8_1D, types.boolean, RO_F8_3D, types.int64, *(types.float64,) * 3, W_F8_2D),
    cache=True,
)
def point_jacobian_rows(kind, qidx, classic, F, link, px, py, pz, J):  # type: ignore[no-untyped-def]
    """Jacobian (6, n) of world point (px, py, pz) fixed to frame ``link`` of ``F``.

    Joint ``i`` moves frames ``i+1`` … tool, so only joints with ``i + 1 <= link``
    contribute; the other columns are zero.
    """
    N = kind.shape[0]
    J[:, :] = 0.0
    for i in range(N):
        k = qidx[i]
        if k < 0 or i + 1 > link:
            continue
        f = _axis_frame(i, classic)
        _screw(J, k, kind[i] == 0, F[f, 0, 2], F[f, 1, 2], F[f, 2, 2],
               F[f, 0, 3], F[f, 1, 3], F[f, 2, 3], px, py, pz)  # fmt: skip


@njit(cache=True)
def param_jacobian(classic, F, J):  # type: ignore[no-untyped-def]
    """Jacobian (6, 4N+6) of the tool pose w.r.t. DH parameters and base (P-I Eq. 15–19).

    Columns per joint ``[a, alpha, d, theta]``, then base ``[x, y, z, roll, pitch, yaw]``
    (URDF rpy). Each parameter moves the tool by a unit screw: for modified DH,
    ``a`` translates along x of frame i-1, ``alpha`` rotates about it, ``d``
    translates along z of frame i and ``theta`` rotates about it; for classic DH,
    ``theta``/``d`` act on z of frame i-1 and ``a``/``alpha`` on x of frame i.
    Columns are geometric: linear velocity of the tool point and angular velocity.
    """
    N = F.shape[0] - 2
    px = F[N + 1, 0, 3]
    py = F[N + 1, 1, 3]
    pz = F[N + 1, 2, 3]
    for i in range(N):
        P = F[i]
        C = F[i + 1]
        c = 4 * i
        if classic:
            X = C
            Z = P
        else:
            X = P
            Z = C
        # a: translation along x; alpha: rotation about x
        _screw(J, c, False, X[0, 0], X[1, 0], X[2, 0], 0.0, 0.0, 0.0, px, py, pz)
        _screw(J, c + 1, True, X[0, 0], X[1, 0], X[2, 0], X[0, 3], X[1, 3], X[2, 3], px, py, pz)
        # d: translation along z; theta: rotation about z
        _screw(J, c + 2, False, Z[0, 2], Z[1, 2], Z[2, 2], 0.0, 0.0, 0.0, px, py, pz)
        _screw(J, c + 3, True, Z[0, 2], Z[1, 2], Z[2, 2], Z[0, 3], Z[1, 3], Z[2, 3], px, py, pz)
    c = 4 * N
    B = F[0]
    bx = B[0, 3]
    by = B[1, 3]
    bz = B[2, 3]
    _screw(J, c, False, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, px, py, pz)
    _screw(J, c + 1, False, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, px, py, pz)
    _screw(J, c + 2, False, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, px, py, pz)
    # R = Rz(yaw) Ry(pitch) Rx(roll): roll about the base x axis, pitch about
    # Rz(yaw) y, yaw about world z; all through the base origin.
    yaw = math.atan2(B[1, 0], B[0, 0])
    _screw(J, c + 3, True, B[0, 0], B[1, 0], B[2, 0], bx, by, bz, px, py, pz)
    _screw(J, c + 4, True, -math.sin(yaw), math.cos(yaw), 0.0, bx, by, bz, px, py, pz)
    _screw(J, c + 5, True, 0.0, 0.0, 1.0, bx, by, bz, px, py, pz)


@njit((*_CHAIN, RO_F8_2D, types.boolean), cache=True)
def jacobians_batch(kind, qidx, dh, classic, base, tool, Q, with_params):  # type: ignore[no-untyped-def]
    """Tool poses (m,4,4), tool Jacobians (m,6,n) and, if asked, parameter
    Jacobians (m, 6, 4N+6) for a batch of configurations in one pass."""
    m = Q.shape[0]
    n = Q.shape[1]
    N = kind.shape[0]
    T = np.empty((m, 4, 4))
    J = np.empty((m, 6, n))
    P = np.empty((m, 6, 4 * N + 6)) if with_params else np.empty((0, 6, 4 * N + 6))
    F = np.empty((N + 2, 4, 4))
    for s in range(m):
        frames(kind, qidx, dh, classic, base, tool, Q[s], F)
        T[s] = F[N + 1]
        tool_jacobian(kind, qidx, classic, F, n, J[s])
        if with_params:
            param_jacobian(classic, F, P[s])
    return T, J, P
