"""Text input files read safely: one size bound, UTF-8 checked, YAML and JSON parsed with
their nesting bounded, every failure an :class:`~reachwise.errors.InputError` (or the
subclass the caller names) that names the file and, where there is one, the line.

A file larger than :data:`MAX_TEXT_BYTES` is refused before it is read whole; bytes
that are not UTF-8 name the line they are on; YAML or JSON nested deeper than
:data:`MAX_NESTING` levels (no reachwise file needs more than ten) is refused, as is
nesting deep enough to exhaust the parser's recursion, and a document that YAML
aliases expand beyond :data:`MAX_NODES` values.
"""

from __future__ import annotations

import json
import os
from typing import Any, Literal

import yaml

from reachwise.errors import InputError

__all__ = ["MAX_NESTING", "MAX_NODES", "MAX_TEXT_BYTES", "nesting_depth", "parse_text", "read_text"]

#: Largest text input file read (bytes); far beyond any robot, task or scenario file.
MAX_TEXT_BYTES = 64 * 1024 * 1024
#: Deepest nesting of mappings and lists accepted in a YAML or JSON file.
MAX_NESTING = 64
#: Most values (mappings, lists and scalars, YAML aliases expanded) in one document.
MAX_NODES = 1_000_000


def read_text(
    path: str | os.PathLike[str],
    source: str,
    error: type[InputError] = InputError,
    max_bytes: int = MAX_TEXT_BYTES,
) -> str:
    """The UTF-8 text of ``path`` (at most ``max_bytes``), or ``error`` naming ``source``."""
    try:
        with open(path, "rb") as fh:
            raw = fh.read(max_bytes + 1)
    except OSError as exc:
        raise error(source, "file", f"cannot read: {exc.strerror or exc}") from None
    if len(raw) > max_bytes:
        raise error(source, "file", f"larger than {max_bytes} bytes")
    return decode_text(raw, source, error)


def decode_text(raw: bytes, source: str, error: type[InputError] = InputError) -> str:
    """``raw`` decoded as UTF-8, or ``error`` naming the line of the first bad byte."""
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise error(
            source, f"line {line}", f"not UTF-8 text (byte 0x{raw[exc.start]:02x})"
        ) from None


def nesting_depth(data: Any, max_nodes: int | None = None) -> int:
    """How deeply mappings and lists nest in ``data`` (a scalar: 0), without recursion;
    ``-1`` once more than ``max_nodes`` values were visited (YAML aliases can make a
    small file a huge tree)."""
    deepest = 0
    stack = [(data, 1)]
    visited = 0
    while stack:
        value, depth = stack.pop()
        visited += 1
        if max_nodes is not None and visited > max_nodes:
            return -1
        if isinstance(value, dict):
            items: Any = value.values()
        elif isinstance(value, list | tuple):
            items = value
        else:
            continue
        deepest = max(deepest, depth)
        stack.extend((v, depth + 1) for v in items)
    return deepest


def parse_text(
    text: str, source: str, fmt: Literal["yaml", "json"], error: type[InputError] = InputError
) -> Any:
    """The YAML or JSON document ``text``; malformed or too deeply nested text is
    ``error`` naming ``source`` (and the line where the parser gives one)."""
    try:
        if fmt == "yaml":
            _check_yaml_depth(text, source, error)
        data = json.loads(text) if fmt == "json" else yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise error(source, where, f"not valid YAML: {problem}") from None
    except json.JSONDecodeError as exc:
        raise error(source, f"line {exc.lineno}", f"not valid JSON: {exc.msg}") from None
    except RecursionError:
        raise error(source, "", f"nested deeper than {MAX_NESTING} levels") from None
    depth = nesting_depth(data, MAX_NODES)
    if depth < 0:
        raise error(source, "", f"more than {MAX_NODES} values (aliases expanded)")
    if depth > MAX_NESTING:
        raise error(source, "", f"nested deeper than {MAX_NESTING} levels")
    return data


def _check_yaml_depth(text: str, source: str, error: type[InputError]) -> None:
    """Refuse YAML nested deeper than :data:`MAX_NESTING` from its event stream, before
    PyYAML's recursive composer builds it (which takes seconds to fail on deep input)."""
    depth = 0
    for event in yaml.parse(text, Loader=yaml.SafeLoader):
        if isinstance(event, yaml.MappingStartEvent | yaml.SequenceStartEvent):
            depth += 1
            if depth > MAX_NESTING:
                line = event.start_mark.line + 1 if event.start_mark is not None else 0
                raise error(source, f"line {line}", f"nested deeper than {MAX_NESTING} levels")
        elif isinstance(event, yaml.MappingEndEvent | yaml.SequenceEndEvent):
            depth -= 1
