"""MoveIt's SRDF: the self-collision pairs it disables, read and written.

An SRDF lists the link pairs MoveIt never checks, each with the reason its Setup
Assistant found::

    <disable_collisions link1="panda_link0" link2="panda_link1" reason="Adjacent"/>

Reasons are ``Adjacent`` (one joint joins them), ``Never`` (never in collision over
random configurations), ``Always`` (always in collision), ``Default`` (in collision at
the default pose) and ``User``. :func:`write_srdf` hands reachwise's excluded pairs
(:class:`~reachwise.distance.self_pairs.SelfPairs`) to MoveIt: ``adjacent`` →
``Adjacent``, ``always`` → ``Always``, ``never`` → ``Never``; watched pairs are not
written (MoveIt checks every pair it is not told to disable). :func:`read_srdf` reads
the disabled pairs and the ``group_state`` poses (named joint values). Every problem
is an :class:`~reachwise.errors.InputError` naming the file, the element and its line.
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from reachwise.distance.self_pairs import SelfPairs
from reachwise.errors import InputError
from reachwise.io.atomic import atomic_write
from reachwise.io.xml_tree import read_xml

__all__ = ["REASONS", "DisabledPair", "Srdf", "read_srdf", "srdf_text", "write_srdf"]

Reason = Literal["Adjacent", "Never", "Always", "Default", "User"]
#: The reasons MoveIt's Setup Assistant writes.
REASONS: tuple[str, ...] = ("Adjacent", "Never", "Always", "Default", "User")
_OURS = {"adjacent": "Adjacent", "always": "Always", "never": "Never"}


@dataclass(frozen=True)
class DisabledPair:
    """One ``<disable_collisions>``: two links MoveIt does not check, and why."""

    link1: str
    link2: str
    reason: str


@dataclass(frozen=True)
class Srdf:
    """What reachwise reads of an SRDF: the robot's name, its disabled pairs and its
    named poses (``group_state`` name → joint name → value)."""

    robot: str
    disabled: tuple[DisabledPair, ...]
    poses: dict[str, dict[str, float]]

    def disabled_pairs(self) -> set[frozenset[str]]:
        """The disabled pairs, each as a set of its two links."""
        return {frozenset((p.link1, p.link2)) for p in self.disabled}


def srdf_text(pairs: SelfPairs) -> str:
    """The SRDF (XML) disabling every pair ``pairs`` excludes, with MoveIt's reasons."""
    root = ET.Element("robot", name=pairs.robot)
    root.append(
        ET.Comment(
            f" reachwise self-collision pairs: margin {pairs.margin:g} m, {pairs.samples} random "
            "configurations; watched pairs are not listed (MoveIt checks them) "
        )
    )
    for p in pairs.excluded:
        ET.SubElement(
            root, "disable_collisions", link1=p.a, link2=p.b, reason=_OURS.get(p.rule, "User")
        )
    ET.indent(root, space="  ")
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def write_srdf(pairs: SelfPairs, path: str | os.PathLike[str]) -> Path:
    """Write :func:`srdf_text` of ``pairs`` to ``path`` (whole, then renamed into place)."""
    return atomic_write(path, srdf_text(pairs))


def read_srdf(path: str | os.PathLike[str]) -> Srdf:
    """The disabled pairs and named poses of the SRDF file ``path`` (module docstring)."""
    source = str(path)
    root = read_xml(Path(path), source)
    if root.tag != "robot":
        raise InputError(source, "", "the root element of an SRDF must be <robot>")
    disabled = []
    seen: dict[frozenset[str], int] = {}
    for el in root.findall("disable_collisions"):
        where = f"<disable_collisions> (line {el.line})"
        a, b, why = el.get("link1"), el.get("link2"), el.get("reason", "User")
        if not a or not b:
            raise InputError(source, where, "link1 and link2 are required")
        if a == b:
            raise InputError(source, where, f"link {a!r} is paired with itself")
        if why not in REASONS:
            raise InputError(source, where, f"unknown reason {why!r}; MoveIt's: {REASONS}")
        key = frozenset((a, b))
        if key in seen:
            continue  # MoveIt files repeat pairs; the first reason is kept
        seen[key] = el.line
        disabled.append(DisabledPair(a, b, why))
    poses: dict[str, dict[str, float]] = {}
    for el in root.findall("group_state"):
        name = el.get("name")
        if not name:
            raise InputError(source, f"<group_state> (line {el.line})", "name is required")
        values: dict[str, float] = {}
        for j in el.findall("joint"):
            where = f"<group_state name={name!r}> <joint> (line {j.line})"
            jn, raw = j.get("name"), j.get("value")
            if not jn or raw is None:
                raise InputError(source, where, "name and value are required")
            try:
                v = float(raw.split()[0]) if raw.split() else math.nan
            except ValueError:
                raise InputError(source, where, f"value {raw!r} is not a number") from None
            if not math.isfinite(v):
                raise InputError(source, where, f"value {raw!r} is not a finite number")
            values[jn] = v
        poses[name] = values
    return Srdf(root.get("name") or "", tuple(disabled), poses)
