"""Serial topologies: a compact spec, its design template, and the enumerator (P-II §2, §5).

Topology synthesis (P-II §2, Fig. 1; thesis §4.2, §5.1) decides *which* chain to build
— the number, type and order of the joints and the twist between consecutive axes —
before the dimensional synthesis sizes it. P-II hand-picks six topologies (Table 1)
with locked twist angles; it notes that "all possible topologies [could be] generated
automatically and then optimized". This module does that.

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

**Template.** ``to_template`` turns a spec into a template ``Robot``: every free ``a``
and ``d`` within ``length_bounds`` (P-II §5.1: [−2, 2] m), twist angles locked (P-II
Table 1, "Fixed: yes"), prismatic strokes ``prismatic_limits`` ([0, 3] m), revolute
ranges ``revolute_limits`` ([−π, π]), base x, y, z free within ``base_bounds`` (P-II §5:
"the manipulator base frame is freely movable"; orientation fixed), tool = last frame.
With ``minimal=True`` (default) parameters that are *exactly* redundant are not freed:
the first row's ``a`` and ``d`` (pure translations of the whole chain, which the free
base position already provides) and a row's ``d`` when its axis is parallel to the
previous one whose offset is already free (only the sum of the two offsets matters).
Redundant columns make the design Jacobian rank deficient without adding any reach.

**Enumeration** (``enumerate_topologies``, rules in ``EnumerationRules``): every chain of
``min_joints``…``max_joints`` movable joints of the allowed ``types`` with at most
``max_prismatic`` prismatic joints, twists from ``twists`` (default {0, ±π/2}), the first
joint's type and axis as allowed (``first_axis`` ``vertical``: α₀ = 0; ``horizontal``:
α₀ = ±π/2), optionally only the type patterns in ``patterns``. Pruned (each rule is a
proof that the chain adds nothing a kept chain lacks):

1. *Parallel prismatic pair* — two consecutive prismatic joints with parallel axes
   (twist 0 or π between them) slide along one line: one of them is redundant.
2. *Coincident revolute pair* — two consecutive revolute joints with parallel axes and
   a locked ``a = 0`` between them share one axis: only the sum of the angles matters.
   (The enumerator frees every ``a``, so this only prunes specs given with locked links.)
3. *Planar redundancy* — more than ``max_parallel_revolute`` (3) consecutive revolute
   joints with parallel axes: a planar 3R chain already spans all planar motions.
4. *Rotational mobility* — the tool orientation changes only through revolute joints,
   and a run of revolute joints with parallel axes (prismatic or fixed rows between
   them included) contributes one rotation axis. Fewer such axes than
   ``min_rotation_axes`` (3 for 6-D task points, 2 for 5-D) cannot orient the tool.
5. *Axis-reversal (mirror) equivalence* — reversing the axis of a revolute (or fixed)
   row ``k`` other than the last maps the chain onto one with ``alpha_k`` and
   ``alpha_{k+1}`` each changed by π (so ±π/2 swap sign), ``theta_k`` and ``d_k``
   negated and ``q_k → −q_k``: the same set of tool poses when the revolute range and
   the length bounds are symmetric about 0. Of each class of equivalent sign patterns
   only one is kept: the one whose twists, read base to tool, prefer +π/2, then 0, then
   −π/2, then π. (Not applied to prismatic rows, whose stroke [0, 3] m is not
   symmetric, nor to the last row, which carries the tool frame.)

Pure: no files, no clocks, no printing (``builtin_set`` reads the packaged templates).
"""

from __future__ import annotations

import itertools
import math
import re
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import InputError
from reachwise.kinematics.robot import DesignSpace, Joint, JointType, Robot

KINDS: tuple[str, ...] = ("R", "P", "F")
_JOINT_TYPE: dict[str, JointType] = {"R": "revolute", "P": "prismatic", "F": "fixed"}
_KIND_OF = {v: k for k, v in _JOINT_TYPE.items()}
FREE_FLAGS: tuple[str, ...] = ("ad", "a", "d", "")
DEFAULT_TWISTS: tuple[float, ...] = (0.0, math.pi / 2, -math.pi / 2)
FIRST_AXES: tuple[str, ...] = ("any", "vertical", "horizontal")
BUILTIN_SETS: dict[str, tuple[str, ...]] = {
    "p2": tuple(f"p2-man{i}" for i in range(1, 7)),
}
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


# ---- template ---------------------------------------------------------------------------
@dataclass(frozen=True)
class TemplateOptions:
    """Bounds of a generated template (P-II §5.1; base bounds are our choice).

    ``length_bounds`` for every free ``a``/``d`` (m); ``prismatic_limits`` the stroke
    (m); ``revolute_limits`` (rad); ``base_bounds`` for base x, y, z (m; orientation
    fixed); ``minimal`` leaves exactly redundant parameters locked (module docstring).
    """

    length_bounds: tuple[float, float] = (-2.0, 2.0)
    prismatic_limits: tuple[float, float] = (0.0, 3.0)
    revolute_limits: tuple[float, float] = (-math.pi, math.pi)
    base_bounds: Mapping[str, tuple[float, float]] = field(
        default_factory=lambda: {"x": (-2.0, 2.0), "y": (-2.0, 2.0), "z": (-2.0, 2.0)}
    )
    minimal: bool = True

    def __post_init__(self) -> None:
        for name in ("length_bounds", "prismatic_limits", "revolute_limits"):
            lo, hi = (float(v) for v in getattr(self, name))
            if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
                raise InputError(_SRC, name, f"need finite lo <= hi, got [{lo}, {hi}]")
            object.__setattr__(self, name, (lo, hi))
        base = {str(k): (float(v[0]), float(v[1])) for k, v in self.base_bounds.items()}
        for k, (lo, hi) in base.items():
            if k not in ("x", "y", "z"):
                raise InputError(_SRC, f"base_bounds.{k}", "only x, y, z may be free")
            if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
                raise InputError(_SRC, f"base_bounds.{k}", f"need lo <= hi, got [{lo}, {hi}]")
        object.__setattr__(self, "base_bounds", base)

    @property
    def symmetric(self) -> bool:
        """Length bounds and revolute range symmetric about 0 (mirror rule 5 holds)."""
        lo, hi = self.length_bounds
        rlo, rhi = self.revolute_limits
        return abs(lo + hi) < 1e-12 and abs(rlo + rhi) < 1e-12


def free_parameters(spec: TopologySpec, options: TemplateOptions | None = None) -> list[set[str]]:
    """Per row, the set of DH parameters (``a``, ``d``) the template frees."""
    opt = options or TemplateOptions()
    base_xyz = all(c in opt.base_bounds for c in "xyz")
    out: list[set[str]] = []
    covered = False  # translation along the current axis already available
    for i, j in enumerate(spec.joints):
        free = set(j.free)
        if opt.minimal:
            if i == 0 and base_xyz:
                free.clear()
                covered = True
            elif _parallel(j.alpha) and covered:
                free.discard("d")
            else:
                covered = "d" in free
        out.append(free)
    return out


def to_template(
    spec: TopologySpec | str, options: TemplateOptions | None = None, name: str | None = None
) -> Robot:
    """The design template of a topology (module docstring): a ``Robot`` whose
    ``design`` frees the ``a``/``d`` of ``free_parameters`` and the base x, y, z.
    Nominal values are the middle of each bound."""
    sp = as_spec(spec)
    opt = options or TemplateOptions()
    mid_len = 0.5 * sum(opt.length_bounds)
    free = free_parameters(sp, opt)
    joints: list[Joint] = []
    design: dict[int, dict[str, tuple[float, float]]] = {}
    for i, (j, fr) in enumerate(zip(sp.joints, free, strict=True)):
        limits = {"R": opt.revolute_limits, "P": opt.prismatic_limits}.get(j.kind, (0.0, 0.0))
        a = mid_len if "a" in fr else 0.0
        d = mid_len if "d" in fr else 0.0
        joints.append(
            Joint(
                _JOINT_TYPE[j.kind],
                a=a,
                alpha=j.alpha,
                d=d,
                theta=j.theta,
                limits=limits,
                name=f"j{i + 1}",
            )
        )
        if fr:
            design[i] = {p: opt.length_bounds for p in ("a", "d") if p in fr}
    base = np.eye(4)
    for k, c in enumerate("xyz"):
        if c in opt.base_bounds:
            lo, hi = opt.base_bounds[c]
            base[k, 3] = 0.5 * (lo + hi)
    return Robot(
        name=name or str(sp),
        joints=tuple(joints),
        convention="modified",
        base=base,
        design=DesignSpace(joints=design, base=dict(opt.base_bounds)),
    )


# ---- rules ------------------------------------------------------------------------------
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


# ---- rule checks on one spec (general: any twist, any offsets) -------------------------
def _rx(a: float) -> NDArray[np.float64]:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])


def _rz(t: float) -> NDArray[np.float64]:
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def rotation_axes(spec: TopologySpec) -> int:
    """Number of distinct rotation axes: runs of revolute joints whose axes stay parallel
    (rows between two revolutes are fixed rotations ``Rx(alpha) Rz(theta)``; rule 4)."""
    count = 0
    R: NDArray[np.float64] | None = None  # fixed rotation since the last revolute
    for j in spec.joints:
        if R is not None:
            R = R @ _rx(j.alpha)
        if j.kind == "R":
            if R is None or abs(abs(float(R[2, 2])) - 1.0) > 1e-9:
                count += 1
            R = np.eye(3)
        elif R is not None:
            R = R @ _rz(j.theta)
    return count


def violations(
    spec: TopologySpec | str,
    rules: EnumerationRules | None = None,
    options: TemplateOptions | None = None,
) -> list[str]:
    """The pruning rules (1–5 of the module docstring) ``spec`` breaks; empty if none."""
    sp = as_spec(spec)
    ru = rules or EnumerationRules()
    free = free_parameters(sp, options)
    out: list[str] = []
    js = sp.joints
    run = 1
    worst = 1 if js[0].kind == "R" else 0
    for i in range(1, len(js)):
        prev, cur = js[i - 1], js[i]
        par = _parallel(cur.alpha)
        if prev.kind == "P" and cur.kind == "P" and par:
            out.append(f"1 parallel prismatic pair at rows {i}-{i + 1}")
        if prev.kind == "R" and cur.kind == "R" and par and "a" not in free[i]:
            out.append(f"2 coincident revolute axes at rows {i}-{i + 1}")
        run = run + 1 if (prev.kind == "R" and cur.kind == "R" and par) else 1
        if cur.kind == "R":
            worst = max(worst, run)
    if worst > ru.max_parallel_revolute:
        out.append(f"3 {worst} consecutive parallel revolute joints")
    axes = rotation_axes(sp)
    if axes < ru.min_rotation_axes:
        out.append(f"4 {axes} rotation axes < {ru.min_rotation_axes}")
    if ru.mirror and (options or TemplateOptions()).symmetric:
        canon = canonical(sp, ru)
        if str(canon) != str(sp):
            out.append(f"5 mirror-equivalent to {canon}")
    return out


def canonical(spec: TopologySpec | str, rules: EnumerationRules | None = None) -> TopologySpec:
    """The representative of ``spec``'s axis-reversal class (rule 5): every subset of the
    reversible rows (revolute or fixed, not the last) is reversed and, among the results
    whose twists the ``rules`` allow (all results without rules; ``spec`` itself always
    counts), the one whose twists read best base to tool (+π/2 < 0 < −π/2 < π, offsets
    as tie-break) wins."""
    sp = as_spec(spec)
    js = sp.joints
    n = len(js)
    flippable = [k for k in range(n - 1) if js[k].kind in ("R", "F")]
    allowed = None if rules is None else _twist_masks(rules, n)
    best: tuple[tuple[float, ...], TopologySpec] | None = None
    for mask in itertools.product((False, True), repeat=len(flippable)):
        alpha = [j.alpha for j in js]
        theta = [j.theta for j in js]
        for k, f in zip(flippable, mask, strict=True):
            if f:
                alpha[k] += math.pi
                alpha[k + 1] -= math.pi
                theta[k] = -theta[k]
        cand = TopologySpec(
            tuple(JointSpec(j.kind, a, t, j.free) for j, a, t in zip(js, alpha, theta, strict=True))
        )
        if any(mask) and allowed is not None and not _allowed(cand, allowed):
            continue
        key = tuple(
            v for j in cand.joints for v in (_twist_rank(j.alpha), round(math.degrees(j.theta), 6))
        )
        if best is None or key < best[0]:
            best = (key, cand)
    if best is None:  # pragma: no cover - the empty product has one element
        return sp
    return best[1]


def _allowed(spec: TopologySpec, allowed: NDArray[np.bool_]) -> bool:
    for k, j in enumerate(spec.joints):
        r = _twist_rank(j.alpha)
        if r >= len(_TWIST_CODES) or not allowed[k, int(r)]:
            return False
    return True


def _twist_rank(alpha: float) -> float:
    for c, v in enumerate(_TWIST_CODES):
        if abs(_wrap(alpha - v)) < 1e-9:
            return float(c)
    return 10.0 + round(math.degrees(_wrap(alpha)), 6)


# ---- enumeration (vectorized over the twists of one type pattern; theta = 0) -----------
def _type_patterns(rules: EnumerationRules) -> Iterator[str]:
    if rules.patterns:
        yield from (p for p in rules.patterns if rules.min_joints <= len(p) <= rules.max_joints)
        return
    for n in range(rules.min_joints, rules.max_joints + 1):
        for combo in itertools.product(rules.types, repeat=n):
            yield "".join(combo)


def _pattern_ok(p: str, rules: EnumerationRules) -> bool:
    k = p.count("P")
    return (
        rules.min_prismatic <= k <= rules.max_prismatic
        and p[0] in rules.first_types
        and set(p) <= set(rules.types)
        and rules.min_joints <= len(p) <= rules.max_joints
    )


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


def _pattern_keep(
    pattern: str, rules: EnumerationRules, options: TemplateOptions
) -> NDArray[np.int64]:
    """Twist codes ``(m, n)`` of every kept chain of one type pattern (rules 1, 3–5)."""
    n = len(pattern)
    allowed = _twist_masks(rules, n)
    choices = [np.flatnonzero(allowed[k]) for k in range(n)]
    C = np.array(list(itertools.product(*choices)), dtype=np.int64).reshape(-1, n)
    keep = np.ones(len(C), dtype=np.bool_)
    par = (C == 1) | (C == 3)  # twist 0 or π: axis parallel to the previous one
    isR = np.array([c == "R" for c in pattern])
    isP = ~isR
    for k in range(1, n):
        if isP[k - 1] and isP[k]:
            keep &= ~par[:, k]  # rule 1
    run = np.full(len(C), 1 if isR[0] else 0)
    worst = run.copy()
    for k in range(1, n):
        if isR[k]:
            run = np.where(isR[k - 1] & par[:, k], run + 1, 1)
            worst = np.maximum(worst, run)
        else:
            run = np.zeros(len(C), dtype=np.int64)
    keep &= worst <= rules.max_parallel_revolute  # rule 3
    # rule 4: with theta = 0 the fixed rotation between two revolutes is Rx(sum of twists)
    deg = np.array([90, 0, -90, 180], dtype=np.int64)[C]
    axes = np.zeros(len(C), dtype=np.int64)
    acc: NDArray[np.int64] | None = None
    for k in range(n):
        if acc is not None:
            acc = acc + deg[:, k]
        if isR[k]:
            axes += 1 if acc is None else (acc % 180 != 0).astype(np.int64)
            acc = np.zeros(len(C), dtype=np.int64)
    keep &= axes >= rules.min_rotation_axes
    if rules.mirror and options.symmetric:  # rule 5
        flippable = [k for k in range(n - 1) if isR[k]]
        weights = 4 ** np.arange(n - 1, -1, -1, dtype=np.int64)
        own = C @ weights
        best = own.copy()
        for mask in itertools.product((0, 1), repeat=len(flippable)):
            if not any(mask):
                continue
            t = np.zeros(n, dtype=np.int64)
            for k, f in zip(flippable, mask, strict=True):
                if f:
                    t[k] ^= 1
                    t[k + 1] ^= 1
            Cf = (C + 2 * t) % 4
            valid = allowed[np.arange(n), Cf].all(axis=1)
            key = Cf @ weights
            best = np.where(valid & (key < best), key, best)
        keep &= own == best
    return C[keep]


def enumerate_topologies(
    rules: EnumerationRules | None = None, options: TemplateOptions | None = None
) -> list[TopologySpec]:
    """Every topology the rules allow, pruned by rules 1–5, in a fixed order (joint
    count, then type pattern R before P base to tool, then twists +π/2, 0, −π/2, π).
    All ``a`` and ``d`` free, ``theta = 0``. With ``rules.sample`` an evenly spaced
    deterministic selection of that many."""
    ru = rules or EnumerationRules()
    opt = options or TemplateOptions()
    out: list[TopologySpec] = []
    seen: set[str] = set()
    for pattern in _type_patterns(ru):
        if pattern in seen or not _pattern_ok(pattern, ru):
            continue
        seen.add(pattern)
        for row in _pattern_keep(pattern, ru, opt):
            out.append(
                TopologySpec(
                    tuple(
                        JointSpec(c, _TWIST_CODES[int(k)])
                        for c, k in zip(pattern, row, strict=True)
                    )
                )
            )
    if ru.sample is not None and ru.sample < len(out):
        idx = np.unique(np.round(np.linspace(0, len(out) - 1, ru.sample)).astype(np.int64))
        out = [out[int(i)] for i in idx]
    return out


# ---- named sets --------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Topology:
    """A candidate of a sweep: its ``name`` (the key it is stored under), its design
    ``template`` and its ``spec`` (``str(spec)`` is the canonical string)."""

    name: str
    template: Robot
    spec: TopologySpec

    @classmethod
    def from_spec(
        cls, spec: TopologySpec | str, options: TemplateOptions | None = None
    ) -> Topology:
        sp = as_spec(spec)
        return cls(str(sp), to_template(sp, options), sp)

    @classmethod
    def from_robot(cls, robot: Robot, name: str | None = None) -> Topology:
        return cls(name or robot.name, robot, TopologySpec.from_robot(robot))


def builtin_set(name: str) -> list[Topology]:
    """A named set of topologies; ``p2``: the six configurations of P-II Table 1 as the
    packaged templates ``p2-man1`` … ``p2-man6`` (DH tables 3–7, bounds of §5.1)."""
    if name not in BUILTIN_SETS:
        raise InputError(_SRC, "set", f"{name!r}: choose one of {sorted(BUILTIN_SETS)}")
    from reachwise.io.robot_file import load_robot

    return [Topology.from_robot(load_robot(r)) for r in BUILTIN_SETS[name]]


def topologies_from_specs(
    specs: Sequence[TopologySpec | str], options: TemplateOptions | None = None
) -> list[Topology]:
    """Topologies of the given specs (duplicates by canonical string dropped, order kept)."""
    out: dict[str, Topology] = {}
    for s in specs:
        t = Topology.from_spec(s, options)
        out.setdefault(t.name, t)
    return list(out.values())
