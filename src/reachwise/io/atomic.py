"""Atomic file writes: a reader sees the old file or the new one, never half of one.

Every file reachwise writes goes through here. The new content goes to a temporary
file with a unique name in the target's folder (``.NAME.<random>.tmp``, created
exclusively, so two writers never share one), is flushed and ``fsync``'ed, then
renamed over the target with :func:`os.replace` (atomic on POSIX and Windows), and the
folder is ``fsync``'ed where the platform allows it, so the rename itself survives a
power cut. If anything fails before the rename the temporary file is removed and the
old file is left as it was.

- :func:`atomic_write` — write ``bytes`` or ``str`` in one call;
- :func:`atomic_open` — a file object for writers that stream (``csv``, ``np.save``,
  ``Figure.savefig(fh, format="png")``, plyfile, pypcd4), committed when the ``with``
  block ends without an exception.

Concurrent writers to one path each commit a complete file; the last rename wins.
"""

from __future__ import annotations

import os
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any, Literal

__all__ = ["TEMP_SUFFIX", "atomic_open", "atomic_write", "temp_path"]

#: Every temporary file ends with this (a crash can leave one; nothing else does).
TEMP_SUFFIX = ".tmp"

#: ``"w"`` (text) or ``"wb"`` (binary).
WriteMode = Literal["w", "wt", "wb"]


def temp_path(target: Path) -> Path:
    """A fresh temporary name next to ``target``: ``.NAME.<32 hex digits>.tmp``."""
    return target.with_name(f".{target.name}.{uuid.uuid4().hex}{TEMP_SUFFIX}")


def atomic_write(path: str | os.PathLike[str], data: bytes | str, encoding: str = "utf-8") -> Path:
    """Write ``data`` to ``path`` atomically (module docstring); return the path.

    ``str`` data is encoded with ``encoding``; line endings are written as given.
    """
    raw = data.encode(encoding) if isinstance(data, str) else bytes(data)
    with atomic_open(path, "wb") as fh:
        fh.write(raw)
    return Path(path)


@contextmanager
def atomic_open(
    path: str | os.PathLike[str],
    mode: WriteMode = "w",
    *,
    encoding: str = "utf-8",
    newline: str | None = None,
) -> Iterator[IO[Any]]:
    """Open a temporary file for writing; on a clean exit make it ``path`` atomically.

    ``mode`` is ``"w"`` (text, ``encoding`` and ``newline`` as for :func:`open`) or
    ``"wb"``. An exception inside the ``with`` block removes the temporary file,
    leaves ``path`` untouched and propagates.
    """
    if mode not in ("w", "wt", "wb"):
        raise ValueError(f"atomic_open: mode must be 'w' or 'wb', not {mode!r}")
    target = Path(path)
    tmp = temp_path(target)
    # O_EXCL: the name is ours alone; 0o666 & ~umask: the usual permissions of a new file
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666)
    try:
        if mode == "wb":
            fh: IO[Any] = os.fdopen(fd, "wb")
        else:
            fh = os.fdopen(fd, "w", encoding=encoding, newline=newline)
    except BaseException:
        os.close(fd)
        tmp.unlink(missing_ok=True)
        raise
    try:
        with fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, target)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    _fsync_folder(target.parent)


def _fsync_folder(folder: Path) -> None:
    """Make a rename in ``folder`` durable, where the platform supports it."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:  # e.g. Windows: a folder cannot be opened
        return
    try:
        os.fsync(fd)
    except OSError:  # some file systems refuse fsync on a folder
        pass
    finally:
        os.close(fd)
