"""Point-cloud files: PLY, PCD, XYZ/CSV/TXT and NPY; meshes sampled into clouds.

The formats are read and written by the libraries built for them (plyfile, pypcd4,
numpy, trimesh) and their output is checked here: every failure — a missing or
unreadable file, a truncated or corrupt body, missing ``x``/``y``/``z`` fields, a
wrong shape, non-finite coordinates, an empty cloud — is a
:class:`reachwise.errors.CloudError` that names the file, the field and the reason.

Precision of each format (what a save/load round trip gives back):

=========  ===================================================================
``.ply``   ``double`` x/y/z properties, binary little-endian (default) or ASCII;
           exact for float64 either way (plyfile writes ASCII with 17+ digits).
           Reading accepts any numeric x/y/z property type (float32 is widened
           exactly).
``.pcd``   ``F 8`` (float64) x/y/z fields, ``binary`` (default) or ``ascii``;
           binary is exact, ASCII is rounded to 10 decimals (pypcd4 writes
           ``%.10f``: at most 5e-11 m off). Reading also accepts
           ``binary_compressed`` and float32 fields. The header's ``VIEWPOINT`` is
           not applied (as in PCL, points are returned as stored).
``.xyz``   whitespace-separated ``x y z`` rows, ``%.17g``: exact.
``.txt``   same as ``.xyz``. Reading detects the delimiter (comma, semicolon or
``.csv``   whitespace), ``#`` comments and an optional header row naming the
           ``x``, ``y``, ``z`` columns (other columns are ignored); without a
           header the first three columns are x, y, z. ``.csv`` is written with
           an ``x,y,z`` header, comma-separated, ``%.17g``: exact.
``.npy``   a float64 (N, 3) array (or a structured array with x, y, z fields on
           reading): exact.
=========  ===================================================================

Text formats (ASCII PLY/PCD, XYZ/CSV/TXT) cut in the middle of the last number cannot
be told from a shorter number; binary files are checked against their headers.
"""

from __future__ import annotations

import os
import struct
from pathlib import Path
from typing import IO, Any, BinaryIO, cast

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import CloudError
from reachwise.geometry.cloud import (
    DEFAULT_MESH_POINTS,
    MAX_SAMPLED_POINTS,
    PointCloud,
    sample_mesh_surface,
)
from reachwise.io.atomic import atomic_open
from reachwise.io.cloud_headers import (
    MAX_CLOUD_POINTS,
    check_npy,
    check_pcd,
    check_ply,
    check_text_size,
)
from reachwise.io.meshes import MESH_FORMATS, load_mesh
from reachwise.io.text_input import decode_text

__all__ = [
    "CLOUD_FORMATS",
    "MAX_CLOUD_POINTS",
    "MESH_FORMATS",
    "cloud_format",
    "load_cloud",
    "load_mesh_cloud",
    "save_cloud",
]

#: Cloud file suffixes and the format each one means.
CLOUD_FORMATS: dict[str, str] = {
    ".ply": "ply",
    ".pcd": "pcd",
    ".xyz": "xyz",
    ".txt": "xyz",
    ".csv": "csv",
    ".npy": "npy",
}

_XYZ = ("x", "y", "z")


def cloud_format(path: str | os.PathLike[str], fmt: str | None = None) -> str:
    """The format name (``ply``, ``pcd``, ``xyz``, ``csv``, ``npy``) of ``path``.

    ``fmt`` overrides the suffix; it may be a format name or a suffix (``".txt"``).
    """
    p = Path(path)
    key = (fmt if fmt is not None else p.suffix).lower()
    if key in CLOUD_FORMATS.values():
        return key
    if not key.startswith("."):
        key = "." + key
    if key not in CLOUD_FORMATS:
        known = ", ".join(sorted(CLOUD_FORMATS))
        got = repr(fmt) if fmt is not None else f"suffix {p.suffix or '(none)'!r}"
        raise CloudError(str(path), "format", f"unknown cloud format {got}; use one of {known}")
    return CLOUD_FORMATS[key]


# ----------------------------------------------------------------------------- load


def load_cloud(
    path: str | os.PathLike[str],
    *,
    fmt: str | None = None,
    frame: str = "world",
    name: str | None = None,
    drop_non_finite: bool = False,
    max_points: int = MAX_CLOUD_POINTS,
) -> PointCloud:
    """Read a point cloud file into a :class:`PointCloud` (float64, metres).

    The format comes from the suffix (see :data:`CLOUD_FORMATS`) or ``fmt``. Rows with
    NaN or infinite coordinates are an error that states their count and the first
    row, unless ``drop_non_finite`` is set: then they are removed (organized scans mark
    "no return" with NaN), and a file of nothing but such rows is still an error. The
    cloud's ``name`` defaults to the path as given. A file declaring or holding more
    than ``max_points`` points is refused before it is read: binary headers are checked
    against the file's size, and an XYZ or CSV file larger than ``max_points`` rows of
    :data:`~reachwise.io.cloud_headers.TEXT_ROW_BYTES` bytes is refused unread
    (:mod:`reachwise.io.cloud_headers`).
    """
    source = str(path)
    kind = cloud_format(path, fmt)
    p = Path(path)
    if not p.exists():
        raise CloudError(source, "file", "no such file")
    if not p.is_file():
        raise CloudError(source, "file", "not a regular file")
    try:
        if kind == "ply":
            check_ply(p, source, max_points)
            pts = _read_ply(p, source)
        elif kind == "pcd":
            check_pcd(p, source, max_points)
            pts = _read_pcd(p, source)
        elif kind == "npy":
            check_npy(p, source, max_points)
            pts = _read_npy(p, source)
        else:
            check_text_size(p, source, max_points)
            pts = _read_text(p, source, max_points)
    except OSError as exc:
        raise CloudError(source, "file", f"cannot read: {exc.strerror or exc}") from None
    return _to_cloud(pts, source, frame, source if name is None else name, drop_non_finite)


def _to_cloud(
    pts: NDArray[Any], source: str, frame: str, name: str, drop_non_finite: bool
) -> PointCloud:
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise CloudError(source, "points", f"expected shape (N, 3), got {pts.shape}")
    if len(pts) == 0:
        raise CloudError(source, "points", "the file holds no points")
    pts = pts.astype(np.float64, copy=False)
    bad = ~np.isfinite(pts).all(axis=1)
    if bad.any():
        if not drop_non_finite or bad.all():
            first = int(np.flatnonzero(bad)[0])
            raise CloudError(
                source,
                "points",
                f"{int(bad.sum())} of {len(pts)} points are not finite (NaN or inf); "
                f"the first is point {first} (0-based)",
            )
        pts = pts[~bad]
    return PointCloud(pts, frame=frame, name=name)


def _read_ply(path: Path, source: str) -> NDArray[Any]:
    import plyfile

    try:
        data = plyfile.PlyData.read(str(path))
    except plyfile.PlyParseError as exc:
        raise CloudError(source, "file", f"not a valid PLY file: {exc}") from None
    except (ValueError, TypeError, EOFError, struct.error, UnicodeDecodeError) as exc:
        raise CloudError(source, "file", f"not a valid PLY file: {exc}") from None
    names = [el.name for el in data.elements]
    if "vertex" not in names:
        raise CloudError(source, "vertex", f"no 'vertex' element (elements: {names})")
    vertex = data["vertex"]
    props = [prop.name for prop in vertex.properties]
    missing = [k for k in _XYZ if k not in props]
    if missing:
        raise CloudError(
            source, f"vertex.{missing[0]}", f"missing property {missing} (properties: {props})"
        )
    cols = []
    for k in _XYZ:
        col = np.asarray(vertex.data[k])
        if col.dtype.kind not in "fiu":
            raise CloudError(source, f"vertex.{k}", f"not a numeric scalar ({col.dtype})")
        cols.append(col.astype(np.float64))
    return np.column_stack(cols) if len(vertex.data) else np.empty((0, 3))


def _read_pcd(path: Path, source: str) -> NDArray[Any]:
    import pypcd4

    try:
        pcd = pypcd4.PointCloud.from_path(path)
    except Exception as exc:  # pypcd4 raises ValueError, pydantic and lzf errors alike
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise CloudError(source, "file", f"not a valid PCD file: {reason}") from None
    fields = list(pcd.fields)
    missing = [k for k in _XYZ if k not in fields]
    if missing:
        raise CloudError(source, missing[0], f"missing field {missing} (fields: {fields})")
    declared = int(pcd.metadata.points)
    got = len(pcd.pc_data)  # pcd.points echoes the header, not the data read
    if got != declared:
        raise CloudError(
            source, "POINTS", f"header declares {declared} points, the file holds {got}: truncated"
        )
    counts = dict(zip(pcd.fields, pcd.metadata.count, strict=True))
    for k in _XYZ:
        if counts[k] != 1:
            raise CloudError(source, k, f"expected COUNT 1, got {counts[k]}")
    return np.asarray(pcd.numpy(_XYZ), dtype=np.float64).reshape(-1, 3)


def _read_npy(path: Path, source: str) -> NDArray[Any]:
    try:
        arr = np.load(path, allow_pickle=False)
    except (ValueError, EOFError) as exc:
        raise CloudError(source, "file", f"not a valid NPY file: {exc}") from None
    if not isinstance(arr, np.ndarray):
        raise CloudError(source, "file", "expected a .npy array, got an archive")
    if arr.dtype.names is not None:
        missing = [k for k in _XYZ if k not in arr.dtype.names]
        if missing:
            raise CloudError(
                source, missing[0], f"missing field {missing} (fields: {list(arr.dtype.names)})"
            )
        arr = np.stack([np.asarray(arr[k]).reshape(-1) for k in _XYZ], axis=1)
    if arr.dtype.kind not in "fiu":
        raise CloudError(source, "points", f"expected real numbers, got dtype {arr.dtype}")
    return arr


def _split(line: str, delimiter: str | None) -> list[str]:
    return [t.strip().strip("'\"") for t in line.split(delimiter)]


def _is_number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def _read_text(path: Path, source: str, max_points: int) -> NDArray[Any]:
    text = decode_text(path.read_bytes(), source, CloudError)
    rows = [
        (no, line.split("#", 1)[0].strip()) for no, line in enumerate(text.splitlines(), start=1)
    ]
    rows = [(no, line) for no, line in rows if line]
    if not rows:
        raise CloudError(source, "points", "the file holds no points")
    first = rows[0][1]
    delimiter = "," if "," in first else ";" if ";" in first else None
    head = _split(first, delimiter)
    if all(_is_number(t) for t in head):
        columns = [0, 1, 2]
        ncols = len(head)
    else:
        lower = [t.lower() for t in head]
        missing = [k for k in _XYZ if k not in lower]
        if missing:
            raise CloudError(source, f"line {rows[0][0]}", f"header {head} has no column {missing}")
        columns = [lower.index(k) for k in _XYZ]
        ncols = len(head)
        rows = rows[1:]
        if not rows:
            raise CloudError(source, "points", "the file holds a header but no points")
    if len(rows) > max_points:
        raise CloudError(
            source, "points", f"{len(rows)} rows, more than the bound {max_points} points "
            "(raise it with --max-points / max_points)",
        )  # fmt: skip
    if ncols < 3:
        raise CloudError(
            source, f"line {rows[0][0]}", f"expected at least 3 columns (x, y, z), got {ncols}"
        )
    try:
        return np.loadtxt([line for _, line in rows], delimiter=delimiter, usecols=columns, ndmin=2)
    except ValueError:
        pass
    # Locate the first bad row for the message (only on the error path).
    for no, line in rows:
        tokens = _split(line, delimiter)
        if len(tokens) != ncols:
            raise CloudError(
                source, f"line {no}", f"{len(tokens)} columns, expected {ncols}"
            ) from None
        bad = [t for i, t in enumerate(tokens) if i in columns and not _is_number(t)]
        if bad:
            raise CloudError(source, f"line {no}", f"not a number: {bad[0]!r}") from None
    raise CloudError(source, "points", "could not parse the rows")  # pragma: no cover


# ----------------------------------------------------------------------------- save


def save_cloud(
    cloud: PointCloud, path: str | os.PathLike[str], *, fmt: str | None = None, ascii: bool = False
) -> Path:
    """Write ``cloud``'s points (in its own frame) to ``path``; returns the path.

    The format comes from the suffix or ``fmt``. PLY and PCD are binary unless
    ``ascii``; XYZ/TXT/CSV are text and NPY binary whatever ``ascii`` says. Coordinates
    are written as float64 (see the module docstring for each format's precision).
    The file is written to a temporary name and then renamed, so a failed write
    never leaves a truncated cloud under ``path``.
    """
    if not isinstance(cloud, PointCloud):
        raise CloudError(str(path), "cloud", f"expected a PointCloud, got {type(cloud).__name__}")
    target = Path(path)
    kind = cloud_format(target, fmt)
    source = str(path)
    if not target.parent.is_dir():
        raise CloudError(source, "file", f"directory {str(target.parent)!r} does not exist")
    pts = cloud.points
    try:
        with atomic_open(target, "wb") as fh:
            if kind == "ply":
                _write_ply(pts, fh, ascii)
            elif kind == "pcd":
                _write_pcd(pts, fh, ascii)
            elif kind == "npy":
                np.save(fh, np.ascontiguousarray(pts), allow_pickle=False)
            elif kind == "csv":
                np.savetxt(fh, pts, fmt="%.17g", delimiter=",", header="x,y,z", comments="")
            else:
                np.savetxt(fh, pts, fmt="%.17g", delimiter=" ")
    except OSError as exc:
        raise CloudError(source, "file", f"cannot write: {exc.strerror or exc}") from None
    return target


def _write_ply(pts: NDArray[np.float64], fh: IO[bytes], ascii: bool) -> None:
    import plyfile

    vertex = np.empty(len(pts), dtype=[("x", "<f8"), ("y", "<f8"), ("z", "<f8")])
    vertex["x"], vertex["y"], vertex["z"] = pts[:, 0], pts[:, 1], pts[:, 2]
    element = plyfile.PlyElement.describe(vertex, "vertex")
    plyfile.PlyData([element], text=ascii, byte_order="<").write(fh)


def _write_pcd(pts: NDArray[np.float64], fh: IO[bytes], ascii: bool) -> None:
    import pypcd4

    pcd = pypcd4.PointCloud.from_points(pts, _XYZ, (np.float64, np.float64, np.float64))
    encoding = pypcd4.Encoding.ASCII if ascii else pypcd4.Encoding.BINARY
    pcd.save(cast(BinaryIO, fh), encoding=encoding)


# ---------------------------------------------------------------------------- meshes


def load_mesh_cloud(
    path: str | os.PathLike[str],
    n: int = DEFAULT_MESH_POINTS,
    seed: int | np.random.Generator = 0,
    *,
    scale: float | tuple[float, float, float] = 1.0,
    frame: str = "world",
    name: str | None = None,
    max_points: int = MAX_SAMPLED_POINTS,
) -> PointCloud:
    """Read a triangle mesh (:func:`reachwise.io.meshes.load_mesh`: STL, OBJ, PLY, OFF,
    glTF, COLLADA), sample ``n`` points.

    The thesis converts each CAD part into a 1000-point cloud (P-III §5, P-V §V); this is
    that step: area-weighted uniform surface samples, reproducible with ``seed`` (see
    :func:`reachwise.geometry.cloud.sample_mesh_surface`). ``scale`` multiplies the
    mesh coordinates first (``0.001`` for a CAD part drawn in millimetres; three
    factors scale x, y, z). A file with several bodies is sampled as their union.
    Errors are those of :func:`~reachwise.io.meshes.load_mesh`; ``n`` above
    ``max_points`` is refused.
    """
    source = str(path)
    mesh = load_mesh(path, scale=scale)
    return sample_mesh_surface(
        np.asarray(mesh.vertices, dtype=np.float64),
        np.asarray(mesh.faces),
        n,
        seed,
        frame=frame,
        name=source if name is None else name,
        max_points=max_points,
    )
