"""Messages derived from type hints: the wire form of a registered scene operation's
arguments and result (:mod:`reachwise.distance.scene_ops`), so that a new query needs
no encoder, decoder, service method or client method of its own.

:func:`encode_value` turns a value of a hinted type into plain msgpack data and
:func:`decode_value` checks received data against the hint, field by field, into a
typed :class:`~reachwise.server.protocol.fields.ProtocolError` naming the offending
path. The forms follow the rest of the protocol: a float64 array travels as
``[dtype, shape, bytes]``, a frozen dataclass as a map of its fields (strict: unknown
fields are errors), tuples, lists and other iterables as lists, ``dict[str, X]`` as a map. The hints
are finite, so decoding recurses at most as deep as the hint nests.

The request is ``call``
(:class:`~reachwise.server.protocol.requests.OperationCall`, body ``{"operation",
"arguments"}``) and its reply
:class:`~reachwise.server.protocol.replies.OperationResult` (body ``{"result"}``).
"""

from __future__ import annotations

import collections.abc
import dataclasses
import types
import typing
from typing import Any, Literal

import numpy as np

import reachwise.distance.scene_queries  # noqa: F401  (registers the scene's own operations)
from reachwise.distance.scene_ops import OPERATIONS, ArrayShape, SceneOperation
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
    check_name,
    check_text,
    encode_array,
    safe_repr,
)

__all__ = ["decode_value", "encode_value", "operation"]

#: Most dimensions of an array an operation takes or gives.
MAX_ARRAY_DIMS = 4


#: Sequence hints the wire carries as a list (any iterable is sent; a tuple is received).
_SEQUENCES = (tuple, list, collections.abc.Iterable, collections.abc.Sequence)


def _is_array(hint: Any) -> bool:
    return typing.get_origin(hint) is np.ndarray or hint is np.ndarray


def _strip(hint: Any) -> Any:
    """``hint`` without ``Annotated`` metadata."""
    while typing.get_origin(hint) is typing.Annotated:
        hint = typing.get_args(hint)[0]
    return hint


def encode_value(value: Any, hint: Any) -> Any:
    """``value`` (of type ``hint``) as plain msgpack data."""
    hint = _strip(hint)
    origin = typing.get_origin(hint)
    if value is None:
        return None
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
        hints = typing.get_type_hints(hint, include_extras=True)
        return {
            f.name: encode_value(getattr(value, f.name), hints[f.name])
            for f in dataclasses.fields(hint)
        }
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
        shapes = [m for m in hint.__metadata__ if isinstance(m, ArrayShape)]
        if shapes and _is_array(_strip(hint)):
            return check_array(raw, where, shape=shapes[0].shape, finite=shapes[0].finite)
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
        hints = typing.get_type_hints(hint, include_extras=True)
        fields = {}
        for f in dataclasses.fields(hint):
            optional = f.default is not dataclasses.MISSING
            got = r.get(f.name, optional=optional)
            fields[f.name] = (
                f.default
                if optional and f.name not in r.body
                else decode_value(got, hints[f.name], r.path(f.name))
            )
        r.done()
        return hint(**fields)
    raise ProtocolError(ErrorCode.INVALID, where, "the wire carries no values of this type")


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
