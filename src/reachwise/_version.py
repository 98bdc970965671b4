"""The package version, in a module of its own so that no module needs the package root
(importing ``reachwise`` loads every layer and compiles the numba kernels), and the
fingerprint of the source this process runs."""

from __future__ import annotations

import hashlib
from functools import cache
from pathlib import Path

__version__ = "0.1.0"


def tree_fingerprint(root: Path) -> str:
    """Hash of every ``.py`` file under ``root``: relative path and content, in path order."""
    h = hashlib.sha256()
    for p in sorted(root.rglob("*.py")):
        rel = p.relative_to(root).as_posix().encode()
        data = p.read_bytes()
        for part in (rel, data):
            h.update(len(part).to_bytes(8, "little"))
            h.update(part)
    return h.hexdigest()[:16]


@cache
def source_fingerprint() -> str:
    """:func:`tree_fingerprint` of this package, read once per process.

    Two processes with the same version but a different checkout (an edit, a landing, a
    ``git checkout`` while a sweep's workers start) compute different designs; this tells
    them apart where ``__version__`` cannot. About 30 ms for the whole package."""
    return tree_fingerprint(Path(__file__).parent)
