"""What every distance strategy shares: the result type and the input checks (each
cloud's index is :mod:`reachwise.distance.index`).

The result convention (all strategies, thesis P-V Table 1 "no risk" exits included):

- within the margin (``distance <= margin``): ``distance`` is the exact shortest distance
  between the two placed clouds, ``point_a``/``point_b`` the closest pair in world
  coordinates (``‖point_a - point_b‖ == distance``), ``index_a``/``index_b`` their rows
  in the input clouds and ``direction`` the unit collision-line vector from b to a,
  ``(point_a - point_b) / distance``. When the clouds touch (distance 0) the direction
  is the unit vector from b's centroid to a's centroid in world (the way that pushes a
  out of b), and world +z if the centroids coincide as well.
- beyond the margin: ``no_risk=True``, ``distance=inf`` (read: "greater than the
  margin"; a controller's repulsion term is zero there), NaN points and direction and
  indices -1. Strategies may stop as soon as "beyond the margin" is certain, so no
  finite distance is promised then.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

import reachwise.distance._kernels as K
from reachwise.distance.index import cloud_centroid
from reachwise.errors import InputError
from reachwise.geometry.cloud import PointCloud

#: Largest accepted deviation max|RᵀR - I| of a pose's rotation part. Rotations that
#: deviate by more than 1e-12 but at most this are replaced by the nearest rotation
#: (polar decomposition) before use, by every strategy alike.
ROTATION_TOLERANCE = 1e-6


@dataclass(frozen=True, eq=False)
class DistanceResult:
    """Shortest distance between two placed point clouds (thesis §3.1, P-V Table 1).

    ``distance`` in metres; ``point_a``, ``point_b``, ``direction`` shape (3,), world
    frame; ``direction`` is the unit vector from ``point_b`` to ``point_a``. See the
    module docstring for the values at distance 0 and beyond the margin
    (``no_risk=True``: ``distance=inf``, NaN vectors, indices -1).
    """

    distance: float
    point_a: NDArray[np.float64]
    point_b: NDArray[np.float64]
    direction: NDArray[np.float64]
    index_a: int
    index_b: int
    no_risk: bool

    def swapped(self) -> DistanceResult:
        """The same result seen from the other side: a and b exchanged."""
        if self.no_risk:
            return self
        d = -self.direction
        d.setflags(write=False)
        return DistanceResult(
            self.distance,
            self.point_b,
            self.point_a,
            d,
            self.index_b,
            self.index_a,
            False,
        )


def _nan3() -> NDArray[np.float64]:
    v = np.full(3, np.nan)
    v.setflags(write=False)
    return v


#: The one "no risk" result (immutable, shared).
NO_RISK = DistanceResult(math.inf, _nan3(), _nan3(), _nan3(), -1, -1, True)


def as_cloud(data: PointCloud | ArrayLike, name: str) -> PointCloud:
    """``data`` as a PointCloud (CloudError for a bad array)."""
    if isinstance(data, PointCloud):
        return data
    return PointCloud.of(data, name=name)


_EYE = np.eye(4)


def pose_array(pose: ArrayLike | None, name: str) -> NDArray[np.float64]:
    """A C-contiguous, writable float64 (4, 4) array of ``pose`` (shape checked only)."""
    if pose is None:
        return _EYE
    try:
        P = np.ascontiguousarray(pose, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(name, "", f"not a numeric 4x4 matrix: {exc}") from None
    if P.shape != (4, 4):
        raise InputError(name, "", f"expected a 4x4 homogeneous matrix, got shape {P.shape}")
    if not P.flags.writeable:
        P = P.copy()
    return P


def check_pose(pose: ArrayLike | None, name: str) -> NDArray[np.float64]:
    """Validate a 4x4 rigid pose; return it as float64 (rotation snapped if needed).

    Errors (:class:`~reachwise.errors.InputError`): wrong shape, NaN/inf, a bottom row
    other than ``0 0 0 1``, a rotation part that is not orthonormal within
    :data:`ROTATION_TOLERANCE` or is a reflection (det < 0).
    """
    P = pose_array(pose, name)
    status = int(K.pose_status(P))
    if status == 0:
        return P
    if status == 1:
        raise InputError(name, "", "contains NaN or inf")
    if status == 2:
        raise InputError(name, "bottom row", f"must be [0, 0, 0, 1], got {P[3].tolist()}")
    R = P[:3, :3]
    dev = float(np.abs(R.T @ R - np.eye(3)).max())
    det = float(np.linalg.det(R))
    if dev > ROTATION_TOLERANCE:
        raise InputError(
            name,
            "rotation",
            f"not orthonormal: max|RᵀR - I| = {dev:.3g} > {ROTATION_TOLERANCE:g}",
        )
    if det <= 0.0:
        raise InputError(name, "rotation", f"not a proper rotation (det = {det:.6g})")
    U, _, Vt = np.linalg.svd(R)
    Q = np.array(P, copy=True)
    Q[:3, :3] = U @ Vt
    return np.ascontiguousarray(Q)


def check_added_stamp(stamp: float, name: str) -> float:
    """The stamp (s) of object ``name``'s cloud as it is added: a time, +inf (does not
    age) or NaN (unknown); -inf, a bool or a non-number is an InputError."""
    if isinstance(stamp, bool) or not isinstance(stamp, numbers.Real) or stamp == -math.inf:
        raise InputError(
            "scene", f"object {name!r}", f"stamp must be a time in s, inf or NaN, got {stamp!r}"
        )
    return float(stamp)


def check_margin(margin: float) -> float:
    """The margin as a float >= 0 (inf allowed); InputError otherwise."""
    try:
        m = float(margin)
    except (TypeError, ValueError):
        raise InputError("margin", "", f"must be a number, got {margin!r}") from None
    if math.isnan(m) or m < 0.0:
        raise InputError("margin", "", f"must be >= 0 metres (inf allowed), got {margin!r}")
    return m


def world(points: NDArray[np.float64], pose: NDArray[np.float64]) -> NDArray[np.float64]:
    """Points (N, 3) of a cloud frame mapped to world by ``pose``."""
    return np.asarray(points @ pose[:3, :3].T + pose[:3, 3])


def result_from_pair(
    a: PointCloud,
    b: PointCloud,
    pose_a: NDArray[np.float64],
    pose_b: NDArray[np.float64],
    ia: int,
    ib: int,
    margin: float,
) -> DistanceResult:
    """The result for the closest pair (row ``ia`` of a, row ``ib`` of b), or NO_RISK if
    that pair is farther apart than ``margin``."""
    pa = np.ascontiguousarray(pose_a[:3, :3] @ a.points[ia] + pose_a[:3, 3])
    pb = np.ascontiguousarray(pose_b[:3, :3] @ b.points[ib] + pose_b[:3, 3])
    ca = np.ascontiguousarray(pose_a[:3, :3] @ cloud_centroid(a) + pose_a[:3, 3])
    cb = np.ascontiguousarray(pose_b[:3, :3] @ cloud_centroid(b) + pose_b[:3, 3])
    out = np.empty(10)
    K.finish(pa, pb, ca, cb, margin, out)
    if out[0] > margin:
        return NO_RISK
    out.setflags(write=False)
    return DistanceResult(float(out[0]), out[1:4], out[4:7], out[7:10], int(ia), int(ib), False)
