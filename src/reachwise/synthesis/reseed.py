"""Re-seeding of the ``dls`` solver: the joints of the unreached task points re-solved
by IK on the current design, with restarts.

Given the design, the task points are independent inverse-kinematics problems; the
solver re-seeds when a window of iterations made little progress (a trapped branch, a
joint stuck at a limit). With clearance terms, a re-seeded pose's joints are kept only
where they lower that pose's share of the merit (``keep_clearer``).

Pure maths: numpy in and out.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from reachwise.kinematics.ik import solve_ik
from reachwise.synthesis.clearance import ClearanceModel
from reachwise.synthesis.clearance_rows import pose_merits
from reachwise.synthesis.init import locked_robot
from reachwise.synthesis.problem import Evaluation, SynthesisProblem

Array = NDArray[np.float64]


def reseed_points(
    problem: SynthesisProblem,
    z: Array,
    ev: Evaluation,
    rng: np.random.Generator,
    restarts: int,
) -> Array | None:
    """Re-solve the joints of every unreached task point by IK on the current design.

    Given the design, the task points are independent inverse-kinematics problems; a
    point whose joints are trapped (a wrong branch, a joint stuck at a limit) gets
    fresh random restarts. A point's joints are replaced only when IK lowers its
    weighted error. Returns the new vector, or None if nothing improved.
    """
    pos_ok, ori_ok, _ = problem.point_status(ev)
    todo = np.flatnonzero(~(pos_ok & ori_ok))
    if todo.size == 0:
        return None
    design, Q = problem.split(z)
    robot = locked_robot(problem, problem.robot_at(design))
    task = problem.task
    w = task.tol_position / task.tol_orientation
    improved = False
    for k in todo:
        res = solve_ik(
            robot, task.poses[k], q0=Q[k], mask=int(task.dims[k]), rng=rng,
            tol_position=float(task.tol_position[k]),
            tol_orientation=float(task.tol_orientation[k]), max_iter=80, restarts=restarts,
        )  # fmt: skip
        before = ev.position_error[k] + w[k] * ev.orientation_error[k]
        if res.position_error + w[k] * res.orientation_error < before:
            Q[k] = res.q
            improved = True
    return problem.pack(design, Q) if improved else None


def keep_clearer(
    problem: SynthesisProblem,
    z: Array,
    ev: Evaluation,
    z2: Array,
    wx: Array,
    clearance: ClearanceModel,
) -> Array | None:
    """``z2`` (re-seeded joints, same design as ``z``) with each pose's joints kept only
    where they lower that pose's share of the merit, clearance rows included: the IK of
    ``reseed_points`` knows the task only, and joints that reach a pose through a body
    would raise the merit and undo the solver's progress. None if no pose gained."""
    before = pose_merits(problem, ev, wx, z, clearance)
    after = pose_merits(problem, problem.evaluate(z2), wx, z2, clearance)
    better = after < before
    if not better.any():
        return None
    p, nf = problem.p, problem.n_free_joints
    Q = np.where(better[:, None], z2[p:].reshape(-1, nf), z[p:].reshape(-1, nf))
    return np.concatenate([z[:p], Q.ravel()])
