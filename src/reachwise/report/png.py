"""Figures written as PNG files, atomically (:mod:`reachwise.io.atomic`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from reachwise.io.atomic import atomic_open

__all__ = ["save_png"]


def save_png(figure: Any, path: str | Path, dpi: int) -> Path:
    """Write the matplotlib ``figure`` to ``path`` as a PNG of ``dpi``; return the path.
    A reader of ``path`` never sees a half-written image."""
    with atomic_open(path, "wb") as fh:
        figure.savefig(fh, format="png", dpi=dpi)
    return Path(path)
