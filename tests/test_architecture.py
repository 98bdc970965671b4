"""The package's import structure, read from its source (every import: at module level,
inside a function, or under ``if TYPE_CHECKING:`` — a type-only import still ties two
files together, and a cycle through it is a cycle of the design): no module cycle,
nothing imports the package root, no submodule imports its own package's ``__init__``,
and the math layers import nothing from the layers that touch files, clocks, sockets or
screens. ``lint-imports`` (the contracts in pyproject.toml) checks the layer order and
the forbidden edges; this test states the rules that must hold whatever the order, and
is itself tested on a small package that breaks each of them. ``docs/architecture.md``
names only what exists and states every contract of ``pyproject.toml``; those checks
are tested on pages that break them."""

from __future__ import annotations

import ast
import importlib
import re
import tomllib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

import reachwise

SRC = Path(reachwise.__file__).parent.parent
ROOT = "reachwise"
MATH = ("kinematics", "geometry", "tasks", "distance", "control", "synthesis")
UPPER = ("io", "runtime", "sim", "server", "report", "viz", "cli", "benchmarks")


@dataclass(frozen=True)
class Import:
    """``source`` imports ``target`` at ``line``; ``origin`` is the module named in the
    statement (``from origin import …``), which runs ``origin``'s ``__init__``."""

    source: str
    target: str
    origin: str
    line: int


def modules(src: Path, root: str) -> dict[str, tuple[Path, bool]]:
    """Every module of package ``root`` under ``src``: name → (file, is a package)."""
    out = {}
    for path in sorted((src / root).rglob("*.py")):
        parts = list(path.relative_to(src).with_suffix("").parts)
        is_package = parts[-1] == "__init__"
        if is_package:
            parts = parts[:-1]
        out[".".join(parts)] = (path, is_package)
    return out


def _statements(tree: ast.AST) -> Iterator[ast.Import | ast.ImportFrom]:
    """Import statements anywhere in ``tree``: module level, function bodies and
    ``if TYPE_CHECKING:`` blocks alike."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Import | ast.ImportFrom):
            yield node


def imports(src: Path, root: str) -> list[Import]:
    """Every import between modules of ``root`` (see the module docstring)."""
    mods = modules(src, root)
    found = []
    for name, (path, is_package) in mods.items():
        for node in _statements(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                pairs = [(a.name, a.name) for a in node.names]
            else:
                if node.level:
                    base = name.split(".")[: len(name.split(".")) - node.level + is_package]
                    origin = ".".join(base + ([node.module] if node.module else []))
                else:
                    origin = node.module or ""
                pairs = [
                    (origin, f"{origin}.{a.name}" if f"{origin}.{a.name}" in mods else origin)
                    for a in node.names
                ]
            for origin, target in pairs:
                if target == root or target.startswith(root + "."):
                    while target not in mods and "." in target:
                        target = target.rsplit(".", 1)[0]
                    found.append(Import(name, target, origin, node.lineno))
    return found


def cycles(edges: list[Import]) -> list[list[str]]:
    """Groups of modules that import each other, directly or through others (Tarjan)."""
    graph: dict[str, set[str]] = {}
    for e in edges:
        if e.source != e.target:
            graph.setdefault(e.source, set()).add(e.target)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                out.append(sorted(group))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(out)


def root_imports(edges: list[Import], root: str) -> list[str]:
    """Modules that import the package root (its ``__init__`` loads everything)."""
    return sorted({f"{e.source}:{e.line}" for e in edges if e.origin == root})


def own_init_imports(edges: list[Import], mods: dict[str, tuple[Path, bool]]) -> list[str]:
    """Submodules that import a package they are inside (other than the root), e.g.
    ``from reachwise.distance import _kernels`` in ``reachwise.distance.engine``."""
    bad = set()
    for e in edges:
        if mods[e.source][1]:  # a package's __init__ may import its own submodules
            continue
        parents = e.source.split(".")[:-1]
        ancestors = {".".join(parents[:k]) for k in range(2, len(parents) + 1)}
        if e.origin in ancestors:
            bad.add(f"{e.source}:{e.line} imports {e.origin}")
    return sorted(bad)


def upward_imports(
    edges: list[Import], lower: tuple[str, ...], upper: tuple[str, ...]
) -> list[str]:
    """Imports from a module of a ``lower`` layer into an ``upper`` one."""

    def layer(module: str) -> str:
        parts = module.split(".")
        return parts[1] if len(parts) > 1 else ""

    return sorted(
        f"{e.source}:{e.line} -> {e.target}"
        for e in edges
        if layer(e.source) in lower and layer(e.target) in upper
    )


# ---- the package --------------------------------------------------------------------

EDGES = imports(SRC, ROOT)
MODULES = modules(SRC, ROOT)


def test_the_scan_sees_the_package() -> None:
    assert len(MODULES) > 100
    pairs = {(e.source, e.target) for e in EDGES}
    assert ("reachwise.io.robot_file", "reachwise.kinematics.robot") in pairs  # module level
    assert ("reachwise.cli.synth", "reachwise.synthesis.synthesize") in pairs  # in a function


def test_no_module_cycle() -> None:
    assert cycles(EDGES) == []


def test_nothing_imports_the_package_root() -> None:
    assert root_imports(EDGES, ROOT) == []


def test_no_submodule_imports_its_own_package() -> None:
    assert own_init_imports(EDGES, MODULES) == []


def test_the_math_layers_import_no_upper_layer() -> None:
    assert upward_imports(EDGES, MATH, UPPER) == []


# ---- the checks themselves, on a package that breaks every rule ---------------------

_BROKEN = {
    "__init__.py": "",
    "_version.py": "__version__ = '1'\n",
    "geo/__init__.py": "from pkg.geo.shape import Box\n",
    "geo/shape.py": (
        "from __future__ import annotations\n"
        "from typing import TYPE_CHECKING\n"
        "from pkg import _version\n"  # through the root: runs its __init__
        "from pkg.geo import core\n"  # own package's __init__
        "if TYPE_CHECKING:\n"
        "    from pkg.io.files import Reader\n"  # for the type checker only: still an edge
        "else:\n"
        "    Reader = None\n"
        "class Box:\n"
        "    def save(self):\n"
        "        from pkg.io.files import write\n"  # up into io, inside a function
        "        return write(self)\n"
    ),
    "geo/core.py": "from .. import __version__\n",  # the root, relatively
    "io/__init__.py": "",
    "io/files.py": "import pkg.geo.shape as S\ndef write(x):\n    return S\n",
    "io/plain.py": "from . import files\n",  # own package, relatively
}


@pytest.fixture
def broken(tmp_path: Path) -> Path:
    for rel, text in _BROKEN.items():
        (tmp_path / "pkg" / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / "pkg" / rel).write_text(text)
    return tmp_path


def test_the_checks_find_each_known_violation(broken: Path) -> None:
    edges = imports(broken, "pkg")
    mods = modules(broken, "pkg")
    assert ("pkg.geo.shape", "pkg.io.files") in {(e.source, e.target) for e in edges}
    assert any(e.line == 6 and e.source == "pkg.geo.shape" for e in edges)  # TYPE_CHECKING
    assert cycles(edges) == [["pkg.geo.shape", "pkg.io.files"]]
    assert root_imports(edges, "pkg") == ["pkg.geo.core:1", "pkg.geo.shape:3"]
    assert own_init_imports(edges, mods) == [
        "pkg.geo.shape:4 imports pkg.geo",
        "pkg.io.plain:1 imports pkg.io",
    ]
    assert upward_imports(edges, ("geo",), ("io",)) == [
        "pkg.geo.shape:11 -> pkg.io.files",
        "pkg.geo.shape:6 -> pkg.io.files",
    ]


def test_an_import_under_type_checking_makes_a_cycle(broken: Path) -> None:
    """A cycle that only a type-only import closes is still found."""
    files = broken / "pkg" / "io" / "files.py"
    files.write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import pkg.geo.shape\n"
    )
    shape = broken / "pkg" / "geo" / "shape.py"
    shape.write_text(
        "from typing import TYPE_CHECKING\n"
        "def save():\n"
        "    from pkg.io.files import write\n"  # function level the other way
        "    return write\n"
    )
    assert cycles(imports(broken, "pkg")) == [["pkg.geo.shape", "pkg.io.files"]]


# ---- docs/architecture.md names only what exists ------------------------------------

DOC = SRC.parent / "docs" / "architecture.md"
_SPAN = re.compile(r"`([^`]+)`")
_DOTTED = re.compile(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)+(:[A-Za-z_]\w*(\.[A-Za-z_]\w*)*)?")
_BARE = re.compile(r"[A-Za-z_]\w*")


def resolve_name(name: str, mods: dict[str, tuple[Path, bool]], root: str) -> Any:
    """The object ``name`` denotes: ``module.path:attr.attr`` or a dotted name whose
    longest prefix that is a module of ``root`` is imported and the rest looked up on it
    (``root.`` may be left out). Raises ``LookupError`` for what does not exist."""
    path, _, attrs = name.partition(":")
    if not path.startswith(root + ".") and path != root:
        path = f"{root}.{path}"
    parts = path.split(".")
    k = next((k for k in range(len(parts), 0, -1) if ".".join(parts[:k]) in mods), 0)
    if k == 0:
        raise LookupError(f"{name}: no module of {root}")
    if attrs and k != len(parts):
        raise LookupError(f"{name}: {path} is not a module")
    obj: Any = importlib.import_module(".".join(parts[:k]))
    for a in parts[k:] + (attrs.split(".") if attrs else []):
        if not hasattr(obj, a):
            raise LookupError(f"{name}: {a!r} not found")
        obj = getattr(obj, a)
    return obj


def missing_names(text: str, mods: dict[str, tuple[Path, bool]], root: str) -> list[str]:
    """The names ``text`` (Markdown) cites in backticks that do not exist: every dotted
    name whose first part is a package or module of ``root``; in a table row, also each
    bare name after one, looked up in the module of the dotted name before it."""
    tops = {m.split(".")[1] for m in mods if m.count(".") >= 1} | {root}
    bad = []
    for line in text.splitlines():
        in_table = line.startswith("|")
        module: Any = None
        for span in _SPAN.findall(line):
            span = span.strip()
            if _DOTTED.fullmatch(span) and span.split(".")[0].split(":")[0] in tops:
                try:
                    obj = resolve_name(span, mods, root)
                except LookupError as exc:
                    bad.append(str(exc))
                    module = None
                    continue
                module = obj if isinstance(obj, type(importlib)) else None
                if module is None:
                    module = importlib.import_module(getattr(obj, "__module__", root))
            elif in_table and module is not None and _BARE.fullmatch(span):
                if not hasattr(module, span):
                    bad.append(f"{span}: not in {module.__name__}")
    return bad


def test_the_architecture_page_names_only_what_exists() -> None:
    text = DOC.read_text()
    assert len(_SPAN.findall(text)) > 100
    assert missing_names(text, MODULES, ROOT) == []


def test_the_page_check_finds_a_missing_module_function_and_bare_name() -> None:
    text = (
        "The loop is `sim.simulate.run_world`; `kinematics.fk:fk` too.\n"
        "Gone: `sim.nowhere.build`, `kinematics.fk.no_such`, `control._kernel.control_step`.\n"
        "| 3.1 | J | `kinematics.jacobian.jacobian`, `point_jacobian`, `no_jacobian` |\n"
        "`Robot.fk` and `reachwise simulate` are not module paths: not checked.\n"
    )
    assert missing_names(text, MODULES, ROOT) == [
        "sim.nowhere.build: 'nowhere' not found",
        "kinematics.fk.no_such: 'no_such' not found",
        "control._kernel.control_step: '_kernel' not found",
        "no_jacobian: not in reachwise.kinematics.jacobian",
    ]


# ---- docs/architecture.md states every import-linter contract -----------------------

PYPROJECT = SRC.parent / "pyproject.toml"
_DIAGRAM = re.compile(r"```\n(.*?)```", re.S)


def unstated_contracts(text: str, contracts: list[dict[str, Any]], root: str) -> list[str]:
    """The import-linter ``contracts`` the page ``text`` does not state (module names
    without ``root.``): a ``layers`` contract is the page's first diagram, each layer
    starting a line of it, top to bottom; a ``forbidden`` one between packages is
    written ``source → a | b`` in backticks, one from modules names each module in
    backticks; an ``independence`` one is a sentence that says "independent" and names
    each package in backticks. Any other type is reported as not checked."""

    def short(module: str) -> str:
        return re.sub(rf"\b{re.escape(root)}\.", "", module.strip("()"))

    bad = []
    sentences = re.split(r"(?<=[.;])\s+|\n\s*\n|\n- ", text)
    diagram = _DIAGRAM.search(text)
    rows = diagram.group(1).splitlines() if diagram else []
    for c in contracts:
        if c["type"] == "layers":
            at = -1
            for layer in map(short, c["layers"]):
                starts = re.compile(
                    r"^(?:\s*top|\s*bottom)?\s+" + re.escape(layer) + r"(?:\s{2,}|$)"
                )
                found = [i for i, row in enumerate(rows) if starts.match(row)]
                if not found or found[0] <= at:
                    bad.append(f"{c['name']}: layer {layer!r} not in the diagram in order")
                else:
                    at = found[0]
        elif c["type"] == "forbidden":
            sources = [short(m) for m in c["source_modules"]]
            forbidden = [short(m) for m in c["forbidden_modules"]]
            if all("." not in m for m in sources):
                edges = [f"`{m} → {' | '.join(forbidden)}`" for m in sources]
                bad += [f"{c['name']}: {e} not stated" for e in edges if e not in text]
            else:
                named = [f"`{m}`" for m in sources + forbidden]
                bad += [f"{c['name']}: {n} not named" for n in named if n not in text]
        elif c["type"] == "independence":
            names = [f"`{short(m)}`" for m in c["modules"]]
            if not any("independent" in x and all(n in x for n in names) for x in sentences):
                bad.append(f"{c['name']}: no sentence says {', '.join(names)} are independent")
        else:
            bad.append(f"{c['name']}: contract type {c['type']!r} not checked")
    return bad


def test_the_architecture_page_states_every_contract() -> None:
    contracts = tomllib.loads(PYPROJECT.read_text())["tool"]["importlinter"]["contracts"]
    assert len(contracts) >= 9
    assert unstated_contracts(DOC.read_text(), contracts, ROOT) == []


_CONTRACTS: list[dict[str, Any]] = [
    {"name": "L", "type": "layers", "layers": ["(pkg.api)", "pkg.sim | pkg.io", "pkg.maths"]},
    {"name": "F", "type": "forbidden", "source_modules": ["pkg.sim"],
     "forbidden_modules": ["pkg.io", "pkg.api"]},
    {"name": "M", "type": "forbidden", "source_modules": ["pkg.sim.world", "pkg.sim.run"],
     "forbidden_modules": ["pkg.io"]},
    {"name": "I", "type": "independence", "modules": ["pkg.sim", "pkg.maths"]},
]  # fmt: skip


def test_the_contract_check_passes_a_page_that_states_them() -> None:
    page = (
        "```\n top   api        the facade\n       sim | io\nbottom maths\n```\n\n"
        "- `sim → io | api`: never; `sim.world` and `sim.run` import no `io`.\n"
        "- `sim` is independent\n  of `maths`.\n"
    )
    assert unstated_contracts(page, _CONTRACTS, "pkg") == []


def test_the_contract_check_finds_what_the_page_leaves_out() -> None:
    page = (
        "```\n top   sim | io     the middle\n       api\n       mathsy\n```\n"
        "`sim → io` is forbidden; `sim.world` imports no `io`.\n"
        "`sim` is independent of `io`; `maths` stands alone.\n"
    )
    contracts = [*_CONTRACTS, {"name": "A", "type": "acyclic_siblings"}]
    assert unstated_contracts(page, contracts, "pkg") == [
        "L: layer 'sim | io' not in the diagram in order",
        "L: layer 'maths' not in the diagram in order",
        "F: `sim → io | api` not stated",
        "M: `sim.run` not named",
        "I: no sentence says `sim`, `maths` are independent",
        "A: contract type 'acyclic_siblings' not checked",
    ]
