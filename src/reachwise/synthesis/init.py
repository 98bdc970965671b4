"""Initial values of the synthesis (P-I §3.3, P-II §4.4).

Design sets are drawn from a Beta distribution scaled to each parameter's bounds;
for every set the joint values of every task point are solved by inverse kinematics
on that design, and the set that comes closest to the task (smallest summed,
row-weighted error) is kept. A task larger than ``sample`` points (87, the size of
P-I's task) compares the sets on ``sample`` evenly spaced points — a sample ranks a
handful of designs as well as every point does — and solves the remaining points for
the chosen set only, so the initialization grows with the task like the solver does.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from reachwise.kinematics.ik import solve_ik
from reachwise.kinematics.robot import Robot
from reachwise.synthesis.problem import SynthesisProblem

Array = NDArray[np.float64]


@dataclass(frozen=True)
class InitialGuess:
    """The chosen start: decision vector, its score and the scores of every set."""

    z: Array
    score: float
    scores: Array
    designs: Array


def beta_designs(
    problem: SynthesisProblem, rng: np.random.Generator, count: int, a: float = 2.0, b: float = 2.0
) -> Array:
    """``count`` design vectors, each coordinate ``lo + (hi − lo) · Beta(a, b)``."""
    lo, hi = problem.bounds
    u = rng.beta(a, b, size=(count, problem.p))
    return np.asarray(lo[: problem.p] + (hi[: problem.p] - lo[: problem.p]) * u)


def locked_robot(problem: SynthesisProblem, robot: Robot) -> Robot:
    """``robot`` with each locked joint's limits collapsed onto its locked value."""
    if not problem.locked:
        return robot
    joints = list(robot.joints)
    for k, v in problem.locked.items():
        j = robot.movable_joints[k]
        joints[j] = replace(joints[j], limits=(v, v))
    return replace(robot, joints=tuple(joints))


def seed_joints(
    problem: SynthesisProblem,
    design: Array,
    rng: np.random.Generator,
    restarts: int = 2,
    max_iter: int = 60,
    points: NDArray[np.int64] | None = None,
    Q: Array | None = None,
) -> tuple[Array, float]:
    """IK of the task points ``points`` (default all) on ``design``, written into ``Q``
    (default a new ``(K, n)`` array); returns ``Q`` and the score
    ``Σ (e_p + (tol_p/tol_o) e_o)`` of the closest solutions found."""
    robot = locked_robot(problem, problem.robot_at(design))
    task = problem.task
    Q = np.empty((problem.K, robot.n)) if Q is None else Q
    score = 0.0
    mid = 0.5 * (robot.lower + robot.upper)
    for k in range(problem.K) if points is None else points:
        res = solve_ik(
            robot,
            task.poses[k],
            q0=mid,
            mask=int(task.dims[k]),
            rng=rng,
            tol_position=float(task.tol_position[k]),
            tol_orientation=float(task.tol_orientation[k]),
            max_iter=max_iter,
            restarts=restarts,
        )
        Q[k] = res.q
        w = task.tol_position[k] / task.tol_orientation[k]
        score += res.position_error + w * res.orientation_error
    return Q, float(score)


def initial_guess(
    problem: SynthesisProblem, rng: np.random.Generator, sets: int = 8, sample: int = 87
) -> InitialGuess:
    """Best of ``sets`` Beta-distributed designs, each seeded by IK (P-I §3.3; compared
    on ``sample`` points of a larger task, module docstring)."""
    designs = beta_designs(problem, rng, sets)
    K = problem.K
    idx = None
    if K > sample:
        idx = np.unique(np.round(np.linspace(0, K - 1, sample)).astype(np.int64))
    best: tuple[float, int, Array] | None = None
    scores = np.empty(sets)
    for i, d in enumerate(designs):
        Q, score = seed_joints(problem, d, rng, points=idx)
        scores[i] = score
        if best is None or score < best[0]:
            best = (score, i, Q)
    if best is None:  # sets == 0
        raise ValueError("initial_guess needs at least one design set")
    score, i, Q = best
    if idx is not None:  # the chosen set: the points not in the sample
        rest = np.setdiff1d(np.arange(K), idx)
        Q, more = seed_joints(problem, designs[i], rng, points=rest, Q=Q)
        score += more
    return InitialGuess(problem.pack(designs[i], Q), score, scores, designs)
