"""Global escape from a local minimum: an OMPL RRT-Connect path in joint space.

The reactive controller (thesis §3.3) can be trapped where the goal's attraction and
the obstacles' repulsion cancel (thesis Fig. 3.3, §6.3.2; the controller reports
``stalled``). The thesis names the cure, a hybrid of a local and a global method
(§3.2, refs. [71, 72]); this module is the global half:

1. **Goal configurations** (:func:`goal_configurations`): inverse kinematics of the
   controller's goal pose (``Robot.ik``, 3-D or 6-D as the goal) from the current
   configuration and from random ones; the solutions that are collision-free are the
   goal states (OMPL ``GoalStates``), nearest first.
2. **Planning** (:func:`plan_path`): RRT-Connect (Kuffner & LaValle 2000) from OMPL
   (``ompl.geometric.RRTConnect`` in a ``SimpleSetup``) over the robot's actuated
   joints within their limits (passive joints stay where they are), with the distance
   scene as the state validity checker (:class:`~reachwise.planning.validity.
   ClearanceChecker`) and OMPL's discrete motion validator at the joint-space
   resolution that bounds every watched point's motion between two checked states by
   ``step`` metres (:meth:`~reachwise.planning.validity.ClearanceChecker.
   joint_resolution`; default a fifth of the smallest margin). Every state of a
   segment is then within ``step/2`` of a checked one, so checking each pair at
   ``ρ_O + step/2`` keeps every state of the path — not only the checked ones — at
   least ``ρ_O`` from the obstacles, and no part can skip through one, however thin.
   A robot stalled by the controller usually sits inside some margins already (the
   repulsion is what stopped it): such pairs are checked at ``start_relax × (their
   distance at the start)`` instead, so the path leaves the start without coming
   (more than ``step/2``) closer than it already is. :attr:`PlanResult.clearance`
   states the guaranteed clearance of each pair.
3. **Shortcutting**: OMPL's ``PathSimplifier`` (``SimpleSetup.simplifySolution()``
   with no time limit: vertex reduction, shortcutting and vertex collapsing repeated
   until nothing improves), every shortcut checked by the same motion validator.

OMPL is the optional ``plan`` extra, imported only when a plan is made. Planning runs
on OMPL's wall clock within ``time_limit`` (a budget, not a reading of ours); the
result reports OMPL's own planning and simplification times. ``seed`` seeds OMPL's
random generators (``ompl.util.RNG.setSeed``) and the IK restarts, so a plan that
finishes within its budget is the same run after run.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from itertools import combinations
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.control.controller import Goal
from reachwise.errors import InputError, MissingDependency
from reachwise.kinematics.ik import finite_limits
from reachwise.kinematics.robot import Robot
from reachwise.planning.goal_states import (
    free_joints,
    goal_configurations,
    held_robot,
)
from reachwise.planning.validity import ClearanceChecker

__all__ = [
    "MISSING",
    "PlanResult",
    "PlannerConfig",
    "conditioning",
    "goal_configurations",
    "held_robot",
    "ompl_available",
    "plan_escape",
    "plan_path",
    "require_ompl",
]

#: What the local-minimum escape needs and where it comes from (the optional extra).
_NEEDED = ("ompl", "plan", "the local-minimum escape")
#: The install hint, as :class:`~reachwise.errors.MissingDependency` words it.
MISSING = str(MissingDependency(*_NEEDED))


def ompl_available() -> bool:
    """True when OMPL's Python bindings can be imported."""
    try:
        require_ompl()
    except MissingDependency:
        return False
    return True


def require_ompl() -> tuple[Any, Any, Any]:
    """OMPL's ``base``, ``geometric`` and ``util`` modules, or a
    :class:`~reachwise.errors.MissingDependency` naming the ``plan`` extra."""
    try:
        from ompl import base as ob
        from ompl import geometric as og
        from ompl import util as ou
    except ImportError:
        raise MissingDependency(*_NEEDED) from None
    return ob, og, ou


@dataclass(frozen=True)
class PlannerConfig:
    """Options of :func:`plan_path` (SI units).

    ``time_limit`` (s): OMPL's wall-clock budget for RRT-Connect; ``seed``: OMPL's
    and the IK restarts' random seed; ``step`` (m): the most any watched point may move
    between two checked states (default: a fifth of the smallest margin); ``range`` (rad):
    RRT-Connect's extension length (default OMPL's, 0.2 × the space's extent);
    ``ik_attempts``: IK solves for goal configurations, ``max_goals``: goal states kept;
    ``start_relax``: margin factor for pairs already within their margin at the start;
    ``simplify``: shortcut the path.
    """

    time_limit: float = 5.0
    seed: int = 1
    step: float | None = None
    range: float | None = None
    ik_attempts: int = 16
    max_goals: int = 8
    start_relax: float = 0.99
    simplify: bool = True

    def __post_init__(self) -> None:
        if not (math.isfinite(self.time_limit) and self.time_limit > 0):
            raise InputError("planner", "time_limit", f"must be > 0, got {self.time_limit}")
        if self.step is not None and not (math.isfinite(self.step) and self.step > 0):
            raise InputError("planner", "step", f"must be > 0, got {self.step}")
        if self.range is not None and not (math.isfinite(self.range) and self.range > 0):
            raise InputError("planner", "range", f"must be > 0, got {self.range}")
        if self.ik_attempts < 1 or self.max_goals < 1:
            raise InputError("planner", "ik_attempts/max_goals", "must be >= 1")
        if not 0 < self.start_relax <= 1:
            raise InputError("planner", "start_relax", f"must be in (0, 1], got {self.start_relax}")
        if not 0 < self.seed < 2**32:
            raise InputError("planner", "seed", f"must be in 1 .. 2^32 - 1, got {self.seed}")


@dataclass(frozen=True, eq=False)
class PlanResult:
    """Outcome of :func:`plan_path`.

    ``success`` with ``path`` (m, n) joint configurations from the start to a goal
    configuration (straight joint-space segments, each validated), or ``reason`` why
    not (``path`` then holds the start only). ``status``: OMPL's planner status;
    ``planning_time`` and ``simplify_time`` (s): OMPL's own measurements;
    ``raw_states``: states of RRT-Connect's path before shortcutting; ``goals`` the
    goal configurations offered; ``clearance`` the distance every state of the path
    keeps, per pair of ``pairs`` (``ρ_O``, or less for a pair the start was already
    inside); ``step`` (m) and ``resolution`` (rad): the workspace and joint-space
    spacing of checked states; ``checks`` validity checks;
    ``held`` the entries of ``q`` kept at their start values (besides passive
    joints); ``plans`` how many RRT-Connect runs the times add up.
    """

    success: bool
    reason: str
    path: NDArray[np.float64]
    status: str = ""
    planning_time: float = 0.0
    simplify_time: float = 0.0
    raw_states: int = 0
    goals: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 0)))
    pairs: tuple[str, ...] = ()
    clearance: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    step: float = math.nan
    resolution: float = math.nan
    checks: int = 0
    held: tuple[int, ...] = ()
    plans: int = 1

    @property
    def length(self) -> float:
        """Joint-space length of the path (L2, rad or m)."""
        if self.path.shape[0] < 2:
            return 0.0
        return float(np.linalg.norm(np.diff(self.path, axis=0), axis=1).sum())


def _seed(ou: Any, seed: int) -> None:
    """Seed OMPL's generator of seeds; new planners and samplers draw from it. OMPL
    logs an error when a seed was set before (it still reseeds): keep it quiet."""
    level = ou.getLogLevel()
    ou.setLogLevel(ou.LOG_NONE)
    try:
        ou.RNG.setSeed(int(seed))
    finally:
        ou.setLogLevel(level)


def plan_path(
    checker: ClearanceChecker,
    q_start: ArrayLike,
    goal: Goal | ArrayLike,
    config: PlannerConfig | None = None,
    *,
    hold: Sequence[int] = (),
) -> PlanResult:
    """A collision-free joint path from ``q_start`` to ``goal`` (a
    :class:`~reachwise.control.Goal` pose, solved by :func:`goal_configurations`, or
    goal configurations ``(g, n)``) with RRT-Connect, shortcut; see the module
    docstring. The entries of ``q`` in ``hold`` and passive joints keep their start
    values. Never raises on a problem without a
    solution: the result says why (invalid start, no goal configuration, OMPL's status
    such as a timeout)."""
    cfg = config or PlannerConfig()
    ompl = require_ompl()
    robot = checker.robot
    q0 = np.asarray(q_start, dtype=float).reshape(-1)
    if q0.shape != (robot.n,) or not np.isfinite(q0).all():
        raise InputError("planner", "q_start", f"expected {robot.n} finite values")
    start_only = q0[None, :].copy()

    free = free_joints(robot, hold)
    held = tuple(sorted(int(k) for k in hold))

    def fail(reason: str, **kw: Any) -> PlanResult:
        return PlanResult(False, reason, start_only, pairs=checker.pairs, held=held, **kw)

    if not checker.within_limits(q0):
        return fail("the start configuration is outside the joint limits")
    d0 = checker.distances(q0, exact=True)
    if np.any(d0 <= 1e-6):
        bad = [p for p, d in zip(checker.pairs, d0, strict=True) if d <= 1e-6]
        return fail(f"the start configuration is in contact: {', '.join(bad)}")
    step, margins = _step_and_margins(checker, d0, cfg)
    clearance = margins - 0.5 * step
    check = checker.with_margins(margins)
    _seed(ompl[2], cfg.seed)
    if isinstance(goal, Goal):
        goals = goal_configurations(
            check, goal, q0, hold=hold, attempts=cfg.ik_attempts, max_goals=cfg.max_goals,
            rng=np.random.default_rng(cfg.seed),
        )  # fmt: skip
        if goals.shape[0] == 0:
            return fail(
                f"no collision-free goal configuration among {cfg.ik_attempts} inverse "
                "kinematics solutions",
                clearance=clearance,
                step=step,
            )
    else:
        goals, reason = _given_goals(check, goal, q0, free)
        if reason:
            return fail(reason)
    joints = np.flatnonzero(free)
    resolution = check.joint_resolution(step, joints)
    run = _rrt_connect(ompl, check, q0, goals, joints, resolution, cfg)
    common: dict[str, Any] = dict(
        status=run.status,
        planning_time=run.planning_time,
        simplify_time=run.simplify_time,
        raw_states=run.raw_states,
        goals=goals,
        clearance=clearance,
        step=step,
        resolution=resolution,
        checks=check.checks,
    )
    if not run.exact:
        return fail(
            f"RRT-Connect found no path within {cfg.time_limit:g} s ({run.status})", **common
        )
    path = np.repeat(q0[None, :], len(run.states), axis=0)
    path[:, joints] = np.array(run.states)
    return PlanResult(True, "", path, pairs=checker.pairs, held=held, **common)


def _step_and_margins(
    checker: ClearanceChecker, d0: NDArray[np.float64], cfg: PlannerConfig
) -> tuple[float, NDArray[np.float64]]:
    """The motion step (m) between checked states and the margin (m) each pair is
    checked at: its own plus half a step, or for a pair already inside its margin at
    the start (distances ``d0``) ``start_relax`` times its distance there, with a step
    fine enough to keep that clearance positive."""
    step = cfg.step if cfg.step is not None else 0.2 * float(checker.margins.min())
    inside = d0 < checker.margins + 0.5 * step
    if inside.any():  # a close start: a finer step keeps its clearance positive
        step = min(step, cfg.start_relax * float(d0[inside].min()))
    return step, np.where(inside, cfg.start_relax * d0, checker.margins + 0.5 * step)


def _given_goals(
    check: ClearanceChecker, goal: ArrayLike, q0: NDArray[np.float64], free: NDArray[np.bool_]
) -> tuple[NDArray[np.float64], str]:
    """The given goal configurations that are valid, and why none is (or ``""``)."""
    n = check.robot.n
    goals = np.asarray(goal, dtype=float).reshape(-1, n)
    if goals.size == 0 or not np.isfinite(goals).all():
        raise InputError("planner", "goal", f"expected (g, {n}) finite joint values")
    if np.any(goals[:, ~free] != q0[~free]):
        return goals, "a goal configuration moves a passive or held joint"
    goals = np.array([g for g in goals if check.is_valid(g)]).reshape(-1, n)
    if goals.shape[0] == 0:
        return goals, "every goal configuration is in collision or outside the limits"
    return goals, ""


@dataclass(frozen=True)
class _Search:
    """What one RRT-Connect query returned: OMPL's status, its planning and
    shortcutting times (s), the states of its raw path and the free joints' values
    along the shortcut path (empty without an exact solution)."""

    status: str
    exact: bool
    planning_time: float
    simplify_time: float
    raw_states: int
    states: list[list[float]]


def _rrt_connect(
    ompl: tuple[Any, Any, Any],
    check: ClearanceChecker,
    q0: NDArray[np.float64],
    goals: NDArray[np.float64],
    joints: NDArray[np.intp],
    resolution: float,
    cfg: PlannerConfig,
) -> _Search:
    """RRT-Connect (OMPL ``SimpleSetup``) from ``q0`` to any of ``goals`` over the
    entries ``joints`` of ``q`` within the joint limits, every state checked by
    ``check`` and every motion at ``resolution`` (rad or m); the other entries keep
    their values in ``q0``. The path is shortcut when ``cfg.simplify``."""
    ob, og, ou = ompl
    k = joints.size
    lo, hi = finite_limits(check.robot)
    level = ou.getLogLevel()
    ou.setLogLevel(ou.LOG_NONE)  # OMPL logs to stdout; the result carries its status
    try:
        space = ob.RealVectorStateSpace(k)
        bounds = ob.RealVectorBounds(k)
        for i, j in enumerate(joints):
            bounds.setLow(i, float(lo[j]))
            bounds.setHigh(i, float(hi[j]))
        space.setBounds(bounds)
        si = ob.SpaceInformation(space)
        q = q0.copy()

        def valid(state: Any) -> bool:
            for i, j in enumerate(joints):
                q[j] = state[i]
            return check.is_valid(q)

        si.setStateValidityChecker(valid)
        si.setStateValidityCheckingResolution(min(1.0, resolution / space.getMaximumExtent()))
        si.setup()

        def state_of(values: NDArray[np.float64]) -> Any:
            s = space.allocState()
            for i, j in enumerate(joints):
                s[i] = float(values[j])
            return s

        ss = og.SimpleSetup(si)
        ss.setStartState(state_of(q0))
        goal_states = ob.GoalStates(si)
        for g in goals:
            goal_states.addState(state_of(g))
        ss.setGoal(goal_states)
        planner = og.RRTConnect(si)
        if cfg.range is not None:
            planner.setRange(cfg.range)
        ss.setPlanner(planner)
        ss.setup()
        status = ss.solve(cfg.time_limit)
        plan_time = float(ss.getLastPlanComputationTime())
        exact = bool(ss.haveExactSolutionPath())
        raw = ss.getSolutionPath().getStateCount() if exact else 0
        simp_time = 0.0
        if exact and cfg.simplify:
            ss.simplifySolution()  # no time limit: simplifyMax, deterministic
            simp_time = float(ss.getLastSimplificationTime())
        states = (
            [list(s[i] for i in range(k)) for s in ss.getSolutionPath().getStates()]
            if exact
            else []
        )
    finally:
        ou.setLogLevel(level)
    return _Search(status.asString(), exact, plan_time, simp_time, raw, states)


def conditioning(
    robot: Robot, path: ArrayLike, joints: ArrayLike, dims: int = 6, per_segment: int = 10
) -> float:
    """Smallest singular value of the tool Jacobian's ``dims`` rows (3: linear, 6: all)
    restricted to the columns ``joints``, over the path's waypoints and
    ``per_segment`` states along each segment: how far from singular a controller
    driving only those joints stays along the path."""
    P = np.asarray(path, dtype=float).reshape(-1, robot.n)
    cols = np.asarray(joints)
    if P.shape[0] == 1:
        dense = P
    else:
        u = np.linspace(0.0, 1.0, per_segment, endpoint=False)
        dense = np.concatenate(
            [P[i] + u[:, None] * (P[i + 1] - P[i]) for i in range(P.shape[0] - 1)] + [P[-1:]]
        )
    return float(
        min(np.linalg.svd(robot.jacobian(q)[:dims, cols], compute_uv=False)[-1] for q in dense)
    )


def plan_escape(
    checker: ClearanceChecker,
    q_start: ArrayLike,
    goal: Goal,
    config: PlannerConfig | None = None,
    *,
    dims: int = 6,
    candidates: int = 3,
    sigma_floor: float = 0.05,
) -> PlanResult:
    """A path that a task-space controller with ``dims``-D goals (3 or 6) can follow
    joint by joint.

    A robot with more actuated joints than ``dims`` is redundant for such goals: the
    controller's pseudo-inverse (Eq. 3.5) moves it in its null space as it sees fit,
    and its joints drift off a planned joint path although its tool follows the path's
    tool poses. So the surplus joints are held at their start values: with as many
    free joints as goal dimensions, a tool pose fixes the joints locally, and following
    the poses follows the joint path — as long as the remaining joints stay clear of
    singular configurations. A first plan with every joint free ranks the choices of
    held joints by :func:`conditioning` along it (a choice that leaves the others
    near-singular would make the controller's damping, Eq. 3.6, give up accuracy);
    the best ``candidates`` are planned again with those joints held, and the first
    whose own path keeps the smallest singular value at least ``sigma_floor`` (else
    the best conditioned) is returned. ``planning_time`` and ``simplify_time`` add up
    every run (``plans``), and so does ``checks``."""
    if dims not in (3, 6):
        raise InputError("planner", "dims", f"3 or 6, got {dims}")
    robot = checker.robot
    free = [int(k) for k in np.flatnonzero(np.asarray(robot.actuated))]
    surplus = len(free) - dims
    first = plan_path(checker, q_start, goal, config)
    if surplus <= 0 or not first.success:
        return first
    choices = [list(c) for c in combinations(free, surplus)]

    def score(path: NDArray[np.float64], hold: list[int]) -> float:
        return conditioning(robot, path, [k for k in free if k not in hold], dims)

    ranked = sorted(choices, key=lambda h: -score(first.path, h))
    total_p, total_s, checks, runs = first.planning_time, first.simplify_time, first.checks, 1
    best: tuple[float, PlanResult] | None = None
    last = first
    for hold in ranked[:candidates]:
        last = plan_path(checker, q_start, goal, config, hold=hold)
        total_p += last.planning_time
        total_s += last.simplify_time
        checks += last.checks
        runs += 1
        if not last.success:
            continue
        sigma = score(last.path, hold)
        if best is None or sigma > best[0]:
            best = (sigma, last)
        if sigma >= sigma_floor:
            break
    if best is None:
        return replace(
            last,
            reason=f"no path with {surplus} joint(s) held for a {dims}-D follower: {last.reason}",
            planning_time=total_p,
            simplify_time=total_s,
            checks=checks,
            plans=runs,
        )
    return replace(best[1], planning_time=total_p, simplify_time=total_s, checks=checks, plans=runs)
