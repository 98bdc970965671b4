"""Point-cloud file headers checked against the bytes behind them, before anything is
allocated.

A header states how many points follow and how each is stored; a reader that trusts
it allocates what a hostile or broken file claims (a PLY declaring 4 000 000 000
vertices) or reads the wrong bytes without a word (39 vertices declared over 40 rows
drops one; ``property char x`` over double data, a PCD ``SIZE 8 8 4``, give garbage).
Each function here reads only the header, then checks

- the point count against ``max_points`` (a bound the caller, and the user through
  ``--max-points``, can raise),
- the size of the data the header describes against the size of the file (binary),
  or the number of data lines against the number of rows (ASCII),
- the field types: x, y, z scalars of at least 16 bits, and for a PCD the header's own
  consistency (``WIDTH × HEIGHT = POINTS``, one ``SIZE``/``TYPE``/``COUNT`` per field,
  sizes a type can have).

Every failure is a :class:`~reachwise.errors.CloudError` naming the file, the header
field and what is wrong.
"""

from __future__ import annotations

import math
import os
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from reachwise.errors import CloudError

__all__ = [
    "MAX_CLOUD_POINTS",
    "TEXT_ROW_BYTES",
    "check_npy",
    "check_pcd",
    "check_ply",
    "check_text_size",
    "count_lines",
]

#: Default bound on the points of one cloud file (about 1.2 GB as float64 x, y, z).
MAX_CLOUD_POINTS = 50_000_000
#: Longest header read (bytes): PLY and PCD headers are a few hundred bytes.
_MAX_HEADER = 64 * 1024
_XYZ = ("x", "y", "z")
#: Largest point record accepted (bytes): x, y, z and a few hundred more values.
_MAX_ROW_BYTES = 4096
#: Bytes an XYZ or CSV row may take on average (x, y, z and about seven more values at
#: full float precision, comments and blank lines included): with ``max_points`` it
#: bounds the size of a text cloud file read whole.
TEXT_ROW_BYTES = 256

_PLY_SIZES = {
    "char": 1, "int8": 1, "uchar": 1, "uint8": 1, "short": 2, "int16": 2, "ushort": 2,
    "uint16": 2, "int": 4, "int32": 4, "uint": 4, "uint32": 4, "float": 4, "float32": 4,
    "double": 8, "float64": 8,
}  # fmt: skip
_PCD_SIZES = {"F": (4, 8), "I": (1, 2, 4, 8), "U": (1, 2, 4, 8)}


def _check_count(source: str, field: str, count: int, max_points: int) -> None:
    if count > max_points:
        raise CloudError(
            source, field, f"declares {count} points, more than the bound {max_points} "
            "(raise it with --max-points / max_points)",
        )  # fmt: skip


def check_text_size(path: Path, source: str, max_points: int) -> None:
    """Refuse an XYZ or CSV file larger than ``max_points`` rows of
    :data:`TEXT_ROW_BYTES` bytes (plus a header of up to 64 KiB) before it is read:
    a text file has no header stating its count, so its size is the bound."""
    size = path.stat().st_size
    limit = _MAX_HEADER + max_points * TEXT_ROW_BYTES
    if size > limit:
        raise CloudError(
            source, "file", f"{size} bytes, more than {limit}: {max_points} points of at most "
            f"{TEXT_ROW_BYTES} bytes a row (raise the bound with --max-points / max_points)",
        )  # fmt: skip


def _header_lines(path: Path, source: str, kind: str, last: bytes) -> tuple[list[str], int]:
    """The header's lines up to and including the one starting with ``last``, and the
    header's length in bytes."""
    with open(path, "rb") as fh:
        head = fh.read(_MAX_HEADER)
    lines: list[str] = []
    offset = 0
    for raw in head.splitlines(keepends=True):
        if not raw.endswith(b"\n") and offset + len(raw) == len(head):
            break  # cut off: no end of header within the bytes read
        offset += len(raw)
        try:
            line = raw.decode("ascii").strip()
        except UnicodeDecodeError:
            raise CloudError(
                source, f"header line {len(lines) + 1}", f"not a valid {kind} header (not ASCII)"
            ) from None
        lines.append(line)
        if raw.startswith(last):
            return lines, offset
    raise CloudError(source, "header", f"not a valid {kind} file: no {last.decode()!r} line")


def count_lines(path: Path, offset: int) -> int:
    """The non-empty lines of ``path`` after byte ``offset``, read in blocks."""
    n = 0
    tail = b""
    with open(path, "rb") as fh:
        fh.seek(offset)
        while block := fh.read(1 << 20):
            block = tail + block
            lines = block.split(b"\n")
            tail = lines.pop()
            n += sum(1 for line in lines if line.strip())
    return n + (1 if tail.strip() else 0)


@dataclass(frozen=True)
class _PlyElement:
    name: str
    count: int
    props: list[tuple[str, str, bool]]  # name, type, is a list

    def row_bytes(self) -> int:
        """Bytes of one row (lists counted by their length prefix only)."""
        return sum(_PLY_SIZES[t] for _, t, _ in self.props)


def check_ply(path: Path, source: str, max_points: int) -> None:
    """A PLY file's header against its data (module docstring)."""
    lines, offset = _header_lines(path, source, "PLY", b"end_header")
    if not lines or lines[0] != "ply":
        raise CloudError(source, "header", "not a valid PLY file: no 'ply' magic line")
    fmt = ""
    elements: list[_PlyElement] = []
    for no, line in enumerate(lines[1:-1], start=2):
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        where = f"header line {no}"
        if words[0] == "format" and len(words) == 3:
            fmt = words[1]
        elif words[0] == "element" and len(words) == 3 and words[2].isdecimal():
            elements.append(_PlyElement(words[1], int(words[2]), []))
        elif words[0] == "property" and elements and len(words) in (3, 5):
            is_list = words[1] == "list"
            types = words[2:4] if is_list else words[1:2]
            if len(words) != (5 if is_list else 3) or any(t not in _PLY_SIZES for t in types):
                raise CloudError(source, where, f"unknown property {line!r}")
            elements[-1].props.append((words[-1], types[-1] if not is_list else types[0], is_list))
        else:
            raise CloudError(source, where, f"not a valid PLY header line: {line[:80]!r}")
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise CloudError(source, "format", f"unknown PLY format {fmt!r}")
    vertex = next((e for e in elements if e.name == "vertex"), None)
    if vertex is None:
        return  # the reader names the missing element
    _check_count(source, "element vertex", vertex.count, max_points)
    for name, typ, is_list in vertex.props:
        if name in _XYZ and (is_list or _PLY_SIZES[typ] < 2):
            kind = "a list" if is_list else f"{typ} (8 bits)"
            raise CloudError(source, f"vertex.{name}", f"a coordinate cannot be {kind}")
    if fmt == "ascii":
        rows = sum(e.count for e in elements)
        got = count_lines(path, offset)
        if got != rows:
            raise CloudError(
                source, "element vertex", f"header declares {rows} data rows, the file holds {got}"
            )
        return
    body = path.stat().st_size - offset
    least = sum(e.count * e.row_bytes() for e in elements)
    exact = not any(is_list for e in elements for *_, is_list in e.props)
    if body < least or (exact and body != least):
        declared = ", ".join(f"{e.count} {e.name}" for e in elements)
        raise CloudError(
            source, "element vertex",
            f"header declares {declared} ({least} bytes of data), the file holds {body} bytes",
        )  # fmt: skip


def check_pcd(path: Path, source: str, max_points: int) -> None:
    """A PCD file's header against itself and its data (module docstring)."""
    lines, offset = _header_lines(path, source, "PCD", b"DATA")
    head: dict[str, list[str]] = {}
    for line in lines:
        words = line.split()
        if words and not words[0].startswith("#"):
            head[words[0].upper()] = words[1:]
    fields = head.get("FIELDS", [])
    n = len(fields)
    if not fields:
        raise CloudError(source, "FIELDS", "missing")
    spec: dict[str, list[str]] = {}
    for key in ("SIZE", "TYPE", "COUNT"):
        spec[key] = head.get(key, ["1"] * n if key == "COUNT" else [])
        if len(spec[key]) != n:
            raise CloudError(source, key, f"{len(spec[key])} values for {n} fields {fields}")
    row = 0
    for name, size, typ, count in zip(
        fields, spec["SIZE"], spec["TYPE"], spec["COUNT"], strict=True
    ):
        if not (size.isdecimal() and count.isdecimal()) or int(size) not in _PCD_SIZES.get(typ, ()):
            raise CloudError(
                source, name, f"SIZE {size} TYPE {typ} COUNT {count} is not a PCD field"
            )
        if name in _XYZ and int(size) < 2:
            raise CloudError(source, name, f"a coordinate cannot be {size} byte")
        row += int(size) * int(count)
    if row > _MAX_ROW_BYTES:
        raise CloudError(source, "COUNT", f"{row} bytes per point, more than {_MAX_ROW_BYTES}")
    numbers = {}
    for key in ("WIDTH", "HEIGHT", "POINTS"):
        value = head.get(key, [])
        if key == "POINTS" and not value:
            continue
        if len(value) != 1 or not value[0].isdecimal():
            raise CloudError(source, key, f"expected one count, got {' '.join(value)!r}")
        numbers[key] = int(value[0])
    points = numbers.get("POINTS", numbers["WIDTH"] * numbers["HEIGHT"])
    _check_count(source, "POINTS", points, max_points)
    if numbers["WIDTH"] * numbers["HEIGHT"] != points:
        raise CloudError(
            source, "WIDTH",
            f"WIDTH {numbers['WIDTH']} x HEIGHT {numbers['HEIGHT']} is not POINTS {points}",
        )  # fmt: skip
    data = (head.get("DATA") or [""])[0].lower()
    body = path.stat().st_size - offset
    if data == "ascii":
        got = count_lines(path, offset)
        if got != points:
            raise CloudError(
                source, "POINTS", f"header declares {points} points, the file holds {got}"
            )
    elif data == "binary":
        if body != points * row:
            raise CloudError(
                source, "POINTS",
                f"header declares {points} points of {row} bytes ({points * row} bytes), "
                f"the file holds {body} bytes",
            )  # fmt: skip
    elif data == "binary_compressed":
        with open(path, "rb") as fh:
            fh.seek(offset)
            sizes = fh.read(8)
        if len(sizes) < 8:
            raise CloudError(source, "DATA", "binary_compressed data without its sizes")
        packed, unpacked = struct.unpack("<II", sizes)
        if unpacked != points * row or packed > body - 8:
            raise CloudError(
                source, "DATA",
                f"compressed block of {packed} bytes ({body - 8} present) unpacking to "
                f"{unpacked} bytes, for {points} points of {row} bytes",
            )  # fmt: skip
    else:
        raise CloudError(source, "DATA", f"unknown encoding {data!r}")


def _npy_header(fh: Any, source: str) -> tuple[tuple[int, ...], np.dtype[Any]]:
    fmt = np.lib.format
    try:
        version = fmt.read_magic(fh)
        if version == (1, 0):
            shape, _, dtype = fmt.read_array_header_1_0(fh)
        elif version == (2, 0):
            shape, _, dtype = fmt.read_array_header_2_0(fh)
        else:
            raise ValueError(f"NPY version {version[0]}.{version[1]} is not read")
    except Exception as exc:  # numpy parses the header dict with ast/tokenize: any error
        raise CloudError(source, "header", f"not a valid NPY file: {exc}") from None
    return tuple(int(d) for d in shape), dtype


def check_npy(path: Path, source: str, max_points: int) -> None:
    """An NPY file's header (shape and dtype) against the bound and the file's size."""
    with open(path, "rb") as fh:
        shape, dtype = _npy_header(fh, source)
        offset = fh.tell()
    if dtype.hasobject:
        raise CloudError(source, "dtype", f"objects ({dtype}) are not coordinates")
    values = math.prod(shape)
    points = values if dtype.names is not None else values // 3
    _check_count(source, "shape", points, max_points)
    need = values * dtype.itemsize
    body = os.path.getsize(path) - offset
    if body != need:
        raise CloudError(
            source, "shape",
            f"header declares shape {shape} of {dtype} ({need} bytes), the file holds {body} bytes",
        )  # fmt: skip
