"""Every typed input error raised under ``io/`` and ``cli/`` names where the input came
from: a file (a path or a robot's source file) wherever there is one; a command-line
option, a command, or an argument of a Python call only where no file is involved."""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

import pytest

import reachwise
import reachwise.errors as errors
from reachwise.errors import InputError
from reachwise.io.robot_clouds import link_cloud
from reachwise.io.robot_file import load_robot

PACKAGE = Path(reachwise.__file__).parent
TYPED = {
    name
    for name, obj in vars(errors).items()
    if inspect.isclass(obj) and issubclass(obj, InputError)
}
#: Literal sources that name no file, and why none exists there.
NO_FILE = {
    "replay": "arguments of reachwise.replay / ReplaySpec, given in Python",
    "transform tree": "a TransformTree built in memory from messages",
}


def _literal_sources(files: list[Path], root: Path = PACKAGE) -> list[tuple[str, int, str]]:
    """(file, line, source) of each ``raise <typed error>("literal", ...)``."""
    found = []
    for f in files:
        for node in ast.walk(ast.parse(f.read_text(), str(f))):
            if not (isinstance(node, ast.Raise) and isinstance(node.exc, ast.Call)):
                continue
            fn = node.exc.func
            name = fn.id if isinstance(fn, ast.Name) else getattr(fn, "attr", None)
            if name in TYPED and node.exc.args and isinstance(node.exc.args[0], ast.Constant):
                found.append((str(f.relative_to(root)), node.lineno, node.exc.args[0].value))
    return found


def _allowed(source: object) -> bool:
    text = str(source)
    return text.startswith(("--", "reachwise ")) or text in NO_FILE


def test_no_typed_error_under_io_or_cli_hides_its_file_behind_a_literal() -> None:
    files = sorted([*PACKAGE.glob("io/**/*.py"), *PACKAGE.glob("cli/*.py")])
    assert len(files) > 20
    bad = [s for s in _literal_sources(files) if not _allowed(s[2])]
    assert bad == []


def test_the_check_finds_a_literal_source(tmp_path: Path) -> None:
    code = tmp_path / "x.py"
    code.write_text(
        "def f(path):\n"
        "    raise CloudError('cloud', 'points', 'too many')\n"
        "    raise errors.TaskError('--points', '', 'needs --plans')\n"
        "    raise InputError(str(path), 'x', 'bad')\n"
    )
    found = _literal_sources([code], tmp_path)
    assert found == [("x.py", 2, "cloud"), ("x.py", 3, "--points")]
    assert [s for s in found if not _allowed(s[2])] == [("x.py", 2, "cloud")]


def test_a_link_cloud_error_names_the_robot_file(tmp_path: Path) -> None:
    path = tmp_path / "arm.yaml"
    path.write_text(
        "name: arm\njoints: [{type: revolute, a: 0.5, limits: [-1, 1]}]\n"
        "geometry: {link_1: {box: [0.1, 0.1, 0.1]}}\n"
    )
    robot = load_robot(str(path))
    with pytest.raises(InputError) as info:
        link_cloud(robot, "link_1", density=-1.0)
    assert info.value.source == str(path) and info.value.field == "density"
