"""The errors reachwise raises on purpose: one root, one class per kind of failure.

A user who hands reachwise a broken robot file, task file or point cloud must learn
which file, which entry and what is wrong, never read a numpy traceback; a user who
lacks an optional package must learn what to install; a controller whose collision
server went silent must learn that it did, not that its input was bad.

- :class:`ReachwiseError` — the root; catch it to catch everything below.
- :class:`InputError` (also a ``ValueError``) — bad input: ``source`` (a file path or an
  argument name), ``field`` and ``reason``. :class:`RobotFileError`,
  :class:`TaskError` and :class:`CloudError` say which kind of input.
- :class:`UnknownName` (also a ``KeyError``) — a lookup of a name that does not exist;
  the message lists the valid names.
- :class:`MissingDependency` (also an ``ImportError``) — an optional package is not
  installed; the message says, in one format, what it is for and how to install it.
- :class:`ServerUnavailable` (also a ``TimeoutError``) — a service did not answer.

Each class carries the exit code the command line gives it (:attr:`~ReachwiseError.exit_code`): bad
input 2, missing dependency 3, unavailable service 4, anything else 1.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable
from typing import ClassVar, TypeVar

__all__ = [
    "CloudError",
    "InputError",
    "MissingDependency",
    "NameTaken",
    "ReachwiseError",
    "RobotFileError",
    "ServerUnavailable",
    "TaskError",
    "UnknownName",
    "check_choice",
]


class ReachwiseError(Exception):
    """Base class of every error reachwise raises on purpose."""

    #: Exit code of the ``reachwise`` command when this error ends it.
    exit_code: ClassVar[int] = 1


class InputError(ReachwiseError, ValueError):
    """Bad input: ``source`` (a file path or an argument name), ``field`` and ``reason``."""

    exit_code: ClassVar[int] = 2

    def __init__(self, source: str, field: str, reason: str) -> None:
        self.source = source
        self.field = field
        self.reason = reason
        where = f"{source}: {field}" if field else source
        super().__init__(f"{where}: {reason}")

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


class RobotFileError(InputError):
    """A robot file (YAML or URDF) or robot definition is invalid."""


class CloudError(InputError):
    """A point cloud or point-cloud file is invalid."""


class TaskError(InputError):
    """A task file or task definition is invalid."""


class NameTaken(InputError):
    """A name that must be new (a robot or object added to a scene) is taken already."""


#: How many valid names an :class:`UnknownName` message lists before it abbreviates.
_LISTED = 30


class UnknownName(InputError, KeyError):
    """A lookup of ``name`` among ``valid`` names failed; the message lists the valid ones
    and, when one is close (``difflib``), the name meant (``did you mean 'sb60'?``).

    ``kind`` says what was looked up (``"robot"``, ``"object"``, ``"strategy"``, …);
    ``field`` where the name was written (default: ``kind``). The closest valid name
    (:func:`difflib.get_close_matches`), if any is close, is offered. It is a
    ``KeyError`` too, so code that looks names up in a mapping keeps working.
    """

    def __init__(
        self, source: str, kind: str, name: str, valid: Iterable[str], *, field: str | None = None
    ) -> None:
        self.kind = kind
        self.name = name
        self.valid = tuple(sorted(str(v) for v in valid))
        shown = ", ".join(self.valid[:_LISTED])
        if len(self.valid) > _LISTED:
            shown += f", … ({len(self.valid) - _LISTED} more)"
        reason = (
            f"unknown {kind} {name!r}; valid: {shown}"
            if self.valid
            else (f"unknown {kind} {name!r}; there are none")
        )
        close = difflib.get_close_matches(str(name), self.valid, n=1, cutoff=0.6)
        #: The valid name ``name`` most likely misspells, or None.
        self.suggestion = close[0] if close else None
        if self.suggestion is not None:
            reason += f"; did you mean {self.suggestion!r}?"
        super().__init__(source, kind if field is None else field, reason)


_S = TypeVar("_S", bound=str)


def check_choice(value: object, valid: tuple[_S, ...], *, source: str, kind: str) -> _S:
    """``value`` as one of the ``valid`` names (the values of a ``Literal`` mode, e.g.
    ``typing.get_args(Strategy)``), or :class:`UnknownName` listing them."""
    for v in valid:
        if value == v:
            return v
    raise UnknownName(source, kind, str(value), valid)


class MissingDependency(ReachwiseError, ImportError):
    """An optional package is missing: ``purpose`` needs ``package``, from the ``extra``.

    The message always has the same form::

        the local-minimum escape needs the optional package 'ompl': pip install "reachwise[plan]"

    ``extra=""`` names a package that no extra brings (one reachwise installs only on
    some platforms, or one a broken environment lost): the hint installs the package
    itself, ``pip install "embreex"``.
    """

    exit_code: ClassVar[int] = 3

    def __init__(self, package: str, extra: str, purpose: str) -> None:
        self.package = package
        self.extra = extra
        self.purpose = purpose
        self.hint = f'pip install "reachwise[{extra}]"' if extra else f'pip install "{package}"'
        super().__init__(
            f"{purpose} needs the optional package {package!r}: {self.hint}", name=package
        )

    def __str__(self) -> str:
        return str(self.args[0])


class ServerUnavailable(ReachwiseError, TimeoutError):
    """A service (the collision server) did not answer within its deadline."""

    exit_code: ClassVar[int] = 4

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else "the server did not answer"
