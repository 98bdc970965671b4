"""Topology specs: one ``JointSpec`` per DH row and their string form (P-II §2, Table 1).

**Spec.** A ``TopologySpec`` lists one ``JointSpec`` per DH row, base to tool: the kind
(``R`` revolute, ``P`` prismatic, ``F`` fixed), the twist ``alpha`` (rad) from the
previous joint axis to this one — modified DH, P-I Eq. 2–3: row ``i`` carries
``alpha_{i-1}``, so the first row's twist is measured from the base frame's z axis —
the offset ``theta`` (rad), and which of the row's ``a`` and ``d`` are free design
parameters (``"ad"`` by default; a locked one is 0). The string form is one token per
row, separated by blanks (blanks may be left out)::

    KIND[(ALPHA_DEG[,THETA_DEG])][:FREE]       KIND in R P F, FREE in ad a d -
    "R(0) R(90) P(90) R(90) R(90) R(90)"       P-II Man4's twists (Table 6)
    "R R(90,-90):a P(-90):d"                   theta -90°, only a / only d free
    "RRPRRR"                                   letters only: default twists

Angles are in degrees in the string only (the field says so); a token without
``(…)`` takes the default twist: 0 for the first row (the first axis along the base z
axis, vertical), 90° for every other row (consecutive axes perpendicular, the pattern of
P-II Man2/Man4, Tables 4 and 6). ``str(spec)`` gives the canonical string, which is also
the name a sweep stores the topology under.

Pure: no files, no clocks, no printing.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from reachwise.errors import InputError
from reachwise.kinematics.robot import JointType, Robot

KINDS: tuple[str, ...] = ("R", "P", "F")
_JOINT_TYPE: dict[str, JointType] = {"R": "revolute", "P": "prismatic", "F": "fixed"}
_KIND_OF = {v: k for k, v in _JOINT_TYPE.items()}
FREE_FLAGS: tuple[str, ...] = ("ad", "a", "d", "")
_SRC = "topology"
_ANG_TOL = 1e-9


def _deg(x: float) -> str:
    v = math.degrees(x)
    r = round(v)
    if abs(v - r) < 1e-6:
        return str(int(r)) if r != 0 else "0"
    return f"{v:.6g}"


def _wrap(angle: float) -> float:
    """Angle in (−π, π]."""
    a = math.remainder(angle, 2 * math.pi)
    return math.pi if abs(a + math.pi) < _ANG_TOL else a


def _parallel(alpha: float) -> bool:
    """True when a twist leaves consecutive axes parallel (0 or π)."""
    return abs(math.sin(alpha)) < 1e-9


@dataclass(frozen=True)
class JointSpec:
    """One DH row of a topology: kind, twist ``alpha`` (rad, from the previous axis),
    offset ``theta`` (rad) and which of ``a``, ``d`` are free design parameters."""

    kind: str
    alpha: float = 0.0
    theta: float = 0.0
    free: str = "ad"

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise InputError(_SRC, "kind", f"{self.kind!r}: choose one of {KINDS}")
        flags = "".join(c for c in "ad" if c in self.free)
        if set(self.free) - set("ad") or len(flags) != len(self.free):
            raise InputError(_SRC, "free", f"{self.free!r}: use 'ad', 'a', 'd' or ''")
        for f in ("alpha", "theta"):
            v = float(getattr(self, f))
            if not math.isfinite(v):
                raise InputError(_SRC, f, f"must be finite, got {v}")
            object.__setattr__(self, f, _wrap(v))
        object.__setattr__(self, "free", flags)

    def __str__(self) -> str:
        body = _deg(self.alpha) if self.theta == 0 else f"{_deg(self.alpha)},{_deg(self.theta)}"
        suffix = "" if self.free == "ad" else f":{self.free or '-'}"
        return f"{self.kind}({body}){suffix}"


@dataclass(frozen=True)
class TopologySpec:
    """A serial topology: the joint rows base to tool (see the module docstring)."""

    joints: tuple[JointSpec, ...]

    def __post_init__(self) -> None:
        js = tuple(self.joints)
        if not js:
            raise InputError(_SRC, "joints", "a topology needs at least one joint")
        if not any(j.kind != "F" for j in js):
            raise InputError(_SRC, "joints", "a topology needs at least one movable joint")
        object.__setattr__(self, "joints", js)

    def __str__(self) -> str:
        return " ".join(str(j) for j in self.joints)

    @property
    def types(self) -> str:
        """Joint kinds of the movable joints, e.g. ``RRPRRR`` (P-II Table 1 notation)."""
        return "".join(j.kind for j in self.joints if j.kind != "F")

    @property
    def n_joints(self) -> int:
        """Number of joint variables (movable joints)."""
        return len(self.types)

    @property
    def n_prismatic(self) -> int:
        return self.types.count("P")

    @property
    def twists(self) -> tuple[float, ...]:
        return tuple(j.alpha for j in self.joints)

    @classmethod
    def from_robot(cls, robot: Robot) -> TopologySpec:
        """The topology of a robot: kinds, twists and offsets of its DH rows, and its
        design section's free ``a`` / ``d`` (a modified-DH robot)."""
        if robot.convention != "modified":
            raise InputError(robot.name, "convention", "topologies use modified DH")
        rows = []
        for i, j in enumerate(robot.joints):
            params = robot.design.joints.get(i, {})
            free = "".join(c for c in "ad" if c in params)
            rows.append(JointSpec(_KIND_OF[j.type], j.alpha, j.theta, free))
        return cls(tuple(rows))


_TOKEN = re.compile(
    r"\s*([RPF])(?:\(\s*([-+]?(?:\d+\.?\d*|\.\d+))\s*(?:,\s*([-+]?(?:\d+\.?\d*|\.\d+))\s*)?\))?"
    r"(?::(ad|a|d|-))?",
    re.IGNORECASE,
)


def parse_topology(text: str) -> TopologySpec:
    """Parse the string form (module docstring), e.g. ``"R(0) R(90) P(90) R(90)"``.

    Raises ``InputError`` naming the position of the first character it cannot read.
    """
    if not isinstance(text, str) or not text.strip():
        raise InputError(_SRC, "spec", "empty topology string")
    rows: list[JointSpec] = []
    pos = 0
    s = text.rstrip()
    while pos < len(s):
        m = _TOKEN.match(s, pos)
        if m is None or m.end() == pos:
            raise InputError(_SRC, "spec", f"cannot read {text!r} at character {pos + 1}")
        kind = m.group(1).upper()
        default = 0.0 if not rows else 90.0
        alpha = math.radians(float(m.group(2))) if m.group(2) else math.radians(default)
        theta = math.radians(float(m.group(3))) if m.group(3) else 0.0
        flag = m.group(4)
        free = "ad" if flag is None else ("" if flag == "-" else flag.lower())
        rows.append(JointSpec(kind, alpha, theta, free))
        pos = m.end()
    return TopologySpec(tuple(rows))


def as_spec(spec: TopologySpec | str) -> TopologySpec:
    return spec if isinstance(spec, TopologySpec) else parse_topology(spec)
