"""The kinematic model every part of reachwise shares: ``Joint`` and ``Robot``.

Frames follow the modified Denavit–Hartenberg convention of the thesis (P-I Eq. 2–3,
Craig): joint ``i`` maps frame ``i-1`` to frame ``i`` by
``Rx(alpha) Tx(a) Rz(theta) Tz(d)``; its axis is the z axis of frame ``i``. Classic DH
(``Rz(theta) Tz(d) Tx(a) Rx(alpha)``, axis = z of frame ``i-1``) is computed natively:
the tool pose is the same either way, link frames are those of the table as written.

For a revolute joint ``theta`` is an offset added to ``q``; for a prismatic joint ``d``
is. ``q`` holds one value per non-fixed joint (passive ones included), base to tool.

Frames are numbered ``link_0`` (the base frame, ``world <- base``), ``link_1`` …
``link_N`` (after joint ``1`` … ``N``, fixed joints included) and ``tool``, unless the
robot names them (``frame_names``: a robot read from a URDF names each frame after the
URDF link riding on it). Shapes belong to bodies (:mod:`reachwise.kinematics.bodies`):
one per frame by default, one per URDF link for a robot read from a URDF.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.errors import InputError, RobotFileError, UnknownName
from reachwise.kinematics.bodies import Body, chain_bodies
from reachwise.kinematics.chain import Chain
from reachwise.kinematics.design_bodies import DesignBody
from reachwise.kinematics.fk import fk as _fk
from reachwise.kinematics.fk import fk_all as _fk_all
from reachwise.kinematics.ik import IKResult
from reachwise.kinematics.ik import solve_ik as _solve_ik
from reachwise.kinematics.jacobian import jacobian as _jacobian
from reachwise.kinematics.jacobian import param_jacobian as _param_jacobian
from reachwise.kinematics.jacobian import point_jacobian as _point_jacobian
from reachwise.kinematics.link_geometry import LinkGeometry, shapes_by_link
from reachwise.kinematics.transforms import Pose, check_pose

JointType = Literal["revolute", "prismatic", "fixed"]
Convention = Literal["modified", "classic"]
DH_PARAMS: tuple[str, ...] = ("a", "alpha", "d", "theta")
BASE_PARAMS: tuple[str, ...] = ("x", "y", "z", "roll", "pitch", "yaw")
#: the design objectives a :class:`DesignSpace` may weight (their maths is in
#: ``synthesis.objectives``): name -> +1 when higher is better, -1 when lower is better
OBJECTIVES: dict[str, int] = {
    "gci": 1, "kci": 1, "size": -1, "limits": -1, "bounds": -1, "clearance": 1,
}  # fmt: skip
_KIND = {"revolute": 0, "prismatic": 1, "fixed": 2}


@dataclass(frozen=True)
class Joint:
    """One DH row: the joint type, its four parameters (m, rad) and its actuator limits.

    ``limits`` bound ``q`` (rad or m; default ``(−π, π)`` for a revolute joint and
    unbounded for a prismatic one), ``vmax`` bounds ``|q̇|`` (rad/s or m/s). A passive
    joint is moved by the plant (e.g. a freely hanging grabber), never commanded.
    """

    type: JointType
    a: float = 0.0
    alpha: float = 0.0
    d: float = 0.0
    theta: float = 0.0
    limits: tuple[float, float] = None  # type: ignore[assignment]  # set by type below
    vmax: float = float("inf")
    passive: bool = False
    name: str = ""

    def __post_init__(self) -> None:
        if self.type not in _KIND:
            raise InputError("joint", "type", f"unknown joint type {self.type!r}")
        if self.limits is None:
            default = {"revolute": (-np.pi, np.pi), "prismatic": (-np.inf, np.inf)}
            object.__setattr__(self, "limits", default.get(self.type, (0.0, 0.0)))
        object.__setattr__(self, "limits", (float(self.limits[0]), float(self.limits[1])))
        for f in ("a", "alpha", "d", "theta"):
            v = getattr(self, f)
            if not np.isfinite(v):
                raise InputError("joint", f, f"must be finite, got {v}")
        lo, hi = self.limits
        if np.isnan(lo) or np.isnan(hi):
            raise InputError("joint", "limits", "NaN limit")
        if self.type != "fixed" and not lo <= hi:
            raise InputError("joint", "limits", f"lower {lo} > upper {hi}")
        if not self.vmax > 0:
            raise InputError("joint", "vmax", f"must be > 0, got {self.vmax}")
        if self.passive and self.type == "fixed":
            raise InputError("joint", "passive", "a fixed joint cannot be passive")

    @property
    def movable(self) -> bool:
        return self.type != "fixed"


@dataclass(frozen=True)
class DesignSpace:
    """What a synthesis may change and within which bounds (P-I §3, P-II §4.1).

    ``joints`` maps a 0-based joint index to ``{param: (lo, hi)}`` with params among
    ``a, alpha, d, theta``; ``base`` maps ``x, y, z, roll, pitch, yaw`` to bounds.
    What a designer asks beyond reach (``synthesis.objectives``): ``min_length`` (m)
    every free ``a`` and ``d`` keeps in magnitude (a link that can be built),
    ``margin`` the fraction of each range the ``bounds`` objective keeps free, and
    ``objective`` the weights of the named objectives (``{"gci": 1.0, "size": 0.2}``).
    ``bodies`` are the bodies whose clearance the synthesis keeps
    (``reachwise.kinematics.design_bodies.DesignBody``) and ``clearance`` (m) the
    smallest distance every watched pair keeps at every task pose (0: not checked).
    """

    joints: Mapping[int, Mapping[str, tuple[float, float]]] = field(default_factory=dict)
    base: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    min_length: float = 0.0
    margin: float = 0.05
    objective: Mapping[str, float] = field(default_factory=dict)
    bodies: tuple[DesignBody, ...] = ()
    clearance: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "bodies", tuple(self.bodies))
        if not (np.isfinite(self.clearance) and self.clearance >= 0):
            raise InputError("design", "clearance", f"must be >= 0, got {self.clearance}")
        names = [b.name for b in self.bodies]
        if len(set(names)) != len(names):
            raise InputError("design", "bodies", "two bodies share a name")
        if not (np.isfinite(self.min_length) and self.min_length >= 0):
            raise InputError("design", "min_length", f"must be >= 0, got {self.min_length}")
        if not (np.isfinite(self.margin) and 0 < self.margin < 0.5):
            raise InputError("design", "margin", f"must lie in (0, 0.5), got {self.margin}")
        for name, w in self.objective.items():
            if not (np.isfinite(w) and w >= 0):
                raise InputError("design", f"objective.{name}", f"weight must be >= 0, got {w}")
        for j, params in self.joints.items():
            for p, (lo, hi) in params.items():
                if p not in DH_PARAMS:
                    raise InputError("design", f"joints.{j}.{p}", "unknown DH parameter")
                _check_bounds(f"joints.{j}.{p}", lo, hi)
        for p, (lo, hi) in self.base.items():
            if p not in BASE_PARAMS:
                raise InputError("design", f"base.{p}", f"unknown base coordinate {p!r}")
            _check_bounds(f"base.{p}", lo, hi)

    @property
    def free(self) -> list[tuple[str, int, str]]:
        """Free parameters in decision order: ``("joint", j, p)`` then ``("base", -1, p)``."""
        out = [
            ("joint", j, p) for j in sorted(self.joints) for p in DH_PARAMS if p in self.joints[j]
        ]
        out += [("base", -1, p) for p in BASE_PARAMS if p in self.base]
        return out

    @property
    def size(self) -> int:
        return len(self.free)


def _check_bounds(where: str, lo: float, hi: float) -> None:
    if not (np.isfinite(lo) and np.isfinite(hi)):
        raise InputError("design", where, f"bounds must be finite, got [{lo}, {hi}]")
    if lo > hi:
        raise InputError("design", where, f"lower bound {lo} > upper bound {hi}")


@dataclass(frozen=True, eq=False)
class Robot:
    """A serial chain with base and tool frames, limits, geometry and design bounds.

    Immutable: ``with_parameters`` returns a new robot. Methods take ``q`` of shape
    ``(n,)`` or a batch ``(m, n)`` and return poses ``(4, 4)`` / ``(m, 4, 4)`` and
    geometric Jacobians in the world frame, linear rows first.

    ``geometry`` maps a body (``body_names``; by default the frames ``link_names``) to
    its collision shapes, ``visual`` to the shapes a viewer draws (a URDF's
    ``<visual>`` elements); each value is a tuple of
    :class:`~reachwise.kinematics.link_geometry.LinkGeometry` in the frame the body
    rides on (one shape alone is accepted and stored as a one-shape tuple).
    ``frame_names`` names the rows of ``fk_all`` (default ``link_0`` … ``tool``);
    ``bodies`` maps each body to its ``reachwise.kinematics.bodies.Body`` (default:
    one per frame, a chain).
    """

    name: str
    joints: tuple[Joint, ...]
    convention: Convention = "modified"
    base: Pose = field(default_factory=lambda: np.eye(4))
    tool: Pose = field(default_factory=lambda: np.eye(4))
    geometry: Mapping[str, tuple[LinkGeometry, ...]] = field(default_factory=dict)
    design: DesignSpace = field(default_factory=DesignSpace)
    source: str | None = None
    visual: Mapping[str, tuple[LinkGeometry, ...]] = field(default_factory=dict)
    frame_names: tuple[str, ...] = ()
    bodies: Mapping[str, Body] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.joints:
            raise RobotFileError(self.source or self.name, "joints", "a robot needs joints")
        if self.convention not in ("modified", "classic"):
            raise RobotFileError(self.source or self.name, "convention", "modified or classic")
        object.__setattr__(self, "joints", tuple(self.joints))
        for f in ("base", "tool"):
            M = check_pose(getattr(self, f), f"{self.source or self.name}: {f}")
            M = M.copy()
            M.setflags(write=False)
            object.__setattr__(self, f, M)
        self._check_names()
        names = set(self.body_names)
        for f in ("geometry", "visual"):
            shapes = shapes_by_link(self.source or self.name, getattr(self, f), f)
            for link in shapes:
                if link not in names:
                    raise RobotFileError(self.source or self.name, f"{f}.{link}", "no such link")
            object.__setattr__(self, f, shapes)
        for j in self.design.joints:
            if not 0 <= j < len(self.joints):
                raise RobotFileError(
                    self.source or self.name, f"design.joints.{j}", "no such joint"
                )
        for b in self.design.bodies:
            where = f"design.bodies.{b.name}"
            if b.link not in names:
                raise RobotFileError(self.source or self.name, where, f"no link {b.link!r}")
            if b.follows_design and b.link in ("link_0", "tool"):
                raise RobotFileError(
                    self.source or self.name, where, "the base and tool follow no DH row"
                )

    def _check_names(self) -> None:
        src = self.source or self.name
        object.__setattr__(self, "frame_names", tuple(str(f) for f in self.frame_names))
        if self.frame_names:
            if len(self.frame_names) != len(self.joints) + 2:
                raise RobotFileError(
                    src, "frame_names", f"expected {len(self.joints) + 2} names (one per frame)"
                )
            if len(set(self.frame_names)) != len(self.frame_names) or not all(self.frame_names):
                raise RobotFileError(src, "frame_names", "names must be unique and non-empty")
        object.__setattr__(self, "bodies", dict(self.bodies))
        frames = set(self.link_names)
        for name, body in self.bodies.items():
            if body.frame not in frames:
                raise RobotFileError(src, f"bodies.{name}", f"no frame {body.frame!r}")
            if body.parent and body.parent not in self.bodies:
                raise RobotFileError(src, f"bodies.{name}", f"no body {body.parent!r}")

    # ---- sizes and per-joint arrays -------------------------------------------------
    @cached_property
    def n(self) -> int:
        """Number of joint variables: every non-fixed joint, passive ones included."""
        return sum(j.movable for j in self.joints)

    @cached_property
    def movable_joints(self) -> tuple[int, ...]:
        """Index (into ``joints``) of the joint behind each entry of ``q``."""
        return tuple(i for i, j in enumerate(self.joints) if j.movable)

    @cached_property
    def link_names(self) -> tuple[str, ...]:
        """The frames, the rows of ``fk_all``: ``frame_names``, or ``link_0`` (base),
        ``link_1`` … ``link_N`` and ``tool``."""
        if self.frame_names:
            return self.frame_names
        return (*(f"link_{i}" for i in range(len(self.joints) + 1)), "tool")

    @cached_property
    def body_tree(self) -> Mapping[str, Body]:
        """Every body with its frame and parent (``bodies``, or one body per frame)."""
        return self.bodies if self.bodies else chain_bodies(self.link_names)

    @cached_property
    def body_names(self) -> tuple[str, ...]:
        """The bodies (the names ``geometry`` and clouds use), base to tool: each
        frame's bodies in the order given."""
        row = {f: i for i, f in enumerate(self.link_names)}
        return tuple(sorted(self.body_tree, key=lambda b: row[self.body_tree[b].frame]))

    def frame_of(self, name: str) -> str:
        """The frame (``link_names`` entry) that body or frame ``name`` rides on;
        ``"tool"`` always names the tool frame."""
        body = self.body_tree.get(name)
        if body is not None:
            return body.frame
        if name in self.link_names:
            return name
        if name == "tool":
            return self.link_names[-1]
        valid = sorted({*self.link_names, *self.body_names})
        raise UnknownName(self.source or self.name, "link", name, valid)

    @cached_property
    def lower(self) -> NDArray[np.float64]:
        return _ro(np.array([self.joints[i].limits[0] for i in self.movable_joints], float))

    @cached_property
    def upper(self) -> NDArray[np.float64]:
        return _ro(np.array([self.joints[i].limits[1] for i in self.movable_joints], float))

    @cached_property
    def vmax(self) -> NDArray[np.float64]:
        return _ro(np.array([self.joints[i].vmax for i in self.movable_joints], float))

    @cached_property
    def actuated(self) -> NDArray[np.bool_]:
        """True for each entry of ``q`` the controller may command (not passive)."""
        return _ro(np.array([not self.joints[i].passive for i in self.movable_joints]))

    @cached_property
    def prismatic(self) -> NDArray[np.bool_]:
        return _ro(np.array([self.joints[i].type == "prismatic" for i in self.movable_joints]))

    @cached_property
    def dh(self) -> NDArray[np.float64]:
        """``(N, 4)`` table of a, alpha, d, theta (offsets) for every joint."""
        return _ro(np.array([[j.a, j.alpha, j.d, j.theta] for j in self.joints], float))

    @cached_property
    def arrays(self) -> Chain:
        qidx = np.full(len(self.joints), -1, dtype=np.int64)
        for k, i in enumerate(self.movable_joints):
            qidx[i] = k
        return Chain(
            kind=_ro(np.array([_KIND[j.type] for j in self.joints], dtype=np.int64)),
            qidx=_ro(qidx),
            dh=np.ascontiguousarray(self.dh),
            classic=self.convention == "classic",
            base=np.ascontiguousarray(self.base),
            tool=np.ascontiguousarray(self.tool),
        )

    @cached_property
    def design_names(self) -> tuple[str, ...]:
        """Names of the free design parameters in the thesis's DH notation (P-I Table 1):
        modified DH row ``i`` (1-based) holds ``a_{i-1}, alpha_{i-1}, d_i, theta_i``, so
        SB60's free parameters read ``a1 a2 d3 d4 a4 d6 d7``; classic row ``i`` holds
        ``a_i, alpha_i, d_i, theta_i``. Base coordinates read ``base.x`` etc."""
        classic = self.convention == "classic"

        def name(kind: str, j: int, p: str) -> str:
            if kind != "joint":
                return f"base.{p}"
            return f"{p}{j + 1 if classic or p in ('d', 'theta') else j}"

        return tuple(name(kind, j, p) for kind, j, p in self.design.free)

    def link_index(self, link: int | str) -> int:
        """Row of ``fk_all`` for a link given by index or by name (a frame, or a body:
        the frame it rides on)."""
        if isinstance(link, str):
            return self.link_names.index(self.frame_of(link))
        k = int(link)
        if not 0 <= k < len(self.link_names):
            raise InputError(self.name, "link", f"link index {k} outside 0..{len(self.joints) + 1}")
        return k

    def within_limits(self, q: ArrayLike, tol: float = 0.0) -> NDArray[np.bool_] | bool:
        """True where ``q`` (``(n,)`` or ``(m, n)``) is inside the joint limits."""
        Q = np.asarray(q, dtype=float)
        ok = np.all((Q >= self.lower - tol) & (Q <= self.upper + tol), axis=-1)
        return bool(ok) if ok.ndim == 0 else ok

    # ---- kinematics (implemented in fk.py / jacobian.py / ik.py) -------------------
    def fk(self, q: ArrayLike) -> Pose:
        """Tool pose in world, ``(4, 4)`` or ``(m, 4, 4)``."""
        return _fk(self, q)

    def fk_all(self, q: ArrayLike) -> Pose:
        """World pose of every frame (``link_names`` order): ``(N+2, 4, 4)`` or batched."""
        return _fk_all(self, q)

    def jacobian(self, q: ArrayLike) -> NDArray[np.float64]:
        """Geometric tool Jacobian in world, linear rows first: ``(6, n)`` or ``(m, 6, n)``."""
        return _jacobian(self, q)

    def point_jacobian(
        self, q: ArrayLike, link: int | str, point: ArrayLike, frame: str = "link"
    ) -> NDArray[np.float64]:
        """``(3, n)`` Jacobian of a point fixed to ``link`` (given in the link frame, or
        in world coordinates when ``frame="world"``)."""
        return _point_jacobian(self, q, link, point, frame)

    def param_jacobian(self, q: ArrayLike) -> NDArray[np.float64]:
        """``(6, 4N + 6)`` Jacobian of the tool pose w.r.t. every DH parameter and the base."""
        return _param_jacobian(self, q)

    def ik(
        self,
        T: ArrayLike,
        q0: ArrayLike | None = None,
        mask: Any = None,
        rng: np.random.Generator | int | None = None,
        **options: Any,
    ) -> IKResult:
        """Inverse kinematics by damped least squares (see ``reachwise.kinematics.ik``)."""
        return _solve_ik(self, T, q0=q0, mask=mask, rng=rng, **options)

    # ---- derived robots and files --------------------------------------------------
    def with_parameters(
        self, dh: ArrayLike | None = None, base: ArrayLike | None = None, name: str | None = None
    ) -> Robot:
        """A copy with a new ``(N, 4)`` DH table and/or a new 4x4 base pose."""
        from dataclasses import replace

        joints = self.joints
        if dh is not None:
            table = np.asarray(dh, dtype=float)
            if table.shape != (len(self.joints), 4):
                raise InputError(
                    self.name, "dh", f"expected {(len(self.joints), 4)}, got {table.shape}"
                )
            joints = tuple(
                replace(j, a=float(r[0]), alpha=float(r[1]), d=float(r[2]), theta=float(r[3]))
                for j, r in zip(self.joints, table, strict=True)
            )
        return replace(
            self,
            joints=joints,
            base=self.base if base is None else np.asarray(base, dtype=float),
            name=self.name if name is None else name,
        )


def _ro(a: NDArray[Any]) -> NDArray[Any]:
    a.setflags(write=False)
    return a
