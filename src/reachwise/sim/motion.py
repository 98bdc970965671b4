"""Trajectories of moving obstacles: the pose and the velocity of an object at time ``t``.

The thesis (§6.3) and P-V (§VI) leave moving obstacles to future work; the simulator
moves an environment object along one of these trajectories and puts its pose into
the distance scene every tick (:mod:`reachwise.sim.simulate`). Pure math: arrays in,
arrays out, no files, no clocks.

- :class:`WaypointTrajectory`: poses at given times; between two waypoints the
  position is interpolated linearly and the orientation by spherical linear
  interpolation (``scipy.spatial.transform.Slerp``), so within a segment the object
  moves with the constant linear velocity ``v = (p₁ − p₀)/(t₁ − t₀)`` and the constant
  world angular velocity ``ω = R₀ log(R₀ᵀR₁)/(t₁ − t₀)`` (the rotation vector of the
  segment's relative rotation, turned into the world frame). Before the first
  waypoint and after the last the object stands still at that waypoint; with
  ``loop`` the motion repeats with period ``t_last − t_first`` (the last pose must
  equal the first, so that the object never jumps).
- :class:`ConstantVelocity`: ``p(t) = p₀ + v τ``, ``R(t) = exp([ω]× τ) R₀`` with
  ``τ = clip(t, start, stop) − start`` (``ω`` in the world frame): standing still
  before ``start`` and after ``stop``.

Both give ``pose(t)`` (4×4) and ``twist(t) = (v, ω)``, the velocity of the object
frame's origin and its angular velocity, both in the world frame; a point ``x`` of the
object moves with ``v + ω × (x − p)`` (:func:`point_velocity`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation, Slerp

from reachwise.errors import InputError

__all__ = [
    "ConstantVelocity",
    "Trajectory",
    "WaypointTrajectory",
    "point_velocity",
]

_SRC = "motion"


@runtime_checkable
class Trajectory(Protocol):
    """What the simulator needs of a moving object's trajectory."""

    def pose(self, t: float) -> NDArray[np.float64]: ...

    def twist(self, t: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]: ...

    @property
    def max_speed(self) -> float: ...


def _pose(p: NDArray[np.float64], R: NDArray[np.float64]) -> NDArray[np.float64]:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = p
    return T


def _check_time(t: float) -> float:
    tt = float(t)
    if not math.isfinite(tt):
        raise InputError(_SRC, "t", f"must be finite, got {t!r}")
    return tt


@dataclass(frozen=True, eq=False)
class WaypointTrajectory:
    """Poses at increasing times: ``times`` (k,) s, ``positions`` (k, 3) m and
    ``quats`` (k, 4) scipy ``(x, y, z, w)`` unit quaternions (normalised here).

    ``loop``: repeat with period ``times[-1] − times[0]`` (needs the last pose equal to
    the first). One waypoint is an object standing still.
    """

    times: NDArray[np.float64]
    positions: NDArray[np.float64]
    quats: NDArray[np.float64]
    loop: bool = False
    _slerp: Slerp | None = field(init=False, repr=False, default=None)

    def __post_init__(self) -> None:
        t = np.array(self.times, dtype=float).reshape(-1)
        p = np.array(self.positions, dtype=float)
        q = np.array(self.quats, dtype=float)
        k = t.size
        if k == 0:
            raise InputError(_SRC, "waypoints", "give at least one waypoint")
        if p.shape != (k, 3) or q.shape != (k, 4):
            raise InputError(
                _SRC, "waypoints", f"expected ({k}, 3) positions and ({k}, 4) quaternions"
            )
        if not (np.isfinite(t).all() and np.isfinite(p).all() and np.isfinite(q).all()):
            raise InputError(_SRC, "waypoints", "times, positions and orientations must be finite")
        if k > 1 and not np.all(np.diff(t) > 0):
            raise InputError(_SRC, "waypoints", f"times must increase strictly, got {t.tolist()}")
        norm = np.linalg.norm(q, axis=1)
        if not np.all(norm > 1e-12):
            raise InputError(_SRC, "waypoints", "a quaternion is zero")
        q = q / norm[:, None]
        # shortest arcs: each quaternion on the same side as its predecessor
        for i in range(1, k):
            if float(q[i] @ q[i - 1]) < 0.0:
                q[i] = -q[i]
        if self.loop:
            if k < 2:
                raise InputError(_SRC, "loop", "a looping trajectory needs two waypoints or more")
            same_p = np.allclose(p[0], p[-1], atol=1e-9)
            same_r = abs(abs(float(q[0] @ q[-1])) - 1.0) < 1e-12
            if not (same_p and same_r):
                raise InputError(
                    _SRC, "loop", "the last waypoint must repeat the first (else the object jumps)"
                )
        for name, arr in (("times", t), ("positions", p), ("quats", q)):
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        if k > 1:
            object.__setattr__(self, "_slerp", Slerp(t, Rotation.from_quat(q)))

    @property
    def period(self) -> float:
        """``times[-1] − times[0]`` (s)."""
        return float(self.times[-1] - self.times[0])

    def _local(self, t: float) -> float:
        """``t`` mapped into ``[times[0], times[-1]]`` (wrapped with ``loop``)."""
        t0, t1 = float(self.times[0]), float(self.times[-1])
        if self.loop and t > t1:
            return t0 + math.fmod(t - t0, t1 - t0)
        return min(max(t, t0), t1)

    def _segment(self, t: float) -> int:
        """Index ``i`` of the segment ``[times[i], times[i+1]]`` holding ``t``."""
        i = int(np.searchsorted(self.times, t, side="right")) - 1
        return min(max(i, 0), self.times.size - 2)

    def pose(self, t: float) -> NDArray[np.float64]:
        """World pose (4×4) at time ``t`` (s)."""
        tt = self._local(_check_time(t))
        if self._slerp is None:
            return _pose(self.positions[0], Rotation.from_quat(self.quats[0]).as_matrix())
        i = self._segment(tt)
        t0, t1 = self.times[i], self.times[i + 1]
        s = (tt - t0) / (t1 - t0)
        p = (1.0 - s) * self.positions[i] + s * self.positions[i + 1]
        R = self._slerp([tt]).as_matrix()[0]
        return _pose(p, R)

    def twist(self, t: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(v, ω)`` at ``t``: the origin's velocity and the angular velocity (world,
        m/s and rad/s). At a waypoint the velocity of the segment that starts there;
        zero outside ``[times[0], times[-1]]`` unless looping."""
        t_in = _check_time(t)
        zero = (np.zeros(3), np.zeros(3))
        if self._slerp is None:
            return zero
        if not self.loop and (t_in < self.times[0] or t_in >= self.times[-1]):
            return zero
        i = self._segment(self._local(t_in))
        return self._segment_twist(i)

    def _segment_twist(self, i: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        dt = float(self.times[i + 1] - self.times[i])
        v = (self.positions[i + 1] - self.positions[i]) / dt
        R0 = Rotation.from_quat(self.quats[i])
        rel = (R0.inv() * Rotation.from_quat(self.quats[i + 1])).as_rotvec()
        w = R0.apply(rel) / dt
        return np.asarray(v, dtype=float), np.asarray(w, dtype=float)

    @property
    def max_speed(self) -> float:
        """Largest speed of the object frame's origin over the trajectory (m/s)."""
        if self._slerp is None:
            return 0.0
        return max(
            float(np.linalg.norm(self._segment_twist(i)[0])) for i in range(self.times.size - 1)
        )


@dataclass(frozen=True, eq=False)
class ConstantVelocity:
    """Constant linear velocity ``velocity`` (m/s) and angular velocity
    ``angular_velocity`` (rad/s, world frame) from ``start`` to ``stop`` (s), starting
    at the pose ``pose0``; standing still outside ``[start, stop]``."""

    pose0: NDArray[np.float64]
    velocity: NDArray[np.float64]
    angular_velocity: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    start: float = 0.0
    stop: float = math.inf

    def __post_init__(self) -> None:
        P = np.array(self.pose0, dtype=float)
        if P.shape != (4, 4) or not np.isfinite(P).all():
            raise InputError(_SRC, "pose", "expected a finite 4x4 pose")
        R = P[:3, :3]
        if not np.allclose(R @ R.T, np.eye(3), atol=1e-9) or not np.linalg.det(R) > 0:
            raise InputError(_SRC, "pose", "its rotation part is not a rotation")
        v = np.array(self.velocity, dtype=float).reshape(-1)
        w = np.array(self.angular_velocity, dtype=float).reshape(-1)
        if (
            v.shape != (3,)
            or w.shape != (3,)
            or not (np.isfinite(v).all() and np.isfinite(w).all())
        ):
            raise InputError(_SRC, "velocity", "velocity and angular velocity: 3 finite values")
        if not (math.isfinite(self.start) and self.stop > self.start):
            raise InputError(
                _SRC, "stop", f"need finite start < stop, got {self.start}, {self.stop}"
            )
        for name, arr in (("pose0", P), ("velocity", v), ("angular_velocity", w)):
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    def pose(self, t: float) -> NDArray[np.float64]:
        tau = min(max(_check_time(t), self.start), self.stop) - self.start
        R = Rotation.from_rotvec(self.angular_velocity * tau).as_matrix() @ self.pose0[:3, :3]
        return _pose(self.pose0[:3, 3] + self.velocity * tau, R)

    def twist(self, t: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        tt = _check_time(t)
        if self.start <= tt < self.stop:
            return self.velocity.copy(), self.angular_velocity.copy()
        return np.zeros(3), np.zeros(3)

    @property
    def max_speed(self) -> float:
        return float(np.linalg.norm(self.velocity))


def point_velocity(
    twist: tuple[ArrayLike, ArrayLike], origin: ArrayLike, points: ArrayLike
) -> NDArray[np.float64]:
    """Velocity of rigidly carried ``points`` (m, world), ``v + ω × (x − origin)``, for
    the ``twist`` ``(v, ω)`` of a frame whose origin is at ``origin``."""
    v = np.asarray(twist[0], dtype=float)
    w = np.asarray(twist[1], dtype=float)
    x = np.asarray(points, dtype=float) - np.asarray(origin, dtype=float)
    return np.asarray(v + np.cross(w, x), dtype=float)
