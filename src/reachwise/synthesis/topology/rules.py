"""What the enumerator generates: ``EnumerationRules`` and their ``KEY=VALUE`` form.

The rules choose the joint counts and types, the allowed twists (multiples of 90°, P-II
Table 1 "Fixed: yes") and the first joint's axis; the pruning rules they switch on are
described in ``pruning``. Pure: no files, no clocks, no printing.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import InputError
from reachwise.synthesis.topology.spec import _SRC, _wrap

DEFAULT_TWISTS: tuple[float, ...] = (0.0, math.pi / 2, -math.pi / 2)
FIRST_AXES: tuple[str, ...] = ("any", "vertical", "horizontal")


@dataclass(frozen=True)
class EnumerationRules:
    """What the enumerator generates and prunes (module docstring, rules 1–5).

    ``twists`` in rad; ``first_axis`` one of ``any``, ``vertical``, ``horizontal``;
    ``first_types`` the kinds allowed for the first joint; ``patterns`` (optional) the
    only type strings to generate, e.g. ``("RRPRRR", "RRPRRRP")``; ``sample`` (optional)
    keeps that many topologies evenly spaced over the ordered list (deterministic).
    """

    min_joints: int = 6
    max_joints: int = 6
    types: str = "RP"
    min_prismatic: int = 0
    max_prismatic: int = 2
    twists: tuple[float, ...] = DEFAULT_TWISTS
    first_axis: str = "any"
    first_types: str = "RP"
    patterns: tuple[str, ...] = ()
    max_parallel_revolute: int = 3
    min_rotation_axes: int = 3
    mirror: bool = True
    sample: int | None = None

    def __post_init__(self) -> None:
        if not 1 <= self.min_joints <= self.max_joints:
            raise InputError(_SRC, "joints", f"need 1 <= min <= max, got "
                             f"{self.min_joints}-{self.max_joints}")  # fmt: skip
        if self.max_joints > 10:
            raise InputError(_SRC, "joints", "at most 10 joints")
        for name in ("types", "first_types"):
            raw = set(str(getattr(self, name)).upper())
            if not raw or raw - {"R", "P"}:
                raise InputError(_SRC, name, f"{getattr(self, name)!r}: use R and/or P")
            object.__setattr__(self, name, "".join(sorted(raw, key="RP".index)))
        if not 0 <= self.min_prismatic <= self.max_prismatic:
            raise InputError(_SRC, "prismatic", "need 0 <= min_prismatic <= max_prismatic")
        tw = []
        for t in self.twists:
            w = _wrap(float(t))
            if not any(abs(w - c) < 1e-9 for c in _TWIST_CODES):
                raise InputError(_SRC, "twists", f"{math.degrees(w):g}°: use 0, ±90 or 180")
            tw.append(_code_angle(w))
        if not tw:
            raise InputError(_SRC, "twists", "no twist angle allowed")
        object.__setattr__(self, "twists", tuple(_TWIST_CODES[c] for c in sorted(set(tw))))
        if self.first_axis not in FIRST_AXES:
            raise InputError(_SRC, "first_axis", f"{self.first_axis!r}: one of {FIRST_AXES}")
        pats = tuple(p.upper() for p in self.patterns)
        for p in pats:
            if not p or set(p) - {"R", "P"}:
                raise InputError(_SRC, "patterns", f"{p!r}: a string of R and P")
        object.__setattr__(self, "patterns", pats)
        if self.sample is not None and self.sample < 1:
            raise InputError(_SRC, "sample", "must be >= 1")


# Twist codes, ordered by preference for the canonical representative (rule 5).
_TWIST_CODES: tuple[float, ...] = (math.pi / 2, 0.0, -math.pi / 2, math.pi)


def _code_angle(angle: float) -> int:
    for c, v in enumerate(_TWIST_CODES):
        if abs(_wrap(angle - v)) < 1e-9:
            return c
    raise InputError(_SRC, "twists", f"{math.degrees(angle):g}° is not a multiple of 90°")


_RULES_KEYS = ("joints", "types", "prismatic", "max_prismatic", "twists", "first",
               "first_type", "patterns", "parallel", "rotations", "mirror", "sample")  # fmt: skip


def _int_range(value: str, key: str) -> tuple[int, int]:
    try:
        if "-" in value:
            lo, hi = value.split("-", 1)
            return int(lo), int(hi)
        return int(value), int(value)
    except ValueError:
        raise InputError(_SRC, key, f"{value!r}: an integer or a range like 6-7") from None


def parse_rules(text: str) -> EnumerationRules:
    """Rules from ``KEY=VALUE`` pairs separated by blanks or ``;`` (CLI ``--enumerate``):

    ``joints=6-7`` (count or range), ``types=RP``, ``prismatic=0-2`` (or
    ``max_prismatic=2``), ``twists=0,90,-90`` (degrees), ``first=vertical|horizontal|any``,
    ``first_type=R``, ``patterns=RRPRRR,PRRRRR``, ``parallel=3`` (max consecutive
    parallel revolutes), ``rotations=3`` (min rotation axes), ``mirror=on|off``,
    ``sample=N``. Unknown keys are errors.
    """
    kw: dict[str, object] = {}
    for part in re.split(r"[;\s]+", text.strip()):
        if not part:
            continue
        if "=" not in part:
            raise InputError(_SRC, "rules", f"{part!r}: expected KEY=VALUE")
        key, value = (s.strip() for s in part.split("=", 1))
        key = key.lower()
        if key not in _RULES_KEYS:
            raise InputError(_SRC, f"rules.{key}", f"unknown rule; keys: {', '.join(_RULES_KEYS)}")
        if key == "joints":
            kw["min_joints"], kw["max_joints"] = _int_range(value, key)
        elif key == "prismatic":
            kw["min_prismatic"], kw["max_prismatic"] = _int_range(value, key)
        elif key == "max_prismatic":
            kw["max_prismatic"] = _int_range(value, key)[1]
        elif key == "types":
            kw["types"] = value
        elif key == "first_type":
            kw["first_types"] = value
        elif key == "twists":
            try:
                kw["twists"] = tuple(math.radians(float(v)) for v in value.split(",") if v)
            except ValueError:
                raise InputError(
                    _SRC, "rules.twists", f"{value!r}: degrees, e.g. 0,90,-90"
                ) from None
        elif key == "first":
            kw["first_axis"] = value.lower()
        elif key == "patterns":
            kw["patterns"] = tuple(v for v in value.split(",") if v)
        elif key == "parallel":
            kw["max_parallel_revolute"] = _int_range(value, key)[1]
        elif key == "rotations":
            kw["min_rotation_axes"] = _int_range(value, key)[1]
        elif key == "mirror":
            if value.lower() not in ("on", "off", "true", "false", "1", "0"):
                raise InputError(_SRC, "rules.mirror", f"{value!r}: on or off")
            kw["mirror"] = value.lower() in ("on", "true", "1")
        elif key == "sample":
            kw["sample"] = _int_range(value, key)[1]
    return EnumerationRules(**kw)  # type: ignore[arg-type]


def _twist_masks(rules: EnumerationRules, n: int) -> NDArray[np.bool_]:
    """``(n, 4)``: which twist codes each row may take (first-axis rule on row 0)."""
    allowed = np.zeros((n, 4), dtype=np.bool_)
    for t in rules.twists:
        allowed[:, _code_angle(t)] = True
    if rules.first_axis == "vertical":
        allowed[0] = False
        allowed[0, 1] = True  # α₀ = 0
    elif rules.first_axis == "horizontal":
        allowed[0] = False
        allowed[0, 0] = allowed[0, 2] = True
    return allowed
