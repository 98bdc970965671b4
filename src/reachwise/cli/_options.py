"""Typed option groups: a command takes a few frozen dataclasses instead of one
parameter per command-line option.

Each field of a group carries its typer option (:func:`cli`) and its unit in the
field's comment; :func:`typed_command` turns a function of groups into the typer
command whose options are the groups' fields, in order, so the command line and its
help are those of a flat signature while the code receives
``SolverOptions(...)``-like objects built once::

    @dataclass(frozen=True)
    class Output:
        out: Path = cli(typer.Option(..., "--out", help="Output folder."))

    @typed_command()
    def command(output: Output) -> None: ...
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable
from dataclasses import MISSING, field, fields, is_dataclass
from typing import Any, TypeVar, get_type_hints

import typer
from typer.models import ParameterInfo

__all__ = ["cli", "typed_command"]

R = TypeVar("R")


def cli(info: ParameterInfo) -> Any:
    """A group field that is the command-line option or argument ``info``
    (``typer.Option(...)`` / ``typer.Argument(...)``). The field has no default of its
    own: a group is built from every option's value."""
    return field(metadata={"cli": info})


def typed_command(
    order: tuple[str, ...] = (),
) -> Callable[[Callable[..., R]], Callable[..., R]]:
    """A decorator making the typer command of a function whose parameters are each a
    frozen dataclass group of :func:`cli` fields: the command's signature lists every
    field of every group (the options typer sees, in the groups' order, or in
    ``order`` where given: the command line's help order), and calling it builds each
    group from those values and calls the function with the groups. A parameter
    annotated :class:`typer.Context` is passed through as it is."""
    return functools.partial(_typed_command, order=order)


def _typed_command(func: Callable[..., R], order: tuple[str, ...]) -> Callable[..., R]:
    hints = get_type_hints(func)
    groups: list[tuple[str, type]] = []
    params: list[inspect.Parameter] = []
    annotations: dict[str, Any] = {}
    passed: list[str] = []  # a typer.Context parameter, passed as it is
    for name in inspect.signature(func).parameters:
        group = hints[name]
        if group is typer.Context:
            passed.append(name)
            kind = inspect.Parameter.POSITIONAL_OR_KEYWORD
            params.insert(len(passed) - 1, inspect.Parameter(name, kind))
            annotations[name] = group
            continue
        if not (is_dataclass(group) and isinstance(group, type)):
            raise TypeError(f"{func.__name__}: {name} is not a dataclass group")
        types = get_type_hints(group)
        for f in fields(group):
            if "cli" not in f.metadata or f.default is not MISSING:
                raise TypeError(f"{group.__name__}.{f.name}: declare it with cli(...)")
            kind = inspect.Parameter.POSITIONAL_OR_KEYWORD
            params.append(inspect.Parameter(f.name, kind, default=f.metadata["cli"]))
            annotations[f.name] = types[f.name]
        groups.append((name, group))
    if len(annotations) != len(params):
        raise TypeError(f"{func.__name__}: two groups share a field name")
    if order:
        if sorted(order) != sorted(set(annotations) - set(passed)):
            raise TypeError(f"{func.__name__}: order must name every field once")
        params[len(passed) :] = sorted(params[len(passed) :], key=lambda p: order.index(p.name))

    @functools.wraps(func)
    def command(**values: Any) -> R:
        built = {
            name: group(**{f.name: values[f.name] for f in fields(group)}) for name, group in groups
        }
        return func(**{name: values[name] for name in passed}, **built)

    command.__signature__ = inspect.Signature(  # type: ignore[attr-defined]
        [p.replace(annotation=annotations[p.name]) for p in params]
    )
    command.__annotations__ = annotations
    del command.__wrapped__  # type: ignore[attr-defined]  # typer must see the options
    return command
