"""``import reachwise``: light (the command line's start-up answers Ctrl-C before the
heavy modules load), and every public name of ``__all__`` resolves to its definition."""

from __future__ import annotations

import importlib
import os
import subprocess
import sys

import pytest

import reachwise


def test_import_loads_no_numeric_module() -> None:
    code = "import sys, reachwise; print([m for m in ('numpy', 'numba') if m in sys.modules])"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


@pytest.mark.parametrize("name", [n for n in reachwise.__all__ if n != "__version__"])
def test_public_name_is_its_definition(name: str) -> None:
    value = getattr(reachwise, name)
    assert value is getattr(importlib.import_module(value.__module__), name)
    assert name in dir(reachwise)


def test_unknown_name_is_an_attribute_error() -> None:
    with pytest.raises(AttributeError, match="no_such_name"):
        _ = reachwise.no_such_name
    assert reachwise.distance.closest_points is not None  # a subpackage, on first use
