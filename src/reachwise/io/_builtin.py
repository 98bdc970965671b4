"""The data files shipped with reachwise (robots, tasks, scenarios), and the one way a
"built-in name or file path" argument is resolved.

:func:`load_named` is what ``load_robot``, ``load_task`` and ``load_scenario`` share: a
built-in name is read from ``reachwise/data/<kind>/<name>.yaml``; an existing file, or
anything that looks like a file (a known suffix or a folder in it), is handed to the
file loader, which names the file in its errors; anything else is an
:class:`~reachwise.errors.UnknownName` that lists the built-ins.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Literal, TypeVar

from reachwise.errors import UnknownName

__all__ = ["Builtin", "BuiltinKind", "builtin_names", "builtin_text", "load_named"]

#: The folders of ``reachwise/data`` that hold built-ins.
BuiltinKind = Literal["robots", "tasks", "scenarios"]

_T = TypeVar("_T")


def builtin_names(kind: BuiltinKind) -> list[str]:
    """Sorted names of the ``*.yaml`` files in ``reachwise/data/<kind>``."""
    folder = resources.files("reachwise.data") / kind
    return sorted(f.name[:-5] for f in folder.iterdir() if f.name.endswith(".yaml"))


def builtin_text(kind: BuiltinKind, name: str) -> str:
    """Text of the built-in ``reachwise/data/<kind>/<name>.yaml``."""
    return (resources.files("reachwise.data") / kind / f"{name}.yaml").read_text()


@dataclass(frozen=True)
class Builtin:
    """One built-in data file: ``kind`` (``"robots"`` …) and ``name``."""

    kind: BuiltinKind
    name: str

    @property
    def label(self) -> str:
        """How errors name it: ``built-in robot sb60``."""
        return f"built-in {self.kind[:-1]} {self.name}"

    @property
    def folder(self) -> Path:
        """The folder its relative paths (meshes …) start from."""
        return Path(str(resources.files("reachwise.data") / self.kind))

    def text(self) -> str:
        return builtin_text(self.kind, self.name)


def load_named(
    kind: BuiltinKind,
    name_or_path: str | Path,
    *,
    from_builtin: Callable[[Builtin], _T],
    from_file: Callable[[Path], _T],
    suffixes: tuple[str, ...],
) -> _T:
    """``from_builtin(Builtin(kind, name))`` for a built-in name, else
    ``from_file(path)`` for an existing file or a path that looks like one (a suffix in
    ``suffixes`` or a folder part; the file loader reports a missing file), else
    :class:`~reachwise.errors.UnknownName` listing the built-in names."""
    s = str(name_or_path)
    names = builtin_names(kind)
    if s in names:
        return from_builtin(Builtin(kind, s))
    p = Path(s)
    if p.is_file() or p.suffix.lower() in suffixes or len(p.parts) > 1:
        return from_file(p)
    raise UnknownName(s, f"built-in {kind[:-1]}", s, names)
