"""Is a joint configuration collision-free? The distance scene as a planner's validity check.

A global planner (:mod:`reachwise.planning.escape`) asks two things of the world:

- **state validity**: at joint values ``q`` of one robot, every watched pair that
  involves one of the robot's parts keeps at least its collision margin ``ρ_O`` (the
  same margins the controller avoids, thesis Eq. 3.16), and ``q`` is within the joint
  limits. :class:`ClearanceChecker` answers it from a snapshot of the distance scene
  (:class:`~reachwise.distance.scene.Scene` or the collision server's client): the
  clouds of every object, the poses of everything that is not on this robot (other
  robots, moving objects) frozen where they are now, and one warm-started
  :class:`~reachwise.distance.engine.PairQuery` per pair whose margin is ``ρ_O``, so a
  pair farther away than its margin is answered "no risk" after a few box tests.
- **motion validity**: a straight joint-space segment is checked at discrete states.
  :func:`sweep_bounds` gives, per joint, an upper bound ``R_k`` on the speed of any
  point of the robot's watched parts per unit joint speed (the largest distance of a
  part point from joint ``k``'s axis over every configuration, 1 for a prismatic
  joint), so along a segment every such point moves at most ``Σ_k R_k |Δq_k| ≤
  ‖R‖₂ ‖Δq‖₂`` (Cauchy–Schwarz). Checking states ``s`` apart in joint space therefore
  bounds the workspace motion between checks by ``‖R‖₂ s``
  (:meth:`ClearanceChecker.joint_resolution`): with that at most ``δ < 2 ρ_O`` no part
  can pass through an obstacle between two checked states, however thin (it would have
  to move from ``ρ_O`` on one side to ``ρ_O`` on the other), and every state of the
  segment keeps at least ``ρ_O − δ/2``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.distance.engine import PairQuery, StrategyName
from reachwise.distance.scene import OnLink, SceneLike
from reachwise.errors import InputError
from reachwise.kinematics.ik import finite_limits
from reachwise.kinematics.robot import Robot

__all__ = ["ClearanceChecker", "WatchedPart", "sweep_bounds"]


@dataclass(frozen=True)
class WatchedPart:
    """A cloud on a robot link: frame index (``robot.link_names``) and the largest
    distance of its points from the link frame's origin (m), offset included."""

    frame: int
    radius: float


def _joint_reach(robot: Robot, j: int) -> float:
    """Largest length of joint ``j``'s translation, ``√(a² + d²)`` (prismatic: the
    largest ``|q + d|`` within the limits)."""
    jt = robot.joints[j]
    d = abs(jt.d)
    if jt.type == "prismatic":
        lo, hi = jt.limits
        if not (math.isfinite(lo) and math.isfinite(hi)):
            return math.inf
        d = max(abs(lo + jt.d), abs(hi + jt.d))
    return math.hypot(jt.a, d)


def sweep_bounds(robot: Robot, parts: list[WatchedPart]) -> NDArray[np.float64]:
    """Per entry of ``q``: ``R_k`` (m/rad, or 1 for a prismatic joint, 0 for a joint
    that moves none of ``parts``), a bound on ``|ṗ| / |q̇_k|`` for every point ``p`` of
    the parts in every configuration.

    A revolute joint moves a point at ``|ω × r| ≤ r`` per rad/s, ``r`` the point's
    distance from the joint axis. The axis passes through the origin of frame
    ``j + 1`` (modified DH, joint ``j`` 0-based) or of frame ``j`` (classic DH), and
    from there to the point the chain adds one translation of length ``√(a² + d²)``
    per later joint (the tool offset for the tool frame) plus the point's distance
    from its own frame's origin — the triangle inequality bounds ``r`` by their sum.
    """
    classic = robot.convention == "classic"
    N = len(robot.joints)
    reach = [_joint_reach(robot, j) for j in range(N)]
    tool = float(np.linalg.norm(robot.tool[:3, 3]))
    out = np.zeros(robot.n)
    for k, j in enumerate(robot.movable_joints):
        best = 0.0
        for part in parts:
            f = part.frame  # frame f is after joint f-1; frame N+1 is the tool
            if f < j + 1:
                continue  # joint j does not move this part
            if robot.joints[j].type == "prismatic":
                best = max(best, 1.0)
                continue
            first = j if classic else j + 1
            chain = sum(reach[first : min(f, N)]) + (tool if f == N + 1 else 0.0)
            best = max(best, chain + part.radius)
        out[k] = best
    return out


class ClearanceChecker:
    """Validity of one robot's joint configurations in a frozen copy of a distance scene.

    ``scene``: the scene (its current state is the snapshot: other robots' joints and
    moving objects' poses stay as they are now); ``robot``: the planning robot's name
    in it and its model; ``margins``: ``ρ_O`` per pair ``(a, b)`` of object names
    (default: the scene's pair margin). Only pairs with at least one object on this
    robot count (the others cannot change with its joints). ``strategy`` of the
    distance engine (``"brute"`` for a reference).
    """

    def __init__(
        self,
        scene: SceneLike,
        robot: Robot,
        name: str | None = None,
        margins: Mapping[tuple[str, str], float] | None = None,
        *,
        strategy: StrategyName = "default",
    ) -> None:
        self.robot = robot
        self.name = robot.name if name is None else name
        objects = scene.objects
        poses = scene.poses()
        link_index = {n: i for i, n in enumerate(robot.link_names)}
        mine: dict[str, tuple[int, NDArray[np.float64]]] = {}
        for obj in objects.values():
            src = obj.source
            if isinstance(src, OnLink) and src.robot == self.name:
                mine[obj.name] = (link_index[src.link], np.asarray(src.offset, dtype=float))
        if not mine:
            raise InputError("planner", "robot", f"robot {self.name!r} has no clouds in the scene")
        margins = margins or {}
        self._pairs: list[tuple[str, str]] = []
        self._queries: list[PairQuery] = []
        # per pair and side: (frame index, offset) of a part of this robot, or
        # (-1, world pose) of anything else (frozen)
        self._sides: list[tuple[tuple[int, NDArray[np.float64]], ...]] = []
        margin_list = []
        watched: set[str] = set()
        self.self_pairs = False
        for pair in scene.pairs:
            a, b = pair.a, pair.b
            if a not in mine and b not in mine:
                continue
            m = float(margins.get((a, b), margins.get((b, a), pair.margin)))
            if not (math.isfinite(m) and m > 0):
                raise InputError("planner", f"margin of {a}|{b}", f"must be > 0, got {m}")
            self._pairs.append((a, b))
            margin_list.append(m)
            self._queries.append(
                PairQuery(objects[a].cloud, objects[b].cloud, margin=m, strategy=strategy)
            )
            self._sides.append(
                tuple(mine[n] if n in mine else (-1, poses[n].copy()) for n in (a, b))
            )
            watched.update(n for n in (a, b) if n in mine)
            self.self_pairs |= a in mine and b in mine
        if not self._pairs:
            raise InputError("planner", "pairs", f"no watched pair involves robot {self.name!r}")
        self.margins = np.array(margin_list)
        self.margins.setflags(write=False)
        self.parts = [
            WatchedPart(
                mine[n][0],
                float(
                    np.max(
                        np.linalg.norm(
                            objects[n].cloud.points @ mine[n][1][:3, :3].T + mine[n][1][:3, 3],
                            axis=1,
                        )
                    )
                ),
            )
            for n in sorted(watched)
        ]
        self.lower, self.upper = finite_limits(robot)
        self.checks = 0

    @property
    def pairs(self) -> tuple[str, ...]:
        """The checked pairs, ``"a|b"``."""
        return tuple(f"{a}|{b}" for a, b in self._pairs)

    def with_margins(self, margins: ArrayLike) -> ClearanceChecker:
        """A copy checking the same pairs against other margins (same order as
        :attr:`pairs`)."""
        m = np.asarray(margins, dtype=float).reshape(-1)
        if m.shape != self.margins.shape or not (np.isfinite(m).all() and (m > 0).all()):
            raise InputError("planner", "margins", f"expected {self.margins.size} values > 0")
        new = object.__new__(ClearanceChecker)
        new.__dict__.update(self.__dict__)
        new.margins = m.copy()
        new.margins.setflags(write=False)
        new._queries = [
            PairQuery(q.a, q.b, margin=float(mi), strategy=q.strategy)
            for q, mi in zip(self._queries, m, strict=True)
        ]
        new.checks = 0
        return new

    # ------------------------------------------------------------------ queries
    def _poses(
        self, q: NDArray[np.float64]
    ) -> list[tuple[NDArray[np.float64], NDArray[np.float64]]]:
        frames = self.robot.fk_all(q)
        out: list[tuple[NDArray[np.float64], NDArray[np.float64]]] = []
        for (fa, pa), (fb, pb) in self._sides:
            out.append((frames[fa] @ pa if fa >= 0 else pa, frames[fb] @ pb if fb >= 0 else pb))
        return out

    def _q(self, q: ArrayLike) -> NDArray[np.float64]:
        qq = np.asarray(q, dtype=np.float64).reshape(-1)
        if qq.shape != (self.robot.n,) or not np.isfinite(qq).all():
            raise InputError("planner", "q", f"expected {self.robot.n} finite values")
        return qq

    def within_limits(self, q: ArrayLike, tol: float = 1e-9) -> bool:
        qq = self._q(q)
        return bool(np.all(qq >= self.lower - tol) and np.all(qq <= self.upper + tol))

    def distances(self, q: ArrayLike, *, exact: bool = False) -> NDArray[np.float64]:
        """Per pair, the distance at ``q`` (m); ``inf`` beyond the pair's margin unless
        ``exact`` (then every distance is exact)."""
        qq = self._q(q)
        out = np.empty(len(self._pairs))
        for i, (pa, pb) in enumerate(self._poses(qq)):
            res = self._queries[i](pa, pb, math.inf if exact else None)
            out[i] = res.distance
        return out

    def is_valid(self, q: ArrayLike) -> bool:
        """``q`` within the limits and every pair at least its margin apart."""
        qq = self._q(q)
        self.checks += 1
        if not (np.all(qq >= self.lower - 1e-9) and np.all(qq <= self.upper + 1e-9)):
            return False
        for i, (pa, pb) in enumerate(self._poses(qq)):
            res = self._queries[i](pa, pb)
            if not (res.no_risk or res.distance >= self.margins[i]):
                return False
        return True

    # ------------------------------------------------------------------ motions
    @property
    def sweep(self) -> NDArray[np.float64]:
        """:func:`sweep_bounds` of the watched parts, per entry of ``q``; doubled when
        a self pair is checked (both of its parts move)."""
        R = sweep_bounds(self.robot, self.parts)
        return R * (2.0 if self.self_pairs else 1.0)

    def joint_resolution(self, step: float, joints: ArrayLike | None = None) -> float:
        """Joint-space (L2) spacing of checked states such that no watched point moves
        more than ``step`` metres from one to the next; ``joints`` selects the planned
        entries of ``q`` (the others stay fixed)."""
        if not (math.isfinite(step) and step > 0):
            raise InputError("planner", "step", f"must be > 0, got {step}")
        R = self.sweep
        if joints is not None:
            R = R[np.asarray(joints)]
        norm = float(np.linalg.norm(R))
        if not math.isfinite(norm):
            raise InputError("planner", "step", "a prismatic joint without finite limits")
        return step / norm if norm > 0 else math.inf
