"""Scene queries written once: a registry of typed operations on a distance scene.

A function that reads a :class:`~reachwise.distance.scene.Scene` — ``(scene, *args) ->
result`` with type hints on every argument and on the result — becomes a *scene
operation* with :func:`scene_operation`. Its name, typed arguments and typed result
are all the collision server needs: the wire messages of the call and of its answer are
derived from the hints (``reachwise.server.protocol.typed``), the server dispatches
the call to the same function on its own scene, and calling the function with a
remote scene (anything with a :meth:`RemoteOperations.run_operation`, such as
``reachwise.server.client.SceneClient``) carries the call over the wire. So a new
query is written once and works in process and through the server alike::

    @scene_operation
    def watched_count(scene: Scene, kind: PairKind) -> int:
        return sum(p.kind == kind for p in scene.pairs)

    watched_count(scene, "self")   # in process
    watched_count(client, "self")  # through the collision server

Operations registered with :func:`scene_operation` read the scene; they run under the
server's scene lock, between queries. Operations that *change* it — the pair rules
(:meth:`Scene.watch <reachwise.distance.scene.Scene.watch>` and its kin) — are
registered with :func:`scene_change`: the server runs them in order on its writer
thread, persists the scene before it replies and sends a new layout with the next
answer, and a client that mirrors the scene applies the same function to its copy.
A method of :class:`~reachwise.distance.scene.Scene` can be registered as it is
(``self`` is the scene), so the remote scene takes it over by assignment.
An operation too slow to hold the lock (fusing a depth frame) is registered with
:func:`staged_operation`: its expensive stage runs without the lock and only a cheap
hand-over under it; a mirroring client applies it to its copy too (it hands a
result over into the scene, as a streamed cloud does), but the server neither
persists nor re-sends its layout for it.

Argument and result types the wire carries: ``bool``, ``int``, ``float``, ``str``,
``None``, ``Literal`` names, float64 arrays (``NDArray[np.float64]``, their shape
given by :class:`ArrayShape`), ``tuple``, ``list``, ``Iterable`` and ``Sequence``
(sent as lists), ``dict`` with string keys, unions with ``None`` and frozen
dataclasses of those.
"""

from __future__ import annotations

import functools
import inspect
import typing
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Concatenate, ParamSpec, Protocol, TypeVar, runtime_checkable

from reachwise.errors import InputError

__all__ = [
    "OPERATIONS",
    "Argument",
    "ArrayShape",
    "RemoteOperations",
    "SceneOperation",
    "scene_change",
    "scene_operation",
    "staged_operation",
]

_P = ParamSpec("_P")
_R = TypeVar("_R")
_S = TypeVar("_S")
_T = TypeVar("_T")


@runtime_checkable
class RemoteOperations(Protocol):
    """A scene held elsewhere that runs registered operations by name."""

    def run_operation(self, name: str, arguments: dict[str, Any]) -> Any: ...


@dataclass(frozen=True)
class ArrayShape:
    """What an array argument or result must be on the wire, given as
    ``Annotated[NDArray[np.float64], ArrayShape((4, 4))]`` (or ``Annotated[ArrayLike,
    ...]`` for an argument that takes any array-like): its ``shape`` (None: any
    length) and whether every value must be ``finite``. An array hint without it takes
    any shape of up to four dimensions, NaN and inf included."""

    shape: tuple[int | None, ...]
    finite: bool = True


@dataclass(frozen=True)
class Argument:
    """One argument of an operation: its ``name``, type ``hint``, whether it has a
    ``default`` (then ``default`` holds it) and whether it is ``keyword_only``."""

    name: str
    hint: Any
    has_default: bool = False
    default: Any = None
    keyword_only: bool = False


@dataclass(frozen=True)
class SceneOperation:
    """A registered scene operation: wire ``name``, the ``function`` that answers it on
    a scene, its typed ``arguments`` (after the scene), ``result`` type and whether it
    ``mutates`` the scene. With a ``hand_over`` (:func:`staged_operation`) the
    ``function`` is the operation's first stage, run without the server's scene lock,
    and ``hand_over(scene, prepared)`` its second, run under it; the answer is the
    second's."""

    name: str
    function: Callable[..., Any]
    arguments: tuple[Argument, ...]
    result: Any
    mutates: bool = False
    hand_over: Callable[[Any, Any], Any] | None = None

    def bind(self, args: tuple[Any, ...], kwargs: dict[str, Any]) -> dict[str, Any]:
        """The call's arguments by name (defaults left out); a wrong call is an
        :class:`~reachwise.errors.InputError`."""
        names = [a.name for a in self.arguments]
        positional = [a.name for a in self.arguments if not a.keyword_only]
        if len(args) > len(positional):
            raise InputError(
                self.name,
                "arguments",
                f"takes {len(positional)} positional arguments, got {len(args)}",
            )
        out = dict(zip(positional, args, strict=False))
        for key, value in kwargs.items():
            if key not in names:
                raise InputError(self.name, key, f"unknown argument; arguments: {names}")
            if key in out:
                raise InputError(self.name, key, "given twice")
            out[key] = value
        for a in self.arguments:
            if a.name not in out and not a.has_default:
                raise InputError(self.name, a.name, "required argument is missing")
        return out


#: Every registered operation by name.
OPERATIONS: dict[str, SceneOperation] = {}


def _describe(
    function: Callable[..., Any],
    name: str,
    mutates: bool,
    hand_over: Callable[[Any, Any], Any] | None = None,
) -> SceneOperation:
    hints = typing.get_type_hints(function, include_extras=True)
    params = list(inspect.signature(function).parameters.values())
    if not params:
        raise TypeError(f"scene operation {name!r} must take the scene as its first argument")
    arguments = []
    for p in params[1:]:
        if p.kind not in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY):
            raise TypeError(f"scene operation {name!r}: argument {p.name!r} must be named")
        if p.name not in hints:
            raise TypeError(f"scene operation {name!r}: argument {p.name!r} has no type hint")
        has_default = p.default is not inspect.Parameter.empty
        arguments.append(
            Argument(p.name, hints[p.name], has_default, p.default, p.kind == p.KEYWORD_ONLY)
        )
    if hand_over is not None:
        hints = typing.get_type_hints(hand_over, include_extras=True)
    if "return" not in hints:
        raise TypeError(f"scene operation {name!r} has no result type hint")
    return SceneOperation(name, function, tuple(arguments), hints["return"], mutates, hand_over)


def scene_operation(
    function: Callable[Concatenate[_S, _P], _R],
) -> Callable[Concatenate[_S | RemoteOperations, _P], _R]:
    """Register ``function`` (``(scene, *args) -> result``, fully type-hinted) as the
    scene operation of its name, one that reads the scene, and return it, extended:
    called with a remote scene (:class:`RemoteOperations`) it runs on that scene's
    server instead."""
    return _register(function, mutates=False)


def scene_change(
    function: Callable[Concatenate[_S, _P], _R],
) -> Callable[Concatenate[_S | RemoteOperations, _P], _R]:
    """Register ``function`` as :func:`scene_operation` does, as an operation that
    changes the scene (see the module docstring for what the server and a mirroring
    client do with it)."""
    return _register(function, mutates=True)


def staged_operation(
    hand_over: Callable[[_S, _T], _R],
) -> Callable[
    [Callable[Concatenate[_S, _P], _T]], Callable[Concatenate[_S | RemoteOperations, _P], _R]
]:
    """Register the decorated function ``prepare`` (``(scene, *args) -> prepared``,
    type-hinted arguments) and ``hand_over`` (``(scene, prepared) -> result``,
    type-hinted result) as one reading scene operation of ``prepare``'s name, in two
    stages: the server runs ``prepare`` without its scene lock — the expensive part,
    which must not read or change the scene's own state (it may look up and guard
    state of its own) — and only ``hand_over`` under the lock, between queries, so a
    slow operation never holds up the answers. In process the call is
    ``hand_over(scene, prepare(scene, *args))``; with a remote scene it runs on that
    scene's server, as :func:`scene_operation` does."""

    def register(
        prepare: Callable[Concatenate[_S, _P], _T],
    ) -> Callable[Concatenate[_S | RemoteOperations, _P], _R]:
        call = _register(prepare, mutates=False, hand_over=hand_over)
        call.__annotations__ = {
            **prepare.__annotations__,
            "return": hand_over.__annotations__.get("return"),
        }
        return call  # type: ignore[return-value]

    return register


def _register(
    function: Callable[Concatenate[_S, _P], Any],
    mutates: bool,
    hand_over: Callable[[_S, Any], _R] | None = None,
) -> Callable[Concatenate[_S | RemoteOperations, _P], _R]:
    name = function.__name__
    if name in OPERATIONS and OPERATIONS[name].function is not function:
        raise ValueError(f"a scene operation named {name!r} is registered already")
    op = _describe(function, name, mutates, hand_over)

    @functools.wraps(function)
    def call(scene: _S | RemoteOperations, /, *args: _P.args, **kwargs: _P.kwargs) -> _R:
        if isinstance(scene, RemoteOperations):
            result: _R = scene.run_operation(name, op.bind(tuple(args), dict(kwargs)))
            return result
        if hand_over is not None:
            return hand_over(scene, function(scene, *args, **kwargs))
        out: _R = function(scene, *args, **kwargs)
        return out

    OPERATIONS[name] = op
    return call
