"""Occlusion-aware clouds (beyond P-V; P-V Fig. 5: the missing points behind the
obstacle made the return path wrong).

A beam that hits a surface observes the free space in front of the hit, nothing behind
it: everything farther along the beam is unknown. :func:`shadow_points` fills that
unknown space with *virtual* points: each return ``h = o + r d`` is extended along its
own beam to ``o + (r + s) d`` for ``s = spacing, 2 spacing, … ≤ depth``, stopping at
the ground (nothing enters the ground) — so the occluded space up to ``depth`` behind
every observed surface counts as occupied. ``depth`` is the thickness the caller is
willing to assume for unseen objects (a longer depth is more conservative). The
virtual points never lie in front of any surface a beam observed: each lies on its own
beam, behind its own hit. :class:`OcclusionFill` holds the settings;
:func:`~reachwise.geometry.scan_scene.scan_scene` and
:meth:`~reachwise.geometry.scan_scene.ScanScene.process` take one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.errors import InputError
from reachwise.geometry.checks import finite_number
from reachwise.geometry.cloud import DEFAULT_VOXEL

__all__ = ["OcclusionFill", "shadow_points"]

_SRC = "scanner"


def shadow_points(
    origin: ArrayLike,
    hits: ArrayLike,
    depth: float,
    spacing: float = DEFAULT_VOXEL,
    ground: float | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Virtual points in the occluded space behind each hit, seen from ``origin``.

    Each hit ``h`` (range ``r = |h − o| > 0``, beam direction ``d = (h − o)/r``) gets
    the points ``h + s d`` for ``s = spacing, 2 spacing, …`` up to ``depth``: the beam
    observed the space in front of ``h`` to be free and nothing behind it, so the
    unknown space up to ``depth`` behind the surface is taken as occupied. With
    ``ground`` (world z, m), a point below it is dropped, and so is the rest of its
    beam (the ground is solid; nothing needs to be avoided under it); ``-inf`` or
    ``None`` keeps them all. Hits at the origin (no direction) give no point.

    Returns ``(points (V, 3), ray (V,))``: ``ray[k]`` is the index of the hit that
    point ``k`` extends. Every point lies on its hit's beam, farther than the hit.
    """
    o = np.asarray(origin, dtype=np.float64).reshape(-1)
    h = np.asarray(hits, dtype=np.float64)
    if o.shape != (3,) or not np.isfinite(o).all():
        raise InputError(_SRC, "origin", "expected 3 finite coordinates")
    if h.ndim != 2 or h.shape[1] != 3 or not np.isfinite(h).all():
        raise InputError(_SRC, "hits", f"expected finite (N, 3) points, got shape {h.shape}")
    D = finite_number(depth, _SRC, "depth", positive=True)
    step = finite_number(spacing, _SRC, "spacing", positive=True)
    if D / step > 10_000:
        raise InputError(_SRC, "spacing", f"depth/spacing = {D / step:.0f} samples per beam")
    v = h - o
    r = np.linalg.norm(v, axis=1)
    ok = r > 0.0
    d = np.zeros_like(v)
    d[ok] = v[ok] / r[ok, None]
    s_max = np.where(ok, D, 0.0)
    if ground is not None and ground != -math.inf:
        g = finite_number(ground, _SRC, "ground")
        down = d[:, 2] < 0.0
        with np.errstate(divide="ignore", invalid="ignore"):
            to_ground = np.where(down, (h[:, 2] - g) / -d[:, 2], np.inf)
        s_max = np.where(h[:, 2] >= g, np.minimum(s_max, to_ground), 0.0)
    count = np.floor(s_max / step + 1e-9).astype(np.int64)
    count = np.maximum(count, 0)
    ray = np.repeat(np.arange(len(h), dtype=np.int64), count)
    if ray.size == 0:
        return np.zeros((0, 3)), ray
    first = np.cumsum(count) - count
    k = np.arange(ray.size, dtype=np.int64) - np.repeat(first, count) + 1
    pts = h[ray] + (k * step)[:, None] * d[ray]
    return pts, ray


@dataclass(frozen=True)
class OcclusionFill:
    """Settings of the occlusion fill (:func:`shadow_points`): ``depth`` (m) behind
    each return; ``spacing`` (m) between virtual points along a beam (``None``: the
    scene's voxel, so the fill is as dense as the cloud); ``ground`` (world z, m)
    below which no virtual point is kept (``None``: the scene's ground, if any)."""

    depth: float = 1.0
    spacing: float | None = None
    ground: float | None = None

    def __post_init__(self) -> None:
        finite_number(self.depth, _SRC, "occlusion depth", positive=True)
        if self.spacing is not None:
            finite_number(self.spacing, _SRC, "occlusion spacing", positive=True)
        if self.ground is not None and self.ground != -math.inf:
            finite_number(self.ground, _SRC, "occlusion ground")
