"""Collision-avoidance path controller of one manipulator (thesis §3.3, P-III §3, P-V §III).

One tick, ``Controller.step(q, goal, distances, now) -> (q̇, status)``:

1. **Primary task** (Eq. 3.8–3.13). Proportional control of the tool position,
   ``ṗ_G = k_v (p_d − p)``, and of its orientation with the unit-quaternion error
   ``e_O = η ε_d − η_d ε − S(ε_d) ε`` (Eq. 3.9), ``ω = k_w e_O``; 3-D goals control the
   position only. Tool parts near an obstacle (a hanging grabber, a drill feed) add
   their repulsive velocities in task space, ``ṗ = ṗ_G + Σ ṗ_Oi`` (P-V Eq. 6), and the
   linear and angular velocities are bounded by scaling their vectors (Eq. 3.12–3.13,
   P-V Eq. 7).
2. **Damped pseudo-inverse** (Eq. 3.5–3.6) with the damping of P-I Eq. 14:
   ``λ² = (1 − (σ_min/ε)²) λ_max²`` inside the singular region ``σ_min < ε``, else 0.
3. **Avoidance in the null space** (Eq. 3.14–3.18). Every watched pair closer than its
   margin ``ρ_O`` gives an avoidance point at the robot part's closest point, its
   point Jacobian ``J_Oi`` (for a self-collision pair the relative Jacobian of the two
   closest points) and the Khatib velocity ``ẋ_Oi = μ (1/ρ_i − 1/ρ_O)/ρ_i² n_i`` along
   the collision line (Eq. 3.16–3.17, capped at ``v_rep_max``); then
   ``q̇ = J̃⁺ ẋ + Σ_i (I − J⁺J) J̃_Oi⁺ ẋ_Oi`` (Eq. 3.18). The projector uses the exact
   (rank-truncated) pseudo-inverse, so the avoidance motion never disturbs the task —
   the same as the thesis's ``I − J̃⁺J`` outside the singular region, where ``λ = 0``.
4. **Joint limits** (``limits``). Joints that are passive, locked or outside their
   range get weight 0 in a weighted pseudo-inverse (P-II Eq. 25–28; a joint outside
   its range is driven back inward and the others solve for the rest of the task);
   a joint moving toward a limit within ``limit_zone`` gets a weight falling to 0 at
   the limit. Finally the whole ``q̇`` is scaled by one factor ``α ≤ 1`` so that every
   joint respects ``|q̇| ≤ v_max`` and the position velocity damper — never clipped
   joint by joint.
5. **Guard** (our addition, beyond the thesis). Eq. 3.18 "gives up the desired
   velocity" only as far as the repulsion outweighs it. So that no pair can
   interpenetrate even when the primary task is infeasible, every active pair's
   distance rate ``ρ̇_i = n_iᵀ J_Oi q̇`` must stay above the velocity damper
   ``−ξ (ρ_i − ρ_s)/(ρ_O − ρ_s)``: the goal part of the task velocity is scaled by the
   largest ``s ∈ [0, 1]`` that satisfies it (the tool deviates or slows down), and if
   even ``s = 0`` does not, the whole motion is slowed down (the robot stops before
   ``ρ_s``).

   *Guard memory.* The distance query gives one closest point pair per watched pair.
   Near an edge or corner of a sampled cloud that pair flips between points on either
   side from tick to tick (the normal's component across the edge changes sign), and a
   guard that sees only this tick's pair admits a motion that slides along one
   collision line straight into the other: each tick's constraint is met, the sideways
   motions cancel out, and the component toward the obstacle accumulates (a drift of
   centimetres per second through ``ρ_s``). The guard therefore also constrains the
   collision lines of the last ``guard_memory`` ticks: each is kept as the robot part's
   point in its link frame and the other end — a point of a static obstacle (world),
   or of the other link for a self-collision pair — and re-measured at the current
   joint state, ``ρ_r = ‖p_a(q) − p_b‖``, ``n_r = (p_a(q) − p_b)/ρ_r``. Both ends are
   cloud points, so the remembered pair is an exact point pair of the same two objects:
   ``ρ_r`` is never below the true distance, and its damper bound is as sound as the
   current pair's (the remembered lines add guard constraints only, no repulsion:
   Eq. 3.16–3.18 keep their single closest point). With both sides of the edge
   constrained the tool slides along the crease between them instead of through it.
   Pairs with a moving obstacle (nonzero obstacle velocity) are not remembered — their
   points have moved on; the memory is cleared by a protective stop and by ``reset``.
6. **Moving obstacles** (our addition; the thesis, §6.3, and P-V leave them to future
   work). Eq. 3.16–3.17 and the guard treat the other object as still. When it moves,
   the distance changes at ``ρ̇_i = n_iᵀ (J_Oi q̇ − v_Bi)``, with ``v_Bi`` the velocity
   of the obstacle's closest point; its approach speed ``u_i = max(0, n_iᵀ v_Bi)``
   (the part of that velocity along the collision line toward the robot) is added to
   the repulsive speed, ``ẋ_Oi = (min(Khatib, v_rep_max) + u_i) n_i`` — the robot part
   backs away at least as fast as the obstacle comes, so the Khatib term keeps its
   static meaning relative to the obstacle — and the guard's damper bound becomes
   ``n_iᵀ J_Oi q̇ ≥ −ξ (ρ_i − ρ_s)/(ρ_O − ρ_s) + u_i``, which is the static damper on
   the true rate ``ρ̇_i``. When even ``s = 0`` cannot back away fast enough, the robot
   is only slowed down for its own approach, never for the obstacle's (stopping
   would not help). The retreat is bounded by ``v_max`` (Eq. 3.12) and the joint
   speeds: the margin ``ρ_O`` must cover the obstacle's speed times the time the
   robot needs to reach it (``reachwise.control.safety.protective_separation``).
   ``velocity_aware=False`` ignores the obstacles' velocities (the static law).
7. **Safety and status** (``safety``): missing, repeated, old or non-finite distance
   data ⇒ protective stop; per tick the state is ``moving``, ``reached``, ``locked``,
   ``protective_stop`` (with the reason) or ``stalled`` (no progress toward the goal
   for ``stall_time`` — the local minimum of thesis Fig. 3.3, reported, not hidden).

The arithmetic of one tick is one compiled kernel (``reachwise.control.tick``) on typed
input groups, built and validated once here, so a tick costs tens of microseconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.control.avoidance import AvoidancePoints
from reachwise.control.safety import DataCheck, SafetyConfig, check_data, stop_ramp
from reachwise.control.tick.step import control_step
from reachwise.control.tick.types import (
    MEM_AGE,
    MEM_COLS,
    AvoidanceSettings,
    Gains,
    JointLimits,
    Target,
    TickDiagnostics,
    check_static,
)
from reachwise.errors import InputError
from reachwise.kinematics.dls import EPSILON_CONTROL, LAMBDA_MAX
from reachwise.kinematics.robot import Robot
from reachwise.kinematics.transforms import check_pose

__all__ = ["ControlStatus", "Controller", "ControllerConfig", "Goal", "State"]

State = Literal["moving", "reached", "locked", "protective_stop", "stalled"]


@dataclass(frozen=True)
class ControllerConfig:
    """Gains and limits of the controller (SI units).

    ``kv`` (1/s) and ``kw`` (1/s): position and orientation gains (Eq. 3.8, 3.10);
    ``v_max`` (m/s), ``w_max`` (rad/s): task velocity bounds (Eq. 3.12–3.13);
    ``lambda_max``, ``epsilon``: damping schedule (P-I Eq. 14, ``reachwise.kinematics.dls``);
    ``mu`` (m⁴/s): Khatib coefficient (Eq. 3.16–3.17), ``v_rep_max`` (m/s) caps a repulsive
    speed; ``k_limit`` (1/s): position-limit velocity damper, ``limit_zone`` (rad or
    m): where the limit weighting starts; ``guard``, ``stop_distance`` ``ρ_s`` (m) and
    ``approach_speed`` ``ξ`` (m/s): the approach guard; ``avoidance``: False gives the
    conventional controller (no avoidance, no distance data needed);
    ``position_tolerance`` (m), ``orientation_tolerance`` (rad): goal reached;
    ``stall_time`` (s), ``stall_progress`` (m, orientation counted 1 m/rad): stall
    detection; ``velocity_aware``: use moving obstacles' velocities (item 6 above);
    ``safety``: data freshness and protective stop; ``guard_memory``: how many past
    ticks' collision lines the guard keeps constraining (item 5; 0 = this tick's only).
    """

    kv: float = 1.0
    kw: float = 1.0
    v_max: float = 0.5
    w_max: float = 0.3
    lambda_max: float = LAMBDA_MAX
    epsilon: float = EPSILON_CONTROL
    mu: float = 2e-4
    v_rep_max: float = 1.0
    k_limit: float = 2.0
    limit_zone: float = 0.1
    guard: bool = True
    stop_distance: float = 0.04
    approach_speed: float = 0.5
    avoidance: bool = True
    position_tolerance: float = 0.005
    orientation_tolerance: float = 0.01
    stall_time: float = 3.0
    stall_progress: float = 0.01
    velocity_aware: bool = True
    reaction_time: float = 0.0
    guard_memory: int = 2
    safety: SafetyConfig = field(default_factory=SafetyConfig)

    def __post_init__(self) -> None:
        positive = (
            "kv", "kw", "v_max", "w_max", "epsilon", "k_limit", "limit_zone",
            "approach_speed", "position_tolerance", "orientation_tolerance", "stall_time",
            "stall_progress", "v_rep_max",
        )  # fmt: skip
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name in positive and not (isinstance(v, int | float) and v > 0):
                raise InputError("controller", f.name, f"must be > 0, got {v!r}")
        for name in ("lambda_max", "mu", "stop_distance", "reaction_time"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise InputError("controller", name, f"must be finite and >= 0, got {v!r}")
        gm = self.guard_memory
        if isinstance(gm, bool) or not isinstance(gm, int) or not 0 <= gm <= 10:
            raise InputError("controller", "guard_memory", f"must be an int 0..10, got {gm!r}")

    @property
    def dt(self) -> float:
        return self.safety.dt


@dataclass(frozen=True, eq=False)
class Goal:
    """A tool goal: a 4x4 pose; ``dims`` 3 (position only) or 6 (full pose).

    ``position_tolerance``/``orientation_tolerance`` override the controller's.
    """

    pose: NDArray[np.float64]
    dims: Literal[3, 6] = 6
    position_tolerance: float | None = None
    orientation_tolerance: float | None = None

    def __post_init__(self) -> None:
        if self.dims not in (3, 6):
            raise InputError("goal", "dims", f"3 or 6, got {self.dims!r}")
        P = check_pose(self.pose, "goal pose").copy()
        P.setflags(write=False)
        object.__setattr__(self, "pose", P)

    @classmethod
    def at(cls, xyz: ArrayLike, **kw: float) -> Goal:
        """A 3-D (position-only) goal."""
        T = np.eye(4)
        T[:3, 3] = np.asarray(xyz, dtype=float)
        return cls(T, 3, **kw)  # type: ignore[arg-type]

    @property
    def position(self) -> NDArray[np.float64]:
        return self.pose[:3, 3]


@dataclass(frozen=True)
class ControlStatus:
    """What the controller did this tick and why.

    ``state``: ``moving``, ``reached``, ``locked``, ``protective_stop`` or
    ``stalled``; ``reason`` says why for the last two. ``position_error`` (m),
    ``orientation_error`` (rad, 0 for 3-D goals); ``task_scale`` ``s`` (1 = the path
    is followed), ``limit_scale`` ``α`` (1 = no joint at a bound), ``guard_scale``
    (1 = no pair closing in too fast); ``sigma_min`` and ``damping`` ``λ`` of the
    pseudo-inverse; ``active_points`` within their margins, ``min_distance`` (m, inf
    when none).
    """

    state: State
    reason: str = ""
    position_error: float = math.nan
    orientation_error: float = math.nan
    task_scale: float = 1.0
    limit_scale: float = 1.0
    guard_scale: float = 1.0
    sigma_min: float = math.nan
    damping: float = 0.0
    active_points: int = 0
    min_distance: float = math.inf


class Controller:
    """The controller of one robot; keeps the little state a tick needs (last command,
    last sequence number, protective-stop ramp, stall clock)."""

    def __init__(
        self,
        robot: Robot,
        config: ControllerConfig | None = None,
        *,
        locked_joints: tuple[int, ...] = (),
    ) -> None:
        self.robot = robot
        self.config = cfg = config or ControllerConfig()
        usable = np.array(robot.actuated, dtype=np.bool_)
        for k in locked_joints:
            if not 0 <= k < robot.n:
                raise InputError(robot.name, "locked_joints", f"no joint variable {k}")
            usable[k] = False
        limits = JointLimits(
            lower=robot.lower,
            upper=robot.upper,
            vmax=robot.vmax,
            usable=usable,
            passive=np.array(~np.asarray(robot.actuated), dtype=np.bool_),
            zone=np.full(robot.n, float(cfg.limit_zone)),
        )
        gains = Gains(
            kv=float(cfg.kv),
            kw=float(cfg.kw),
            v_max=float(cfg.v_max),
            w_max=float(cfg.w_max),
            lambda_max=float(cfg.lambda_max),
            epsilon=float(cfg.epsilon),
            mu=float(cfg.mu),
            v_rep_max=float(cfg.v_rep_max),
            k_limit=float(cfg.k_limit),
        )
        settings = AvoidanceSettings(
            avoidance=bool(cfg.avoidance),
            guard=bool(cfg.guard),
            stop_distance=float(cfg.stop_distance),
            approach_speed=float(cfg.approach_speed),
            reaction_time=float(cfg.reaction_time),
            velocity_aware=bool(cfg.velocity_aware),
        )
        check_static(robot.arrays, limits, gains, settings)
        # the groups every tick passes, as the compiled entry takes them (plain tuples)
        self._groups = (tuple(robot.arrays), tuple(limits), tuple(gains), tuple(settings))
        self._depth = cfg.guard_memory if cfg.avoidance else 0
        self._mem = np.zeros((0, MEM_COLS))
        self._target: tuple[Goal | None, tuple[object, ...]] = (None, ())
        self.locked = False
        self.reset()

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        """Forget the last command, sequence and stall clock (e.g. for a new goal)."""
        self._last_cmd = np.zeros(self.robot.n)
        self._last_seq: int | None = None
        self._faults = 0
        self._fault_reason = ""
        self._goal: Goal | None = None
        self._best = math.inf
        self._best_t = 0.0
        self._forget()

    def _forget(self) -> None:
        """Drop the guard's remembered collision lines (rows of ``MEM_COLS`` columns,
        see ``tick.types``; age 0 marks an empty row)."""
        self._mem[:, MEM_AGE] = 0.0

    def _memory_for(self, rows: int) -> NDArray[np.float64]:
        """The memory, grown to hold ``guard_memory`` ticks of ``rows`` lines each."""
        need = self.config.guard_memory * rows
        if self._mem.shape[0] < need:
            grown = np.zeros((max(need, 2 * self._mem.shape[0]), MEM_COLS))
            grown[: self._mem.shape[0]] = self._mem
            self._mem = grown
        return self._mem

    # ------------------------------------------------------------------ tick
    def step(
        self,
        q: ArrayLike,
        goal: Goal,
        distances: AvoidancePoints | None,
        now: float,
    ) -> tuple[NDArray[np.float64], ControlStatus]:
        """One control tick at time ``now`` (s): joint velocity command and status."""
        qq = np.ascontiguousarray(q, dtype=np.float64)
        if qq.shape != (self.robot.n,) or not np.isfinite(qq).all():
            raise InputError(self.robot.name, "q", f"expected {self.robot.n} finite values")
        cfg = self.config
        if self.locked:
            self._forget()
            self._last_cmd = np.zeros(self.robot.n)
            return self._last_cmd.copy(), ControlStatus("locked", "locked while working")
        if goal is not self._goal:
            self._goal = goal
            self._best = math.inf
            self._best_t = now
        if cfg.avoidance:
            if distances is None:
                chk = check_data(None, None, self._last_seq, now, cfg.safety)
            elif not distances.valid:
                chk = DataCheck(False, f"missing distance data: {distances.reason}")
            else:
                values = (distances.distance, distances.a_point, distances.normal)
                chk = check_data(
                    distances.sequence, distances.stamp, self._last_seq, now, cfg.safety, values,
                    cloud_stamp=distances.cloud_stamp, cloud=distances.cloud,
                )  # fmt: skip
            if not chk.ok or distances is None:
                self._best_t = now  # the stall clock does not run while stopped
                return self._stop(chk.reason)
            self._last_seq = distances.sequence
        pts = distances if (cfg.avoidance and distances is not None) else _NO_POINTS
        qdot, diag = self._tick(qq, goal, pts)
        self._faults = 0
        self._last_cmd = qdot.copy()
        ptol = (
            cfg.position_tolerance if goal.position_tolerance is None else goal.position_tolerance
        )
        otol = (
            cfg.orientation_tolerance
            if goal.orientation_tolerance is None
            else goal.orientation_tolerance
        )
        pe = diag.position_error
        oe = diag.orientation_error if goal.dims == 6 else 0.0
        state: State = "moving"
        reason = ""
        if pe <= ptol and oe <= otol:
            state = "reached"
            self._best_t = now
        else:
            err = pe + oe
            if err < self._best - cfg.stall_progress:
                self._best = err
                self._best_t = now
            elif now - self._best_t >= cfg.stall_time:
                state = "stalled"
                reason = (
                    f"no progress toward the goal for {now - self._best_t:.2f} s "
                    f"(error {err:.3f}, best {self._best:.3f}); a local minimum"
                )
        status = ControlStatus(
            state,
            reason,
            position_error=pe,
            orientation_error=oe,
            task_scale=diag.task_scale,
            limit_scale=diag.limit_scale,
            guard_scale=diag.guard_scale,
            sigma_min=diag.sigma_min,
            damping=diag.damping,
            active_points=diag.active_points,
            min_distance=diag.min_distance,
        )
        return qdot, status

    def _stop(self, reason: str) -> tuple[NDArray[np.float64], ControlStatus]:
        st = self.config.safety.stop_ticks
        self._faults += 1
        self._forget()
        cmd = stop_ramp(self._last_cmd, st - self._faults, st)
        return cmd, ControlStatus("protective_stop", reason)

    def _tick(
        self, q: NDArray[np.float64], goal: Goal, p: AvoidancePoints
    ) -> tuple[NDArray[np.float64], TickDiagnostics]:
        """Run the compiled tick on this controller's groups, the goal's and ``p``'s."""
        if self._target[0] is not goal:
            self._target = (goal, tuple(Target(pose=goal.pose, six=goal.dims == 6)))
        memory = (self._memory_for(len(p)), self._depth)
        try:
            return control_step(*self._groups, self._target[1], p.kernel_rows, memory, q)  # type: ignore[no-any-return]
        except IndexError as exc:  # raised by the kernel before it computes anything
            field = "b_link" if "b_link" in str(exc) else "a_link"
            last = len(self.robot.link_names) - 1
            raise InputError(
                "avoidance points", field, f"frame index outside {self.robot.name}'s 0 … {last}"
            ) from None


_NO_POINTS = AvoidancePoints.empty(0, 0.0)
