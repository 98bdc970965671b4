"""No file is longer than 550 lines and no function longer than 90: one concept per
file (about 500 lines), one step per function (about 80), with some slack. Compiled
kernels are exempt when their docstring says why (numba would pass the state a longer
function keeps in registers through memory at every helper call): a jit-decorated
function whose docstring says so, a module of jit kernels whose module docstring says
so — the rule :mod:`tests.test_signatures` uses for long parameter lists. What still
waits for its split is listed by name, so the list can only shrink. The check is
tested on code that breaks it."""

from __future__ import annotations

import ast
from pathlib import Path

import reachwise
from tests.test_signatures import _compiled_with_reason

PACKAGE = Path(reachwise.__file__).parent
MAX_FILE_LINES = 550
MAX_FUNCTION_LINES = 90
#: Files and functions over the bounds not split yet (module path, or module path:
#: function): each an entry to remove once it is split; a stale entry fails the test.
#: Empty: every file and function is within the bounds or a documented kernel.
WAITING: set[str] = set()


def _lines(source: str) -> int:
    return source.count("\n") + (0 if source.endswith("\n") or not source else 1)


def _kernel_module(tree: ast.Module) -> bool:
    """A module of jit kernels whose docstring says they are compiled (numba)."""
    doc = (ast.get_docstring(tree) or "").lower()
    kernels = any(
        isinstance(n, ast.FunctionDef) and any("jit" in ast.unparse(d) for d in n.decorator_list)
        for n in ast.walk(tree)
    )
    return kernels and ("compiled" in doc or "numba" in doc)


def long_code(root: Path) -> dict[str, int]:
    """``module path`` or ``module path:function`` -> lines, for every file and function
    over the bounds that is not an exempt compiled kernel."""
    found = {}
    for f in sorted(root.rglob("*.py")):
        source = f.read_text()
        tree = ast.parse(source, str(f))
        name = f.relative_to(root).as_posix()
        if _lines(source) > MAX_FILE_LINES and not _kernel_module(tree):
            found[name] = _lines(source)
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                n = (node.end_lineno or node.lineno) - node.lineno + 1
                if n > MAX_FUNCTION_LINES and not _compiled_with_reason(node):
                    found[f"{name}:{node.name}"] = n
    return found


def test_no_file_or_function_is_too_long() -> None:
    found = long_code(PACKAGE)
    assert {k: v for k, v in found.items() if k not in WAITING} == {}
    assert sorted(WAITING - set(found)) == [], "done: remove from WAITING"


def _function(name: str, lines: int, decorator: str = "", doc: str = "") -> str:
    body = "".join(f"    x{i} = {i}\n" for i in range(lines - 1 - bool(doc)))
    head = f"{decorator}\n" if decorator else ""
    return f"{head}def {name}():\n{f'    {doc!r}{chr(10)}' if doc else ''}{body}"


def test_the_check_finds_long_code_and_exempts_documented_kernels(tmp_path: Path) -> None:
    functions = {
        "long": _function("long", 91),
        "at_bound": _function("at_bound", 90),
        "kernel": _function("kernel", 120, "@njit(cache=True)", "One compiled function."),
        "silent_kernel": _function("silent_kernel", 95, "@njit(cache=True)"),
        "said_not_jit": _function("said_not_jit", 95, doc="One compiled function."),
        "method": "class C:\n"
        + "".join(f"    {line}\n" for line in _function("method", 92).splitlines()),
    }
    for name, code in functions.items():
        (tmp_path / f"{name}.py").write_text(code)
    (tmp_path / "big.py").write_text('"""Plain module."""\n' + "x = 0\n" * 551)
    (tmp_path / "fits.py").write_text('"""Plain module."""\n' + "x = 0\n" * 549)
    (tmp_path / "kernels.py").write_text(
        '"""Numba kernels, compiled in one module."""\n'
        + _function("k", 3, "@njit(cache=True)", "Compiled.")
        + "x = 0\n" * 600
    )
    (tmp_path / "says_no_kernel.py").write_text('"""Compiled."""\n' + "x = 0\n" * 600)
    assert long_code(tmp_path) == {
        "long.py:long": 91,
        "silent_kernel.py:silent_kernel": 95,
        "said_not_jit.py:said_not_jit": 95,
        "method.py:method": 92,
        "big.py": 552,
        "says_no_kernel.py": 601,
    }
