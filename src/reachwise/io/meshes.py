"""The one mesh reader of reachwise: robot link meshes, obstacle meshes, mesh clouds.

:func:`load_mesh` reads a triangle mesh file with trimesh (STL, OBJ, PLY, OFF, glTF/GLB,
and COLLADA ``.dae`` through pycollada), checks it and returns a fresh
``trimesh.Trimesh`` in metres. Every failure is a :class:`~reachwise.errors.CloudError`
whose ``reason`` says what is wrong; callers that know more (the robot file, the link,
the URI) re-raise it with their own ``source`` and ``field`` and the same reason:

- no such file, not a regular file, an unknown suffix;
- a binary STL shorter than its triangle count says (truncated);
- a file trimesh cannot parse (garbage, a broken COLLADA document);
- no triangles (an empty, point-only or truncated file), non-finite vertices, zero
  surface area;
- a bad ``scale`` (one or three finite, non-zero factors; a negative factor mirrors
  the mesh and its faces are flipped so they keep facing outward).

A file with several bodies (a COLLADA scene, an OBJ with several objects) is returned
as their union, each body placed by the file's own scene graph. The vertex and face
arrays of the last files read are kept (keyed by path, size and modification time), so
a robot whose links share a mesh, or a test suite that loads the same arm again, reads
each file once.
"""

from __future__ import annotations

import math
import os
import struct
from collections import OrderedDict
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import CloudError

if TYPE_CHECKING:
    import trimesh

__all__ = ["MESH_FORMATS", "load_mesh", "mesh_scale"]

#: Mesh file suffixes :func:`load_mesh` reads (through trimesh; ``.dae`` needs pycollada).
MESH_FORMATS: tuple[str, ...] = (".stl", ".obj", ".ply", ".off", ".glb", ".gltf", ".dae")

_CACHE: OrderedDict[tuple[str, int, int], tuple[NDArray[np.float64], NDArray[np.int64]]] = (
    OrderedDict()
)
_CACHE_SIZE = 64


def mesh_scale(
    scale: float | Sequence[float] | None, source: str, field: str
) -> NDArray[np.float64]:
    """``scale`` as three finite, non-zero factors (one number means all three)."""
    if scale is None:
        return np.ones(3)
    if isinstance(scale, bool):
        raise CloudError(source, field, f"must be one or three numbers, got {scale!r}")
    values = [scale] if isinstance(scale, int | float | np.floating | np.integer) else list(scale)
    if len(values) not in (1, 3):
        raise CloudError(source, field, f"must be one or three numbers, got {len(values)}")
    try:
        out = np.array([float(v) for v in values], dtype=float)
    except (TypeError, ValueError):
        raise CloudError(source, field, f"must be numbers, got {scale!r}") from None
    if not np.isfinite(out).all() or np.any(out == 0.0):
        raise CloudError(source, field, f"factors must be finite and ≠ 0, got {scale!r}")
    return np.repeat(out, 3) if len(out) == 1 else out


def _check_binary_stl(path: Path, source: str) -> None:
    """Reject a binary STL whose size disagrees with its triangle count (truncated)."""
    size = path.stat().st_size
    with open(path, "rb") as fh:
        head = fh.read(84)
    if head[:5].lower() == b"solid" and b"\0" not in head:
        return  # ASCII STL
    if len(head) < 84:
        raise CloudError(source, "file", f"{size} bytes is too short for an STL file")
    (count,) = struct.unpack("<I", head[80:84])
    expected = 84 + 50 * count
    if size < expected:
        raise CloudError(
            source,
            "file",
            f"binary STL header declares {count} triangles ({expected} bytes), "
            f"the file has {size} bytes: truncated",
        )


def _read(p: Path, source: str) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    import trimesh

    suffix = p.suffix.lower()
    try:
        if suffix == ".stl":
            _check_binary_stl(p, source)
        loaded = trimesh.load(str(p), force="mesh", process=False)
    except CloudError:
        raise
    except OSError as exc:
        raise CloudError(source, "file", f"cannot read: {exc.strerror or exc}") from None
    except ImportError as exc:  # pragma: no cover - pycollada is a dependency
        raise CloudError(source, "file", f"reading {suffix} files needs {exc.name}") from None
    except Exception as exc:  # trimesh and its readers raise many kinds
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise CloudError(source, "file", f"not a readable mesh: {first}") from None
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise CloudError(
            source,
            "faces",
            "no triangles could be read (an empty, truncated, broken or point-only file)",
        )
    v = np.array(loaded.vertices, dtype=np.float64)
    f = np.array(loaded.faces, dtype=np.int64)
    if f.ndim != 2 or f.shape[1] != 3 or f.min() < 0 or f.max() >= len(v):
        raise CloudError(source, "faces", "faces refer to vertices the file does not have")
    bad = int((~np.isfinite(v).all(axis=1)).sum())
    if bad:
        raise CloudError(source, "vertices", f"{bad} of {len(v)} vertices are not finite")
    v.setflags(write=False)
    f.setflags(write=False)
    return v, f


def load_mesh(
    path: str | os.PathLike[str],
    *,
    scale: float | Sequence[float] | None = None,
    source: str | None = None,
) -> trimesh.Trimesh:
    """The triangle mesh in file ``path`` (vertices times ``scale``), checked (see the
    module docstring); a new ``trimesh.Trimesh`` the caller may transform. ``source``
    names the file in errors (default: the path)."""
    import trimesh

    src = str(path) if source is None else source
    p = Path(path)
    if not p.exists():
        raise CloudError(src, "file", "no such file")
    if not p.is_file():
        raise CloudError(src, "file", "not a regular file")
    if p.suffix.lower() not in MESH_FORMATS:
        raise CloudError(
            src,
            "format",
            f"unknown mesh suffix {p.suffix or '(none)'!r}; use one of {', '.join(MESH_FORMATS)}",
        )
    factors = mesh_scale(scale, src, "scale")
    st = p.stat()
    key = (os.path.realpath(p), st.st_size, st.st_mtime_ns)
    hit = _CACHE.get(key)
    if hit is None:
        hit = _read(p, src)
        _CACHE[key] = hit
        while len(_CACHE) > _CACHE_SIZE:
            _CACHE.popitem(last=False)
    else:
        _CACHE.move_to_end(key)
    v, f = hit
    vertices = v * factors
    faces = f[:, ::-1] if math.prod(factors) < 0 else f
    mesh = trimesh.Trimesh(vertices=vertices, faces=np.array(faces), process=False)
    mesh.merge_vertices()
    if not mesh.area > 0.0:
        raise CloudError(src, "faces", "the mesh has zero surface area")
    return mesh
