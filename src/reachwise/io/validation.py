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
from typing import Annotated, Any, Literal, Union, get_args, get_origin

from pydantic import BaseModel, ConfigDict, ValidationError, ValidationInfo, field_validator

from reachwise.errors import InputError

__all__ = ["StrictModel", "closest_key", "field_path", "input_error", "valid_keys"]


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


_NUMBERS = (float, int)


def _bool_in_number(annotation: Any, value: Any) -> str | None:
    """Where ``value`` holds a boolean that ``annotation`` means as a number (YAML's
    ``true`` would pass as 1): ``""`` for the value itself, ``"[2]"`` or ``"[key]"``
    inside it; ``None`` when there is none. Nested models check their own fields."""
    members = _members(annotation)
    if any(m is bool or m is Any for m in members):
        return None
    if isinstance(value, bool):
        numbers = any(
            m in _NUMBERS
            or (get_origin(m) is Literal and any(type(a) in _NUMBERS for a in get_args(m)))
            for m in members
        )
        return "" if numbers else None
    if isinstance(value, list | tuple):
        for m in members:
            origin, args = get_origin(m), get_args(m)
            if origin in (list, tuple, set, frozenset, Sequence) and args:
                for i, v in enumerate(value):
                    arg = args[-2] if args[-1] is Ellipsis else args[min(i, len(args) - 1)]
                    if origin is tuple and args[-1] is not Ellipsis and i >= len(args):
                        break
                    at = _bool_in_number(arg, v)
                    if at is not None:
                        return f"[{i}]{at}"
                return None
    if isinstance(value, dict):
        for m in members:
            if get_origin(m) in (dict, Mapping) and len(get_args(m)) == 2:
                for k, v in value.items():
                    at = _bool_in_number(get_args(m)[1], v)
                    if at is not None:
                        return f"[{k}]{at}"
                return None
    return None


class StrictModel(BaseModel):
    """Base of reachwise's file schemas: unknown keys, NaN/inf and booleans where a
    number is meant (``kv: true``, ``xyz: [true, 0, 0]``) are errors; the rest of
    pydantic's lax parsing (an integer for a float, a list for a tuple) stays."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    @field_validator("*", mode="before")
    @classmethod
    def _no_bool_as_number(cls, value: Any, info: ValidationInfo) -> Any:
        field = cls.model_fields.get(info.field_name or "")
        if field is not None:
            at = _bool_in_number(field.annotation, value)
            if at is not None:
                where = f" at {at}" if at else ""
                raise ValueError(f"a boolean is not a number{where}")
        return value
