"""Time-parameterize a joint-space path within joint and tool speed limits.

A planned path is a polyline of joint configurations ``q_0 … q_m``; the robot moves
along each segment at a constant joint velocity (linear interpolation in joint space,
the motion the planner validated). Segment ``i`` takes the longest of

- ``max_k |Δq_k| / (f v_max,k)``: every joint within its speed limit ``v_max,k`` (the
  robot file's ``vmax``) scaled by ``f`` (``speed``, ≤ 1);
- the time that keeps the tool's linear speed within ``v_tool`` (m/s) and its angular
  speed within ``ω_tool`` (rad/s) — the controller's bounds of Eq. 3.12–3.13, which
  the reference must not outrun — measured on the tool poses ``fk(q)`` at
  ``samples`` equal steps of the segment (the largest step sets the pace).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.errors import InputError

__all__ = ["TimedPath", "time_path"]


@dataclass(frozen=True, eq=False)
class TimedPath:
    """Joint configurations ``q`` (m, n) at increasing times ``t`` (m,), ``t[0] = 0``;
    linear interpolation in between."""

    t: NDArray[np.float64]
    q: NDArray[np.float64]

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    def at(self, time: float) -> NDArray[np.float64]:
        """The configuration at ``time`` (s), clamped to the path's ends."""
        t = float(np.clip(time, 0.0, self.duration))
        i = int(np.searchsorted(self.t, t, side="right")) - 1
        if i >= len(self.t) - 1:
            return self.q[-1].copy()
        span = self.t[i + 1] - self.t[i]
        w = (t - self.t[i]) / span if span > 0 else 1.0
        return np.asarray((1.0 - w) * self.q[i] + w * self.q[i + 1])

    def velocity(self, time: float) -> NDArray[np.float64]:
        """Joint velocity on the segment containing ``time`` (zero after the end)."""
        t = float(time)
        if t < 0.0 or t >= self.duration:
            return np.zeros(self.q.shape[1])
        i = int(np.searchsorted(self.t, t, side="right")) - 1
        i = min(i, len(self.t) - 2)
        return np.asarray((self.q[i + 1] - self.q[i]) / (self.t[i + 1] - self.t[i]))


def time_path(
    q: ArrayLike,
    vmax: ArrayLike,
    *,
    speed: float = 0.5,
    fk: Callable[[NDArray[np.float64]], NDArray[np.float64]] | None = None,
    tool_speed: float = math.inf,
    tool_rate: float = math.inf,
    samples: int = 16,
) -> TimedPath:
    """Times for the waypoints ``q`` (m, n): each segment at constant joint velocity,
    as fast as ``speed`` × ``vmax`` (per joint) and, with the tool pose function ``fk``
    (batched ``(k, n) -> (k, 4, 4)``), ``tool_speed`` (m/s) and ``tool_rate`` (rad/s)
    allow (see the module docstring). Repeated waypoints are dropped."""
    Q = np.asarray(q, dtype=float)
    if Q.ndim != 2 or Q.shape[0] < 1 or not np.isfinite(Q).all():
        raise InputError("time_path", "q", "expected (m, n) finite joint values, m >= 1")
    n = Q.shape[1]
    v = np.asarray(vmax, dtype=float).reshape(-1)
    if v.shape != (n,) or not (v > 0).all():
        raise InputError("time_path", "vmax", f"expected {n} values > 0")
    if not 0 < speed <= 1:
        raise InputError("time_path", "speed", f"must be in (0, 1], got {speed}")
    for name, val in (("tool_speed", tool_speed), ("tool_rate", tool_rate)):
        if not val > 0:
            raise InputError("time_path", name, f"must be > 0, got {val}")
    if samples < 1:
        raise InputError("time_path", "samples", f"must be >= 1, got {samples}")
    keep = [0]
    for i in range(1, Q.shape[0]):
        if np.any(Q[i] != Q[keep[-1]]):
            keep.append(i)
    Q = Q[keep]
    if Q.shape[0] == 1:
        return TimedPath(np.zeros(1), Q)
    dq = np.diff(Q, axis=0)
    durations = np.max(np.abs(dq) / (speed * v), axis=1)
    if fk is not None and (math.isfinite(tool_speed) or math.isfinite(tool_rate)):
        u = np.linspace(0.0, 1.0, samples + 1)
        for i in range(dq.shape[0]):
            T = np.asarray(fk(Q[i] + u[:, None] * dq[i]))
            step = np.linalg.norm(np.diff(T[:, :3, 3], axis=0), axis=1).max()
            R = np.einsum("kji,kjl->kil", T[:-1, :3, :3], T[1:, :3, :3])
            cos = np.clip((np.trace(R, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
            turn = float(np.arccos(cos).max())
            durations[i] = max(
                durations[i], samples * step / tool_speed, samples * turn / tool_rate
            )
    if not (np.isfinite(durations).all() and (durations > 0).all()):
        raise InputError("time_path", "vmax", "no finite speed bound: give vmax or tool_speed")
    t = np.concatenate([[0.0], np.cumsum(durations)])
    return TimedPath(t, Q)
