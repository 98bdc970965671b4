"""What the synthesis solvers share: their options, their outcome, the row weights
``W_x`` of the task's residual, the convergence test and the workspace's interface.

Pure maths: numpy in and out.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import InputError
from reachwise.kinematics.dls import EPSILON_SOLVER, LAMBDA_MAX
from reachwise.synthesis.problem import Evaluation, SynthesisProblem

Array = NDArray[np.float64]


class Workspace(Protocol):
    """Constraint geometry: signed distance (> 0 inside the free space) and its gradient."""

    def signed_distance(self, points: Array) -> Array: ...

    def gradient(self, points: Array) -> Array: ...


@dataclass(frozen=True)
class SolverOptions:
    """Tuning of the ``dls`` solver (lengths in m, angles in rad); ``lambda_max`` and
    ``epsilon``: the damping schedule (``reachwise.kinematics.dls``);
    ``stationary_decrease`` and ``stationary_gradient``: when a run with clearance terms
    (or any run, with ``stationary_without_clearance``) has found a constrained
    stationary point of its merit (``solvers.solve_dls``); ``clearance_starts``: the
    solves of one run with clearance terms at most, the first from the reach-only start
    and each further one, while none converges, from a clearance-aware start
    (``starts.solve_from_starts``). A run without clearance terms solves once."""

    max_iter: int = 1000
    lambda_max: float = LAMBDA_MAX
    epsilon: float = EPSILON_SOLVER
    err_ref: float = 0.05
    max_step_angle: float = 0.3
    max_step_length: float = 0.5
    workspace_margin: float = 0.1
    workspace_gain: float = 0.5
    samples_per_link: int = 4
    stall_iterations: int = 100
    reseed_every: int = 15
    reseed_restarts: int = 8
    stall_decrease: float = 1e-3
    reseed_progress: float = 0.5
    max_boost: float = 1.0
    stationary_decrease: float = 1e-3
    stationary_gradient: float = 1e-2
    stationary_without_clearance: bool = False
    clearance_starts: int = 1

    def __post_init__(self) -> None:
        starts = self.clearance_starts
        if isinstance(starts, bool) or not isinstance(starts, (int, np.integer)):
            raise InputError("SolverOptions", "clearance_starts", "must be an integer")
        if starts < 1:
            raise InputError("SolverOptions", "clearance_starts", f"must be >= 1, got {starts}")


@dataclass(frozen=True)
class SolveOutcome:
    """What one solver run returns: the final vector, its evaluation and the history."""

    z: Array
    evaluation: Evaluation
    iterations: int
    converged: bool
    cost_history: list[float] = field(default_factory=list)


def row_weights(problem: SynthesisProblem) -> Array:
    """``W_x`` per padded row: 1 for position rows, ``tol_p/tol_o`` for orientation rows."""
    w = np.ones((problem.K, 6))
    w[:, 3:] = (problem.task.tol_position / problem.task.tol_orientation)[:, None]
    return np.where(problem.active_rows, w, 0.0)


def converged(problem: SynthesisProblem, ev: Evaluation) -> bool:
    pos_ok, ori_ok, _ = problem.point_status(ev)
    return bool(pos_ok.all() and ori_ok.all())
