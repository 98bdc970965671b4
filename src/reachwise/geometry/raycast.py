"""The ray-cast backend of the scanner models: the first hit of each ray on a set of
triangle meshes.

Ray casting uses trimesh: Embree when it is installed, the pure-Python
``ray_triangle`` backend (numpy + rtree) otherwise (or on request). Either backend only
picks the triangle; the hit distance is then recomputed in float64 from that
triangle's plane, so both give the same points to rounding.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Literal, get_args

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.errors import InputError, MissingDependency, UnknownName

if TYPE_CHECKING:
    from typing import TypeAlias

    import trimesh

    #: A mesh: a ``trimesh.Trimesh`` or a ``(vertices (V, 3), faces (F, 3))`` pair.
    MeshLike: TypeAlias = trimesh.Trimesh | tuple[ArrayLike, ArrayLike]

__all__ = ["Engine", "cast_rays", "first_hits"]

#: trimesh's ray backend: ``"embree"``, ``"triangle"``, or ``"auto"`` (Embree if installed).
Engine = Literal["auto", "embree", "triangle"]

_SRC = "scanner"


def _as_meshes(meshes: object) -> list[tuple[NDArray[np.float64], NDArray[np.int64]]]:
    """Validated ``(vertices, faces)`` of each mesh: Trimesh objects or array pairs."""
    import trimesh

    single = isinstance(meshes, trimesh.Trimesh) or (
        isinstance(meshes, tuple)
        and len(meshes) == 2
        and not isinstance(meshes[0], trimesh.Trimesh)
        and np.ndim(meshes[0]) == 2
    )
    items = [meshes] if single else meshes
    if not isinstance(items, Sequence) or isinstance(items, str) or len(items) == 0:
        raise InputError(
            _SRC, "meshes", "expected a trimesh.Trimesh, a (vertices, faces) pair, or a list"
        )
    out = []
    for i, m in enumerate(items):
        where = f"meshes[{i}]"
        if isinstance(m, trimesh.Trimesh):
            v_in, f_in = m.vertices, m.faces
        elif isinstance(m, tuple | list) and len(m) == 2:
            v_in, f_in = m
        else:
            raise InputError(
                _SRC, where, f"expected a Trimesh or (vertices, faces), got {type(m).__name__}"
            )
        try:
            v = np.asarray(v_in, dtype=np.float64)
            f = np.asarray(f_in)
        except (TypeError, ValueError) as exc:
            raise InputError(_SRC, where, f"not numeric: {exc}") from None
        if v.ndim != 2 or v.shape[1] != 3 or not np.isfinite(v).all():
            raise InputError(_SRC, where, f"vertices must be finite (V, 3), got {v.shape}")
        if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0 or not np.issubdtype(f.dtype, np.integer):
            raise InputError(_SRC, where, f"faces must be integer (F, 3), F >= 1, got {f.shape}")
        if f.min() < 0 or f.max() >= len(v):
            raise InputError(_SRC, where, f"face indices must lie in [0, {len(v) - 1}]")
        out.append((v, f.astype(np.int64)))
    return out


def cast_rays(
    meshes: MeshLike | Sequence[MeshLike],
    origins: ArrayLike,
    directions: ArrayLike,
    *,
    engine: Engine = "auto",
) -> tuple[NDArray[np.bool_], NDArray[np.float64]]:
    """First hit of each ray: ``(hit, distance)``, distance along the unit direction.

    ``engine`` picks trimesh's ray backend: ``"embree"`` (needs ``embreex``),
    ``"triangle"`` (pure numpy + rtree) or ``"auto"`` (Embree if installed). The backend
    only names the first triangle hit; the distance is recomputed in float64 from that
    triangle's plane. Rays that miss have ``hit`` False and distance ``inf``.
    """
    hit, dist, _ = first_hits(meshes, origins, directions, engine=engine)
    return hit, dist


def first_hits(
    meshes: MeshLike | Sequence[MeshLike],
    origins: ArrayLike,
    directions: ArrayLike,
    *,
    engine: Engine = "auto",
) -> tuple[NDArray[np.bool_], NDArray[np.float64], NDArray[np.int64]]:
    """:func:`cast_rays`, and which mesh each ray hit first: ``(hit, distance, mesh)``
    with ``mesh`` the index into ``meshes`` (``-1`` for a miss)."""
    import trimesh
    from trimesh.ray import ray_triangle

    parts = _as_meshes(meshes)
    offsets = np.cumsum([0] + [len(v) for v, _ in parts[:-1]])
    mesh = trimesh.Trimesh(
        vertices=np.concatenate([v for v, _ in parts]),
        faces=np.concatenate([f + off for (_, f), off in zip(parts, offsets, strict=True)]),
        process=False,
    )
    o = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
    d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    if o.shape != d.shape:
        raise InputError(_SRC, "origins", f"shape {o.shape} differs from directions {d.shape}")
    norm = np.linalg.norm(d, axis=1)
    if not (np.isfinite(o).all() and np.isfinite(d).all() and (norm > 0).all()):
        raise InputError(_SRC, "directions", "rays need finite origins and non-zero directions")
    d = d / norm[:, None]
    if engine == "auto":
        engine = "embree" if trimesh.ray.has_embree else "triangle"
    if engine == "embree":
        if not trimesh.ray.has_embree:
            raise MissingDependency("embreex", "", "the Embree ray backend of the scanner")
        from trimesh.ray import ray_pyembree

        intersector: object = ray_pyembree.RayMeshIntersector(mesh)
    elif engine == "triangle":
        intersector = ray_triangle.RayMeshIntersector(mesh)
    else:
        raise UnknownName(_SRC, "ray engine", str(engine), get_args(Engine))
    try:
        tri = np.asarray(intersector.intersects_first(o, d), dtype=np.int64)  # type: ignore[attr-defined]
    except ImportError:  # ray_triangle needs rtree, which trimesh does not require
        raise MissingDependency("rtree", "", f"trimesh's {engine!r} ray backend") from None
    dist = np.full(len(o), np.inf)
    hit = tri >= 0
    face_ends = np.cumsum([len(f) for _, f in parts])
    which = np.where(hit, np.searchsorted(face_ends, tri, side="right"), -1)
    if hit.any():
        v = np.asarray(mesh.vertices)[np.asarray(mesh.faces)[tri[hit]]]
        n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
        denom = np.einsum("ij,ij->i", n, d[hit])
        num = np.einsum("ij,ij->i", n, v[:, 0] - o[hit])
        with np.errstate(divide="ignore", invalid="ignore"):
            t = num / denom
        good = np.isfinite(t) & (t > 0)
        idx = np.flatnonzero(hit)
        dist[idx[good]] = t[good]
        hit[idx[~good]] = False
        which[idx[~good]] = -1
    return hit, dist, which.astype(np.int64)
