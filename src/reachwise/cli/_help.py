"""How ``reachwise … --help`` reads: usage lines in click's plain form, no type label on
flags, lists of built-ins read from the data folder.

Typer labels every option with its Python type (``<bool>`` on ``--help`` itself and on
every on/off flag, where it says nothing the flag does not) and wraps required
arguments in braces on the usage line (``reachwise simulate [OPTIONS] {scenario}``).
:func:`plain_help` gives every command and group of an app the classes below, which
print ``reachwise simulate [OPTIONS] SCENARIO`` (an optional argument in brackets, a
repeated one followed by ``...``) and leave flags unlabelled; everything else is
typer's own rendering. Help texts are read as Markdown, so a docstring's line breaks
do not break the printed lines and its literal quotes are not printed.
"""

from __future__ import annotations

from typing import Any

import typer
from typer.core import TyperArgument, TyperCommand, TyperGroup, TyperOption

from reachwise.io._builtin import BuiltinKind, builtin_names

__all__ = ["HelpCommand", "HelpGroup", "builtins", "plain_help", "usage_pieces"]


def usage_pieces(command: TyperCommand | TyperGroup, ctx: Any) -> list[str]:
    """The usage line of ``command`` after its path: ``[OPTIONS]``, then each argument
    upper-cased (``SCENARIO``), in brackets when optional, ``...`` when repeated."""
    pieces = [command.options_metavar] if command.options_metavar else []
    for param in command.get_params(ctx):
        if isinstance(param, TyperArgument):
            name = (param.metavar or param.name or "").upper()
            piece = name if param.required else f"[{name}]"
            pieces.append(piece + ("..." if param.nargs != 1 else ""))
        else:
            pieces.extend(param.get_usage_pieces(ctx))
    return pieces


def _unlabelled_flags(params: list[Any]) -> list[Any]:
    """``params`` with every flag's type label dropped (an empty metavar), each
    argument's name shown upper-cased as on the usage line."""
    for param in params:
        if isinstance(param, TyperOption) and param.is_flag and param.metavar is None:
            param.metavar = ""
        elif isinstance(param, TyperArgument) and param.metavar is None and param.name:
            param.metavar = param.name.upper()
    return params


class HelpCommand(TyperCommand):
    """A typer command whose help has a plain usage line and unlabelled flags."""

    def get_params(self, ctx: Any) -> list[Any]:
        return _unlabelled_flags(super().get_params(ctx))

    def collect_usage_pieces(self, ctx: Any) -> list[str]:
        return usage_pieces(self, ctx)


class HelpGroup(TyperGroup):
    """A typer command group whose help has a plain usage line and unlabelled flags."""

    def get_params(self, ctx: Any) -> list[Any]:
        return _unlabelled_flags(super().get_params(ctx))

    def collect_usage_pieces(self, ctx: Any) -> list[str]:
        return [*usage_pieces(self, ctx), self.subcommand_metavar]


def plain_help(app: typer.Typer) -> typer.Typer:
    """Give ``app``, its sub-apps and every command registered on them with typer's default
    classes :class:`HelpGroup` and :class:`HelpCommand`, and read their help texts as
    Markdown (paragraphs re-flowed to the terminal, ``code`` shown without its quotes);
    returns ``app``."""
    if app.info.cls in (None, TyperGroup) or isinstance(
        app.info.cls, typer.models.DefaultPlaceholder
    ):
        app.info.cls = HelpGroup
    app.rich_markup_mode = "markdown"
    for info in app.registered_commands:
        if info.cls in (None, TyperCommand):
            info.cls = HelpCommand
    for group in app.registered_groups:
        if group.typer_instance is not None:
            plain_help(group.typer_instance)
    return app


def builtins(kind: BuiltinKind) -> str:
    """The built-in names of ``kind`` for a help text, read from the data folder:
    ``"hiab-xs033, p2-man1, …"``."""
    return ", ".join(builtin_names(kind))
