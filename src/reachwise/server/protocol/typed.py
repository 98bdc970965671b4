"""Messages derived from type hints: the wire form of a registered scene operation's
arguments and result (:mod:`reachwise.distance.scene_ops`), so that a new query needs
no encoder, decoder, service method or client method of its own; and the bodies of the
protocol's own requests and replies, frozen dataclasses whose fields are encoded and
checked from their hints (:func:`encode_fields`, :func:`decode_fields`) unless the
message writes its own (the per-tick messages, whose speed matters).

:func:`encode_value` turns a value of a hinted type into plain msgpack data and
:func:`decode_value` checks received data against the hint, field by field, into a
typed :class:`~reachwise.server.protocol.fields.ProtocolError` naming the offending
path. The forms follow the rest of the protocol: a float64 array travels as
``[dtype, shape, bytes]``, a frozen dataclass as a map of its fields (strict: unknown
fields are errors; a None field that defaults to None is left out), tuples, lists and
other iterables as lists, ``dict[str, X]`` as a map; ``dict[str, Any]`` is a map of
plain data (:func:`~reachwise.server.protocol.fields.check_model`); a
:class:`~reachwise.kinematics.robot.Robot` travels as its YAML mapping
(:func:`~reachwise.io.robot_file.robot_to_dict`, read back and checked by
:func:`~reachwise.io.robot_file.robot_from_dict`); a class with its own
``wire()`` and ``parse(value, where)`` (a pair's compact list) travels in its own
form. ``Annotated[float, Bound(...)]`` (or ``int``) bounds a number. The hints are
finite, so decoding recurses at most as deep as the hint nests.

The request is ``call``
(:class:`~reachwise.server.protocol.requests.OperationCall`, body ``{"operation",
"arguments"}``) and its reply
:class:`~reachwise.server.protocol.replies.OperationResult` (body ``{"result"}``).
"""

from __future__ import annotations

import collections.abc
import dataclasses
import functools
import types
import typing
from dataclasses import dataclass
from typing import Annotated, Any, Literal, TypeVar

import numpy as np

# the scene's own operations and the scene memories' are registered by importing them
import reachwise.distance.scene_memories
import reachwise.distance.scene_queries  # noqa: F401
from reachwise.distance.scene_ops import OPERATIONS, ArrayShape, SceneOperation
from reachwise.distance.scene_types import RobotLike
from reachwise.errors import InputError
from reachwise.io.robot_file import robot_from_dict, robot_to_dict
from reachwise.kinematics.robot import Robot
from reachwise.server.protocol.fields import (
    FLOAT,
    MAX_LIST,
    ErrorCode,
    ProtocolError,
    Reader,
    check_array,
    check_bool,
    check_float,
    check_int,
    check_list,
    check_map,
    check_model,
    check_name,
    check_text,
    encode_array,
    safe_repr,
)

__all__ = [
    "Bound",
    "Count",
    "Name",
    "Stamp",
    "decode_fields",
    "decode_value",
    "encode_fields",
    "encode_value",
    "operation",
]

_T = TypeVar("_T")


@dataclass(frozen=True)
class Bound:
    """The check of a number field on the wire: ``finite`` (no inf) and ``minimum``."""

    finite: bool = True
    minimum: float | None = None


#: A name an object or robot is addressed by (:func:`~reachwise.server.protocol.fields.check_name`).
Name = Annotated[str, "name"]
#: A time stamp (s, the sender's clock): a finite number.
Stamp = Annotated[float, Bound()]
#: A count: an integer >= 0.
Count = Annotated[int, Bound(minimum=0)]

#: Most dimensions of an array an operation takes or gives.
MAX_ARRAY_DIMS = 4


#: Sequence hints the wire carries as a list (any iterable is sent; a tuple is received).
_SEQUENCES = (tuple, list, collections.abc.Iterable, collections.abc.Sequence)


def _is_array(hint: Any) -> bool:
    return typing.get_origin(hint) is np.ndarray or hint is np.ndarray


def _shaped(hint: Any) -> bool:
    """Whether ``hint`` carries an :class:`ArrayShape`: an array on the wire, whatever
    array-like (``ArrayLike``) the function takes."""
    return typing.get_origin(hint) is typing.Annotated and any(
        isinstance(m, ArrayShape) for m in hint.__metadata__
    )


def _strip(hint: Any) -> Any:
    """``hint`` without ``Annotated`` metadata."""
    while typing.get_origin(hint) is typing.Annotated:
        hint = typing.get_args(hint)[0]
    return hint


@functools.cache
def _field_hints(cls: Any) -> tuple[tuple[dataclasses.Field[Any], Any], ...]:
    """The fields of dataclass ``cls`` with their resolved hints."""
    hints = typing.get_type_hints(cls, include_extras=True)
    return tuple((f, hints[f.name]) for f in dataclasses.fields(cls))


def encode_fields(value: Any) -> dict[str, Any]:
    """The frozen dataclass ``value`` as a map of its encoded fields (a None field that
    defaults to None left out)."""
    return {
        f.name: encode_value(v, hint)
        for f, hint in _field_hints(typing.cast(Any, type(value)))
        if (v := getattr(value, f.name)) is not None or f.default is not None
    }


def decode_fields(cls: type[_T], r: Reader) -> _T:
    """An instance of the frozen dataclass ``cls`` from the fields ``r`` reads, each
    checked against its hint (a field with a default may be absent; the caller's
    ``r.done()`` refuses unknown fields)."""
    fields = {}
    for f, hint in _field_hints(typing.cast(Any, cls)):
        optional = f.default is not dataclasses.MISSING
        got = r.get(f.name, optional=optional)
        if not optional or f.name in r.body:
            fields[f.name] = decode_value(got, hint, r.path(f.name))
    return cls(**fields)


def encode_value(value: Any, hint: Any) -> Any:
    """``value`` (of type ``hint``) as plain msgpack data."""
    if value is not None and _shaped(hint):  # an array-like given as an array
        return encode_array(np.asarray(value, dtype=np.float64))
    hint = _strip(hint)
    origin = typing.get_origin(hint)
    if value is None or hint is Any:
        return value
    if hint is Robot or hint is RobotLike:
        if not isinstance(value, Robot):
            raise InputError(
                "robot", "", "a collision server needs a reachwise Robot (sent as its YAML mapping)"
            )
        return robot_to_dict(value)
    if hasattr(hint, "wire"):
        return value.wire()
    if _is_array(hint):
        return encode_array(np.asarray(value, dtype=np.float64))
    if origin in (typing.Union, types.UnionType):
        inner = [h for h in typing.get_args(hint) if h is not type(None)]
        if len(inner) != 1:
            raise TypeError(f"only unions with None travel, not {hint}")
        return encode_value(value, inner[0])
    if hint in (bool, int, str) or origin is Literal:
        return value
    if hint is float:  # anything else travels as it is: the receiver's check names it
        return float(value) if isinstance(value, int | float) and type(value) is not bool else value
    if origin in _SEQUENCES:
        args = typing.get_args(hint)
        if origin is tuple and not (len(args) == 2 and args[1] is Ellipsis):
            return [encode_value(v, h) for v, h in zip(value, args, strict=True)]
        return [encode_value(v, args[0]) for v in value]
    if origin is dict:
        return {str(k): encode_value(v, typing.get_args(hint)[1]) for k, v in value.items()}
    if dataclasses.is_dataclass(hint) and isinstance(hint, type):
        return encode_fields(value)
    raise TypeError(f"the wire carries no values of type {hint}")


def _decode_array(raw: Any, where: str) -> Any:
    if type(raw) is not list or len(raw) != 3 or type(raw[1]) is not list:
        raise ProtocolError(
            ErrorCode.WRONG_TYPE, where, "expected an array as [dtype, shape, bytes]"
        )
    dims = len(raw[1])
    if dims > MAX_ARRAY_DIMS:
        raise ProtocolError(
            ErrorCode.WRONG_SHAPE, where, f"at most {MAX_ARRAY_DIMS} dimensions, got {dims}"
        )
    return check_array(raw, where, shape=(None,) * dims, dtype=FLOAT, finite=False)


def decode_value(raw: Any, hint: Any, where: str) -> Any:
    """Check received ``raw`` against ``hint`` and build the value; a mismatch is a
    :class:`ProtocolError` naming ``where`` (or the path below it)."""
    if typing.get_origin(hint) is typing.Annotated:
        for m in hint.__metadata__:
            if isinstance(m, ArrayShape):
                return check_array(raw, where, shape=m.shape, finite=m.finite)
            if m == "name" and _strip(hint) is str:
                return check_name(raw, where)
            if isinstance(m, Bound) and _strip(hint) is float:
                return check_float(raw, where, finite=m.finite, minimum=m.minimum)
            if isinstance(m, Bound) and _strip(hint) is int:
                low = None if m.minimum is None else int(m.minimum)
                return check_int(raw, where, minimum=low)
    hint = _strip(hint)
    origin = typing.get_origin(hint)
    if hint is type(None) or hint is None:
        if raw is not None:
            raise ProtocolError(ErrorCode.WRONG_TYPE, where, f"expected nil, got {safe_repr(raw)}")
        return None
    if origin in (typing.Union, types.UnionType):
        if raw is None and type(None) in typing.get_args(hint):
            return None
        inner = [h for h in typing.get_args(hint) if h is not type(None)]
        return decode_value(raw, inner[0], where)
    if _is_array(hint):
        return _decode_array(raw, where)
    if hasattr(hint, "wire"):
        return hint.parse(raw, where)
    if hint is bool:
        return check_bool(raw, where)
    if hint is int:
        return check_int(raw, where)
    if hint is float:
        return check_float(raw, where, finite=False)
    if hint is str:
        return check_text(raw, where)
    if origin is Literal:
        valid = typing.get_args(hint)
        if raw not in valid or type(raw) is not type(valid[0]):
            raise ProtocolError(
                ErrorCode.INVALID, where, f"{safe_repr(raw)} is none of {list(valid)}"
            )
        return raw
    if origin in _SEQUENCES:
        items = check_list(raw, where, MAX_LIST)
        args = typing.get_args(hint)
        if origin is tuple and not (len(args) == 2 and args[1] is Ellipsis):
            if len(items) != len(args):
                raise ProtocolError(
                    ErrorCode.WRONG_SHAPE, where, f"expected {len(args)} entries, got {len(items)}"
                )
            return tuple(
                decode_value(v, h, f"{where}[{i}]")
                for i, (v, h) in enumerate(zip(items, args, strict=True))
            )
        out = [decode_value(v, args[0], f"{where}[{i}]") for i, v in enumerate(items)]
        return out if origin is list else tuple(out)
    if origin is dict and typing.get_args(hint)[1] is Any:
        return check_model(raw, where)
    if hint is Robot or hint is RobotLike:
        return _decode_robot(raw, where)
    if origin is dict:
        entries = check_map(raw, where)
        if len(entries) > MAX_LIST:
            raise ProtocolError(ErrorCode.WRONG_SHAPE, where, f"at most {MAX_LIST} entries")
        value_hint = typing.get_args(hint)[1]
        return {
            check_name(k, where): decode_value(v, value_hint, f"{where}.{k}")
            for k, v in entries.items()
        }
    if dataclasses.is_dataclass(hint) and isinstance(hint, type):
        r = Reader(raw, where)
        value: Any = decode_fields(typing.cast(Any, hint), r)
        r.done()
        return value
    raise ProtocolError(ErrorCode.INVALID, where, "the wire carries no values of this type")


def _decode_robot(raw: Any, where: str) -> Robot:
    """A robot sent as its YAML mapping; what the model gets wrong is ``invalid`` at
    the field below ``where`` that :func:`robot_from_dict` names."""
    try:
        robot = robot_from_dict(check_model(raw, where), "robot")
    except InputError as exc:
        field = f"{where}.{exc.field}" if exc.field else where
        raise ProtocolError(ErrorCode.INVALID, field, exc.reason) from None
    check_name(robot.name, f"{where}.name")  # addressable by every later request
    return robot


def operation(name: object, where: str) -> SceneOperation:
    """The registered operation ``name`` (:attr:`ErrorCode.UNKNOWN_OP` if none)."""
    op = OPERATIONS.get(name) if isinstance(name, str) else None
    if op is None:
        raise ProtocolError(
            ErrorCode.UNKNOWN_OP,
            where,
            f"no scene operation {safe_repr(name)}; operations: {sorted(OPERATIONS)[:20]}",
        )
    return op
