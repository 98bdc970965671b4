"""A small, safe XML reader for robot descriptions: elements with their line numbers.

URDF and ``package.xml`` files are read with the standard library's expat parser,
configured so that a file can never make it read anything else or grow without bound:

- any ``<!ENTITY …>`` declaration (internal or external, general or parameter) is an
  error, so neither entity expansion ("billion laughs") nor external entities
  (``SYSTEM "file:///…"``) can happen; a URDF has no use for entities;
- external DTDs and parameter entities are never read
  (``XML_PARAM_ENTITY_PARSING_NEVER``);
- files larger than :data:`MAX_BYTES` are refused before parsing.

Each element keeps its tag, attributes, children, the line it starts on and whether a
given marker comment sits directly inside it (reachwise marks passive joints with
``<!-- reachwise: passive -->``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from xml.parsers import expat

from reachwise.errors import InputError

__all__ = ["MAX_BYTES", "XmlElement", "parse_xml", "read_xml"]

#: Largest XML file read (bytes): far above any robot description (a 1000-joint chain
#: is about 0.5 MB).
MAX_BYTES = 64 * 1024 * 1024


@dataclass(eq=False)
class XmlElement:
    """One element: ``tag``, ``attrib``, ``children`` (elements only), the ``line`` it
    starts on (1-based), the comments directly inside it and its own text."""

    tag: str
    attrib: dict[str, str]
    line: int
    children: list[XmlElement] = field(default_factory=list)
    comments: list[str] = field(default_factory=list)
    text: str = ""

    def get(self, name: str, default: str | None = None) -> str | None:
        return self.attrib.get(name, default)

    def findall(self, tag: str) -> list[XmlElement]:
        return [c for c in self.children if c.tag == tag]


class _Refused(Exception):
    pass


def parse_xml(data: bytes, source: str, kind: type[InputError] = InputError) -> XmlElement:
    """The root element of the XML document ``data``; raises ``kind`` (an
    :class:`InputError` class) naming ``source`` when it is not well-formed XML or
    declares entities."""
    error = kind
    if len(data) > MAX_BYTES:
        raise error(source, "", f"{len(data)} bytes is more than the {MAX_BYTES} read at most")
    if not data.strip():
        raise error(source, "", "the file is empty")
    parser = expat.ParserCreate()
    parser.SetParamEntityParsing(expat.XML_PARAM_ENTITY_PARSING_NEVER)
    stack: list[XmlElement] = []
    root: list[XmlElement] = []

    def refuse_entity(name: str, *_: object) -> None:
        raise _Refused(f"line {parser.CurrentLineNumber}: entity declaration {name!r} refused")

    def external(*_: object) -> int:
        raise _Refused(f"line {parser.CurrentLineNumber}: external entity reference refused")

    def start(tag: str, attrib: dict[str, str]) -> None:
        el = XmlElement(tag, dict(attrib), parser.CurrentLineNumber)
        if stack:
            stack[-1].children.append(el)
        else:
            root.append(el)
        stack.append(el)

    def end(tag: str) -> None:
        stack.pop()

    def comment(text: str) -> None:
        if stack:
            stack[-1].comments.append(text)

    def chars(text: str) -> None:
        if stack and len(stack[-1].text) < 4096:
            stack[-1].text += text

    parser.EntityDeclHandler = refuse_entity
    parser.UnparsedEntityDeclHandler = refuse_entity
    parser.ExternalEntityRefHandler = external
    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CommentHandler = comment
    parser.CharacterDataHandler = chars
    try:
        parser.Parse(data, True)
    except _Refused as exc:
        raise error(
            source, "", f"not accepted: {exc} (entities are not allowed in a robot description)"
        ) from None
    except expat.ExpatError as exc:
        reason = expat.errors.messages.get(exc.code, str(exc))
        raise error(
            source, "", f"not valid XML: {reason} at line {exc.lineno}, column {exc.offset}"
        ) from None
    except RecursionError:
        raise error(source, "", "not accepted: elements nested too deeply") from None
    if not root:
        raise error(source, "", "no XML element in the file")
    return root[0]


def read_xml(path: Path, source: str, kind: type[InputError] = InputError) -> XmlElement:
    """:func:`parse_xml` of the file ``path`` (refused before reading when too large)."""
    try:
        size = path.stat().st_size
        if size > MAX_BYTES:
            raise kind(source, "", f"{size} bytes is more than the {MAX_BYTES} read at most")
        data = path.read_bytes()
    except OSError as exc:
        raise kind(source, "", f"cannot read: {exc.strerror or exc}") from None
    return parse_xml(data, source, kind)
