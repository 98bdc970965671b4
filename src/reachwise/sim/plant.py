"""Simulated manipulators: a kinematic integrator and a hydraulic-like plant.

Both integrate the commanded joint velocities of the actuated joints over one sample
time ``dt`` and respect the actuators: ``|q̇| ≤ v_max`` and the mechanical end stops
(the joint limits; a joint that starts outside them keeps its start value as its end
stop on that side, so the plant never moves it back by itself).

- ``kinematic``: ``q̇ = command`` (bounded), ``q ← q + q̇ Δt``.
- ``hydraulic``: a heavy boom's valve-cylinder chain as a first-order lag of time
  constant ``τ`` on the joint velocity, ``q̇ ← q̇ + (command − q̇)(1 − e^{−Δt/τ})``,
  followed by a rate limit ``|Δq̇| ≤ a_max Δt`` (the flow the pump can deliver), then
  ``|q̇| ≤ v_max`` and the end stops.

Passive joints (``Joint.passive``) are never commanded: the plant sets them so that a
hanging part hangs under gravity. The model is *quasi-static hanging*: the passive
joints take the values that turn ``hang_axis`` (a unit vector in the frame of the last
passive link, +x for the ``hiab-xs033`` grabber) straight down, found by a few
Gauss–Newton steps on the passive joints from their last values. With
``hang_time_constant > 0`` they relax toward that equilibrium with that time constant
instead — a strongly damped pendulum without its swing. The real grabber swings a
little when the crane accelerates; P-V §V reports it hanging "parallel to the
gravity", which is what this model keeps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.errors import InputError, check_choice
from reachwise.kinematics.robot import Robot

__all__ = [
    "PLANT_KINDS",
    "PLANT_NAMES",
    "Plant",
    "PlantConfig",
    "PlantKind",
    "PlantName",
    "hanging_joints",
]

#: The dynamics of a scenario's own plant: ideal joint velocities, or a first-order
#: lag with a rate limit (a hydraulic drive).
PlantKind = Literal["kinematic", "hydraulic"]
PLANT_KINDS: tuple[PlantKind, ...] = get_args(PlantKind)
#: Which plants a simulation runs: each robot's own (``scenario``) or its MuJoCo
#: model (``mujoco``, :mod:`reachwise.sim.mujoco_plant`).
PlantName = Literal["scenario", "mujoco"]
PLANT_NAMES: tuple[PlantName, ...] = get_args(PlantName)


@dataclass(frozen=True)
class PlantConfig:
    """``kind``: ``kinematic`` or ``hydraulic``; ``time_constant`` τ (s) and
    ``rate_limit`` a_max (rad/s² or m/s², per joint, ``inf`` = none) of the hydraulic
    lag; ``hang_axis`` in the last passive link's frame and ``hang_time_constant`` (s,
    0 = quasi-static) of the passive joints."""

    kind: PlantKind = "kinematic"
    time_constant: float = 0.1
    rate_limit: float = math.inf
    hang_axis: tuple[float, float, float] = (1.0, 0.0, 0.0)
    hang_time_constant: float = 0.0

    def __post_init__(self) -> None:
        check_choice(self.kind, PLANT_KINDS, source="plant", kind="plant kind")
        if not self.time_constant > 0:
            raise InputError("plant", "time_constant", f"must be > 0, got {self.time_constant}")
        if not self.rate_limit > 0:
            raise InputError("plant", "rate_limit", f"must be > 0, got {self.rate_limit}")
        if not self.hang_time_constant >= 0:
            raise InputError(
                "plant", "hang_time_constant", f"must be >= 0, got {self.hang_time_constant}"
            )
        if not np.linalg.norm(self.hang_axis) > 0:
            raise InputError("plant", "hang_axis", "must be a non-zero vector")


def hanging_joints(
    robot: Robot,
    q: ArrayLike,
    axis: ArrayLike = (1.0, 0.0, 0.0),
    iterations: int = 8,
) -> NDArray[np.float64]:
    """``q`` with its passive joints set so that ``axis`` (in the frame of the last
    passive link) points straight down (world −z): quasi-static hanging.

    Gauss–Newton on the passive joint values from their current ones, with numerical
    derivatives; joints stay within their limits.
    """
    qq = np.array(q, dtype=float)
    passive = np.flatnonzero(~np.asarray(robot.actuated))
    if passive.size == 0:
        return qq
    link = robot.movable_joints[int(passive[-1])] + 1
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    down = np.array([0.0, 0.0, -1.0])

    def resid(x: NDArray[np.float64]) -> NDArray[np.float64]:
        qq[passive] = x
        R = robot.fk_all(qq)[link, :3, :3]
        return np.asarray(R @ a - down)

    x = qq[passive].copy()
    h = 1e-6
    for _ in range(iterations):
        r0 = resid(x)
        if float(np.linalg.norm(r0)) < 1e-10:
            break
        Jn = np.empty((3, x.size))
        for j in range(x.size):
            xp = x.copy()
            xp[j] += h
            Jn[:, j] = (resid(xp) - r0) / h
        dx = np.linalg.lstsq(Jn, -r0, rcond=None)[0]
        x = np.clip(x + dx, robot.lower[passive], robot.upper[passive])
    qq[passive] = x
    return qq


class Plant:
    """One simulated manipulator: state ``q`` and actual joint velocity ``qdot``."""

    def __init__(self, robot: Robot, q0: ArrayLike, config: PlantConfig | None = None) -> None:
        self.robot = robot
        self.config = config or PlantConfig()
        q = np.array(q0, dtype=float)
        if q.shape != (robot.n,) or not np.isfinite(q).all():
            raise InputError(robot.name, "q0", f"expected {robot.n} finite values")
        self._act = np.asarray(robot.actuated, dtype=bool)
        self._stop_lo = np.minimum(robot.lower, q)
        self._stop_hi = np.maximum(robot.upper, q)
        self.qdot = np.zeros(robot.n)
        self.q = self._hang(q, 0.0)

    def _hang(self, q: NDArray[np.float64], dt: float) -> NDArray[np.float64]:
        if self._act.all():
            return q
        eq = hanging_joints(self.robot, q, self.config.hang_axis)
        tau = self.config.hang_time_constant
        if tau > 0.0 and dt > 0.0:
            f = 1.0 - math.exp(-dt / tau)
            passive = ~self._act
            eq[passive] = q[passive] + f * (eq[passive] - q[passive])
        return eq

    def step(self, command: ArrayLike, dt: float) -> NDArray[np.float64]:
        """Apply ``command`` (joint velocities; passive entries ignored) for ``dt``
        seconds; returns the new ``q``."""
        cmd = np.asarray(command, dtype=float)
        if cmd.shape != (self.robot.n,) or not np.isfinite(cmd).all():
            raise InputError(self.robot.name, "command", f"expected {self.robot.n} finite values")
        cmd = np.where(self._act, cmd, 0.0)
        vmax = self.robot.vmax
        if self.config.kind == "kinematic":
            v = cmd
        else:
            f = 1.0 - math.exp(-dt / self.config.time_constant)
            dv = f * (cmd - self.qdot)
            lim = self.config.rate_limit * dt
            dv = np.clip(dv, -lim, lim)
            v = self.qdot + dv
        v = np.clip(v, -vmax, vmax)
        q_old = self.q
        q = np.clip(q_old + v * dt, self._stop_lo, self._stop_hi)
        q = np.where(self._act, q, q_old)
        self.qdot = np.where(self._act, (q - q_old) / dt, 0.0)
        # a joint that moved back inside its range gets its normal end stop again
        self._stop_lo = np.maximum(np.minimum(self._stop_lo, q), np.minimum(self.robot.lower, q))
        self._stop_hi = np.minimum(np.maximum(self._stop_hi, q), np.maximum(self.robot.upper, q))
        self.q = self._hang(q, dt)
        return self.q.copy()
