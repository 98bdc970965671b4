"""No function takes more than ten parameters: a longer list is a group of inputs that
wants a name and units (a frozen dataclass, as the CLI's option groups and the kernels'
typed inputs are). Compiled kernels are exempt when their docstring says why (numba
takes arrays and scalars, not objects). The functions still waiting for their groups
are listed by name, so the list can only shrink. The check is tested on code that
breaks it."""

from __future__ import annotations

import ast
from dataclasses import fields
from pathlib import Path

import pytest

import reachwise
from reachwise.sim.run_options import RunKeywords, RunOptions
from reachwise.tasks.task import PointArrayKeywords, PointArrays

PACKAGE = Path(reachwise.__file__).parent
MAX_PARAMETERS = 10
#: Functions over the bound not converted yet (module path: function): each an entry
#: to remove once it takes typed groups; a stale entry fails the test. Empty: every
#: function takes typed groups.
PENDING: set[str] = set()


def _parameters(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    a = fn.args
    names = [*a.posonlyargs, *a.args, *a.kwonlyargs]
    n = len(names) + (a.vararg is not None) + (a.kwarg is not None)
    return n - (1 if names and names[0].arg in ("self", "cls") else 0)


def _compiled_with_reason(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    """A numba kernel (``@njit``/``@jit``) whose docstring says why it takes a long
    list (it names its parameters as arrays or scalars for the compiler)."""
    jit = any("jit" in ast.unparse(d) for d in fn.decorator_list)
    doc = (ast.get_docstring(fn) or "").lower()
    return jit and ("compiled" in doc or "numba" in doc)


def long_signatures(root: Path) -> dict[str, int]:
    """``module path:function`` -> parameter count, for every function over the bound
    that is not an exempt compiled kernel."""
    found = {}
    for f in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(f.read_text(), str(f))):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                n = _parameters(node)
                if n > MAX_PARAMETERS and not _compiled_with_reason(node):
                    found[f"{f.relative_to(root).as_posix()}:{node.name}"] = n
    return found


def test_no_function_takes_more_than_ten_parameters() -> None:
    found = long_signatures(PACKAGE)
    assert sorted(set(found) - PENDING) == []
    assert sorted(PENDING - set(found)) == [], "done: remove from PENDING"


def test_the_check_finds_a_long_signature_and_exempts_a_documented_kernel(
    tmp_path: Path,
) -> None:
    params = ", ".join(f"p{i}" for i in range(11))
    (tmp_path / "m.py").write_text(
        f"def long({params}):\n    pass\n\n"
        f"def method(self, {', '.join(f'p{i}' for i in range(10))}):\n    pass\n\n"
        f"@njit(cache=True)\ndef kernel({params}):\n"
        '    """Compiled: numba takes the arrays one by one."""\n\n'
        f"@njit(cache=True)\ndef silent_kernel({params}):\n    pass\n\n"
        f"def starred(a, *args, b, **kw):\n    pass\n"
    )
    assert long_signatures(tmp_path) == {"m.py:long": 11, "m.py:silent_kernel": 11}


@pytest.mark.parametrize(
    ("group", "keywords"),
    [(RunOptions, RunKeywords), (PointArrays, PointArrayKeywords)],
)
def test_a_group_and_its_keywords_name_the_same_fields(group: type, keywords: type) -> None:
    """A typed group taken also as keywords (``options=`` or ``duration=``, …) lists
    the same fields in both, so a field added to one cannot be missing from the other."""
    assert list(keywords.__annotations__) == [f.name for f in fields(group)]
