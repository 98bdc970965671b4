"""Initial values of the synthesis (P-I §3.3, P-II §4.4).

Design sets are drawn from a Beta distribution scaled to each parameter's bounds;
for every set the joint values of every task point are solved by inverse kinematics
on that design, and the set that comes closest to the task (smallest summed,
row-weighted error) is kept. A task larger than ``sample`` points (87, the size of
P-I's task) compares the sets on ``sample`` evenly spaced points — a sample ranks a
handful of designs as well as every point does — and solves the remaining points for
the chosen set only, so the initialization grows with the task like the solver does.

With bodies to keep clear (a ``ClearanceModel``), the IK of a pose has several
branches that reach it equally well but place the bodies differently: a roll joint
with a full turn puts the feed beam on either side of the hole line, a wide tilt
joint bends the wrist up or down. The reach-only start takes whichever branch the IK
finds first, blind to the bodies. The clearance-aware start solves the IK from one
start per branch cell (``branch_starts``) and keeps, per pose, the solution with the
smallest reach error plus clearance excess (``clearance_rows.clearance_excess``,
summed over the pose's terms, both in metres); the design sets are compared on that
same score. Without bodies the start is the reach-only one, unchanged.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from reachwise.kinematics.ik import solve_ik
from reachwise.kinematics.robot import Robot
from reachwise.synthesis.clearance import ClearanceModel
from reachwise.synthesis.clearance_rows import clearance_excess
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


#: Width (rad) of one branch cell of a wide revolute joint (``branch_starts``).
BRANCH_CELL = 0.5 * np.pi


def branch_starts(robot: Robot) -> Array:
    """IK starts ``(B, n)``, one per branch cell: mid-range joints, with every revolute
    joint whose range spans at least π set to the centres of ⌈span / (π/2)⌉ equal
    parts of its range, in every combination (a ±180° roll: 4 cells, a ±100° tilt: 3)."""
    lo, hi = robot.lower, robot.upper
    mid, span = 0.5 * (lo + hi), hi - lo
    wide = [j for j in range(robot.n) if not robot.prismatic[j] and span[j] >= np.pi - 1e-9]
    cells = [
        lo[j] + span[j] * (np.arange(m) + 0.5) / m
        for j in wide
        for m in [int(np.ceil(span[j] / BRANCH_CELL - 1e-9))]
    ]
    out = np.tile(mid, (int(np.prod([c.size for c in cells])), 1))
    for i, combo in enumerate(itertools.product(*cells)):
        out[i, wide] = combo
    return out


def seed_joints_clear(
    problem: SynthesisProblem,
    design: Array,
    clearance: ClearanceModel,
    max_iter: int = 60,
    points: NDArray[np.int64] | None = None,
    Q: Array | None = None,
) -> tuple[Array, float]:
    """``seed_joints`` choosing each pose's IK branch by its bodies (module docstring):
    the IK of the task points ``points`` (default all) on ``design`` from every
    ``branch_starts`` start, the solution with the smallest reach error plus summed
    clearance excess written into ``Q``; returns ``Q`` and the summed score."""
    robot = locked_robot(problem, problem.robot_at(design))
    task = problem.task
    starts = branch_starts(robot)
    pts = np.arange(problem.K) if points is None else np.asarray(points)
    Q = np.tile(0.5 * (robot.lower + robot.upper), (problem.K, 1)) if Q is None else Q
    Qb = np.repeat(Q[None], len(starts), axis=0)
    score = np.empty((len(starts), pts.size))
    for i, k in enumerate(pts):
        w = task.tol_position[k] / task.tol_orientation[k]
        for b, q0 in enumerate(starts):
            res = solve_ik(
                robot,
                task.poses[k],
                q0=q0,
                mask=int(task.dims[k]),
                tol_position=float(task.tol_position[k]),
                tol_orientation=float(task.tol_orientation[k]),
                max_iter=max_iter,
                restarts=0,
            )
            Qb[b, k] = res.q
            score[b, i] = res.position_error + w * res.orientation_error
    for b in range(len(starts)):
        dist = clearance.distances(problem, problem.pack(design, Qb[b]))[pts]
        score[b] += clearance_excess(dist, clearance.clearance).sum(axis=1)
    pick = np.argmin(score, axis=0)
    Q[pts] = Qb[pick, pts]
    return Q, float(score[pick, np.arange(pts.size)].sum())


def initial_guess(
    problem: SynthesisProblem,
    rng: np.random.Generator,
    sets: int = 8,
    sample: int = 87,
    clearance: ClearanceModel | None = None,
) -> InitialGuess:
    """Best of ``sets`` Beta-distributed designs, each seeded by IK (P-I §3.3; compared
    on ``sample`` points of a larger task; with ``clearance``, on each pose's clearest
    IK branch: module docstring)."""

    def seed(d: Array, points: NDArray[np.int64] | None, Q: Array | None) -> tuple[Array, float]:
        if clearance is None:
            return seed_joints(problem, d, rng, points=points, Q=Q)
        return seed_joints_clear(problem, d, clearance, points=points, Q=Q)

    designs = beta_designs(problem, rng, sets)
    K = problem.K
    idx = None
    if K > sample:
        idx = np.unique(np.round(np.linspace(0, K - 1, sample)).astype(np.int64))
    best: tuple[float, int, Array] | None = None
    scores = np.empty(sets)
    for i, d in enumerate(designs):
        Q, score = seed(d, idx, None)
        scores[i] = score
        if best is None or score < best[0]:
            best = (score, i, Q)
    if best is None:  # sets == 0
        raise ValueError("initial_guess needs at least one design set")
    score, i, Q = best
    if idx is not None:  # the chosen set: the points not in the sample
        rest = np.setdiff1d(np.arange(K), idx)
        Q, more = seed(designs[i], rest, Q)
        score += more
    return InitialGuess(problem.pack(designs[i], Q), score, scores, designs)
