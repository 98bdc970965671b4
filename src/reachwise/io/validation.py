"""One translation of a pydantic ``ValidationError`` into reachwise's bad-input error.

Every file schema of reachwise (robot, task, scenario, server state) is a pydantic model.
When a file does not fit, the user gets one :class:`~reachwise.errors.InputError` (or
the subclass the caller names) with the file, the field as written in the file
(``joints[2].limits``, ``points[0].xyz``) and the reason — never pydantic's report.

- An unknown key is reported before the other errors: a misspelt key is usually why a
  required one is "missing".
- pydantic's internal location tags (validator and union-member names such as
  ``function-after[...]`` or ``tuple[float, float]``) are dropped from the field.
- A tuple given too few values names the tuple and how many values it takes.
- ``(and N more)`` says how many other errors the file has.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from pydantic import ValidationError

from reachwise.errors import InputError

__all__ = ["field_path", "input_error"]


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


def input_error(
    exc: ValidationError,
    source: str,
    error: type[InputError] = InputError,
    lengths: Mapping[str, int] | None = None,
) -> InputError:
    """The ``error`` (an :class:`InputError` class) for ``exc`` raised while validating
    ``source``: its first error (unknown keys first), field and reason (module
    docstring). ``lengths`` gives the number of values of fixed-length tuple fields by
    name, for the message of a tuple given too few values."""
    errors = sorted(exc.errors(), key=lambda e: e["type"] != "extra_forbidden")
    err = errors[0]
    loc = tuple(p for p in err["loc"] if not _is_tag(p))
    msg = str(err["msg"]).removeprefix("Value error, ")
    if err["type"] == "missing" and len(loc) > 1 and isinstance(loc[-1], int):
        n = (lengths or {}).get(str(loc[-2]))
        loc, msg = loc[:-1], f"expected {n} values" if n else "too few values"
    more = f" (and {len(errors) - 1} more)" if len(errors) > 1 else ""
    return error(source, field_path(loc), msg + more)
