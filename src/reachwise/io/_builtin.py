"""Names of the data files shipped with reachwise (robots, tasks, scenarios)."""

from __future__ import annotations

from importlib import resources


def builtin_names(kind: str) -> list[str]:
    """Sorted names of the ``*.yaml`` files in ``reachwise/data/<kind>``."""
    folder = resources.files("reachwise.data") / kind
    return sorted(f.name[:-5] for f in folder.iterdir() if f.name.endswith(".yaml"))


def builtin_text(kind: str, name: str) -> str:
    """Text of the built-in ``reachwise/data/<kind>/<name>.yaml``."""
    return (resources.files("reachwise.data") / kind / f"{name}.yaml").read_text()
