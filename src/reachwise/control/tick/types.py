"""The typed inputs and the result of one compiled controller tick.

Each group is a ``NamedTuple`` with a field specification (dtype, shape) that both
derives its numba type and validates it (``reachwise.kinematics._jit``). Dimensions:
``N`` joints of the chain (fixed ones included), ``n`` joint variables (``q``), ``m``
avoidance rows this tick, ``k`` rows of the guard memory.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import InputError
from reachwise.kinematics._jit import Field, check_group, group_type
from reachwise.kinematics.chain import CHAIN_SPEC, Chain

__all__ = [
    "MEM_AGE",
    "MEM_COLS",
    "AvoidanceRows",
    "AvoidanceSettings",
    "Gains",
    "GuardMemory",
    "JointLimits",
    "Target",
    "TickDiagnostics",
    "check_tick_inputs",
]

#: Columns of ``GuardMemory.lines`` (one remembered collision line per row): frame
#: indices of the robot part and of the other part (-1: a static obstacle), the robot
#: part's point in its link frame, the other end (world, or in the other link's frame),
#: the margin, the tool-part flag and the age in ticks (0: an empty row).
MEM_COLS = 11
#: Column of ``GuardMemory.lines`` holding the age.
MEM_AGE = 10


class JointLimits(NamedTuple):
    """Per joint variable ``(n,)``: position limits ``lower``, ``upper`` (rad or m),
    speed bound ``vmax``; ``usable`` joints the controller may command (not passive,
    not locked); ``passive`` joints the plant moves (a hanging grabber); ``zone`` where
    the limit weighting starts (P-II Eq. 25–28)."""

    lower: NDArray[np.float64]
    upper: NDArray[np.float64]
    vmax: NDArray[np.float64]
    usable: NDArray[np.bool_]
    passive: NDArray[np.bool_]
    zone: NDArray[np.float64]


class Gains(NamedTuple):
    """Gains and bounds of the law: ``kv``, ``kw`` (Eq. 3.8, 3.10), ``v_max``,
    ``w_max`` (Eq. 3.12–3.13), ``lambda_max``, ``epsilon`` (P-I Eq. 14), ``mu``
    (Eq. 3.16–3.17), ``v_rep_max``, ``k_limit`` (the joint-limit velocity damper)."""

    kv: float
    kw: float
    v_max: float
    w_max: float
    lambda_max: float
    epsilon: float
    mu: float
    v_rep_max: float
    k_limit: float


class AvoidanceSettings(NamedTuple):
    """``avoidance``: False gives the conventional controller; ``guard`` the approach
    guard with ``stop_distance`` ``ρ_s`` and ``approach_speed`` ``ξ``;
    ``reaction_time`` and ``velocity_aware`` for moving obstacles."""

    avoidance: bool
    guard: bool
    stop_distance: float
    approach_speed: float
    reaction_time: float
    velocity_aware: bool


class Target(NamedTuple):
    """The tool goal: ``pose`` (4, 4) and ``six`` (True: position and orientation)."""

    pose: NDArray[np.float64]
    six: bool


class AvoidanceRows(NamedTuple):
    """This tick's ``m`` avoidance points (see ``AvoidancePoints``): frame index and
    world point of the robot part (``a_link``, ``a_point``) and of the other part on
    the same robot (``b_link`` ``-1`` otherwise), the unit ``normal`` pointing away from
    the other part, the other part's ``obstacle_velocity``, ``distance``, ``margin``
    ``ρ_O`` and ``task_space`` (a tool part handled in task space, P-V Eq. 6)."""

    a_link: NDArray[np.int64]
    a_point: NDArray[np.float64]
    b_link: NDArray[np.int64]
    b_point: NDArray[np.float64]
    normal: NDArray[np.float64]
    obstacle_velocity: NDArray[np.float64]
    distance: NDArray[np.float64]
    margin: NDArray[np.float64]
    task_space: NDArray[np.bool_]


class GuardMemory(NamedTuple):
    """The guard's remembered collision lines: ``lines`` (k, ``MEM_COLS``), updated by
    the tick, holding at least ``depth`` × the rows of any tick; ``depth`` how many
    past ticks are recalled (0: none)."""

    lines: NDArray[np.float64]
    depth: int


class TickDiagnostics(NamedTuple):
    """What one tick measured: tool ``position_error`` (m) and ``orientation_error``
    (rad), ``sigma_min`` and ``damping`` λ of the pseudo-inverse, ``task_scale`` ``s``,
    ``limit_scale`` ``α``, ``active_points`` within their margins, ``guard_scale``,
    ``min_distance`` (m, inf when there is none)."""

    position_error: float
    orientation_error: float
    sigma_min: float
    damping: float
    task_scale: float
    limit_scale: float
    active_points: int
    guard_scale: float
    min_distance: float


_F = float
LIMITS_SPEC = {
    "lower": Field(np.float64, ("n",)),
    "upper": Field(np.float64, ("n",)),
    "vmax": Field(np.float64, ("n",)),
    "usable": Field(np.bool_, ("n",)),
    "passive": Field(np.bool_, ("n",)),
    "zone": Field(np.float64, ("n",)),
}
GAINS_SPEC = {name: Field(_F) for name in Gains._fields}
SETTINGS_SPEC = {
    "avoidance": Field(bool),
    "guard": Field(bool),
    "stop_distance": Field(_F),
    "approach_speed": Field(_F),
    "reaction_time": Field(_F),
    "velocity_aware": Field(bool),
}
TARGET_SPEC = {"pose": Field(np.float64, (4, 4)), "six": Field(bool)}
ROWS_SPEC = {
    "a_link": Field(np.int64, ("m",)),
    "a_point": Field(np.float64, ("m", 3)),
    "b_link": Field(np.int64, ("m",)),
    "b_point": Field(np.float64, ("m", 3)),
    "normal": Field(np.float64, ("m", 3)),
    "obstacle_velocity": Field(np.float64, ("m", 3)),
    "distance": Field(np.float64, ("m",)),
    "margin": Field(np.float64, ("m",)),
    "task_space": Field(np.bool_, ("m",)),
}
MEMORY_SPEC = {"lines": Field(np.float64, ("k", MEM_COLS), writable=True), "depth": Field(int)}

#: numba types of the groups passed to ``step.control_step`` as plain tuples.
LIMITS = group_type(JointLimits, LIMITS_SPEC)
GAINS = group_type(Gains, GAINS_SPEC)
SETTINGS = group_type(AvoidanceSettings, SETTINGS_SPEC)
TARGET = group_type(Target, TARGET_SPEC)
ROWS = group_type(AvoidanceRows, ROWS_SPEC)
MEMORY = group_type(GuardMemory, MEMORY_SPEC)


def check_static(
    chain: Chain, limits: JointLimits, gains: Gains, settings: AvoidanceSettings
) -> None:
    """Validate the groups a controller builds once (its constructor)."""
    dims: dict[str, int] = {}
    check_group(chain, CHAIN_SPEC, dims)
    check_group(limits, LIMITS_SPEC, dims)
    check_group(gains, GAINS_SPEC, dims)
    check_group(settings, SETTINGS_SPEC, dims)
    qidx = chain.qidx
    if qidx.size and (qidx.max() >= dims["n"] or qidx.min() < -1):
        raise InputError("Chain", "qidx", f"indices must lie in -1 … {dims['n'] - 1}")


def check_tick_inputs(
    chain: Chain,
    limits: JointLimits,
    gains: Gains,
    settings: AvoidanceSettings,
    target: Target,
    rows: AvoidanceRows,
    memory: GuardMemory,
    q: NDArray[np.float64],
) -> None:
    """Validate every input of one tick: dtypes, shapes (consistent across the groups),
    contiguity, and the frame indices of the avoidance rows. Raises :class:`InputError`
    naming the group and the field."""
    check_static(chain, limits, gains, settings)
    dims = {"n": limits.lower.shape[0], "N": chain.kind.shape[0]}
    if not isinstance(q, np.ndarray) or q.dtype != np.float64 or q.shape != (dims["n"],):
        raise InputError("q", "", f"expected a float64 array of shape ({dims['n']},)")
    if not q.flags.c_contiguous:
        raise InputError("q", "", "must be C-contiguous")
    check_group(target, TARGET_SPEC, dims)
    check_group(rows, ROWS_SPEC, dims)
    check_group(memory, MEMORY_SPEC, dims)
    frames = dims["N"] + 2
    m = dims["m"]
    if m and (rows.a_link.min() < 0 or rows.a_link.max() >= frames):
        raise InputError("AvoidanceRows", "a_link", f"frame indices must lie in 0 … {frames - 1}")
    if m and (rows.b_link.min() < -1 or rows.b_link.max() >= frames):
        raise InputError("AvoidanceRows", "b_link", f"frame indices must lie in -1 … {frames - 1}")
    if memory.depth < 0 or memory.lines.shape[0] < memory.depth * m:
        raise InputError(
            "GuardMemory", "lines", f"needs depth × m = {memory.depth * m} rows, has {dims['k']}"
        )
