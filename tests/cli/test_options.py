"""Typed option groups (reachwise.cli._options): a command of frozen dataclass groups is
the typer command of their fields, in the given order, and receives the groups built
from the parsed values; malformed groups are refused when the command is made."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pytest
import typer
from typer.testing import CliRunner

from reachwise.cli._options import cli, typed_command


@dataclass(frozen=True)
class Motion:
    #: Speed (m/s).
    speed: float = cli(typer.Option(1.0, "--speed", help="Speed (m/s)."))
    #: Steps.
    steps: int = cli(typer.Option(3, "--steps", min=1, help="Steps."))


@dataclass(frozen=True)
class Where:
    #: Target name.
    target: str = cli(typer.Argument(..., help="Target."))
    #: Output folder.
    out: Path | None = cli(typer.Option(None, "--out", help="Output folder."))


def test_the_groups_arrive_built_from_the_command_line() -> None:
    got: list[tuple[Motion, Where]] = []

    @typed_command(order=("target", "steps", "out", "speed"))
    def command(motion: Motion, where: Where) -> None:
        got.append((motion, where))

    app = typer.Typer()
    app.command()(command)
    res = CliRunner().invoke(app, ["arm", "--speed", "0.5", "--out", "x"])
    assert res.exit_code == 0, res.output
    assert got == [(Motion(0.5, 3), Where("arm", Path("x")))]
    help_text = CliRunner().invoke(app, ["--help"], terminal_width=100).output
    order = [help_text.index(o) for o in ("--steps", "--out", "--speed")]
    assert order == sorted(order)  # the help lists the options in the order given
    assert CliRunner().invoke(app, ["arm", "--steps", "0"]).exit_code == 2  # min=1 kept


def test_a_context_is_passed_through() -> None:
    seen: list[bool] = []

    @typed_command()
    def command(ctx: typer.Context, motion: Motion) -> None:
        seen.append(hasattr(ctx, "invoked_subcommand") and motion.steps == 3)  # typer's context

    app = typer.Typer()
    app.command()(command)
    assert CliRunner().invoke(app, []).exit_code == 0
    assert seen == [True]


@dataclass(frozen=True)
class Plain:
    speed: float = 1.0


@dataclass(frozen=True)
class Clash:
    steps: int = cli(typer.Option(1, "--other-steps"))


def test_malformed_groups_are_refused() -> None:
    def not_a_group(x: int) -> None: ...

    def plain_field(p: Plain) -> None: ...

    def same_name(m: Motion, c: Clash) -> None: ...

    def order_missing(m: Motion) -> None: ...

    with pytest.raises(TypeError, match="not a dataclass group"):
        typed_command()(not_a_group)
    with pytest.raises(TypeError, match=r"Plain.speed: declare it with cli"):
        typed_command()(plain_field)
    with pytest.raises(TypeError, match="share a field name"):
        typed_command()(same_name)
    with pytest.raises(TypeError, match="order must name every field once"):
        typed_command(order=("speed",))(order_missing)
