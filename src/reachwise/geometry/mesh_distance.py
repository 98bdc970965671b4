"""The exact distance between two triangle meshes: the ground truth a simulation judges
clearance by, when the controller only sees a sensed cloud of an object.

Two triangulated surfaces ``A`` and ``B`` that do not cross are nearest at a pair of
points of which at least one is a vertex, or which lie on two edges (the closest
points of two triangles are vertex–face or edge–edge pairs; Ericson, *Real-Time
Collision Detection*, §5.1.9): so

    d(A, B) = min( min_{v ∈ V_A} d(v, B), min_{v ∈ V_B} d(v, A), min_{e ∈ E_A, f ∈ E_B} d(e, f) )

with the point–triangle distance of Ericson §5.1.5 and the segment–segment distance of
§5.1.9. Two surfaces that cross — an edge of one passes through a triangle of the
other — are at distance 0. Whether one solid lies inside the other is a question of
the solids, not of their surfaces; the caller asks it separately
(:mod:`reachwise.sim.contact`).

Pairs are pruned by their bounding boxes against the smallest distance found so far
(first the nearest vertex pair), so only the features near the closest approach are
measured; the result is exact to rounding. Pure math: arrays in, a float out.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from reachwise.errors import InputError

if TYPE_CHECKING:
    import trimesh

__all__ = [
    "mesh_distance",
    "point_triangle_distance",
    "segment_closest_parameters",
    "segment_distance",
]

F64 = NDArray[np.float64]
_SRC = "mesh distance"
_CHUNK = 1 << 18  # pairs measured per numpy batch


def _dot(a: F64, b: F64) -> F64:
    return np.einsum("ij,ij->i", a, b)


def point_triangle_distance(p: ArrayLike, a: ArrayLike, b: ArrayLike, c: ArrayLike) -> F64:
    """Distance of each point ``p[i]`` to the triangle ``(a[i], b[i], c[i])`` (all
    ``(k, 3)``): Ericson's closest point on a triangle (§5.1.5), by Voronoi region."""
    P, A, B, C = (np.asarray(x, dtype=np.float64).reshape(-1, 3) for x in (p, a, b, c))
    ab, ac, ap = B - A, C - A, P - A
    d1, d2 = _dot(ab, ap), _dot(ac, ap)
    bp = P - B
    d3, d4 = _dot(ab, bp), _dot(ac, bp)
    cp = P - C
    d5, d6 = _dot(ab, cp), _dot(ac, cp)
    vc = d1 * d4 - d3 * d2
    vb = d5 * d2 - d1 * d6
    va = d3 * d6 - d5 * d4
    with np.errstate(divide="ignore", invalid="ignore"):
        t_ab = d1 / (d1 - d3)
        t_ac = d2 / (d2 - d6)
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        den = va + vb + vc
        v, w = vb / den, vc / den
    regions = [
        (d1 <= 0) & (d2 <= 0),  # vertex a
        (d3 >= 0) & (d4 <= d3),  # vertex b
        (vc <= 0) & (d1 >= 0) & (d3 <= 0),  # edge ab
        (d6 >= 0) & (d5 <= d6),  # vertex c
        (vb <= 0) & (d2 >= 0) & (d6 <= 0),  # edge ac
        (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0),  # edge bc
    ]
    choices = [
        A,
        B,
        A + np.nan_to_num(t_ab)[:, None] * ab,
        C,
        A + np.nan_to_num(t_ac)[:, None] * ac,
        B + np.nan_to_num(t_bc)[:, None] * (C - B),
    ]
    inside = A + np.nan_to_num(v)[:, None] * ab + np.nan_to_num(w)[:, None] * ac
    q = inside
    for cond, choice in zip(reversed(regions), reversed(choices), strict=True):
        q = np.where(cond[:, None], choice, q)
    return np.asarray(np.linalg.norm(P - q, axis=1))


def segment_distance(p1: ArrayLike, q1: ArrayLike, p2: ArrayLike, q2: ArrayLike) -> F64:
    """Distance between the segments ``p1[i]q1[i]`` and ``p2[i]q2[i]`` (all ``(k, 3)``):
    Ericson's closest points of two segments (§5.1.9), degenerate segments included."""
    P1, Q1, P2, Q2 = (np.asarray(x, dtype=np.float64).reshape(-1, 3) for x in (p1, q1, p2, q2))
    s, t = segment_closest_parameters(P1, Q1, P2, Q2)
    gap = (P1 + s[:, None] * (Q1 - P1)) - (P2 + t[:, None] * (Q2 - P2))
    return np.asarray(np.linalg.norm(gap, axis=1))


def segment_closest_parameters(
    p1: ArrayLike, q1: ArrayLike, p2: ArrayLike, q2: ArrayLike
) -> tuple[F64, F64]:
    """Parameters ``s, t`` in ``[0, 1]`` of the closest points ``p1 + s (q1 − p1)`` and
    ``p2 + t (q2 − p2)`` of two segments, row by row (all ``(k, 3)``): Ericson,
    *Real-Time Collision Detection*, §5.1.9, degenerate segments included."""
    P1, Q1, P2, Q2 = (np.asarray(x, dtype=np.float64).reshape(-1, 3) for x in (p1, q1, p2, q2))
    d1, d2, r = Q1 - P1, Q2 - P2, P1 - P2
    a, e, f = _dot(d1, d1), _dot(d2, d2), _dot(d2, r)
    c, b = _dot(d1, r), _dot(d1, d2)
    tiny = 1e-300
    denom = a * e - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        # the general case (Ericson): s on the lines' closest pair, t from s, re-clamped
        s = np.where(denom > 1e-14 * a * e, np.clip((b * f - c * e) / denom, 0.0, 1.0), 0.0)
        t = (b * s + f) / e
        s_lo = np.clip(-c / a, 0.0, 1.0)  # t clamped to 0: s from p2
        s_hi = np.clip((b - c) / a, 0.0, 1.0)  # t clamped to 1: s from q2
        t_only = np.clip(f / e, 0.0, 1.0)  # the first segment is a point
    s = np.where(t < 0.0, s_lo, np.where(t > 1.0, s_hi, s))
    t = np.clip(t, 0.0, 1.0)
    second_point = e <= tiny
    s = np.where(second_point, s_lo, s)
    t = np.where(second_point, 0.0, t)
    first_point = a <= tiny
    s = np.where(first_point, 0.0, s)
    t = np.where(first_point, np.where(second_point, 0.0, t_only), t)
    return np.asarray(s, dtype=np.float64), np.asarray(t, dtype=np.float64)


def _segments_cross(p: F64, q: F64, a: F64, b: F64, c: F64) -> NDArray[np.bool_]:
    """Does segment ``pq`` pass through triangle ``abc`` (Möller–Trumbore, closed)?"""
    d = q - p
    e1, e2 = b - a, c - a
    h = np.cross(d, e2)
    det = _dot(e1, h)
    ok = np.abs(det) > 1e-300
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = np.where(ok, 1.0 / det, 0.0)
        s = p - a
        u = inv * _dot(s, h)
        qv = np.cross(s, e1)
        v = inv * _dot(d, qv)
        t = inv * _dot(e2, qv)
    return np.asarray(ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t >= 0) & (t <= 1))


def _box_gap(lo1: F64, hi1: F64, lo2: F64, hi2: F64) -> F64:
    """Distance between axis-aligned boxes (rows of ``lo``/``hi``, broadcast)."""
    gap = np.maximum(0.0, np.maximum(lo1 - hi2, lo2 - hi1))
    return np.asarray(np.sqrt((gap * gap).sum(axis=-1)))


def _near_pairs(
    lo1: F64, hi1: F64, lo2: F64, hi2: F64, bound: float
) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Index pairs ``(i, j)`` whose boxes are within ``bound`` of each other: first each
    side's boxes against the other side's whole box, then the survivors pairwise."""
    keep1 = np.flatnonzero(_box_gap(lo1, hi1, lo2.min(axis=0), hi2.max(axis=0)) <= bound)
    keep2 = np.flatnonzero(_box_gap(lo2, hi2, lo1.min(axis=0), hi1.max(axis=0)) <= bound)
    out_i, out_j = [np.zeros(0, np.intp)], [np.zeros(0, np.intp)]
    rows = max(1, _CHUNK // max(1, len(keep2)))
    l2, h2 = lo2[keep2][None], hi2[keep2][None]
    for s in range(0, len(keep1), rows):
        k1 = keep1[s : s + rows]
        i, j = np.nonzero(_box_gap(lo1[k1, None], hi1[k1, None], l2, h2) <= bound)
        out_i.append(k1[i])
        out_j.append(keep2[j])
    return np.concatenate(out_i), np.concatenate(out_j)


def _as_mesh(mesh: object, pose: ArrayLike | None, name: str) -> tuple[F64, NDArray[np.int64]]:
    """World vertices and faces of a Trimesh or ``(vertices, faces)`` pair."""
    if hasattr(mesh, "vertices") and hasattr(mesh, "faces"):
        v_in, f_in = mesh.vertices, mesh.faces
    elif isinstance(mesh, tuple | list) and len(mesh) == 2:
        v_in, f_in = mesh
    else:
        raise InputError(_SRC, name, "expected a trimesh.Trimesh or (vertices, faces)")
    v = np.asarray(v_in, dtype=np.float64)
    f = np.asarray(f_in)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0 or not np.isfinite(v).all():
        raise InputError(_SRC, name, f"vertices must be finite (V, 3), V >= 1, got {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0 or not np.issubdtype(f.dtype, np.integer):
        raise InputError(_SRC, name, f"faces must be integer (F, 3), F >= 1, got {f.shape}")
    if f.min() < 0 or f.max() >= len(v):
        raise InputError(_SRC, name, f"face indices must lie in [0, {len(v) - 1}]")
    if pose is not None:
        T = np.asarray(pose, dtype=np.float64)
        if T.shape != (4, 4) or not np.isfinite(T).all():
            raise InputError(_SRC, f"pose of {name}", f"expected a finite 4x4, got {T.shape}")
        v = v @ T[:3, :3].T + T[:3, 3]
    return v, f.astype(np.int64)


def _edges(f: NDArray[np.int64]) -> NDArray[np.int64]:
    """The unique edges ``(E, 2)`` of faces ``f`` (each once, smaller index first)."""
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    lo, hi = e.min(axis=1), e.max(axis=1)
    key = np.unique(lo * (int(f.max()) + 1) + hi)  # one integer per edge: a fast unique
    return np.column_stack([key // (int(f.max()) + 1), key % (int(f.max()) + 1)])


def mesh_distance(
    a: trimesh.Trimesh | tuple[ArrayLike, ArrayLike],
    b: trimesh.Trimesh | tuple[ArrayLike, ArrayLike],
    pose_a: ArrayLike | None = None,
    pose_b: ArrayLike | None = None,
) -> float:
    """The exact distance (m) between the surfaces of meshes ``a`` and ``b`` (each a
    ``trimesh.Trimesh`` or ``(vertices, faces)``, placed at ``pose_a``/``pose_b``,
    4 × 4, default identity); 0 when they touch or cross (see the module docstring)."""
    va, fa = _as_mesh(a, pose_a, "a")
    vb, fb = _as_mesh(b, pose_b, "b")
    best = float(cKDTree(vb).query(va, k=1)[0].min())  # nearest vertex pair: a bound
    if best == 0.0:
        return 0.0
    ta, tb = va[fa], vb[fb]  # (F, 3, 3) triangle corners
    tlo_a, thi_a = ta.min(axis=1), ta.max(axis=1)
    tlo_b, thi_b = tb.min(axis=1), tb.max(axis=1)
    # vertices of one against the triangles of the other
    for pts, tri, lo, hi in ((va, tb, tlo_b, thi_b), (vb, ta, tlo_a, thi_a)):
        i, j = _near_pairs(pts, pts, lo, hi, best)
        if len(i):
            d = point_triangle_distance(pts[i], *tri[j].transpose(1, 0, 2))
            best = min(best, float(d.min()))
    ea, eb = _edges(fa), _edges(fb)
    sa, sb = va[ea], vb[eb]  # (E, 2, 3)
    slo_a, shi_a = sa.min(axis=1), sa.max(axis=1)
    slo_b, shi_b = sb.min(axis=1), sb.max(axis=1)
    # edges of one crossing triangles of the other: the surfaces cross
    for seg, slo, shi, tri, tlo, thi in (
        (sa, slo_a, shi_a, tb, tlo_b, thi_b),
        (sb, slo_b, shi_b, ta, tlo_a, thi_a),
    ):
        i, j = _near_pairs(slo, shi, tlo, thi, 0.0)
        if len(i) and _segments_cross(seg[i, 0], seg[i, 1], *tri[j].transpose(1, 0, 2)).any():
            return 0.0
    i, j = _near_pairs(slo_a, shi_a, slo_b, shi_b, best)
    if len(i):
        best = min(best, float(segment_distance(sa[i, 0], sa[i, 1], sb[j, 0], sb[j, 1]).min()))
    return best
