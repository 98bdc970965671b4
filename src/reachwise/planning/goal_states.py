"""Where a plan may end and which joints it moves: the collision-free joint
configurations that reach a goal pose (:func:`goal_configurations`, the goal states
of :func:`~reachwise.planning.plan_path`), the robot with some joints held
fixed (:func:`held_robot`) and the mask of the joints a plan moves
(:func:`free_joints`)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.control.controller import Goal
from reachwise.errors import InputError
from reachwise.kinematics.ik import finite_limits
from reachwise.kinematics.robot import DesignSpace, Joint, Robot
from reachwise.planning.validity import ClearanceChecker

__all__ = ["free_joints", "goal_configurations", "held_robot"]


def held_robot(robot: Robot, q: ArrayLike, hold: ArrayLike) -> Robot:
    """``robot`` with the entries of ``q`` selected by the boolean mask ``hold`` turned
    into fixed joints at their values in ``q`` (its ``q`` has the other entries only;
    its frames and forward kinematics are the original's at those values)."""
    qq = np.asarray(q, dtype=float).reshape(-1)
    mask = np.asarray(hold, dtype=bool).reshape(-1)
    if qq.shape != (robot.n,) or mask.shape != (robot.n,):
        raise InputError("planner", "hold", f"expected {robot.n} values")
    joints = list(robot.joints)
    for k, j in enumerate(robot.movable_joints):
        if not mask[k]:
            continue
        jt = joints[j]
        if jt.type == "revolute":
            joints[j] = Joint("fixed", jt.a, jt.alpha, jt.d, jt.theta + qq[k], name=jt.name)
        else:
            joints[j] = Joint("fixed", jt.a, jt.alpha, jt.d + qq[k], jt.theta, name=jt.name)
    return replace(robot, joints=tuple(joints), design=DesignSpace())


def goal_configurations(
    checker: ClearanceChecker,
    goal: Goal,
    q_start: ArrayLike,
    *,
    hold: Sequence[int] = (),
    attempts: int = 16,
    max_goals: int = 8,
    rng: np.random.Generator | int | None = None,
    tolerance: float | None = None,
) -> NDArray[np.float64]:
    """Collision-free joint configurations whose tool reaches ``goal`` (3-D: position,
    6-D: pose), nearest to ``q_start`` first, at most ``max_goals``, from ``attempts``
    IK solves (the first from ``q_start``, the others from random configurations; for
    a 3-D goal every other solve also asks for the tool's orientation at ``q_start``).
    Passive joints and the joints in ``hold`` keep their ``q_start`` values (IK of
    ``held_robot``). ``tolerance`` (m, and rad for 6-D) on the solution's error,
    default the goal's own tolerances or 1 mm / 1 mrad."""
    robot = checker.robot
    q0 = np.asarray(q_start, dtype=float).reshape(-1)
    gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    free = free_joints(robot, hold)
    sub = held_robot(robot, q0, ~free)
    lo, hi = finite_limits(sub)
    ptol = tolerance or goal.position_tolerance or 1e-3
    otol = tolerance or goal.orientation_tolerance or 1e-3
    found: list[NDArray[np.float64]] = []
    keep = np.array(goal.pose, dtype=float)
    keep[:3, :3] = robot.fk(q0)[:3, :3]
    for k in range(attempts):
        seed = q0[free] if k == 0 else gen.uniform(lo, hi)
        # a 3-D goal leaves the orientation free: half the attempts ask for the
        # current one (a path that need not turn the tool), the others for none
        six = goal.dims == 6 or k % 2 == 0
        T = goal.pose if goal.dims == 6 or not six else keep
        res = sub.ik(T, q0=seed, mask=None if six else 3, rng=gen, restarts=4)
        if not res.success:
            continue
        q = q0.copy()
        q[free] = res.q
        P = robot.fk(q)
        if np.linalg.norm(P[:3, 3] - goal.position) > ptol:
            continue
        if goal.dims == 6:
            R = P[:3, :3].T @ goal.pose[:3, :3]
            ang = math.acos(max(-1.0, min(1.0, (np.trace(R) - 1.0) / 2.0)))
            if ang > otol:
                continue
        if any(np.max(np.abs(q - f)) < 1e-3 for f in found):
            continue
        if checker.is_valid(q):
            found.append(q)
    found.sort(key=lambda f: float(np.linalg.norm(f - q0)))
    return np.array(found[:max_goals]).reshape(-1, robot.n)


def free_joints(robot: Robot, hold: Sequence[int]) -> NDArray[np.bool_]:
    """Mask of the planned entries of ``q``: actuated and not held (``hold``: indices
    into ``q``); no joint left, or an index out of range, is an ``InputError``."""
    free = np.array(robot.actuated, dtype=bool)
    for k in hold:
        if not 0 <= int(k) < robot.n:
            raise InputError("planner", "hold", f"no joint variable {k}")
        free[int(k)] = False
    if not free.any():
        raise InputError("planner", "hold", "no joint left to plan with")
    return free
