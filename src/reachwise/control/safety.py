"""Trust in the distance data, the protective stop, and the separation margin.

**Data freshness.** Every distance answer the controller receives carries the sequence
number of the query and two times: ``stamp``, the time of the joint state (and scan)
it describes, and ``computed``, when the answer was ready. The controller refuses data
that are missing, that repeat or go back in sequence, that are older than
``max_age_ticks`` control periods (default 2) at the time of use, or that hold a NaN
or infinite value where a finite one is required. It then decelerates to a
protective stop — linearly from the last command to zero within ``stop_ticks``
ticks — and reports the reason. When valid data return, control resumes.

The same rule covers the point clouds the distances were computed on: a camera or
scanner that stops delivering leaves the scene answering on its last cloud, which
ages. With ``max_cloud_age`` (s; inf by default: clouds never count as stale) a
watched cloud measured longer ago than that — or whose measurement time is unknown —
is missing data, and the controller makes the same protective stop until a fresh
cloud arrives. A cloud that does not age (a CAD part, a map: stamp +inf) never stops
it.

**Protective separation margin** (after ISO/TS 15066:2016 §5.5.4, Eq. 1–2, the
speed-and-separation-monitoring distance ``S_p = S_h + S_r + S_s + C + Z_d + Z_r``).
For a robot part and an obstacle the collision margin ``ρ_O`` of the controller should
be at least

    ρ_O = v_o (T_r + T_s) + v_r T_r + S_s + C + Z_d + Z_r

with ``v_o`` the obstacle's speed towards the robot (0 for a static scan; ISO's
``S_h``), ``v_r`` the robot part's speed, ``T_r`` the reaction time (distance query +
control period + data age, i.e. the time until a command reacts to a new
distance), ``T_s`` the stopping time, ``S_s`` the stopping distance (``v_r²/(2 a)``
for a deceleration ``a``, if not given), ``C`` an intrusion distance (0 here: clouds
are the surfaces themselves), ``Z_d`` the position uncertainty of the measured
distance — for point clouds the cloud resolution, the largest point spacing of the two
clouds (a conservative bound on how much nearer the true surfaces may be than their
nearest samples) — and ``Z_r`` the
robot's position uncertainty (calibration error, kinematic model error).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "DataCheck",
    "SafetyConfig",
    "check_data",
    "protective_separation",
    "stop_ramp",
]


@dataclass(frozen=True)
class SafetyConfig:
    """Freshness and protective-stop settings. ``dt`` is the control period (s);
    ``max_cloud_age`` (s) the oldest a watched cloud may be (inf: no bound)."""

    dt: float = 0.01
    max_age_ticks: float = 2.0
    stop_ticks: int = 5
    max_cloud_age: float = math.inf

    def __post_init__(self) -> None:
        if not self.dt > 0:
            raise ValueError(f"dt must be > 0, got {self.dt}")
        if not self.max_age_ticks >= 0:
            raise ValueError(f"max_age_ticks must be >= 0, got {self.max_age_ticks}")
        if self.stop_ticks < 1:
            raise ValueError(f"stop_ticks must be >= 1, got {self.stop_ticks}")
        if not self.max_cloud_age > 0:
            raise ValueError(f"max_cloud_age must be > 0 s (inf allowed), got {self.max_cloud_age}")

    @property
    def max_age(self) -> float:
        """Oldest acceptable data age in seconds (a little slack for rounding)."""
        return self.max_age_ticks * self.dt * (1.0 + 1e-9) + 1e-12


@dataclass(frozen=True)
class DataCheck:
    """Result of :func:`check_data`: ``ok`` or the ``reason`` why not."""

    ok: bool
    reason: str = ""


def check_data(
    sequence: int | None,
    stamp: float | None,
    last_sequence: int | None,
    now: float,
    config: SafetyConfig,
    values: tuple[NDArray[np.float64], ...] = (),
    *,
    cloud_stamp: float = math.inf,
    cloud: str = "",
) -> DataCheck:
    """Decide whether distance data may be used at time ``now``.

    ``None`` for ``sequence`` means no data arrived; ``values`` are arrays that must be
    finite (the distances, points and directions of the active pairs);
    ``cloud_stamp`` the measurement time of the oldest cloud they were computed on
    (+inf: none ages, NaN: unknown), ``cloud`` its name.
    """
    if sequence is None or stamp is None:
        return DataCheck(False, "missing distance data")
    if last_sequence is not None and sequence <= last_sequence:
        return DataCheck(False, f"stale distance data (sequence {sequence} already used)")
    if not math.isfinite(stamp):
        return DataCheck(False, "distance data without a valid timestamp")
    age = now - stamp
    if age > config.max_age:
        ticks = age / config.dt
        return DataCheck(
            False,
            f"stale distance data (age {age * 1e3:.1f} ms = {ticks:.1f} ticks "
            f"> {config.max_age_ticks:g} ticks)",
        )
    if age < -config.dt:
        return DataCheck(False, f"distance data from the future (age {age * 1e3:.1f} ms)")
    limit = config.max_cloud_age
    if limit != math.inf:
        if cloud_stamp != cloud_stamp:
            return DataCheck(False, f"cloud {cloud!r} without a valid timestamp")
        cloud_age = now - cloud_stamp
        if cloud_age > limit * (1.0 + 1e-9) + 1e-12:
            return DataCheck(
                False,
                f"stale cloud {cloud!r} (age {cloud_age * 1e3:.1f} ms > {limit * 1e3:g} ms)",
            )
    for v in values:
        if v.size and not np.isfinite(v).all():
            return DataCheck(False, "non-finite distance data (NaN or inf)")
    return DataCheck(True)


def stop_ramp(last: NDArray[np.float64], ticks_left: int, stop_ticks: int) -> NDArray[np.float64]:
    """Command while decelerating to a protective stop: the last good command scaled
    linearly to zero, reaching exactly zero ``stop_ticks`` ticks after the fault."""
    if ticks_left <= 0:
        return np.zeros_like(last)
    return np.asarray(last * (ticks_left / stop_ticks), dtype=float)


def protective_separation(
    robot_speed: float,
    reaction_time: float,
    *,
    stopping_time: float = 0.0,
    stopping_distance: float | None = None,
    deceleration: float | None = None,
    obstacle_speed: float = 0.0,
    cloud_resolution: float = 0.0,
    calibration_error: float = 0.0,
    intrusion: float = 0.0,
) -> float:
    """Collision margin (m) as ISO/TS 15066 computes a protective separation distance.

    ``ρ_O = v_o (T_r + T_s) + v_r T_r + S_s + C + Z_d + Z_r`` (see the module
    docstring): ``obstacle_speed`` ``v_o`` and ``robot_speed`` ``v_r`` in m/s,
    ``reaction_time`` ``T_r`` and ``stopping_time`` ``T_s`` in s; ``S_s`` is
    ``stopping_distance`` or, if not given, ``v_r²/(2 deceleration)`` (0 without
    either); ``C`` = ``intrusion``; ``Z_d`` = ``cloud_resolution`` (the largest point
    spacing of the two clouds); ``Z_r`` = ``calibration_error``.
    """
    vals = {
        "robot_speed": robot_speed,
        "reaction_time": reaction_time,
        "stopping_time": stopping_time,
        "obstacle_speed": obstacle_speed,
        "cloud_resolution": cloud_resolution,
        "calibration_error": calibration_error,
        "intrusion": intrusion,
    }
    for k, v in vals.items():
        if not (math.isfinite(v) and v >= 0):
            raise ValueError(f"{k} must be finite and >= 0, got {v}")
    if stopping_distance is not None:
        if not (math.isfinite(stopping_distance) and stopping_distance >= 0):
            raise ValueError(f"stopping_distance must be finite and >= 0, got {stopping_distance}")
        s_s = stopping_distance
    elif deceleration is not None:
        if not deceleration > 0:
            raise ValueError(f"deceleration must be > 0, got {deceleration}")
        s_s = robot_speed**2 / (2.0 * deceleration)
    else:
        s_s = 0.0
    return float(
        obstacle_speed * (reaction_time + stopping_time)
        + robot_speed * reaction_time
        + s_s
        + intrusion
        + cloud_resolution
        + calibration_error
    )
