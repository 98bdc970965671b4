"""Reading a URDF element's attributes and children for :mod:`reachwise.io.urdf_model`:
numbers, one child of a kind, an origin, each mistake a
:class:`~reachwise.errors.RobotFileError` naming the file, the element (with the
offending attribute) and its line (:class:`XmlErrors`)."""

from __future__ import annotations

import math
import re

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import RobotFileError
from reachwise.io.xml_tree import XmlElement
from reachwise.kinematics.transforms import pose_from_xyz_rpy

__all__ = [
    "XmlErrors",
    "attr_numbers",
    "attr_required",
    "attr_scalar",
    "decimal_number",
    "one_child",
    "optional_child",
    "origin_pose",
]

_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")
_NONFINITE = re.compile(r"^[+-]?(nan|inf|infinity)$", re.IGNORECASE)

Mat = NDArray[np.float64]


class XmlErrors:
    """Raises RobotFileError(source, '<what> <tag attr="value"> (line n)', reason)."""

    def __init__(self, source: str) -> None:
        self.source = source

    def __call__(
        self, what: str, el: XmlElement | None, reason: str, attr: str | None = None
    ) -> RobotFileError:
        field = what
        if el is not None:
            shown = f' {attr}="{el.get(attr)}"' if attr is not None and attr in el.attrib else ""
            tag = f"<{el.tag}{shown}>"
            if what.split(" ", 1)[0] == el.tag and not shown:  # the joint/link itself
                tag = ""
            field = " ".join(x for x in (what, tag) if x)
            field += f" (line {el.line})"
        return RobotFileError(self.source, field, reason)


def decimal_number(text: str) -> float | None:
    """``text`` as a decimal number (``nan`` and ``inf`` read too), else ``None``."""
    t = text.strip()
    if _NUMBER.match(t) or _NONFINITE.match(t):
        return float(t)
    return None


def attr_numbers(
    err: XmlErrors,
    what: str,
    el: XmlElement,
    attr: str,
    count: tuple[int, ...],
    default: str | None,
) -> list[float]:
    """The finite numbers of attribute ``attr`` (``default`` when absent; ``None``: it
    is required), as many as one of ``count``."""
    raw = el.get(attr, default)
    if raw is None:
        raise err(what, el, f"{attr} is required", attr)
    parts = raw.split()
    values = [decimal_number(p) for p in parts]
    if any(v is None for v in values):
        bad = next(p for p, v in zip(parts, values, strict=True) if v is None)
        raise err(what, el, f"{attr}: {bad!r} is not a number", attr)
    if len(values) not in count:
        want = " or ".join(str(c) for c in count)
        raise err(what, el, f"{attr} needs exactly {want} numbers, got {len(values)}", attr)
    out = [float(v) for v in values if v is not None]
    if not all(math.isfinite(v) for v in out):
        raise err(what, el, f"{attr} must be finite", attr)
    return out


def attr_scalar(err: XmlErrors, what: str, el: XmlElement, attr: str) -> float | None:
    """An optional single number (``None`` when the attribute is absent)."""
    if attr not in el.attrib:
        return None
    return attr_numbers(err, what, el, attr, (1,), None)[0]


def attr_required(err: XmlErrors, what: str, el: XmlElement, attr: str) -> float:
    """A required single number."""
    return attr_numbers(err, what, el, attr, (1,), None)[0]


def optional_child(err: XmlErrors, what: str, el: XmlElement, tag: str) -> XmlElement | None:
    """The one child ``<tag>`` of ``el`` or ``None``; two are an error."""
    found = el.findall(tag)
    if len(found) > 1:
        raise err(what, found[1], f"more than one <{tag}>")
    return found[0] if found else None


def one_child(err: XmlErrors, what: str, el: XmlElement, tag: str) -> XmlElement:
    """The one child ``<tag>`` of ``el``; none or two are an error."""
    found = optional_child(err, what, el, tag)
    if found is None:
        raise err(what, el, f"<{tag}> is required")
    return found


def origin_pose(err: XmlErrors, what: str, el: XmlElement) -> Mat:
    """The pose of ``el``'s optional ``<origin xyz rpy>`` (identity without one)."""
    o = optional_child(err, what, el, "origin")
    if o is None:
        return np.eye(4)
    xyz = attr_numbers(err, what, o, "xyz", (3,), "0 0 0")
    rpy = attr_numbers(err, what, o, "rpy", (3,), "0 0 0")
    return pose_from_xyz_rpy(xyz, rpy)
