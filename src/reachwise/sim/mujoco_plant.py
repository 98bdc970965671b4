"""A MuJoCo plant: the controller's joint-velocity commands drive a rigid-body model.

:class:`MujocoPlant` has the interface of :class:`reachwise.sim.plant.Plant` (``q``,
``qdot``, ``step(command, dt)``) and runs the robot's MuJoCo model
(:func:`reachwise.sim.mujoco_model.mujoco_model`) instead of integrating the command:

- every actuated joint has a velocity servo, force ``kv (u − q̇)``, with the command
  ``u`` saturated at ``±v_max`` (``ctrlrange``); ``kv = M_jj(q0) / τ`` makes the joint,
  taken alone, a first-order lag of time constant ``τ`` — the same lag as the hydraulic
  plant (``time_constant``) when the scenario uses one, 20 ms (a stiff electric drive)
  otherwise. A finite hydraulic ``rate_limit`` a_max slews the servo's setpoint (the
  valve opening) at most a_max per second, so a joint alone accelerates at most a_max,
  as in the hydraulic plant; the servo force itself is not limited (a loaded valve
  holds). ``M_jj`` is the joint's diagonal entry of the joint-space inertia matrix at
  the start pose; the other joints, the changing pose and the swinging load couple in
  through the rest of the dynamics — which is what this plant is there to expose;
- the drives feed the chain's bias torques forward (gravity and Coriolis, MuJoCo's
  ``qfrc_bias``, the loads of the passive parts included) on the actuated joints, as a
  drive's load holding does: without it a finite-gain velocity servo sags at
  ``G / kv`` under a gravity torque ``G`` (``bias_feedforward=False`` shows that);
- passive joints have no actuator: they swing under gravity with viscous damping
  ``c = 2 ζ √(k M_pp)`` (``k`` the gravity stiffness about the hanging rest, ``M_pp``
  the joint's inertia), damping ratio ``ζ = 0.5`` by default: a grabber on a cardan
  joint with link brakes, swinging visibly (16 % overshoot) but settling within about
  one period. The passive joints start at their physical rest (the quasi-static
  hanging pose of :func:`~reachwise.sim.plant.hanging_joints`, refined to zero gravity
  torque on the passive joints);
- MuJoCo integrates at ``substep`` (1 ms) with ``implicitfast`` within each control
  tick ``dt``; joint limits are MuJoCo's (soft) joint limits, contacts are off (the
  distance scene checks collisions).

The plant records what it was told and what it did; :meth:`MujocoPlant.tracking`
summarises the tracking error, and :func:`plant_comparison` sets a MuJoCo run beside a
run of the same scenario with its own (kinematic or hydraulic) plant.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.errors import InputError
from reachwise.kinematics.robot import Robot
from reachwise.sim.mujoco_model import MujocoRobot, mujoco_model, require_mujoco
from reachwise.sim.plant import PlantConfig, hanging_joints

if TYPE_CHECKING:
    from reachwise.sim.log import SimulationLog

__all__ = ["MujocoPlant", "MujocoPlantConfig", "plant_comparison"]


@dataclass(frozen=True)
class MujocoPlantConfig:
    """``servo_time_constant`` τ (s) of the velocity servos, ``rate_limit`` a_max
    (rad/s² or m/s², ``inf`` = none) of their setpoints, ``substep`` (s) of the
    integrator, ``passive_damping_ratio`` ζ of the passive joints, ``bias_feedforward``
    of gravity and Coriolis torques on the actuated joints, ``density`` (kg/m³) of the
    link geometry and ``hang_axis`` (start pose of the passive joints)."""

    servo_time_constant: float = 0.02
    rate_limit: float = math.inf
    substep: float = 0.001
    passive_damping_ratio: float = 0.5
    bias_feedforward: bool = True
    density: float = 1000.0
    hang_axis: tuple[float, float, float] = (1.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        for name in ("servo_time_constant", "substep", "density"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise InputError("plant", name, f"must be a finite value > 0, got {v}")
        if not self.rate_limit > 0:
            raise InputError("plant", "rate_limit", f"must be > 0, got {self.rate_limit}")
        if not (math.isfinite(self.passive_damping_ratio) and self.passive_damping_ratio >= 0):
            raise InputError(
                "plant", "passive_damping_ratio", f"must be >= 0, got {self.passive_damping_ratio}"
            )

    @classmethod
    def like(cls, plant: PlantConfig, **overrides: Any) -> MujocoPlantConfig:
        """The MuJoCo counterpart of a scenario's plant: a hydraulic plant's lag and rate
        limit become the servo's time constant and setpoint slew limit; a kinematic plant
        gets a stiff 20 ms servo."""
        kw: dict[str, Any] = {"hang_axis": tuple(plant.hang_axis)}
        if plant.kind == "hydraulic":
            kw.update(servo_time_constant=plant.time_constant, rate_limit=plant.rate_limit)
        kw.update(overrides)
        return cls(**kw)


def _inertia(mujoco: Any, m: Any, d: Any) -> NDArray[np.float64]:
    """Dense joint-space inertia matrix at ``d``'s pose (columns of ``M e_i``)."""
    mujoco.mj_forward(m, d)
    M = np.empty((m.nv, m.nv))
    e = np.zeros(m.nv)
    col = np.empty(m.nv)
    for i in range(m.nv):
        e[:] = 0.0
        e[i] = 1.0
        mujoco.mj_mulM(m, d, col, e)
        M[:, i] = col
    return M


class MujocoPlant:
    """One manipulator simulated by MuJoCo: state ``q`` and actual joint velocity
    ``qdot`` (``MjData.qvel``, passive joints included) in reachwise's joint order."""

    def __init__(
        self,
        robot: Robot,
        q0: ArrayLike,
        config: MujocoPlantConfig | None = None,
        meshes: Mapping[str, Any] | None = None,
    ) -> None:
        self._mj = mujoco = require_mujoco()
        self.robot = robot
        self.config = cfg = config or MujocoPlantConfig()
        q = np.array(q0, dtype=float)
        if q.shape != (robot.n,) or not np.isfinite(q).all():
            raise InputError(robot.name, "q0", f"expected {robot.n} finite values")
        self._act = act = np.asarray(robot.actuated, dtype=bool)
        self.mj: MujocoRobot = mujoco_model(
            robot, density=cfg.density, timestep=cfg.substep, meshes=meshes
        )
        m = self.mj.model
        self.data = d = mujoco.MjData(m)
        # a joint that starts outside its limits keeps its start value as its end stop
        jid = m.dof_jntid[self.mj.dof]
        lim = m.jnt_limited[jid].astype(bool)
        m.jnt_range[jid[lim], 0] = np.minimum(m.jnt_range[jid[lim], 0], q[lim])
        m.jnt_range[jid[lim], 1] = np.maximum(m.jnt_range[jid[lim], 1], q[lim])
        q = hanging_joints(robot, q, cfg.hang_axis) if not act.all() else q
        d.qpos[self.mj.qpos] = q
        self._rest_passive(q)
        M = _inertia(mujoco, m, d)
        dofs = self.mj.dof
        m_jj = np.diag(M)[dofs]
        # servo gains from the start pose's inertia
        self.kv = np.where(act, m_jj / cfg.servo_time_constant, 0.0)
        acts = self.mj.actuator[act]
        m.actuator_gainprm[acts, 0] = self.kv[act]
        m.actuator_biasprm[acts, 2] = -self.kv[act]
        self.passive_damping = self._passive_damping(m_jj)
        m.dof_damping[dofs[~act]] = self.passive_damping[~act]
        mujoco.mj_forward(m, d)
        self._vmax = np.asarray(robot.vmax, dtype=float)
        self.q = np.array(d.qpos[self.mj.qpos], dtype=float)
        self.qdot = np.zeros(robot.n)
        self._setpoint = np.zeros(robot.n)  # servo setpoints (slewed commands)
        self._ideal = np.zeros(robot.n)  # an ideal first-order servo on the same setpoints
        self._log_ideal: list[NDArray[np.float64]] = []
        self._log_u: list[NDArray[np.float64]] = []
        self._log_q: list[NDArray[np.float64]] = [self.q.copy()]
        self._log_v: list[NDArray[np.float64]] = []
        self._log_dt: list[float] = []

    # ---- set-up ------------------------------------------------------------------
    def _gravity_passive(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        """Generalised gravity forces on the passive joints at rest at ``q``."""
        m, d, mujoco = self.mj.model, self.data, self._mj
        d.qpos[self.mj.qpos] = q
        d.qvel[:] = 0.0
        mujoco.mj_forward(m, d)
        return np.array(d.qfrc_bias[self.mj.dof[~self._act]])

    def _stiffness(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        """``∂g_p/∂q_p`` of the passive joints' gravity forces (central differences)."""
        pas = np.flatnonzero(~self._act)
        K = np.empty((pas.size, pas.size))
        h = 1e-6
        for c, k in enumerate(pas):
            qp, qm = q.copy(), q.copy()
            qp[k] += h
            qm[k] -= h
            K[:, c] = (self._gravity_passive(qp) - self._gravity_passive(qm)) / (2 * h)
        return K

    def _rest_passive(self, q: NDArray[np.float64]) -> None:
        """Newton steps on the passive joints toward zero gravity torque (their rest)."""
        pas = ~self._act
        if not pas.any():
            return
        lo, hi = self.robot.lower[pas], self.robot.upper[pas]
        best = q.copy()
        g_best = float(np.linalg.norm(self._gravity_passive(best)))
        for _ in range(6):
            if g_best < 1e-9:
                break
            K = self._stiffness(best)
            g = self._gravity_passive(best)
            trial = best.copy()
            trial[pas] = np.clip(best[pas] - np.linalg.lstsq(K, g, rcond=None)[0], lo, hi)
            g_trial = float(np.linalg.norm(self._gravity_passive(trial)))
            if not g_trial < g_best:
                break
            best, g_best = trial, g_trial
        self.data.qpos[self.mj.qpos] = best
        self.data.qvel[:] = 0.0

    def _passive_damping(self, m_jj: NDArray[np.float64]) -> NDArray[np.float64]:
        """``2 ζ √(k M_pp)`` per passive joint (``ω = 1 rad/s`` where gravity gives no
        stiffness); zero for actuated joints."""
        out = np.zeros(self.robot.n)
        pas = np.flatnonzero(~self._act)
        if pas.size == 0:
            return out
        q = np.array(self.data.qpos[self.mj.qpos])
        k = np.diag(self._stiffness(q))
        self.data.qpos[self.mj.qpos] = q
        mp = m_jj[pas]
        omega = np.where(k > 0, np.sqrt(np.maximum(k, 0.0) / mp), 1.0)
        out[pas] = 2.0 * self.config.passive_damping_ratio * mp * omega
        return out

    # ---- the plant interface -----------------------------------------------------
    def step(self, command: ArrayLike, dt: float) -> NDArray[np.float64]:
        """Apply ``command`` (joint velocities; passive entries ignored, the rest
        saturated at ``v_max``) as the servo targets for ``dt`` seconds of MuJoCo time;
        returns the new ``q``."""
        mujoco, m, d = self._mj, self.mj.model, self.data
        cmd = np.asarray(command, dtype=float)
        if cmd.shape != (self.robot.n,) or not np.isfinite(cmd).all():
            raise InputError(self.robot.name, "command", f"expected {self.robot.n} finite values")
        if not (math.isfinite(dt) and dt > 0):
            raise InputError(self.robot.name, "dt", f"must be > 0, got {dt}")
        act = self._act
        u = np.where(act, np.clip(cmd, -self._vmax, self._vmax), 0.0)
        n_sub = max(1, math.ceil(dt / self.config.substep - 1e-9))
        h = dt / n_sub
        m.opt.timestep = h
        dofs = self.mj.dof[act]
        acts = self.mj.actuator[act]
        ff = self.config.bias_feedforward
        slew = self.config.rate_limit * h
        decay = math.exp(-h / self.config.servo_time_constant)
        for _ in range(n_sub):
            r = self._setpoint + np.clip(u - self._setpoint, -slew, slew)
            self._setpoint = r
            d.ctrl[acts] = r[act]
            self._ideal = r + (self._ideal - r) * decay
            mujoco.mj_step1(m, d)
            if ff:
                d.qfrc_applied[dofs] = d.qfrc_bias[dofs]
            mujoco.mj_step2(m, d)
        q = np.array(d.qpos[self.mj.qpos], dtype=float)
        if not np.isfinite(q).all():
            raise InputError(self.robot.name, "mujoco", "the simulation diverged (non-finite q)")
        self.q = q
        self.qdot = np.array(d.qvel[self.mj.dof], dtype=float)
        self._log_u.append(u)
        self._log_ideal.append(self._ideal.copy())
        self._log_q.append(q.copy())
        self._log_v.append(self.qdot.copy())
        self._log_dt.append(dt)
        return q.copy()

    # ---- what it did -------------------------------------------------------------
    def tracking(self) -> dict[str, Any]:
        """Tracking error over the run so far, actuated joints (rad or m, per second):

        - ``velocity_error_rms`` / ``velocity_error_max``: ``|q̇ − u|`` at the end of
          each tick (``u`` the saturated command) — includes the servo's intended lag;
        - ``first_order_error_max``: ``|q̇ − v₁|``, ``v₁`` the ideal first-order servo
          (``τ``) driven by the same (slewed) setpoints: what the multi-body dynamics
          (coupling, the swinging load, limits) add to the servo's own lag;
        - ``position_lag_max``: ``max |q − q_kin|``, the achieved path against the
          kinematically integrated commands (``q_kin ← q_kin + u Δt`` within the end
          stops, from the same start; an ideal first-order servo without rate limit,
          away from the stops, keeps it below ``τ max|u|``: ``position_lag_bound``);
        - ``passive_swing_max`` (rad): the largest angle between the hang axis of the
          last passive link and straight down (the kinematic plant keeps it 0).
        """
        act = self._act
        if not self._log_u:
            return {"ticks": 0}
        U = np.array(self._log_u)[:, act]
        V = np.array(self._log_v)[:, act]
        Q = np.array(self._log_q)
        dts = np.array(self._log_dt)
        verr = np.abs(V - U)
        tau = self.config.servo_time_constant
        e1 = float(np.abs(V - np.array(self._log_ideal)[:, act]).max(initial=0.0))
        # the kinematic plant driven by the same commands: q ← clip(q + u Δt, end stops)
        lo = np.minimum(self.robot.lower, Q[0])[act]
        hi = np.maximum(self.robot.upper, Q[0])[act]
        ref = np.empty_like(Q[:, act])
        ref[0] = Q[0, act]
        for k in range(U.shape[0]):
            ref[k + 1] = np.clip(ref[k] + U[k] * dts[k], lo, hi)
        lag = np.abs(Q[:, act] - ref)
        out: dict[str, Any] = {
            "ticks": int(U.shape[0]),
            "servo_time_constant": tau,
            "kv": [float(v) for v in self.kv],
            "velocity_error_rms": float(np.sqrt(np.mean(verr**2))) if verr.size else 0.0,
            "velocity_error_max": float(verr.max(initial=0.0)),
            "first_order_error_max": e1,
            "position_lag_max": float(lag.max(initial=0.0)),
            "position_lag_bound": float(tau * np.abs(U).max(initial=0.0)),
            "passive_damping": [float(c) for c in self.passive_damping[~act]],
        }
        if not act.all():
            pas = np.flatnonzero(~act)
            link = self.robot.movable_joints[int(pas[-1])] + 1
            axis = np.asarray(self.config.hang_axis, dtype=float)
            axis = axis / np.linalg.norm(axis)
            R = self.robot.fk_all(Q)[:, link, :3, :3]
            down = np.clip(-(R @ axis)[:, 2], -1.0, 1.0)
            out["passive_swing_max"] = float(np.arccos(down).max())
        return out


def plant_comparison(log: SimulationLog, reference: SimulationLog) -> dict[str, Any]:
    """A MuJoCo run beside the same scenario with its own plant: per robot the goal
    times, the minimum distance over its pairs, and the largest difference of joint
    values and tool position at equal times (over the ticks both ran)."""
    out: dict[str, Any] = {"plant": reference.extras.get("plant", "scenario")}
    n = min(log.t.size, reference.t.size)
    robots: dict[str, Any] = {}
    for r in log.robots:
        if r not in reference.robots:
            continue

        def goal_times(lg: SimulationLog, name: str = r) -> list[float | None]:
            return [g.reached_at for g in lg.goals if g.robot == name]

        def min_dist(lg: SimulationLog, name: str = r) -> float | None:
            cols = [
                i
                for i, p in enumerate(lg.pairs)
                if any(s.split("/")[0] == name for s in p.split("|"))
            ]
            if not cols or lg.t.size == 0:
                return None
            v = float(np.min(lg.signed[:, cols]))
            return v if math.isfinite(v) else None

        dq = np.abs(log.q[r][:n] - reference.q[r][:n])
        dtool = np.linalg.norm(log.tool[r][:n, :3, 3] - reference.tool[r][:n, :3, 3], axis=1)
        robots[r] = {
            "goals_reached_at": goal_times(log),
            "reference_goals_reached_at": goal_times(reference),
            "min_distance": min_dist(log),
            "reference_min_distance": min_dist(reference),
            "joint_difference_max": float(dq.max(initial=0.0)),
            "tool_difference_max": float(dtool.max(initial=0.0)),
        }
    out["robots"] = robots
    return out
