"""The modified DH rows of a rigid transform, for reading and writing URDF
(:mod:`reachwise.io.urdf`): the elementary transform of one row (Craig's convention,
:func:`mdh_transform`), the rotation taking z to a joint axis
(:func:`rotation_z_to`), and the decomposition of a transform between two joint
axes into DH rows (:func:`decompose_transform`, with
:func:`decompose_transform_fallback` for the cases it cannot take)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.kinematics.transforms import rot_x as _rx
from reachwise.kinematics.transforms import rot_z as _rz
from reachwise.kinematics.transforms import translation as _tr

__all__ = ["decompose_transform", "decompose_transform_fallback", "mdh_transform", "rotation_z_to"]

_EPS_LEN = 1e-12  # m: a translation this small is dropped (error far below 1e-10)

Mat = NDArray[np.float64]


# ---- elementary transforms ---------------------------------------------------------
def mdh_transform(alpha: float, a: float, theta: float, d: float) -> Mat:
    """``Rx(alpha) Tx(a) Rz(theta) Tz(d)``: one modified-DH row (P-I Eq. 2)."""
    return _rx(alpha) @ _tr(x=a) @ _rz(theta) @ _tr(z=d)


def rotation_z_to(u: ArrayLike) -> Mat:
    """A 4x4 rotation ``A`` with ``A @ [0, 0, 1] = u`` (``u`` a unit vector)."""
    v = np.asarray(u, dtype=float)
    flip = v[2] < -0.5
    if flip:  # work with Rx(π)ᵀ u, whose z is positive, then put Rx(π) back in front
        v = np.array([v[0], -v[1], -v[2]])
    k = np.array([-v[1], v[0], 0.0])  # z × v
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    R = np.eye(3) + K + K @ K / (1.0 + v[2])
    A = np.eye(4)
    A[:3, :3] = R
    if flip:
        A = _rx(math.pi) @ A
    return A


# ---- decomposition of a rigid transform into DH rows -------------------------------
def decompose_transform(G: ArrayLike) -> tuple[float, float, float, float, float, float]:
    """``(θ₁, d₁, α, a, θ₂, d₂)`` with ``G = Rz(θ₁) Tz(d₁) Rx(α) Tx(a) Rz(θ₂) Tz(d₂)``.

    The first factor slides and turns along the ``z`` axis of the start frame to the
    common normal of the two ``z`` axes; the rest is a modified-DH row (P-I Eq. 2) from
    there to the frame of ``G``. When the axes are parallel the normal is taken through
    the start origin (``d₁ = 0``). The sign of the normal is chosen so that
    ``|θ₁| ≤ π/2``, so a transform that already is one DH row returns ``θ₁ = d₁ = 0``
    and its own parameters. Raises ``ValueError`` when the common normal is so far
    away (nearly parallel axes) that the result would lose precision; callers then
    use ``decompose_transform_fallback``.
    """
    T = np.asarray(G, dtype=float)
    zg, xg, p = T[:3, 2], T[:3, 0], T[:3, 3]
    c = float(zg[2])
    n = np.array([-zg[1], zg[0], 0.0])  # e_z × zg
    s = float(np.hypot(n[0], n[1]))
    scale = 1.0 + float(np.linalg.norm(p))
    if s > 1e-14:
        xf = n / s
        sc = (float(p[2]) - c * float(p @ zg)) / s**2  # foot on the start z axis
        tc = (c * float(p[2]) - float(p @ zg)) / s**2  # foot on the end z axis
        if max(abs(sc), abs(tc)) > 1e4 * scale:
            raise ValueError("common normal too far away (axes nearly parallel)")
        d1 = sc
        d2 = -tc
    else:
        xf = np.array([p[0], p[1], 0.0])
        rho = float(np.hypot(p[0], p[1]))
        xf = xf / rho if rho > _EPS_LEN else np.array([1.0, 0.0, 0.0])
        d1 = 0.0
        d2 = float(p[2]) * (1.0 if c > 0 else -1.0)
    if xf[0] < 0 or (xf[0] == 0 and xf[1] < 0):
        xf = -xf
    theta1 = math.atan2(xf[1], xf[0])
    alpha = math.atan2(float(np.cross([0.0, 0.0, 1.0], zg) @ xf), c)
    a = float((p - d1 * np.array([0.0, 0.0, 1.0]) - d2 * zg) @ xf)
    theta2 = math.atan2(float(np.cross(xf, xg) @ zg), float(xf @ xg))
    return theta1, d1, alpha, a, theta2, d2


def decompose_transform_fallback(
    G: ArrayLike,
) -> tuple[float, float, float, float, float, float]:
    """``(φ, p_z, ρ, θa, α, θb)`` with ``G = Rz(φ) Tz(p_z) · Tx(ρ) Rz(θa) · Rx(α) Rz(θb)``.

    Always exact and well conditioned: the translation in cylindrical coordinates
    ``(ρ, φ, p_z)``, then the remaining rotation ``Rz(-φ) R`` as ZXZ Euler angles.
    In DH rows: ``Rz(φ) Tz(p_z)`` joins the previous row's offsets, ``Tx(ρ) Rz(θa)`` is a
    fixed row ``(α=0, a=ρ, θ=θa, d=0)`` and ``Rx(α) Rz(θb)`` the moving row's constant part.
    """
    T = np.asarray(G, dtype=float)
    p = T[:3, 3]
    rho = float(np.hypot(p[0], p[1]))
    phi = math.atan2(float(p[1]), float(p[0])) if rho > _EPS_LEN else 0.0
    Rr = _rz(-phi)[:3, :3] @ T[:3, :3]
    # ZXZ: Rr = Rz(ta) Rx(al) Rz(tb); Rr[2] = (sin al sin tb, sin al cos tb, cos al)
    al = math.atan2(math.hypot(Rr[2, 0], Rr[2, 1]), Rr[2, 2])
    if math.hypot(Rr[2, 0], Rr[2, 1]) > 1e-300:
        tb = math.atan2(Rr[2, 0], Rr[2, 1])
    else:
        tb = 0.0
    # the rest is an exact z-rotation: Rz(ta) = Rr Rz(tb)ᵀ Rx(al)ᵀ
    Z = Rr @ _rz(tb)[:3, :3].T @ _rx(al)[:3, :3].T
    ta = math.atan2(Z[1, 0], Z[0, 0])
    return phi, float(p[2]), rho, ta, al, tb
