"""One translation of a pydantic ``ValidationError`` into reachwise's bad-input error.

Every file schema of reachwise (robot, task, scenario, server state) is a pydantic model.
When a file does not fit, the user gets one :class:`~reachwise.errors.InputError` (or
the subclass the caller names) with the file, the field as written in the file
(``joints[2].limits``, ``points[0].xyz``) and the reason — never pydantic's report.

- An unknown key is reported before the other errors: a misspelt key is usually why a
  required one is "missing". Given the model, it names the closest valid key
  (``did you mean 'margin'?``, :mod:`difflib`).
- pydantic's internal location tags (validator and union-member names such as
  ``function-after[...]`` or ``tuple[float, float]``) are dropped from the field.
- A tuple given too few values names the tuple and how many values it takes.
- Every other problem of the file follows on the same line
  (``; 1 more problem: watch[0].margin: Field required``): nothing is hidden behind a
  count.
"""

from __future__ import annotations

import difflib
import types
from collections.abc import Mapping, Sequence
from typing import Annotated, Any, Union, get_args, get_origin

from pydantic import BaseModel, ValidationError

from reachwise.errors import InputError

__all__ = ["closest_key", "field_path", "input_error", "valid_keys"]


def field_path(loc: tuple[Any, ...]) -> str:
    """A pydantic location as written in a file: ``("joints", 2, "limits")`` →
    ``joints[2].limits``."""
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out


def _is_tag(part: object) -> bool:
    """pydantic's own location entries (validator or union-member names)."""
    return isinstance(part, str) and (part.startswith("function-") or "[" in part)


def _members(annotation: Any) -> list[Any]:
    """The types a value of ``annotation`` may have: unions and ``Optional`` opened,
    ``Annotated`` metadata dropped."""
    origin = get_origin(annotation)
    if origin is Annotated:
        return _members(get_args(annotation)[0])
    if origin is Union or origin is types.UnionType:
        return [m for arg in get_args(annotation) for m in _members(arg)]
    return [annotation]


def _is_model(t: Any) -> bool:
    return isinstance(t, type) and issubclass(t, BaseModel)


def _field(model: type[BaseModel], key: str) -> Any:
    for name, info in model.model_fields.items():
        if key in (name, info.alias, info.validation_alias):
            return info.annotation
    return None


def _step(types_: list[Any], part: Any) -> list[Any]:
    """The types at location entry ``part`` inside values of ``types_``."""
    out: list[Any] = []
    for t in types_:
        origin, args = get_origin(t), get_args(t)
        if _is_model(t) and isinstance(part, str):
            if part == t.__name__:  # a union member's tag: the member itself
                out.append(t)
            elif (annotation := _field(t, part)) is not None:
                out += _members(annotation)
        elif isinstance(part, int) and origin in (list, tuple, set, frozenset, Sequence):
            if origin is tuple and args and args[-1] is not Ellipsis:
                out += _members(args[part]) if part < len(args) else []
            elif args:
                out += _members(args[0])
        elif isinstance(part, str) and origin in (dict, Mapping) and len(args) == 2:
            out += _members(args[1])
    return out


def valid_keys(model: type[BaseModel], loc: Sequence[Any]) -> list[str]:
    """The keys a mapping at ``loc`` (a pydantic location, tags included) may hold:
    the field names and aliases of every model a value there may be; empty when the
    location does not lead to a model."""
    at: list[Any] = [model]
    for part in loc:
        if isinstance(part, str) and part.startswith("function-"):
            continue  # a validator's tag: the type stays
        step = _step(at, part)
        # a discriminated union's tag (``depth`` of ``kind: depth``) names no field:
        # the keys of all its members stay candidates
        at = step if step or not all(_is_model(t) for t in at) else at
    keys: list[str] = []
    for t in at:
        if _is_model(t):
            for name, info in t.model_fields.items():
                keys += [k for k in (name, info.alias) if isinstance(k, str) and k not in keys]
    return keys


def closest_key(key: str, valid: Sequence[str]) -> str | None:
    """The valid key ``key`` most likely misspells (:func:`difflib.get_close_matches`),
    or ``None`` when none is close."""
    found = difflib.get_close_matches(key, list(valid), n=1, cutoff=0.6)
    return found[0] if found else None


def _problem(
    err: Mapping[str, Any], model: type[BaseModel] | None, lengths: Mapping[str, int]
) -> tuple[str, str]:
    """One pydantic error as (field as written in the file, reason)."""
    loc = tuple(p for p in err["loc"] if not _is_tag(p))
    msg = str(err["msg"]).removeprefix("Value error, ")
    if err["type"] == "missing" and len(loc) > 1 and isinstance(loc[-1], int):
        n = lengths.get(str(loc[-2]))
        loc, msg = loc[:-1], f"expected {n} values" if n else "too few values"
    if err["type"] == "extra_forbidden" and model is not None and err["loc"]:
        *parent, key = err["loc"]
        near = closest_key(str(key), valid_keys(model, parent))
        if near is not None:
            msg += f" (did you mean '{near}'?)"
    return field_path(loc), msg


def input_error(
    exc: ValidationError,
    source: str,
    error: type[InputError] = InputError,
    lengths: Mapping[str, int] | None = None,
    model: type[BaseModel] | None = None,
) -> InputError:
    """The ``error`` (an :class:`InputError` class) for ``exc`` raised while validating
    ``source``: field and reason of its first error (unknown keys first), followed by
    every other error (module docstring). ``lengths`` gives the number of values of
    fixed-length tuple fields by name, for the message of a tuple given too few values;
    ``model``, the model validated, lets an unknown key name the closest valid one."""
    errors = sorted(exc.errors(), key=lambda e: e["type"] != "extra_forbidden")
    problems = [_problem(e, model, lengths or {}) for e in errors]
    field, reason = problems[0]
    if len(problems) > 1:
        rest = "; ".join(f"{f}: {r}" if f else r for f, r in problems[1:])
        n = len(problems) - 1
        reason += f"; {n} more problem{'s' if n > 1 else ''}: {rest}"
    return error(source, field, reason)
