"""The design template of a topology (P-II §5.1).

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

Pure: no files, no clocks, no printing.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from reachwise.errors import InputError
from reachwise.kinematics.design_bodies import DesignBody
from reachwise.kinematics.robot import DesignSpace, Joint, Robot
from reachwise.synthesis.topology.spec import _JOINT_TYPE, _SRC, TopologySpec, _parallel, as_spec


@dataclass(frozen=True)
class TemplateOptions:
    """Bounds of a generated template (P-II §5.1; base bounds are our choice).

    ``length_bounds`` for every free ``a``/``d`` (m); ``prismatic_limits`` the stroke
    (m); ``revolute_limits`` (rad); ``base_bounds`` for base x, y, z (m; orientation
    fixed); ``minimal`` leaves exactly redundant parameters locked (module docstring);
    ``body_radius`` (m, 0: none) gives every link a stand-in body, a capsule of that
    radius along its DH row's ``a`` and ``d`` segments (``kinematics.design_bodies``),
    for a sweep that keeps a clearance.
    """

    length_bounds: tuple[float, float] = (-2.0, 2.0)
    prismatic_limits: tuple[float, float] = (0.0, 3.0)
    revolute_limits: tuple[float, float] = (-math.pi, math.pi)
    base_bounds: Mapping[str, tuple[float, float]] = field(
        default_factory=lambda: {"x": (-2.0, 2.0), "y": (-2.0, 2.0), "z": (-2.0, 2.0)}
    )
    minimal: bool = True
    body_radius: float = 0.0

    def __post_init__(self) -> None:
        r = float(self.body_radius)
        if not (math.isfinite(r) and r >= 0):
            raise InputError(_SRC, "body_radius", f"must be >= 0, got {self.body_radius}")
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
        design=DesignSpace(
            joints=design,
            base=dict(opt.base_bounds),
            bodies=tuple(
                DesignBody(f"link_{i + 1}", f"link_{i + 1}", along=("a", "d"),
                           radius=opt.body_radius)
                for i in range(len(joints))
            ) if opt.body_radius > 0 else (),
        ),
    )  # fmt: skip
