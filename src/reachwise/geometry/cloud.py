"""The point cloud: an immutable (N, 3) float64 array of points with a frame name.

Points are expressed in the cloud's own frame (``frame``): a link cloud in its link
frame, a scan in ``world``. Queries place the cloud with a 4x4 pose. A cloud is
validated once, at construction: no NaN/inf, at least one point, shape (N, 3).

The operations below are pure math (numpy in, numpy out; file formats live in
:mod:`reachwise.io.clouds`). They prepare the clouds of the thesis's collision server
(thesis §3.1, P-III §2, P-V §II and §IV):

- :func:`sample_mesh_surface` turns a CAD part into a cloud of surface points; the
  thesis restricts each manipulator part to 1000 points (P-III §5, P-V §V).
- :func:`crop` removes the points outside the working area and :func:`voxel_downsample`
  thins a scan so that "there were only points within 3 cm of each other" (P-V §IV).
- :func:`merge` combines clouds expressed in one frame (several scans, several parts).

Every bad input raises :class:`reachwise.errors.CloudError` naming the source, the field
and the reason.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.errors import CloudError

if TYPE_CHECKING:
    import trimesh

__all__ = [
    "DEFAULT_MESH_POINTS",
    "DEFAULT_VOXEL",
    "PointCloud",
    "crop",
    "crop_mask",
    "merge",
    "sample_mesh_surface",
    "voxel_downsample",
    "voxel_keys",
]

#: Voxel edge of the P-V scan downsampling, metres ("points within 3 cm", P-V §IV).
DEFAULT_VOXEL = 0.03
#: Points per CAD part in the thesis (P-III, P-V: "restricted to 1000").
DEFAULT_MESH_POINTS = 1000
#: Most points sampled on one mesh or shape (a bound against a count that would only
#: exhaust memory; the thesis samples 1000 per part).
MAX_SAMPLED_POINTS = 5_000_000


@dataclass(frozen=True, eq=False)
class PointCloud:
    """An immutable set of 3-D points in metres, expressed in frame ``frame``.

    The cloud holds its (read-only) points, frame, name and ``resolution``, nothing
    else: the spatial index the distance queries need is kept by the distance layer,
    keyed by the cloud (``reachwise.distance.index``), so repeated queries do not
    rebuild it. ``resolution`` (m) is what the cloud guarantees about the surface it
    samples: every point of that surface lies within ``resolution`` of a cloud point
    (a robot's link clouds, ``reachwise.io.robot_clouds.covering_points``), so a
    distance measured to the cloud overstates the one to the surface by at most that
    much; 0 when nothing is guaranteed (a scan, a random sample).
    """

    points: NDArray[np.float64]
    frame: str = "world"
    name: str = ""
    resolution: float = 0.0

    def __post_init__(self) -> None:
        source = self.name or "point cloud"
        try:
            pts = np.array(self.points, dtype=np.float64, copy=True)
        except (TypeError, ValueError) as exc:
            raise CloudError(source, "points", f"not numeric: {exc}") from None
        if pts.ndim == 1 and pts.shape[0] == 3:
            pts = pts.reshape(1, 3)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise CloudError(source, "points", f"expected shape (N, 3), got {pts.shape}")
        if pts.shape[0] == 0:
            raise CloudError(source, "points", "the cloud is empty")
        bad = ~np.isfinite(pts).all(axis=1)
        if bad.any():
            raise CloudError(
                source,
                "points",
                f"{int(bad.sum())} of {pts.shape[0]} points are not finite (NaN or inf)",
            )
        pts.setflags(write=False)
        object.__setattr__(self, "points", pts)
        r = self.resolution
        if isinstance(r, bool) or not isinstance(r, numbers.Real) or not 0.0 <= r < math.inf:
            raise CloudError(source, "resolution", f"must be finite and >= 0, got {r!r}")

    @classmethod
    def of(cls, data: PointCloud | ArrayLike, name: str = "") -> PointCloud:
        """Return ``data`` if it is a PointCloud, else wrap the (N, 3) array."""
        if isinstance(data, PointCloud):
            return data
        return cls(np.asarray(data), name=name)

    @classmethod
    def of_checked(
        cls, points: NDArray[np.float64], *, frame: str = "world", name: str = ""
    ) -> PointCloud:
        """A cloud that takes ``points`` as they are, without a copy or a check of the
        values: for a caller that has just made them — a C-ordered float64 (N, 3) array,
        N ≥ 1, every coordinate finite — in a pass of its own (the distance layer's
        ingestion copies and checks a camera frame in one compiled pass). The array is
        made read-only; nobody may keep a writable view of it. Anything else: use the
        constructor, which copies and checks."""
        if not (
            isinstance(points, np.ndarray)
            and points.dtype == np.float64
            and points.ndim == 2
            and points.shape[1] == 3
            and points.shape[0] >= 1
            and points.flags.c_contiguous
        ):
            raise CloudError(name or "point cloud", "points", "of_checked needs float64 (N, 3)")
        cloud = object.__new__(cls)
        points.setflags(write=False)
        object.__setattr__(cloud, "points", points)
        object.__setattr__(cloud, "frame", frame)
        object.__setattr__(cloud, "name", name)
        return cloud

    def __len__(self) -> int:
        return int(self.points.shape[0])

    @property
    def bounds(self) -> NDArray[np.float64]:
        """Axis-aligned bounds in the cloud frame, shape (2, 3): min row, max row."""
        return np.stack([self.points.min(axis=0), self.points.max(axis=0)])

    def transformed(self, pose: ArrayLike, frame: str | None = None) -> PointCloud:
        """The cloud's points mapped by the 4x4 ``pose`` into ``frame``."""
        T = np.asarray(pose, dtype=np.float64)
        pts = self.points @ T[:3, :3].T + T[:3, 3]
        return PointCloud(pts, frame=frame or self.frame, name=self.name)


# --------------------------------------------------------------------------- helpers


def _source(cloud: PointCloud) -> str:
    return cloud.name or "point cloud"


def _positive_length(value: object, source: str, field_name: str) -> float:
    """``value`` as a finite float > 0, else a CloudError naming ``field_name``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise CloudError(source, field_name, f"expected a number in metres, got {value!r}")
    out = float(value)
    if not np.isfinite(out) or out <= 0.0:
        raise CloudError(source, field_name, f"must be a finite length > 0 m, got {out!r}")
    return out


def _point3(value: ArrayLike, source: str, field_name: str) -> NDArray[np.float64]:
    """``value`` as a finite float64 vector of 3 coordinates, else a CloudError."""
    try:
        out = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise CloudError(source, field_name, f"not numeric: {exc}") from None
    if out.shape != (3,):
        raise CloudError(source, field_name, f"expected 3 coordinates (x, y, z), got {out.shape}")
    if not np.isfinite(out).all():
        raise CloudError(source, field_name, f"coordinates must be finite, got {out.tolist()}")
    return out


def _count(
    value: object, source: str, field_name: str, max_points: int = MAX_SAMPLED_POINTS
) -> int:
    """``value`` as an int from 1 to ``max_points``, else a CloudError."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise CloudError(source, field_name, f"expected a whole number >= 1, got {value!r}")
    out = int(value)
    if out < 1:
        raise CloudError(source, field_name, f"must be >= 1, got {out}")
    if out > max_points:
        raise CloudError(source, field_name, f"at most {max_points} points, got {out}")
    return out


# ----------------------------------------------------------------------- operations


def voxel_keys(
    points: PointCloud | ArrayLike, voxel: float = DEFAULT_VOXEL, origin: ArrayLike | None = None
) -> NDArray[np.int64]:
    """Integer voxel index of every point: ``floor((p - origin) / voxel)``, shape (N, 3).

    The grid is anchored at ``origin`` (default: the origin of the cloud's frame):
    voxel ``(i, j, k)`` is the half-open box ``origin + voxel * ([i, i+1) x [j, j+1) x
    [k, k+1))``. Anchor it away from flat surfaces that lie exactly on a grid plane
    (a floor at z = 0 with the default origin), or rounding splits them into two layers.
    """
    cloud = PointCloud.of(points)
    size = _positive_length(voxel, _source(cloud), "voxel")
    anchor = np.zeros(3) if origin is None else _point3(origin, _source(cloud), "voxel origin")
    with np.errstate(over="ignore"):
        scaled = np.floor((cloud.points - anchor) / size)
    if not np.abs(scaled).max() < 2.0**62:
        raise CloudError(
            _source(cloud), "voxel", f"a {size!r} m voxel is too small for coordinates this large"
        )
    return scaled.astype(np.int64)


def voxel_downsample(
    cloud: PointCloud | ArrayLike, voxel: float = DEFAULT_VOXEL, origin: ArrayLike | None = None
) -> PointCloud:
    """Keep one point per occupied voxel of edge ``voxel`` metres (default 3 cm, P-V §IV).

    Of the input points in a voxel, the one nearest to their centroid is kept; a tie
    goes to the lexicographically smallest ``(x, y, z)``. We keep a measured point
    rather than the centroid itself (MATLAB's ``pcdownsample(..., 'gridAverage', ...)``,
    which P-V used, keeps the centroid) because the centroid of a curved or cornered
    surface patch lies off the surface, and the collision distance is measured to
    surface points. So the output is a subset of the input with exactly one point per
    occupied voxel.

    The grid is anchored at ``origin``, by default the frame origin (see
    :func:`voxel_keys`); MATLAB anchors it at the cloud's minimum corner, which moves
    whenever a point is added, so we take a fixed anchor instead. The output is
    ordered by voxel index (lexicographic ``(i, j, k)``). Centroids are summed in a
    canonical point order, so the result depends only on the set of input points and
    ``voxel``, not on their order. Frame and name are kept.
    """
    cloud = PointCloud.of(cloud)
    keys = voxel_keys(cloud, voxel, origin)
    _, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.reshape(-1)
    # Canonical order: by voxel, then by coordinates (ties and float sums order-free).
    canon = np.lexsort((cloud.points[:, 2], cloud.points[:, 1], cloud.points[:, 0], inverse))
    pts = cloud.points[canon]
    inv = inverse[canon]
    centroid = np.stack([np.bincount(inv, weights=pts[:, j]) / counts for j in range(3)], axis=1)
    diff = pts - centroid[inv]
    d2 = np.einsum("ij,ij->i", diff, diff)
    order = np.lexsort((np.arange(len(pts)), d2, inv))
    grouped = inv[order]
    first = np.ones(len(order), dtype=bool)
    first[1:] = grouped[1:] != grouped[:-1]
    return PointCloud(pts[order[first]], frame=cloud.frame, name=cloud.name)


def crop_mask(cloud: PointCloud | ArrayLike, lo: ArrayLike, hi: ArrayLike) -> NDArray[np.bool_]:
    """Boolean mask of the points inside the closed box ``lo <= p <= hi`` (cloud frame)."""
    cloud = PointCloud.of(cloud)
    source = _source(cloud)
    low = _point3(lo, source, "crop min")
    high = _point3(hi, source, "crop max")
    if (low > high).any():
        raise CloudError(
            source, "crop box", f"min {low.tolist()} exceeds max {high.tolist()} on some axis"
        )
    inside = (cloud.points >= low) & (cloud.points <= high)
    return np.asarray(inside.all(axis=1), dtype=np.bool_)


def crop(cloud: PointCloud | ArrayLike, lo: ArrayLike, hi: ArrayLike) -> PointCloud:
    """The points inside the axis-aligned box ``lo <= p <= hi`` (bounds included).

    This is P-V §IV's "points located outside the working area were removed". The box
    is given in the cloud's own frame, in metres. An empty result is an error (a cloud
    has at least one point), naming the box and the cloud's bounds.
    """
    cloud = PointCloud.of(cloud)
    mask = crop_mask(cloud, lo, hi)
    if not mask.any():
        b = cloud.bounds
        raise CloudError(
            _source(cloud),
            "crop box",
            f"no point of {len(cloud)} lies in [{np.asarray(lo, float).tolist()}, "
            f"{np.asarray(hi, float).tolist()}]; the cloud spans "
            f"[{b[0].tolist()}, {b[1].tolist()}]",
        )
    return PointCloud(cloud.points[mask], frame=cloud.frame, name=cloud.name)


def merge(
    clouds: Sequence[PointCloud | ArrayLike], *, frame: str | None = None, name: str = ""
) -> PointCloud:
    """Concatenate clouds, in order, into one cloud.

    All PointCloud inputs must share one frame (points in different frames cannot be
    stacked without poses: transform them first with :meth:`PointCloud.transformed`).
    ``frame`` sets the result's frame and must then equal the inputs' frames; plain
    arrays take the common frame (``"world"`` if there is none).
    """
    if isinstance(clouds, PointCloud) or len(clouds) == 0:
        raise CloudError(name or "merge", "clouds", "expected a non-empty sequence of clouds")
    parts = [PointCloud.of(c, name=f"{name or 'merge'}[{i}]") for i, c in enumerate(clouds)]
    frames = {c.frame for c, raw in zip(parts, clouds, strict=True) if isinstance(raw, PointCloud)}
    if frame is not None:
        frames.add(frame)
    if len(frames) > 1:
        raise CloudError(
            name or "merge",
            "frame",
            f"clouds are in different frames {sorted(frames)}; transform them into one first",
        )
    out_frame = frames.pop() if frames else "world"
    return PointCloud(np.concatenate([c.points for c in parts]), frame=out_frame, name=name)


def sample_mesh_surface(
    mesh: trimesh.Trimesh | ArrayLike,
    faces: ArrayLike | None = None,
    n: int = DEFAULT_MESH_POINTS,
    seed: int | np.random.Generator = 0,
    *,
    frame: str = "world",
    name: str = "",
    max_points: int = MAX_SAMPLED_POINTS,
) -> PointCloud:
    """``n`` points drawn uniformly over a triangle mesh's surface (area-weighted).

    ``mesh`` is a ``trimesh.Trimesh``, or the (V, 3) vertex array with ``faces`` the
    (F, 3) vertex indices. Each point picks a triangle with probability proportional to
    its area, then a uniform point inside it (``trimesh.sample.sample_surface``). This
    is how the thesis turns CAD parts into 1000-point clouds (P-III §5, P-V §V). The same
    ``seed`` (an int or a ``numpy.random.Generator``) gives the same points.

    Points are in the mesh's coordinates; ``frame`` names that frame (a link frame, say).
    ``n`` above ``max_points`` (default :data:`MAX_SAMPLED_POINTS`) is refused.
    """
    import trimesh

    source = name or "mesh"
    count = _count(n, source, "n", max_points)
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral | np.random.Generator):
        raise CloudError(source, "seed", f"expected an int or numpy Generator, got {seed!r}")
    if isinstance(mesh, trimesh.Trimesh):
        if faces is not None:
            raise CloudError(source, "faces", "give faces only with a vertex array, not a mesh")
        vertices_in: ArrayLike = mesh.vertices
        faces_in: ArrayLike = mesh.faces
    else:
        if faces is None:
            raise CloudError(source, "faces", "required with a vertex array")
        vertices_in, faces_in = mesh, faces
    try:
        vertices = np.asarray(vertices_in, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise CloudError(source, "vertices", f"not numeric: {exc}") from None
    if vertices.ndim != 2 or vertices.shape[1] != 3 or len(vertices) == 0:
        raise CloudError(source, "vertices", f"expected shape (V, 3), V >= 1, got {vertices.shape}")
    bad = int((~np.isfinite(vertices).all(axis=1)).sum())
    if bad:
        raise CloudError(
            source, "vertices", f"{bad} of {len(vertices)} vertices are not finite (NaN or inf)"
        )
    tri = np.asarray(faces_in)
    if tri.ndim != 2 or tri.shape[1] != 3 or len(tri) == 0:
        raise CloudError(source, "faces", f"expected shape (F, 3), F >= 1, got {tri.shape}")
    if not np.issubdtype(tri.dtype, np.integer):
        raise CloudError(source, "faces", f"expected integer vertex indices, got {tri.dtype}")
    if tri.min() < 0 or tri.max() >= len(vertices):
        raise CloudError(
            source,
            "faces",
            f"vertex indices must lie in [0, {len(vertices) - 1}], "
            f"got [{int(tri.min())}, {int(tri.max())}]",
        )
    area = 0.5 * np.linalg.norm(
        np.cross(
            vertices[tri[:, 1]] - vertices[tri[:, 0]], vertices[tri[:, 2]] - vertices[tri[:, 0]]
        ),
        axis=1,
    )
    if not area.sum() > 0.0:
        raise CloudError(source, "faces", "the mesh has zero surface area")
    tm = trimesh.Trimesh(vertices=vertices, faces=tri.astype(np.int64), process=False)
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(int(seed))
    points, _ = trimesh.sample.sample_surface(tm, count, face_weight=area, seed=rng)
    return PointCloud(np.asarray(points, dtype=np.float64), frame=frame, name=name)
