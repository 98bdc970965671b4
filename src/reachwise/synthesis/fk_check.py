"""Does a design reach its task? Forward kinematics, independent of the solver.

The synthesis judges its iterates by its own residual (``problem.evaluate``: the
Jacobian kernel's tool poses and the orientation errors of ``kinematics.orientation``).
A design that leaves the synthesis — a Pareto design a designer may build — is checked
once more from scratch: the robot's own forward kinematics (``Robot.fk``) at every
task posture against the task poses, with other formulas for the orientation error:

* position: ``‖p − p_d‖`` (m);
* 6-D point: the angle of ``R_dᵀ R``, ``2 asin(‖R − R_d‖_F / (2√2))`` (rad; exact for
  rotation matrices, ``‖R − R_d‖_F = 2√2 sin(θ/2)``, and accurate for small angles,
  where ``acos`` of the trace is not);
* 5-D point: the angle between the tool z axis and the task axis,
  ``atan2(‖z × a‖, z · a)``;
* 3-D point: no orientation requirement.

A point is reached when both errors are within the task's tolerances (P-I Fig. 4).
Pure math.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.kinematics.robot import Robot
from reachwise.tasks.task import Task

Array = NDArray[np.float64]


def pose_errors(robot: Robot, q: ArrayLike, task: Task) -> tuple[Array, Array]:
    """Position (m) and orientation (rad, 0 for 3-D points) error of the tool at every
    posture ``q (K, n)`` against the task's ``K`` poses (module docstring)."""
    Q = np.atleast_2d(np.asarray(q, dtype=np.float64))
    T = np.asarray(robot.fk(Q)).reshape(-1, 4, 4)
    pos = np.linalg.norm(T[:, :3, 3] - task.positions, axis=1)
    R, Rd = T[:, :3, :3], task.poses[:, :3, :3]
    frob = np.linalg.norm(R - Rd, axis=(1, 2))
    full = 2.0 * np.arcsin(np.clip(frob / (2.0 * np.sqrt(2.0)), 0.0, 1.0))
    z, a = R[:, :, 2], task.axes
    axis = np.arctan2(np.linalg.norm(np.cross(z, a), axis=1), np.einsum("ki,ki->k", z, a))
    dims = task.dims
    ori = np.where(dims == 6, full, np.where(dims == 5, axis, 0.0))
    return pos, ori


def reached_by_fk(robot: Robot, q: ArrayLike, task: Task) -> NDArray[np.bool_]:
    """Per task point: both errors of ``pose_errors`` within the point's tolerances."""
    pos, ori = pose_errors(robot, q, task)
    return (pos <= task.tol_position) & (ori <= task.tol_orientation)
