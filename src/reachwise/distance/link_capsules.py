"""Capsules that bound link clouds: a cheap lower bound of two clouds' distance.

Each link cloud is bounded by a capsule (a segment along its principal axis and a
radius), so the capsule-capsule distance less both radii — a lower bound of the cloud
distance — is evaluated for a whole batch of configurations at once with numpy; only
the configurations whose bound is within a margin need an exact query
(:mod:`reachwise.distance.self_pairs`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.geometry.cloud import PointCloud
from reachwise.geometry.mesh_distance import segment_closest_parameters

__all__ = ["Capsule", "LinkCapsules", "bounding_capsule", "capsule_distances"]


@dataclass(frozen=True)
class Capsule:
    """A capsule bounding a cloud, in the cloud's frame: the segment ``p0``–``p1`` and
    ``radius`` (every point is within ``radius`` of the segment)."""

    p0: NDArray[np.float64]
    p1: NDArray[np.float64]
    radius: float


def bounding_capsule(points: ArrayLike) -> Capsule:
    """A capsule around ``points``: the segment spans their extent along the principal
    axis (through their mean), the radius is the largest distance to it."""
    P = np.asarray(points, dtype=float).reshape(-1, 3)
    c = P.mean(axis=0)
    X = P - c
    if len(P) > 1:
        _, _, vt = np.linalg.svd(X, full_matrices=False)
        axis = vt[0]
    else:
        axis = np.array([0.0, 0.0, 1.0])
    t = X @ axis
    lo, hi = float(t.min()), float(t.max())
    tc = np.clip(t, lo, hi)
    r = float(np.linalg.norm(X - tc[:, None] * axis[None, :], axis=1).max())
    return Capsule(c + lo * axis, c + hi * axis, r)


def capsule_distances(
    a0: NDArray[np.float64],
    a1: NDArray[np.float64],
    b0: NDArray[np.float64],
    b1: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Distances between segments ``a0``–``a1`` and ``b0``–``b1``, row by row (``(m, 3)``
    each), at their closest points
    (:func:`reachwise.geometry.mesh_distance.segment_closest_parameters`, Ericson's
    *Real-Time Collision Detection*, §5.1.9)."""
    s, t = segment_closest_parameters(a0, a1, b0, b1)
    pa = a0 + s[:, None] * (a1 - a0)
    pb = b0 + t[:, None] * (b1 - b0)
    return np.asarray(np.linalg.norm(pa - pb, axis=1), dtype=float)


class LinkCapsules:
    """World poses of the link clouds' capsules for a batch of configurations.

    ``clouds`` are keyed by link name, each in its link's frame; ``index`` gives each
    link's column in the link frames of a batch (``Robot.fk_all``'s ``(m, links, 4,
    4)``)."""

    def __init__(self, clouds: Mapping[str, PointCloud], index: Mapping[str, int]) -> None:
        self.index = {n: int(index[n]) for n in clouds}
        self.caps = {n: bounding_capsule(c.points) for n, c in clouds.items()}

    def segments(
        self, F: NDArray[np.float64], link: str
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The ends of ``link``'s capsule segment in the world, one row per
        configuration of the link frames ``F``."""
        T = F[:, self.index[link]]
        cap = self.caps[link]
        R, p = T[:, :3, :3], T[:, :3, 3]
        return R @ cap.p0 + p, R @ cap.p1 + p

    def bounds(self, F: NDArray[np.float64], la: str, lb: str) -> NDArray[np.float64]:
        """Lower bounds of the cloud distance of (la, lb) for every configuration."""
        a0, a1 = self.segments(F, la)
        b0, b1 = self.segments(F, lb)
        return capsule_distances(a0, a1, b0, b1) - self.caps[la].radius - self.caps[lb].radius
