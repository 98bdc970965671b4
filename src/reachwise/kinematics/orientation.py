"""Orientation errors: the unit-quaternion error of thesis Eq. 3.9, the rotation-vector
error used by the solvers, and the 5-D error of an axis-symmetric tool (P-II §5).

One implementation of each: the compiled single-pose functions ``*_into`` are what the
IK and controller kernels call; the Python functions (batched over leading axes) call
the same functions through compiled batch loops. Quaternions are exposed in scipy's
``(x, y, z, w)`` order. Rotations are 3×3 matrices (the kernels also take a 4×4 pose
and read its rotation block).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from reachwise.errors import InputError
from reachwise.kinematics._jit import RO_F8_2D, RO_F8_3D

__all__ = [
    "angle_between",
    "axis_error",
    "axis_error_into",
    "quaternion_error",
    "quaternion_error_into",
    "rotation_error",
    "rotation_error_into",
    "skew",
    "unit_quaternion",
]


# --------------------------------------------------------------------------- kernels


@njit(cache=True)
def unit_quaternion(R):  # type: ignore[no-untyped-def]
    """Unit quaternion ``(x, y, z, w)`` of a rotation matrix (Shepperd's method)."""
    t = R[0, 0] + R[1, 1] + R[2, 2]
    out = np.empty(4)
    if t > 0.0:
        s = math.sqrt(t + 1.0) * 2.0
        out[3] = 0.25 * s
        out[0] = (R[2, 1] - R[1, 2]) / s
        out[1] = (R[0, 2] - R[2, 0]) / s
        out[2] = (R[1, 0] - R[0, 1]) / s
    elif R[0, 0] > R[1, 1] and R[0, 0] > R[2, 2]:
        s = math.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2]) * 2.0
        out[3] = (R[2, 1] - R[1, 2]) / s
        out[0] = 0.25 * s
        out[1] = (R[0, 1] + R[1, 0]) / s
        out[2] = (R[0, 2] + R[2, 0]) / s
    elif R[1, 1] > R[2, 2]:
        s = math.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2]) * 2.0
        out[3] = (R[0, 2] - R[2, 0]) / s
        out[0] = (R[0, 1] + R[1, 0]) / s
        out[1] = 0.25 * s
        out[2] = (R[1, 2] + R[2, 1]) / s
    else:
        s = math.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1]) * 2.0
        out[3] = (R[1, 0] - R[0, 1]) / s
        out[0] = (R[0, 2] + R[2, 0]) / s
        out[1] = (R[1, 2] + R[2, 1]) / s
        out[2] = 0.25 * s
    return out


@njit(cache=True)
def quaternion_error_into(R, R_d, e):  # type: ignore[no-untyped-def]
    """``e_O = η ε_d − η_d ε − S(ε_d) ε`` (thesis Eq. 3.9) into ``e``; returns the angle
    ``φ = 2 asin |e_O|`` between ``R`` and ``R_d`` (see :func:`quaternion_error`)."""
    q = unit_quaternion(R)
    qd = unit_quaternion(R_d)
    if q[0] * qd[0] + q[1] * qd[1] + q[2] * qd[2] + q[3] * qd[3] < 0.0:
        for i in range(4):
            qd[i] = -qd[i]
    eta = q[3]
    eta_d = qd[3]
    e[0] = eta * qd[0] - eta_d * q[0] - (qd[1] * q[2] - qd[2] * q[1])
    e[1] = eta * qd[1] - eta_d * q[1] - (qd[2] * q[0] - qd[0] * q[2])
    e[2] = eta * qd[2] - eta_d * q[2] - (qd[0] * q[1] - qd[1] * q[0])
    s = math.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2])
    return 2.0 * math.asin(min(s, 1.0))


@njit(cache=True)
def rotation_error_into(R, R_d, out):  # type: ignore[no-untyped-def]
    """Rotation vector ``φ u`` of ``E = R_d Rᵀ`` into ``out``; returns ``φ ∈ [0, π]``.

    With ``v = vee((E − Eᵀ)/2) = sin φ u`` and ``cos φ = (tr E − 1)/2``:
    ``φ = atan2(|v|, cos φ)`` and ``φ u = (φ/|v|) v``; close to a half turn (``|v|``
    small, ``cos φ < 0``) the axis comes from the symmetric part instead,
    ``u uᵀ = ((E + Eᵀ)/2 − cos φ I)/(1 − cos φ)``, its sign from ``v``.
    """
    E = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            E[i, j] = R_d[i, 0] * R[j, 0] + R_d[i, 1] * R[j, 1] + R_d[i, 2] * R[j, 2]
    vx = 0.5 * (E[2, 1] - E[1, 2])
    vy = 0.5 * (E[0, 2] - E[2, 0])
    vz = 0.5 * (E[1, 0] - E[0, 1])
    s = math.sqrt(vx * vx + vy * vy + vz * vz)
    c = 0.5 * (E[0, 0] + E[1, 1] + E[2, 2] - 1.0)
    phi = math.atan2(s, c)
    if c < 0.0 and s < 1e-4:
        # u u_k = column k of u uᵀ, for the axis k with the largest u_k²
        k = 0
        for i in range(1, 3):
            if E[i, i] > E[k, k]:
                k = i
        u = np.empty(3)
        for i in range(3):
            u[i] = 0.5 * (E[i, k] + E[k, i]) / (1.0 - c)
        u[k] = (E[k, k] - c) / (1.0 - c)
        nrm = math.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2])
        if u[0] * vx + u[1] * vy + u[2] * vz < 0.0:
            nrm = -nrm
        for i in range(3):
            out[i] = phi * u[i] / nrm
    elif s > 1e-7:
        f = phi / s
        out[0] = f * vx
        out[1] = f * vy
        out[2] = f * vz
    else:  # φ ≈ 0, where φ/sin φ = 1
        out[0] = vx
        out[1] = vy
        out[2] = vz
    return phi


@njit(cache=True)
def axis_error_into(R, axis_d, out):  # type: ignore[no-untyped-def]
    """5-D error of an axis-symmetric tool into ``out``: the rotation vector ``φ u`` of
    the shortest rotation taking the tool axis ``z = R[:, 2]`` onto the unit vector
    ``axis_d`` (``u ∥ z × axis_d``); returns ``φ``. Antiparallel axes: a half turn about
    the tool's x axis."""
    cx = R[1, 2] * axis_d[2] - R[2, 2] * axis_d[1]
    cy = R[2, 2] * axis_d[0] - R[0, 2] * axis_d[2]
    cz = R[0, 2] * axis_d[1] - R[1, 2] * axis_d[0]
    s = math.sqrt(cx * cx + cy * cy + cz * cz)
    c = R[0, 2] * axis_d[0] + R[1, 2] * axis_d[1] + R[2, 2] * axis_d[2]
    phi = math.atan2(s, c)
    if s > 1e-12:
        out[0] = phi * cx / s
        out[1] = phi * cy / s
        out[2] = phi * cz / s
    elif c < 0:
        out[0] = math.pi * R[0, 0]
        out[1] = math.pi * R[1, 0]
        out[2] = math.pi * R[2, 0]
    else:
        out[0] = 0.0
        out[1] = 0.0
        out[2] = 0.0
    return phi


@njit((RO_F8_3D, RO_F8_3D), cache=True)
def _quaternion_errors(R, R_d):  # type: ignore[no-untyped-def]
    out = np.empty((R.shape[0], 3))
    for k in range(R.shape[0]):
        quaternion_error_into(R[k], R_d[k], out[k])
    return out


@njit((RO_F8_3D, RO_F8_3D), cache=True)
def _rotation_errors(R, R_d):  # type: ignore[no-untyped-def]
    out = np.empty((R.shape[0], 3))
    for k in range(R.shape[0]):
        rotation_error_into(R[k], R_d[k], out[k])
    return out


@njit((RO_F8_3D, RO_F8_2D), cache=True)
def _axis_errors(R, axis_d):  # type: ignore[no-untyped-def]
    out = np.empty((R.shape[0], 3))
    for k in range(R.shape[0]):
        axis_error_into(R[k], axis_d[k], out[k])
    return out


# --------------------------------------------------------------------------- Python API


def _rotations(name: str, R: ArrayLike) -> NDArray[np.float64]:
    try:
        M = np.asarray(R, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError("orientation", name, f"not numeric: {exc}") from None
    if M.ndim < 2 or M.shape[-2:] != (3, 3):
        raise InputError("orientation", name, f"expected (..., 3, 3), got {M.shape}")
    return M


def _pairs(
    a: NDArray[np.float64], b: NDArray[np.float64], tail_b: int
) -> tuple[NDArray[np.float64], NDArray[np.float64], tuple[int, ...]]:
    """Broadcast the leading axes of ``a`` (…, 3, 3) and ``b`` (…, tail_b dims) and
    flatten them into one C-contiguous batch axis."""
    lead = np.broadcast_shapes(a.shape[:-2], b.shape[: b.ndim - tail_b])
    A = np.ascontiguousarray(np.broadcast_to(a, lead + a.shape[-2:])).reshape(-1, 3, 3)
    B = np.ascontiguousarray(np.broadcast_to(b, lead + b.shape[b.ndim - tail_b :]))
    return A, B.reshape((-1, *b.shape[b.ndim - tail_b :])), lead


def skew(v: ArrayLike) -> NDArray[np.float64]:
    """The skew-symmetric matrix ``S(v)`` with ``S(v) w = v × w``."""
    x, y, z = np.asarray(v, dtype=float)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def quaternion_error(R: ArrayLike, R_d: ArrayLike) -> NDArray[np.float64]:
    """Orientation error ``e_O = η ε_d − η_d ε − S(ε_d) ε`` (thesis Eq. 3.9).

    ``σ = {η, ε}`` and ``σ_d = {η_d, ε_d}`` are the unit quaternions of the current
    rotation ``R`` and the goal ``R_d`` (world frame). ``e_O`` is the vector part of
    ``σ_d * σ⁻¹``, i.e. ``sin(φ/2) u`` for the rotation ``(u, φ)`` taking ``R`` to
    ``R_d``; ``σ_d`` is sign-aligned with ``σ`` so the shorter rotation is taken.
    Batched over (broadcast) leading axes.
    """
    A, B, lead = _pairs(_rotations("R", R), _rotations("R_d", R_d), 2)
    return _quaternion_errors(A, B).reshape((*lead, 3))


def rotation_error(R: ArrayLike, R_d: ArrayLike) -> NDArray[np.float64]:
    """Rotation vector ``φ u`` of ``R_d Rᵀ`` (world frame), ``φ ∈ [0, π]``; batched.

    Same direction as Eq. 3.9's ``e_O`` (``|e_O| = sin(φ/2)``), but linear in the angle,
    which gives the inverse-kinematics iteration its quadratic convergence.
    """
    A, B, lead = _pairs(_rotations("R", R), _rotations("R_d", R_d), 2)
    return _rotation_errors(A, B).reshape((*lead, 3))


def axis_error(R: ArrayLike, axis_d: ArrayLike) -> NDArray[np.float64]:
    """5-D orientation error of an axis-symmetric tool (drill feed, P-II §5).

    Only the direction of the tool z axis ``z = R[:, 2]`` matters: the error is the
    rotation vector ``φ u`` of the shortest rotation taking ``z`` onto ``axis_d``
    (``u ∥ z × axis_d``), with no component about the tool axis; antiparallel axes give
    a half turn about the tool x axis. Batched over (broadcast) leading axes.
    """
    zd = np.asarray(axis_d, dtype=np.float64)
    if zd.ndim < 1 or zd.shape[-1] != 3:
        raise InputError("orientation", "axis_d", f"expected (..., 3), got {zd.shape}")
    nrm = np.linalg.norm(zd, axis=-1, keepdims=True)
    if not np.all(nrm > 0.0) or not np.isfinite(nrm).all():
        raise InputError("orientation", "axis_d", "axes must be finite and nonzero")
    A, B, lead = _pairs(_rotations("R", R), zd / nrm, 1)
    return _axis_errors(A, B).reshape((*lead, 3))


def angle_between(R: ArrayLike, R_d: ArrayLike) -> NDArray[np.float64] | float:
    """Rotation angle (rad) between two orientations, batched."""
    e = np.linalg.norm(rotation_error(R, R_d), axis=-1)
    return float(e) if np.ndim(e) == 0 else e
