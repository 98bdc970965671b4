"""The rules of a tunnel-face drill plan, grouped by zone (SI units: m and rad).

:class:`DrillLayout` holds the face distance, the hole depth, the collar jitter and one
group per zone (:class:`CutLayout`, :class:`StopingLayout`, :class:`ContourLayout`,
:class:`LifterLayout`); :func:`reachwise.tasks.drilling_pattern` turns a layout and a
:class:`~reachwise.tasks.TunnelProfile` into a task. Every group checks its own
fields when built and names a bad one by its flat keyword (``contour_spacing``,
``cut_type``, …), the names :class:`LayoutKeywords` lists and ``layout_with``
accepts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Literal, TypedDict

from reachwise.errors import TaskError

CutType = Literal["v", "parallel"]
_SRC = "drilling pattern"

__all__ = [
    "ContourLayout",
    "CutLayout",
    "CutType",
    "DrillLayout",
    "LayoutKeywords",
    "LifterLayout",
    "StopingLayout",
    "layout_with",
]


def _positive(name: str, value: float) -> float:
    v = float(value)
    if not (math.isfinite(v) and v > 0):
        raise TaskError(_SRC, name, f"must be finite and > 0, got {value}")
    return v


def _angle(name: str, value: float, lo: float, hi: float, *, open_lo: bool = False) -> float:
    """``value`` (rad) within ``[lo, hi)`` degrees (``(lo, hi)`` with ``open_lo``)."""
    v = float(value)
    low_ok = v > math.radians(lo) if open_lo else v >= math.radians(lo)
    if not (low_ok and v < math.radians(hi)):
        lo_b = "(" if open_lo else "["
        raise TaskError(_SRC, name, f"must be in {lo_b}{lo:g}, {hi:g}°) (rad), got {value}")
    return v


def _set(obj: object, name: str, value: object) -> None:
    object.__setattr__(obj, name, value)


@dataclass(frozen=True)
class CutLayout:
    """The cut near the face centre, which opens the first free face.

    ``type``: ``"v"`` (a horizontal V-cut of ``rows`` × ``pairs`` symmetric pairs
    angled up to ``angle`` rad from the tunnel axis, rows ``row_pitch`` m apart, the
    outer rows tilted up to ``vertical_angle`` rad toward the centre row) or
    ``"parallel"`` (a four-section burn cut of 18 holes along the axis). ``center``:
    ``(u, v)`` m in profile coordinates, ``None`` for the centreline at
    ``clip(0.4·height, 1.6, 3.0)`` m above the floor.
    """

    type: CutType = "v"
    center: tuple[float, float] | None = None
    angle: float = math.radians(30.0)
    rows: int = 4
    pairs: int = 2
    row_pitch: float = 0.55
    vertical_angle: float = math.radians(6.0)

    def __post_init__(self) -> None:
        if self.type not in ("v", "parallel"):
            raise TaskError(_SRC, "cut_type", f"must be 'v' or 'parallel', got {self.type!r}")
        _set(self, "angle", _angle("cut_angle", self.angle, 0, 60, open_lo=True))
        _set(self, "vertical_angle", _angle("cut_vertical_angle", self.vertical_angle, 0, 30))
        _set(self, "row_pitch", _positive("cut_row_pitch", self.row_pitch))
        if int(self.rows) < 1 or int(self.pairs) < 1:
            raise TaskError(_SRC, "cut_rows", "cut_rows and cut_pairs must be ≥ 1")
        _set(self, "rows", int(self.rows))
        _set(self, "pairs", int(self.pairs))
        if self.center is not None:
            _set(self, "center", (float(self.center[0]), float(self.center[1])))


@dataclass(frozen=True)
class StopingLayout:
    """Stoping holes along the tunnel axis: rows ``burden`` m apart, holes ``spacing``
    m apart."""

    burden: float = 0.9
    spacing: float = 1.0

    def __post_init__(self) -> None:
        _set(self, "burden", _positive("stoping_burden", self.burden))
        _set(self, "spacing", _positive("stoping_spacing", self.spacing))


@dataclass(frozen=True)
class ContourLayout:
    """Contour holes along walls and roof, ``offset`` m inside the profile, about
    ``spacing`` m apart, tilted outward by ``lookout_angle`` rad (0–15°); the stoping
    region starts ``burden`` m further in."""

    spacing: float = 0.7
    offset: float = 0.15
    burden: float = 0.8
    lookout_angle: float = math.radians(3.0)

    def __post_init__(self) -> None:
        _set(self, "spacing", _positive("contour_spacing", self.spacing))
        _set(self, "offset", _positive("contour_offset", self.offset))
        _set(self, "burden", _positive("contour_burden", self.burden))
        lookout = float(self.lookout_angle)
        if not 0 <= lookout <= math.radians(15):
            raise TaskError(
                _SRC, "lookout_angle", f"must be in [0, 15°] (rad), got {self.lookout_angle}"
            )
        _set(self, "lookout_angle", lookout)


@dataclass(frozen=True)
class LifterLayout:
    """Lifters along the floor, ``height`` m up, ``spacing`` m apart, angled down by
    ``angle`` rad (0–15°; ``None``: the contour's look-out)."""

    spacing: float = 1.0
    height: float = 0.25
    angle: float | None = None

    def __post_init__(self) -> None:
        _set(self, "spacing", _positive("lifter_spacing", self.spacing))
        _set(self, "height", _positive("lifter_height", self.height))
        if self.angle is not None:
            a = float(self.angle)
            if not 0 <= a <= math.radians(15):
                raise TaskError(
                    _SRC, "lifter_angle", f"must be in [0, 15°] (rad), got {self.angle}"
                )
            _set(self, "angle", a)


@dataclass(frozen=True)
class DrillLayout:
    """A drill plan's rules: the face plane ``face_x`` m ahead of the machine origin,
    the ``hole_depth`` (m, sets the V-cut depths), one group per zone and the collar
    ``jitter`` (m, at most a quarter of the contour offset)."""

    face_x: float = 7.0
    hole_depth: float = 4.5
    cut: CutLayout = field(default_factory=CutLayout)
    stoping: StopingLayout = field(default_factory=StopingLayout)
    contour: ContourLayout = field(default_factory=ContourLayout)
    lifters: LifterLayout = field(default_factory=LifterLayout)
    jitter: float = 0.0

    def __post_init__(self) -> None:
        fx = float(self.face_x)
        if not math.isfinite(fx):
            raise TaskError(_SRC, "face_x", f"must be finite, got {self.face_x}")
        _set(self, "face_x", fx)
        _set(self, "hole_depth", _positive("hole_depth", self.hole_depth))
        j = float(self.jitter)
        if not (math.isfinite(j) and 0 <= j <= self.contour.offset / 4):
            raise TaskError(_SRC, "jitter", f"must be in [0, contour_offset/4], got {self.jitter}")
        _set(self, "jitter", j)

    @property
    def lifter_angle(self) -> float:
        """The lifters' downward angle (rad): their own, else the contour's look-out."""
        a = self.lifters.angle
        return self.contour.lookout_angle if a is None else a


class LayoutKeywords(TypedDict, total=False):
    """The fields of a :class:`DrillLayout` as flat keywords (units as there)."""

    face_x: float
    hole_depth: float
    jitter: float
    lookout_angle: float
    contour_spacing: float
    contour_offset: float
    contour_burden: float
    lifter_spacing: float
    lifter_height: float
    lifter_angle: float | None
    stoping_burden: float
    stoping_spacing: float
    cut_type: CutType
    cut_center: tuple[float, float] | None
    cut_angle: float
    cut_rows: int
    cut_pairs: int
    cut_row_pitch: float
    cut_vertical_angle: float


#: Flat keyword -> (group attribute of DrillLayout or "" for its own field, field name).
_FLAT: dict[str, tuple[str, str]] = {
    "face_x": ("", "face_x"),
    "hole_depth": ("", "hole_depth"),
    "jitter": ("", "jitter"),
    "lookout_angle": ("contour", "lookout_angle"),
    "contour_spacing": ("contour", "spacing"),
    "contour_offset": ("contour", "offset"),
    "contour_burden": ("contour", "burden"),
    "lifter_spacing": ("lifters", "spacing"),
    "lifter_height": ("lifters", "height"),
    "lifter_angle": ("lifters", "angle"),
    "stoping_burden": ("stoping", "burden"),
    "stoping_spacing": ("stoping", "spacing"),
    "cut_type": ("cut", "type"),
    "cut_center": ("cut", "center"),
    "cut_angle": ("cut", "angle"),
    "cut_rows": ("cut", "rows"),
    "cut_pairs": ("cut", "pairs"),
    "cut_row_pitch": ("cut", "row_pitch"),
    "cut_vertical_angle": ("cut", "vertical_angle"),
}


def layout_with(layout: DrillLayout, **keywords: object) -> DrillLayout:
    """``layout`` with the fields named by flat keywords (:class:`LayoutKeywords`)
    replaced; an unknown keyword is a :class:`TypeError`, as for any function."""
    unknown = sorted(set(keywords) - set(_FLAT))
    if unknown:
        raise TypeError(f"unexpected drill layout keyword(s): {', '.join(unknown)}")
    groups: dict[str, dict[str, Any]] = {}
    for key, value in keywords.items():
        group, name = _FLAT[key]
        groups.setdefault(group, {})[name] = value
    own = groups.pop("", {})
    changed: dict[str, Any] = {g: replace(getattr(layout, g), **kw) for g, kw in groups.items()}
    return replace(layout, **own, **changed)
