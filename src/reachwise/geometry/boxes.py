"""Bounding boxes of the thesis's distance pipeline (P-III §2, P-V §II, Table 1).

Table 1 (P-V; the same table is P-III's) builds, per query, a chain of boxes:

- step 3: an **AABB** of each cloud in the cloud's own frame, enlarged by ``δx`` beyond
  the tight fit (:meth:`AABB.of_points`, :meth:`AABB.enlarged`);
- step 5: the **extended OBB** (EOBB) — that enlarged AABB placed in the world by the
  cloud's pose (:class:`OBB`, :func:`eobb`);
- step 6: the **separating-axis test** between the two EOBBs (:func:`obb_overlap`);
- step 7–8: the **overlap volume** of the two EOBBs, turned back into an AABB in each
  cloud's frame with the inverse of the input pose (:func:`overlap_box`), so that the
  points of the cloud inside it can be found with the cloud's spatial index (step 9).

Representation: an :class:`OBB` is an axis-aligned box ``box`` (``lo``, ``hi``) expressed
in a frame whose world pose is the 4x4 matrix ``pose``: the set
``{R x + t : lo <= x <= hi}`` with ``R = pose[:3, :3]``, ``t = pose[:3, 3]``. For an EOBB
built from a cloud, that frame is the cloud's frame, so an AABB returned by
:func:`overlap_box` selects cloud points directly.

Pure numpy; metres; poses are proper rigid transforms (rotation part orthonormal).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.errors import InputError

#: Relative tolerance added to the projected radii of the separating-axis test: boxes
#: that are separated by less than this (times the boxes' size) count as overlapping.
#: It keeps the test conservative when two edges are (nearly) parallel and their cross
#: product, a candidate axis, degenerates to (nearly) zero (Gottschalk et al. 1996).
SAT_EPSILON = 1e-12


def _vec3(value: ArrayLike, name: str) -> NDArray[np.float64]:
    v = np.array(value, dtype=np.float64, copy=True).reshape(-1)
    if v.shape != (3,):
        raise InputError(name, "", f"expected 3 numbers, got shape {np.shape(value)}")
    if not np.isfinite(v).all():
        raise InputError(name, "", "contains NaN or inf")
    v.setflags(write=False)
    return v


@dataclass(frozen=True, eq=False)
class AABB:
    """Axis-aligned box ``lo <= x <= hi`` (metres) in some frame; ``lo``, ``hi`` shape (3,)."""

    lo: NDArray[np.float64]
    hi: NDArray[np.float64]

    def __post_init__(self) -> None:
        lo = _vec3(self.lo, "AABB.lo")
        hi = _vec3(self.hi, "AABB.hi")
        if (hi < lo).any():
            raise InputError("AABB", "hi", f"hi {hi.tolist()} is below lo {lo.tolist()}")
        object.__setattr__(self, "lo", lo)
        object.__setattr__(self, "hi", hi)

    @classmethod
    def of_points(cls, points: ArrayLike, delta: float = 0.0) -> AABB:
        """The tight AABB of (N, 3) ``points``, enlarged by ``delta`` (δx, Table 1 step 3)
        on every side."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        if p.shape[0] == 0:
            raise InputError("AABB.of_points", "points", "no points")
        return cls(p.min(axis=0), p.max(axis=0)).enlarged(delta)

    def enlarged(self, delta: float) -> AABB:
        """The box grown by ``delta`` >= 0 metres on all six sides."""
        d = float(delta)
        if not (d >= 0.0 and np.isfinite(d)):
            raise InputError("AABB.enlarged", "delta", f"must be finite and >= 0, got {delta}")
        return AABB(self.lo - d, self.hi + d)

    @property
    def center(self) -> NDArray[np.float64]:
        return 0.5 * (self.lo + self.hi)

    @property
    def half_extents(self) -> NDArray[np.float64]:
        return 0.5 * (self.hi - self.lo)

    def contains(self, points: ArrayLike) -> NDArray[np.bool_]:
        """Boolean mask: which of the (N, 3) ``points`` lie in the closed box."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        return np.all((p >= self.lo) & (p <= self.hi), axis=1)


@dataclass(frozen=True, eq=False)
class OBB:
    """Oriented box: the AABB ``box`` of a frame whose world pose is ``pose`` (4x4).

    ``center``, ``axes`` (columns are the box axes in world) and ``half_extents`` give the
    classic centre/axes/extent form used by the separating-axis test.
    """

    pose: NDArray[np.float64]
    box: AABB

    def __post_init__(self) -> None:
        T = np.array(self.pose, dtype=np.float64, copy=True)
        if T.shape != (4, 4):
            raise InputError("OBB", "pose", f"expected a 4x4 matrix, got shape {T.shape}")
        if not np.isfinite(T).all():
            raise InputError("OBB", "pose", "contains NaN or inf")
        R = T[:3, :3]
        if np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or np.linalg.det(R) <= 0.0:
            raise InputError("OBB", "pose", "rotation part is not a proper rotation")
        T.setflags(write=False)
        object.__setattr__(self, "pose", T)

    @classmethod
    def from_aabb(cls, box: AABB, pose: ArrayLike | None = None) -> OBB:
        """The box ``box`` (in a cloud's frame) placed in world by that cloud's ``pose``."""
        return cls(np.eye(4) if pose is None else np.asarray(pose, dtype=np.float64), box)

    @property
    def axes(self) -> NDArray[np.float64]:
        return np.asarray(self.pose[:3, :3])

    @property
    def center(self) -> NDArray[np.float64]:
        return np.asarray(self.pose[:3, :3] @ self.box.center + self.pose[:3, 3])

    @property
    def half_extents(self) -> NDArray[np.float64]:
        return self.box.half_extents

    def extended(self, margin: float) -> OBB:
        """The extended OBB: every side pushed out by ``margin`` metres."""
        return OBB(self.pose, self.box.enlarged(margin))

    def vertices(self) -> NDArray[np.float64]:
        """The 8 corners in world, shape (8, 3)."""
        lo, hi = self.box.lo, self.box.hi
        corners = np.array(
            [[(hi if (k >> i) & 1 else lo)[i] for i in range(3)] for k in range(8)],
            dtype=np.float64,
        )
        return np.asarray(corners @ self.pose[:3, :3].T + self.pose[:3, 3])

    def to_local(self, points: ArrayLike) -> NDArray[np.float64]:
        """World points (N, 3) expressed in the box's frame."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        return np.asarray((p - self.pose[:3, 3]) @ self.pose[:3, :3])

    def contains(self, points: ArrayLike) -> NDArray[np.bool_]:
        """Boolean mask: which world points (N, 3) lie in the closed box."""
        return self.box.contains(self.to_local(points))


def eobb(box: AABB, pose: ArrayLike | None, margin: float = 0.0) -> OBB:
    """Table 1 step 5: the extended OBB of a cloud whose frame-AABB is ``box``.

    ``box`` is the cloud's AABB in its own frame (step 3, possibly already enlarged by
    δx), ``pose`` the cloud's world pose and ``margin`` an extra enlargement (m).
    """
    return OBB.from_aabb(box.enlarged(margin) if margin else box, pose)


def obb_overlap(a: OBB, b: OBB) -> bool:
    """Table 1 step 6: do two (closed) OBBs intersect? Separating-axis theorem, 15 axes.

    The candidate axes are the three face normals of each box and the nine cross
    products of their edge directions (Gottschalk, Lin & Manocha 1996). The projected
    radii are padded by :data:`SAT_EPSILON` times the boxes' size, so the answer is
    conservative: ``False`` guarantees the boxes are disjoint; boxes that touch, or that
    are separated by less than that tolerance, answer ``True``. Parallel edges make a
    cross-product axis vanish; the padding turns that axis's test into ``0 <= pad``,
    which never reports a false separation.
    """
    A = a.axes
    B = b.axes
    ea = a.half_extents
    eb = b.half_extents
    R = A.T @ B  # B's axes in A's frame
    t = A.T @ (b.center - a.center)
    pad = SAT_EPSILON * (1.0 + float(ea.sum() + eb.sum() + np.abs(t).sum()))
    absR = np.abs(R) + SAT_EPSILON
    # A's face normals
    if (np.abs(t) > ea + absR @ eb + pad).any():
        return False
    # B's face normals
    if (np.abs(R.T @ t) > absR.T @ ea + eb + pad).any():
        return False
    # Edge-edge cross products A_i x B_j
    for i in range(3):
        i1, i2 = (i + 1) % 3, (i + 2) % 3
        for j in range(3):
            j1, j2 = (j + 1) % 3, (j + 2) % 3
            ra = ea[i1] * absR[i2, j] + ea[i2] * absR[i1, j]
            rb = eb[j1] * absR[i, j2] + eb[j2] * absR[i, j1]
            dist = abs(t[i2] * R[i1, j] - t[i1] * R[i2, j])
            if dist > ra + rb + pad:
                return False
    return True


def _box_faces(box: AABB) -> list[NDArray[np.float64]]:
    """The six faces of ``box`` as (4, 3) quads in its frame."""
    lo, hi = box.lo, box.hi
    faces = []
    for axis in range(3):
        u, v = (axis + 1) % 3, (axis + 2) % 3
        for value in (lo[axis], hi[axis]):
            quad = np.empty((4, 3))
            quad[:, axis] = value
            quad[:, u] = [lo[u], hi[u], hi[u], lo[u]]
            quad[:, v] = [lo[v], lo[v], hi[v], hi[v]]
            faces.append(quad)
    return faces


def _clip(
    poly: NDArray[np.float64], normal: NDArray[np.float64], offset: float
) -> NDArray[np.float64]:
    """Sutherland–Hodgman: keep the part of convex polygon ``poly`` with n·x <= offset."""
    if poly.shape[0] == 0:
        return poly
    s = poly @ normal - offset
    inside = s <= 0.0
    if inside.all():
        return poly
    if not inside.any():
        return poly[:0]
    out = []
    n = poly.shape[0]
    for k in range(n):
        p, q = poly[k], poly[(k + 1) % n]
        sp, sq = s[k], s[(k + 1) % n]
        if sp <= 0.0:
            out.append(p)
        if (sp <= 0.0) != (sq <= 0.0):
            out.append(p + (sp / (sp - sq)) * (q - p))
    return np.array(out).reshape(-1, 3)


def _halfspaces(
    box: AABB, M: NDArray[np.float64], pad: float
) -> list[tuple[NDArray[np.float64], float]]:
    """Half-spaces n·x <= c (x in the target frame) of ``box`` placed by rigid ``M``,
    each pushed out by ``pad`` metres."""
    R = M[:3, :3]
    t = M[:3, 3]
    out = []
    for axis in range(3):
        n = R[:, axis]
        nt = float(n @ t)
        out.append((n, float(box.hi[axis]) + nt + pad))  # n·x <= hi + n·t
        out.append((-n, -float(box.lo[axis]) - nt + pad))  # -n·x <= -lo - n·t
    return out


def overlap_box(a: OBB, b: OBB) -> AABB | None:
    """Table 1 steps 7–8: the overlap volume of ``a`` and ``b`` as an AABB in ``a``'s frame.

    What is computed, precisely: the smallest axis-aligned box, in the frame of ``a``
    (the frame whose world pose is ``a.pose``, e.g. ``a``'s cloud frame), that contains
    the intersection polytope ``a ∩ b``, computed with ``b`` grown by a rounding
    allowance of 1e-12 times the boxes' size (and the result padded by the same), so
    that rounding never cuts into that polytope — boxes that merely touch still give a
    (thin) box. The result never extends beyond ``a`` itself. ``None`` when the boxes do
    not intersect. ``overlap_box(b, a)`` is the same region's box in ``b``'s frame.

    Method: every vertex of the convex polytope ``a ∩ b`` lies on a face of ``a`` or of
    ``b``; each face of ``a`` is clipped by the six half-spaces of ``b`` and vice versa
    (Sutherland–Hodgman), and the box spans the surviving polygon vertices, which are
    exactly the vertices of ``a ∩ b`` (plus points on its edges), so the box is tight.
    The points of a cloud inside this box are a superset of its points in ``a ∩ b``.
    """
    Ta = a.pose
    Tb = b.pose
    Ra = Ta[:3, :3]
    # b's frame -> a's frame and back (rigid inverses)
    M_ba = np.eye(4)
    M_ba[:3, :3] = Ra.T @ Tb[:3, :3]
    M_ba[:3, 3] = Ra.T @ (Tb[:3, 3] - Ta[:3, 3])
    M_ab = np.eye(4)
    M_ab[:3, :3] = M_ba[:3, :3].T
    M_ab[:3, 3] = -M_ba[:3, :3].T @ M_ba[:3, 3]

    size = float(
        np.abs(a.box.lo).max()
        + np.abs(a.box.hi).max()
        + np.abs(b.box.lo).max()
        + np.abs(b.box.hi).max()
        + np.abs(M_ba[:3, 3]).max()
    )
    pad = 1e-12 * (1.0 + size)
    pieces = []
    # faces of a (in a's frame) clipped by b's half-spaces expressed in a's frame
    hs_b = _halfspaces(b.box, M_ba, pad)
    for quad in _box_faces(a.box):
        poly = quad
        for n, c in hs_b:
            poly = _clip(poly, n, c)
        if poly.shape[0]:
            pieces.append(poly)
    # faces of b (in b's frame) clipped by a's half-spaces in b's frame, mapped to a's frame
    hs_a = _halfspaces(a.box, M_ab, pad)
    for quad in _box_faces(b.box):
        poly = quad
        for n, c in hs_a:
            poly = _clip(poly, n, c)
        if poly.shape[0]:
            pieces.append(poly @ M_ba[:3, :3].T + M_ba[:3, 3])
    if not pieces:
        return None
    verts = np.concatenate(pieces)
    lo = np.maximum(verts.min(axis=0) - pad, a.box.lo)
    hi = np.minimum(verts.max(axis=0) + pad, a.box.hi)
    if (hi < lo).any():
        return None
    return AABB(lo, hi)
