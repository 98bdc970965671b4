"""Inverse kinematics by damped least squares (P-I Eq. 12–14, P-II Eq. 25–28,
thesis Eq. 3.7).

One iteration solves ``J Δq = e`` for the task error ``e`` (position, and the rotation
vector or the 5-D tool-axis error) with

- damping from the smallest singular value (P-I Eq. 14):
  ``λ² = (1 − (σ_min/ε)²) λ_max²`` inside the singular region ``σ_min < ε``, else 0;
- dynamic joint weighting for the limits (P-II Eq. 25–28): a joint at a bound that the
  step would drive further out is given weight 0 and the step is solved again;
- a secondary goal in the null space (Eq. 3.7): ``z = −k ∇H`` with
  ``H = ½ Σ ((q_i − mid_i)/span_i)²`` keeps redundant joints near mid-range;
- a step-length cap per joint, and projection onto the limits;
- λ_max scaled by ``min(1, ‖e‖/err_ref)`` so the damping fades as the error
  vanishes (Levenberg–Marquardt style): convergence stays quadratic near singular
  solutions, where the plain schedule would crawl.

The loop runs compiled (``_ik_kernel``); random restarts uniform within the limits are
drawn from the caller's generator until one attempt converges.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.errors import InputError
from reachwise.kinematics._ik_kernel import IKBounds, IKSettings, IKTarget, ik_loop
from reachwise.kinematics.dls import EPSILON_SOLVER, LAMBDA_MAX
from reachwise.kinematics.model import KinematicModel
from reachwise.kinematics.transforms import check_pose


@dataclass(frozen=True)
class IKResult:
    """Outcome of one IK solve.

    ``success`` means within both tolerances *and* within the joint limits.
    ``position_error`` (m) and ``orientation_error`` (rad) are measured over the
    constrained task directions only (0 for unconstrained ones).
    """

    q: NDArray[np.float64]
    success: bool
    position_error: float
    orientation_error: float
    iterations: int
    attempts: int = 1


def task_rows(mask: Any) -> tuple[NDArray[np.bool_], bool]:
    """Parse a task mask: ``None``/6 full pose, 5 position + tool axis, 3 position,
    or 6 booleans selecting rows ``x, y, z, rx, ry, rz`` (world frame).

    Returns the row selection and whether the 5-D axis error is used.
    """
    if mask is None:
        return np.ones(6, dtype=np.bool_), False
    if isinstance(mask, int | np.integer) and not isinstance(mask, bool):
        if int(mask) == 6:
            return np.ones(6, dtype=np.bool_), False
        if int(mask) == 5:
            return np.array([1, 1, 1, 0, 0, 0], dtype=np.bool_), True
        if int(mask) == 3:
            return np.array([1, 1, 1, 0, 0, 0], dtype=np.bool_), False
        raise InputError("ik", "mask", f"task dimension must be 3, 5 or 6, got {mask}")
    m = np.asarray(mask)
    if m.shape != (6,) or m.dtype != np.bool_:
        raise InputError("ik", "mask", "expected 3, 5, 6 or six booleans (x y z rx ry rz)")
    if not m.any():
        raise InputError("ik", "mask", "selects no task direction")
    return m.copy(), False


def sample_configurations(
    robot: KinematicModel, rng: np.random.Generator, m: int | None = None
) -> NDArray[np.float64]:
    """Uniform random configurations within the joint limits (``(n,)`` or ``(m, n)``).

    Unbounded revolute joints are drawn from [-π, π], unbounded prismatic ones from
    [-1, 1] m.
    """
    lo, hi = finite_limits(robot)
    size = (robot.n,) if m is None else (m, robot.n)
    return np.asarray(rng.uniform(lo, hi, size=size))


def finite_limits(robot: KinematicModel) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Joint limits with infinite bounds replaced by ±π (revolute) or ±1 m (prismatic)."""
    inf_fill = np.where(robot.prismatic, 1.0, np.pi)
    lo = np.where(np.isfinite(robot.lower), robot.lower, -inf_fill)
    hi = np.where(np.isfinite(robot.upper), robot.upper, inf_fill)
    return lo, hi


@dataclass(frozen=True)
class IKOptions:
    """How :func:`solve_ik` iterates: the tolerances of success, the iteration and
    restart budget, the damping schedule of P-I Eq. 14 and the null-space goal of
    Eq. 3.7. Every field is also a keyword of :func:`solve_ik`."""

    #: Largest position error accepted (m).
    tol_position: float = 1e-6
    #: Largest orientation error accepted (rad).
    tol_orientation: float = 1e-6
    #: Iterations per attempt.
    max_iter: int = 100
    #: Attempts from random configurations after the first.
    restarts: int = 50
    #: Largest damping factor λ_max (P-I Eq. 14; m or rad, as the task error).
    lambda_max: float = LAMBDA_MAX
    #: Singular region: damping starts below this smallest singular value ε.
    epsilon: float = EPSILON_SOLVER
    #: Gain k of the null-space step towards mid-range (Eq. 3.7, dimensionless).
    k_null: float = 0.05
    #: Task error (m) at and above which λ_max applies in full; below, it scales down.
    err_ref: float = 0.01


def solve_ik(
    robot: KinematicModel,
    T: ArrayLike,
    q0: ArrayLike | None = None,
    mask: Any = None,
    rng: np.random.Generator | int | None = None,
    *,
    options: IKOptions | None = None,
    **overrides: Any,
) -> IKResult:
    """Solve ``fk(q) ≈ T`` for the task directions in ``mask``.

    ``q0`` is the first initial guess (default: mid-range); up to ``restarts`` further
    attempts start from random configurations drawn from ``rng`` (a Generator or seed;
    default seed 0, so results are reproducible). Returns the first attempt that
    converges, else the best one with ``success=False``. ``options`` (an
    :class:`IKOptions`) sets the tolerances, budget and damping schedule
    (``reachwise.kinematics.dls``); each of its fields may also be given as a keyword
    (``tol_position=1e-4``), which overrides ``options``.
    """
    opts = replace(options or IKOptions(), **overrides)
    tol_position, tol_orientation = opts.tol_position, opts.tol_orientation
    Td = np.ascontiguousarray(check_pose(T, f"{robot.name}: ik target"))
    rows, axis_mode = task_rows(mask)
    if not (tol_position > 0 and tol_orientation > 0):
        raise InputError("ik", "tolerance", "tolerances must be > 0")
    gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng or 0)
    lo, hi = finite_limits(robot)
    if q0 is None:
        start = 0.5 * (lo + hi)
    else:
        start = np.asarray(q0, dtype=np.float64)
        if start.shape != (robot.n,) or not np.isfinite(start).all():
            raise InputError(robot.name, "q0", f"expected {robot.n} finite values")
        start = np.clip(start, robot.lower, robot.upper)
    span = hi - lo
    max_step = np.where(robot.prismatic, np.clip(0.2 * span, 0.05, 1.0), 0.5)
    # the kernel's groups, passed as plain tuples (see reachwise.kinematics._jit)
    chain = tuple(robot.arrays)
    target = tuple(IKTarget(pose=Td, rows=rows, axis_mode=axis_mode))
    bounds = tuple(IKBounds(lower=robot.lower, upper=robot.upper, max_step=max_step))
    settings = tuple(
        IKSettings(
            tol_position=float(tol_position),
            tol_orientation=float(tol_orientation),
            max_iter=int(opts.max_iter),
            lambda_max=float(opts.lambda_max),
            epsilon=float(opts.epsilon),
            k_null=float(opts.k_null),
            err_ref=float(opts.err_ref),
        )
    )
    best = IKResult(start.copy(), False, np.inf, np.inf, 0, 0)
    total = 0
    restarts = opts.restarts
    for attempt in range(restarts + 1):
        if attempt > 0:
            start = gen.uniform(lo, hi)
        q, it, ep, eo = ik_loop(
            chain, target, bounds, settings, np.ascontiguousarray(start, dtype=np.float64)
        )
        total += int(it)
        ok = bool(ep <= tol_position and eo <= tol_orientation and robot.within_limits(q))
        res = IKResult(q, ok, float(ep), float(eo), total, attempt + 1)
        if ok:
            return res
        if ep + eo < best.position_error + best.orientation_error:
            best = res
    return IKResult(best.q, False, best.position_error, best.orientation_error, total, restarts + 1)
