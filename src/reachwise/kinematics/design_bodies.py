"""Bodies of a template robot whose size follows its design, for clearance checks.

A body sits on one link (a row of ``fk_all``: ``link_0`` … ``link_N``, ``tool``) and is
either

* a capsule that **follows the design**: it runs along the ``a`` segment, the ``d``
  segment or both of the DH row that ends at its link (row ``j`` for ``link_{j+1}``),
  so its length changes with the design parameters (and with a prismatic joint's
  stroke along ``d``); it has a radius (m), or
* a **fixed shape** in the link frame that no design parameter changes (a feed beam, a
  drifter, a bracket): a capsule from ``start`` to ``end`` (link-frame points, m) with a
  radius, or a box of edge lengths ``size`` (m) placed by ``origin``.

A fixed capsule may declare a **contact zone**: the last ``contact`` metres of its axis
before ``end`` (the drill's bit, steel and centralizer at the face touch the rock at
the collar point by design). That part is exempt from the environment clearance and
nothing else is.

The segments of modified DH row ``j`` (P-I Eq. 2–3, ``T_{j+1} = T_j R_x(α) T_x(a)
R_z(θ) T_z(d)``) run from frame ``j``'s origin along its ``x`` axis by ``a`` (the
*elbow*), then along ``z_{j+1}`` by ``d`` (plus a prismatic joint's value) to frame
``j + 1``'s origin; for classic DH (``R_z(θ) T_z(d) T_x(a) R_x(α)``) first ``d`` along
``z_j``, then ``a`` along ``x_{j+1}``.

Pure data: frozen dataclasses, checked on construction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from reachwise.errors import InputError

BodyShape = Literal["capsule", "box"]
Segment = Literal["a", "d"]
Vec3 = tuple[float, float, float]
_IDENTITY = ((1.0, 0.0, 0.0, 0.0), (0.0, 1.0, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0), (0.0, 0.0, 0.0, 1.0))

__all__ = ["BodyShape", "DesignBody", "Segment"]


def _finite(where: str, field: str, v: float) -> float:
    x = float(v)
    if not math.isfinite(x):
        raise InputError("design", f"{where}.{field}", f"must be finite, got {v!r}")
    return x


@dataclass(frozen=True)
class DesignBody:
    """One body on link ``link`` (a name of ``Robot.link_names``), module docstring.

    ``along`` (``("a",)``, ``("d",)`` or ``("a", "d")``) makes it a capsule of ``radius``
    that follows the design; otherwise ``shape`` is ``capsule`` (``start``, ``end``,
    ``radius``, optional ``contact`` length) or ``box`` (``size`` and ``origin``, a 4×4
    pose in the link frame as nested tuples).
    """

    name: str
    link: str
    shape: BodyShape = "capsule"
    along: tuple[Segment, ...] = ()
    radius: float = 0.0
    start: Vec3 = (0.0, 0.0, 0.0)
    end: Vec3 = (0.0, 0.0, 0.0)
    size: Vec3 = (0.0, 0.0, 0.0)
    origin: tuple[tuple[float, ...], ...] = _IDENTITY
    contact: float = 0.0

    def __post_init__(self) -> None:
        where = f"bodies.{self.name}"
        if self.shape not in ("capsule", "box"):
            raise InputError("design", f"{where}.shape", f"capsule or box, got {self.shape!r}")
        for s in self.along:
            if s not in ("a", "d"):
                msg = f"segments are 'a' and 'd', got {s!r}"
                raise InputError("design", f"{where}.along", msg)
        if len(set(self.along)) != len(self.along):
            raise InputError("design", f"{where}.along", "a segment is named twice")
        if self.along and self.shape != "capsule":
            raise InputError("design", f"{where}.along", "only a capsule follows the design")
        r = _finite(where, "radius", self.radius)
        if self.shape == "capsule" and not r > 0:
            raise InputError("design", f"{where}.radius", f"must be > 0, got {self.radius}")
        for f in ("start", "end", "size"):
            v = tuple(_finite(where, f, x) for x in getattr(self, f))
            if len(v) != 3:
                raise InputError("design", f"{where}.{f}", "needs three numbers")
            object.__setattr__(self, f, v)
        if self.shape == "box" and not all(x > 0 for x in self.size):
            raise InputError(
                "design", f"{where}.size", f"edge lengths must be > 0, got {self.size}"
            )
        c = _finite(where, "contact", self.contact)
        if c < 0:
            raise InputError("design", f"{where}.contact", f"must be >= 0, got {c}")
        if c > 0 and (self.shape != "capsule" or self.along):
            raise InputError(
                "design", f"{where}.contact", "only a fixed capsule has a contact zone"
            )
        if self.shape == "capsule" and not self.along and c >= self.length:
            raise InputError(
                "design", f"{where}.contact", f"{c} m covers the whole {self.length} m axis"
            )

    @property
    def follows_design(self) -> bool:
        """True for a capsule along the DH segments of its link's row."""
        return bool(self.along)

    @property
    def length(self) -> float:
        """Axis length of a fixed capsule (m)."""
        return math.dist(self.start, self.end)
