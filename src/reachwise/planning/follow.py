"""Follow a timed joint path with the task-space controller (the hybrid's local half).

The controller of thesis §3.3 tracks a tool goal (Eq. 3.8–3.13) with avoidance in
task and null space (Eq. 3.14–3.18). To follow a planned joint path with that same
controller, avoidance still active, :class:`PathFollower` hands it one intermediate
goal per tick (6-D, or 3-D for a robot with fewer than six actuated joints) a little
ahead of the path parameter ``s``: the position of ``FK(q_ref(s + τ))`` and the
orientation of ``FK(q_ref(s + τ_O))``, with

    τ = 1 / k_v,   τ_O = 2 / k_w,

so that with the proportional laws of Eq. 3.8–3.10 a reference moving at constant
speed is tracked without lag: ``ṗ = k_v (p_d − p)`` moves at ``v`` when the goal leads
by ``τ v``, and ``ω = k_w e_O`` with the quaternion error's ``|e_O| = sin(θ/2) ≈ θ/2``
(Eq. 3.9) turns at ``ω`` when the goal leads by ``θ = 2 ω / k_w`` (a feed-forward by
look-ahead). ``s``
advances with time only while the tool is within ``hold`` (m) and ``hold_angle``
(rad) of the reference at ``s``; when avoidance or a speed bound holds the tool back,
the reference waits and the goal is the reference itself (no look-ahead) until the
tool has caught up. The path is done when ``s`` has reached its end and the tool is
within the hold distance of the final pose; it is stuck when ``s`` has not advanced
for ``stall_time`` seconds.

The controller follows tool poses, not joints: a robot with more free joints than the
goal has dimensions may reach the same poses with other joint values (its null-space
motion is the controller's), so such a path is planned with the surplus joints held
and followed with them locked (:func:`reachwise.planning.plan_escape`).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.control.controller import Goal
from reachwise.errors import InputError
from reachwise.kinematics.robot import Robot
from reachwise.planning.timing import TimedPath

__all__ = ["PathFollower"]


def _angle(Ra: NDArray[np.float64], Rb: NDArray[np.float64]) -> float:
    c = (np.trace(Ra.T @ Rb) - 1.0) / 2.0
    return math.acos(max(-1.0, min(1.0, float(c))))


class PathFollower:
    """Intermediate goals along ``path`` for ``robot``'s controller (see module doc).

    ``lead`` (s): the look-ahead ``τ`` (``1 / k_v``), ``turn_lead`` (s) that of the
    orientation ``τ_O`` (``2 / k_w``; default ``lead``); ``hold`` (m) and ``hold_angle``
    (rad): tracking error beyond which the reference waits; ``stall_time`` (s): how
    long it may wait before the follower is :attr:`stuck`; ``dims``: 6 (tool poses)
    or 3 (tool positions; orientation errors are then ignored).
    """

    def __init__(
        self,
        robot: Robot,
        path: TimedPath,
        *,
        lead: float,
        turn_lead: float | None = None,
        hold: float = 0.05,
        hold_angle: float = 0.25,
        stall_time: float = 3.0,
        dims: int = 6,
    ) -> None:
        turn_lead = lead if turn_lead is None else turn_lead
        checks = (
            ("lead", lead),
            ("turn_lead", turn_lead),
            ("hold", hold),
            ("hold_angle", hold_angle),
        )
        for name, v in checks:
            if not (math.isfinite(v) and v >= 0):
                raise InputError("follower", name, f"must be finite and >= 0, got {v}")
        if not stall_time > 0:
            raise InputError("follower", "stall_time", f"must be > 0, got {stall_time}")
        if dims not in (3, 6):
            raise InputError("follower", "dims", f"3 or 6, got {dims}")
        if path.q.shape[1] != robot.n:
            raise InputError("follower", "path", f"expected {robot.n} joint values per row")
        self.robot = robot
        self.path = path
        self.lead = lead
        self.turn_lead = turn_lead
        self.hold = hold
        self.hold_angle = hold_angle
        self.stall_time = stall_time
        self.dims = dims
        self.s = 0.0
        self.waited = 0.0
        self._end = robot.fk(path.q[-1])

    def errors(self, q: ArrayLike, s: float | None = None) -> tuple[float, float]:
        """Position (m) and orientation (rad) error of the tool at ``q`` from the
        reference at path time ``s`` (default the current one)."""
        T = self.robot.fk(q)
        R = self.robot.fk(self.path.at(self.s if s is None else s))
        eo = _angle(T[:3, :3], R[:3, :3]) if self.dims == 6 else 0.0
        return float(np.linalg.norm(T[:3, 3] - R[:3, 3])), eo

    def goal(self, q: ArrayLike, dt: float) -> Goal:
        """This tick's goal; advances the reference by ``dt`` when the tool keeps up."""
        ep, eo = self.errors(q)
        keeping_up = ep <= self.hold and eo <= self.hold_angle
        if keeping_up and self.s < self.path.duration:
            self.s = min(self.s + dt, self.path.duration)
            self.waited = 0.0
        elif not keeping_up:
            self.waited += dt
        if not keeping_up:  # wait for the tool at the reference itself
            return Goal(self.robot.fk(self.path.at(self.s)), self.dims)  # type: ignore[arg-type]
        T = self.robot.fk(self.path.at(self.s + self.lead))
        if self.dims == 6 and self.turn_lead != self.lead:
            T[:3, :3] = self.robot.fk(self.path.at(self.s + self.turn_lead))[:3, :3]
        return Goal(T, self.dims)  # type: ignore[arg-type]

    @property
    def finished(self) -> bool:
        """The reference has reached the path's end."""
        return self.s >= self.path.duration

    def done(self, q: ArrayLike) -> bool:
        """The reference is at the end and the tool within the hold distance of it."""
        if not self.finished:
            return False
        T = self.robot.fk(q)
        eo = _angle(T[:3, :3], self._end[:3, :3]) if self.dims == 6 else 0.0
        return bool(
            np.linalg.norm(T[:3, 3] - self._end[:3, 3]) <= self.hold and eo <= self.hold_angle
        )

    @property
    def stuck(self) -> bool:
        """The reference has waited ``stall_time`` for the tool."""
        return self.waited >= self.stall_time
