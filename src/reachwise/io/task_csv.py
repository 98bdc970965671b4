"""Task files as CSV (:mod:`reachwise.io.task_file` reads and writes them): one point
per row, a header naming the columns (:data:`CSV_COLUMNS`), ``# name: NAME`` before it;
and the numbers every task file writes (:func:`file_floats`, :func:`quaternion_xyzw`)."""

from __future__ import annotations

import csv
import io
from collections import Counter
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from reachwise.errors import TaskError
from reachwise.tasks.task import Task

__all__ = ["CSV_COLUMNS", "csv_to_dict", "file_floats", "quaternion_xyzw", "render_csv"]


def quaternion_xyzw(R: np.ndarray) -> np.ndarray:
    """The unit quaternion ``(x, y, z, w)`` of rotation ``R``, with ``w ≥ 0``."""
    q = Rotation.from_matrix(R).as_quat()
    return np.asarray(-q if q[3] < 0 else q)


def file_floats(v: np.ndarray, decimals: int | None) -> list[float]:
    """``v`` as the floats a task file writes: rounded to ``decimals`` when given,
    with no negative zero."""
    a = np.asarray(v, dtype=float)
    if decimals is not None:
        a = np.round(a, decimals) + 0.0  # + 0.0 turns -0.0 into 0.0
    return [float(x) for x in a]


_CSV_GROUPS: dict[str, tuple[str, ...]] = {
    "xyz": ("x", "y", "z"),
    "quat": ("qx", "qy", "qz", "qw"),
    "axis": ("ax", "ay", "az"),
    "rpy": ("roll", "pitch", "yaw"),
    "rpy_deg": ("roll_deg", "pitch_deg", "yaw_deg"),
}
_CSV_POINT = ("dims", "tol_position", "tol_orientation", "name", "group")
#: Every column a task CSV may have: the pose groups, then the per-point fields.
CSV_COLUMNS: tuple[str, ...] = (*(c for g in _CSV_GROUPS.values() for c in g), *_CSV_POINT)
#: What ``save_task`` writes: position, quaternion, axis and the per-point fields.
_CSV_WRITE = (*_CSV_GROUPS["xyz"], *_CSV_GROUPS["quat"], *_CSV_GROUPS["axis"], *_CSV_POINT)


def render_csv(task: Task, decimals: int | None) -> str:
    """``task`` as CSV text: a ``# name:`` line, the header and one row per point
    (position, quaternion or axis, and the per-point fields)."""
    buf = io.StringIO()
    buf.write(f"# name: {task.name}\n")
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(_CSV_WRITE)
    for p in task.points:
        q: list[Any] = [""] * 4
        a: list[Any] = [""] * 3
        if p.rotation is not None:
            q = file_floats(quaternion_xyzw(p.rotation), decimals)
        elif p.axis is not None:
            a = file_floats(p.axis, decimals)
        w.writerow(
            [
                *file_floats(p.position, decimals),
                *q,
                *a,
                p.dims,
                repr(p.tol_position),
                repr(p.tol_orientation),
                p.name,
                p.group,
            ]
        )
    return buf.getvalue()


def csv_to_dict(text: str, source: str, default_name: str) -> tuple[dict[str, Any], list[int]]:
    """The task file dictionary of CSV ``text`` (the schema of YAML and JSON, cells
    still strings) and the file line of each point; a header or row error is a
    ``TaskError`` naming its line."""
    lines = text.splitlines()
    name = default_name
    start = 0
    while start < len(lines) and (
        not lines[start].strip() or lines[start].lstrip().startswith("#")
    ):
        body = lines[start].lstrip().removeprefix("#").strip()
        if body.lower().startswith("name:"):
            name = body[5:].strip()
        start += 1
    reader = csv.reader(lines[start:])
    try:
        rows = list(reader)
    except csv.Error as exc:  # a cell beyond csv.field_size_limit, a NUL byte
        raise TaskError(
            source, f"line {start + reader.line_num}", f"not valid CSV: {exc}"
        ) from None
    if not rows:
        raise TaskError(source, "header", "no CSV header (need at least columns x, y, z)")
    header = [h.strip() for h in rows[0]]
    unknown = [h for h in header if h not in CSV_COLUMNS]
    if unknown:
        known = ", ".join(CSV_COLUMNS)
        raise TaskError(source, "header", f"unknown column {unknown[0]!r}; known columns: {known}")
    dup = [h for h, c in Counter(header).items() if c > 1]
    if dup:
        raise TaskError(source, "header", f"duplicate column {dup[0]!r}")
    for key, cols in _CSV_GROUPS.items():
        have = [c for c in cols if c in header]
        if (key == "xyz" or have) and len(have) != len(cols):
            missing = [c for c in cols if c not in header]
            group, miss = ", ".join(cols), ", ".join(missing)
            raise TaskError(source, "header", f"columns {group} go together; missing {miss}")
    col = {h: j for j, h in enumerate(header)}
    points: list[dict[str, Any]] = []
    line_of: list[int] = []
    line = start + 1
    for cells in rows[1:]:
        line += 1
        if not any(c.strip() for c in cells):
            continue
        if len(cells) != len(header):
            raise TaskError(
                source, f"line {line}", f"expected {len(header)} cells, got {len(cells)}"
            )
        i = len(points)
        get = {h: cells[j].strip() for h, j in col.items()}
        pt: dict[str, Any] = {}
        for key, cols in _CSV_GROUPS.items():
            if cols[0] not in col:
                continue
            vals = [get[c] for c in cols]
            if key == "xyz" or any(vals):
                if not all(vals):
                    group = ", ".join(cols)
                    raise TaskError(
                        source,
                        f"points[{i}].{key}",
                        f"give all of {group} or none (CSV line {line})",
                    )
                pt[key] = vals
        if get.get("dims"):
            dims = get["dims"]
            pt["dims"] = int(dims) if dims.isascii() and dims.isdigit() else dims
        tol_cols = (("position", "tol_position"), ("orientation", "tol_orientation"))
        tol = {k: get[c] for k, c in tol_cols if get.get(c)}
        if tol:
            pt["tolerance"] = tol
        for key in ("name", "group"):
            if get.get(key):
                pt[key] = get[key]
        points.append(pt)
        line_of.append(line)
    return {"name": name, "points": points}, line_of
