"""Every ``reachwise … --help``: no type label on flags, a plain usage line, no reST
markup, and the built-ins it lists are the ones in the data folder."""

from __future__ import annotations

import re
from importlib import resources

import pytest
import typer
import typer.main
from typer.testing import CliRunner

from reachwise.cli import app
from reachwise.cli._help import plain_help

runner = CliRunner()
_WIDE = {"COLUMNS": "400"}  # so that no name is wrapped across lines


def _paths(command: object, path: tuple[str, ...] = ()) -> list[tuple[str, ...]]:
    """Every command path of the click tree below ``command``, groups included."""
    out = [path]
    for name, sub in sorted(getattr(command, "commands", {}).items()):
        out += _paths(sub, (*path, name))
    return out


ALL_PATHS = _paths(typer.main.get_command(app))


def _help(application: typer.Typer, path: tuple[str, ...]) -> str:
    res = runner.invoke(application, [*path, "--help"], env=_WIDE)
    assert res.exit_code == 0, res.output
    return res.output


def _problems(text: str) -> list[str]:
    """What a help text must not show: a ``<bool>`` label, braces on the usage line,
    reST double backticks."""
    found = []
    if "<bool>" in text:
        found.append("<bool>")
    usage = next(line for line in text.splitlines() if "Usage:" in line)
    if "{" in usage or "}" in usage:
        found.append(f"braces in {usage.strip()!r}")
    if "``" in text:
        found.append("``")
    return found


def _builtin(kind: str) -> list[str]:
    folder = resources.files("reachwise.data") / kind
    return sorted(
        f.name.removesuffix(".yaml") for f in folder.iterdir() if f.name.endswith(".yaml")
    )


def test_the_tree_holds_every_command() -> None:
    assert ("simulate",) in ALL_PATHS and ("robot", "pairs") in ALL_PATHS
    assert ("task", "generate", "tunnel") in ALL_PATHS and len(ALL_PATHS) > 20


def test_the_checker_sees_typer_defaults() -> None:
    """Without plain_help, typer's own help shows both faults the checker looks for."""
    raw = typer.Typer()

    @raw.command()
    def run(name: str, fast: bool = typer.Option(False, "--fast", help="Go.")) -> None:
        """Run ``it``."""

    assert set(_problems(_help(raw, ()))) == {
        "<bool>",
        "braces in 'Usage: run [OPTIONS] {name}'",
        "``",
    }


def test_plain_help_on_a_fresh_app() -> None:
    app2 = typer.Typer()

    @app2.command()
    def run(name: str, more: list[str] | None = typer.Argument(None), fast: bool = False) -> None:
        """Run ``it``."""

    text = _help(plain_help(app2), ())
    assert _problems(text) == []
    assert "Usage: run [OPTIONS] NAME [MORE]..." in text


@pytest.mark.parametrize("path", ALL_PATHS, ids=lambda p: " ".join(p) or "reachwise")
def test_help_is_plain(path: tuple[str, ...]) -> None:
    assert _problems(_help(app, path)) == []


def test_version_help_has_no_bool_label() -> None:
    text = _help(app, ())
    line = next(line for line in text.splitlines() if "--version" in line)
    assert "<" not in line and "Print the version." in line


def test_robot_pairs_help_prints_no_rest_markup() -> None:
    text = _help(app, ("robot", "pairs"))
    words = " ".join(text.split())  # the help wraps the description at any word
    assert "watch: [{self: {robot: NAME, pairs: auto}, margin: …}]" in words
    assert "``" not in text


@pytest.mark.parametrize(
    ("path", "kind"),
    [
        (("simulate",), "scenarios"),
        (("robot", "show"), "robots"),
        (("robot", "pairs"), "robots"),
        (("robot", "export"), "robots"),
        (("synth",), "tasks"),
        (("topology",), "tasks"),
        (("task", "show"), "tasks"),
    ],
)
def test_help_lists_every_builtin(path: tuple[str, ...], kind: str) -> None:
    names = _builtin(kind)
    assert len(names) >= 1
    text = re.sub(r"\s+", " ", _help(app, path))
    missing = [n for n in names if not re.search(rf"(?<![\w-]){re.escape(n)}(?![\w-])", text)]
    assert missing == []


def test_simulate_help_names_every_builtin_scenario() -> None:
    """The issue's case: the help named 3 of the 9 built-ins of the time; now the list
    is read from the data folder, whatever it holds."""
    names = _builtin("scenarios")
    assert len(names) >= 9
    text = re.sub(r"\s+", " ", _help(app, ("simulate",)))
    assert all(n in text for n in names)
