"""The dimensional-synthesis problem: decision-vector layout, residual and Jacobian blocks.

P-I §3.1 (Eq. 15–21), P-II §4 (Eq. 13–23). One decision vector ``z`` holds

    z = [ design parameters (p) | q of task point 1 (n_f) | … | q of task point K ]

where the design parameters are the free DH parameters of the template (from its
``design`` bounds) followed by the free base coordinates (``x y z roll pitch yaw``), and
``n_f`` is the number of joint variables that are not locked (P-I keeps the feed
rotation fixed). The stacked residual is ``e = [e_1; …; e_K]`` with, per task point,
the position error (3 rows) and the orientation error: the rotation vector of
``R_d Rᵀ`` (6-D), the tool-axis error on the two directions normal to the tool axis
(5-D, P-II §5) or nothing (3-D). The Jacobian is block-arrow shaped: every point's rows
share the ``p`` design columns ``D_k`` and own one block ``J_k`` of joint columns, zero
elsewhere. Rows are padded to 6 per point; inactive rows are zero and flagged.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import InputError
from reachwise.kinematics.jacobian import jacobians
from reachwise.kinematics.orientation import axis_error, rotation_error
from reachwise.kinematics.robot import BASE_PARAMS, DH_PARAMS, Robot
from reachwise.kinematics.transforms import pose_from_xyz_rpy, xyz_rpy_from_pose
from reachwise.tasks.task import Task

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Evaluation:
    """Residual and Jacobian blocks of the problem at one decision vector.

    ``e (K, 6)`` residuals (target − current, inactive rows 0), ``active (K, 6)``,
    ``D (K, 6, p)`` design blocks, ``J (K, 6, n_f)`` joint blocks, ``T (K, 4, 4)`` tool
    poses, ``position_error`` and ``orientation_error`` per point (m, rad).
    """

    e: Array
    active: NDArray[np.bool_]
    D: Array
    J: Array
    T: Array
    position_error: Array
    orientation_error: Array

    @property
    def cost(self) -> float:
        """½ ‖e‖² of the stacked residual."""
        return 0.5 * float(np.sum(self.e * self.e))


@dataclass(frozen=True, eq=False)
class SynthesisProblem:
    """A template robot with design bounds, a task, and which joints stay locked.

    ``locked`` maps an index into ``q`` to the value it keeps during the synthesis.
    """

    template: Robot
    task: Task
    locked: dict[int, float] = field(default_factory=dict)
    #: the last design ``robot_at`` built and its robot (the solver evaluates the task,
    #: the clearance and the workspace at one design before the next trial)
    _last_robot: tuple[bytes, Robot] | None = field(
        default=None, init=False, repr=False, compare=False
    )

    def __post_init__(self) -> None:
        src = self.template.name
        if len(self.task) == 0:
            raise InputError(self.task.name, "points", "the task has no points")
        if self.template.design.size == 0:
            raise InputError(src, "design", "the template has no free design parameter")
        for k, v in self.locked.items():
            if not 0 <= k < self.template.n:
                raise InputError(src, f"locked.{k}", f"no joint variable {k}")
            if not self.template.lower[k] <= v <= self.template.upper[k]:
                raise InputError(src, f"locked.{k}", f"value {v} outside the joint limits")
        if self.n_free_joints == 0:
            raise InputError(src, "locked", "every joint is locked")

    # ---- layout ------------------------------------------------------------------
    @property
    def design_names(self) -> tuple[str, ...]:
        """Names of the design variables (``Robot.design_names``: a1 a2 d3 … base.x)."""
        return self.template.design_names

    @cached_property
    def design_columns(self) -> NDArray[np.int64]:
        """Columns of ``Robot.param_jacobian`` that belong to the design variables."""
        N = len(self.template.joints)
        cols = []
        for kind, j, p in self.template.design.free:
            if kind == "joint":
                cols.append(4 * j + DH_PARAMS.index(p))
            else:
                cols.append(4 * N + BASE_PARAMS.index(p))
        return np.array(cols, dtype=np.int64)

    @property
    def p(self) -> int:
        return self.template.design.size

    @cached_property
    def free_joints(self) -> NDArray[np.int64]:
        return np.array([k for k in range(self.template.n) if k not in self.locked], np.int64)

    @property
    def n_free_joints(self) -> int:
        return int(self.free_joints.size)

    @property
    def K(self) -> int:
        return len(self.task)

    @property
    def size(self) -> int:
        """Number of unknowns: ``p + K n_f``."""
        return self.p + self.K * self.n_free_joints

    @cached_property
    def residual_rows(self) -> int:
        return int(self.active_rows.sum())

    @cached_property
    def active_rows(self) -> NDArray[np.bool_]:
        """``(K, 6)``: which of the six padded rows each task point uses."""
        dims = self.task.dims
        act = np.zeros((self.K, 6), dtype=np.bool_)
        act[:, :3] = True
        act[dims == 5, 3:5] = True
        act[dims == 6, 3:6] = True
        return act

    @cached_property
    def declared_bounds(self) -> tuple[Array, Array]:
        """The design section's bounds of the design variables, ``(p,)`` each (the scale
        of P-I Table 3's normalized values)."""
        d = self.template.design
        lo_d, hi_d = [], []
        for kind, j, p in d.free:
            lo, hi = d.joints[j][p] if kind == "joint" else d.base[p]
            lo_d.append(lo)
            hi_d.append(hi)
        return np.array(lo_d, dtype=np.float64), np.array(hi_d, dtype=np.float64)

    @cached_property
    def design_bounds(self) -> tuple[Array, Array]:
        """Bounds of the design variables the solver keeps: the declared ones, with every
        free ``a`` and ``d`` kept at least ``design.min_length`` from 0 (a link that can
        be built). A range that spans 0 keeps the side of the template's value
        (positive when that is 0); a range narrower than the minimum is an error."""
        lo, hi = (b.copy() for b in self.declared_bounds)
        m = self.template.design.min_length
        if m <= 0:
            return lo, hi
        nominal = self.design_vector()
        for i, (kind, _, p) in enumerate(self.template.design.free):
            if kind != "joint" or p not in ("a", "d"):
                continue
            if lo[i] >= 0 or (hi[i] > 0 and nominal[i] >= 0):
                lo[i] = max(lo[i], m)
            else:
                hi[i] = min(hi[i], -m)
            if lo[i] > hi[i]:
                raise InputError(
                    self.template.name,
                    f"design.{self.design_names[i]}",
                    f"min_length {m} m does not fit the bounds {self.declared_bounds[0][i]}"
                    f"..{self.declared_bounds[1][i]}",
                )
        return lo, hi

    @cached_property
    def bounds(self) -> tuple[Array, Array]:
        """Lower and upper bounds of every decision variable (``design_bounds``, then
        the joint limits of every task point)."""
        lo_d, hi_d = self.design_bounds
        fj = self.free_joints
        lo_q = np.tile(self.template.lower[fj], self.K)
        hi_q = np.tile(self.template.upper[fj], self.K)
        return np.concatenate([lo_d, lo_q]), np.concatenate([hi_d, hi_q])

    @cached_property
    def base_xyz_rpy(self) -> Array:
        xyz, rpy = xyz_rpy_from_pose(self.template.base)
        return np.concatenate([xyz, rpy])

    def design_vector(self, robot: Robot | None = None) -> Array:
        """Current values of the design variables of ``robot`` (default: the template)."""
        r = robot or self.template
        xyzrpy = np.concatenate(xyz_rpy_from_pose(r.base))
        out = []
        for kind, j, p in self.template.design.free:
            if kind == "joint":
                out.append(r.dh[j, DH_PARAMS.index(p)])
            else:
                out.append(xyzrpy[BASE_PARAMS.index(p)])
        return np.array(out, dtype=np.float64)

    def pack(self, design: Array, Q: Array) -> Array:
        """Decision vector from design values ``(p,)`` and joint values ``(K, n)``."""
        return np.concatenate([design, np.asarray(Q)[:, self.free_joints].ravel()])

    def split(self, z: Array) -> tuple[Array, Array]:
        """Design values ``(p,)`` and full joint values ``(K, n)`` (locked ones filled)."""
        Q = np.empty((self.K, self.template.n))
        Q[:, self.free_joints] = z[self.p :].reshape(self.K, self.n_free_joints)
        for k, v in self.locked.items():
            Q[:, k] = v
        return z[: self.p], Q

    def robot_at(self, design: Array, name: str | None = None) -> Robot:
        """The template with the design variables set to ``design``."""
        key = np.asarray(design, dtype=np.float64).tobytes()
        if name is None and self._last_robot is not None and self._last_robot[0] == key:
            return self._last_robot[1]
        dh = np.array(self.template.dh)
        base6 = self.base_xyz_rpy.copy()
        for v, (kind, j, p) in zip(design, self.template.design.free, strict=True):
            if kind == "joint":
                dh[j, DH_PARAMS.index(p)] = v
            else:
                base6[BASE_PARAMS.index(p)] = v
        base = pose_from_xyz_rpy(base6[:3], base6[3:])
        robot = self.template.with_parameters(dh=dh, base=base, name=name)
        if name is None:
            object.__setattr__(self, "_last_robot", (key, robot))
        return robot

    # ---- residual and Jacobian ---------------------------------------------------
    def evaluate(self, z: Array) -> Evaluation:
        """Residual and Jacobian blocks at ``z`` (P-I Eq. 21; P-II Eq. 15–23)."""
        design, Q = self.split(z)
        robot = self.robot_at(design)
        T, Jq, P = jacobians(robot, Q, params=True)
        return self._blocks(T, Jq[:, :, self.free_joints], P[:, :, self.design_columns])

    def _blocks(self, T: Array, Jq: Array, Pd: Array) -> Evaluation:
        task = self.task
        K = self.K
        e = np.zeros((K, 6))
        D = np.zeros((K, 6, self.p))
        J = np.zeros((K, 6, Jq.shape[2]))
        dp = task.positions - T[:, :3, 3]
        e[:, :3] = dp
        D[:, :3] = Pd[:, :3]
        J[:, :3] = Jq[:, :3]
        eo = np.zeros(K)
        dims = task.dims
        six = np.flatnonzero(dims == 6)
        if six.size:
            rv = rotation_error(T[six, :3, :3], task.poses[six, :3, :3])
            e[six, 3:] = rv
            D[six, 3:] = Pd[six, 3:]
            J[six, 3:] = Jq[six, 3:]
            eo[six] = np.linalg.norm(rv, axis=1)
        five = np.flatnonzero(dims == 5)
        if five.size:
            R = T[five, :3, :3]
            ev = axis_error(R, task.axes[five])
            basis = R[:, :, :2]  # tool x and y axes, normal to the tool axis
            e[five, 3:5] = np.einsum("kib,ki->kb", basis, ev)
            D[five, 3:5] = np.einsum("kib,kic->kbc", basis, Pd[five, 3:])
            J[five, 3:5] = np.einsum("kib,kic->kbc", basis, Jq[five, 3:])
            eo[five] = np.linalg.norm(ev, axis=1)
        return Evaluation(
            e=e,
            active=self.active_rows,
            D=D,
            J=J,
            T=T,
            position_error=np.linalg.norm(dp, axis=1),
            orientation_error=eo,
        )

    def dense_jacobian(self, ev: Evaluation) -> Array:
        """The full stacked Jacobian ``(rows, size)`` — for tests and small problems."""
        act = ev.active
        rows = []
        nf = self.n_free_joints
        for k in range(self.K):
            blk = np.zeros((int(act[k].sum()), self.size))
            blk[:, : self.p] = ev.D[k][act[k]]
            blk[:, self.p + k * nf : self.p + (k + 1) * nf] = ev.J[k][act[k]]
            rows.append(blk)
        return np.vstack(rows)

    def dense_residual(self, ev: Evaluation) -> Array:
        return ev.e[ev.active]

    def point_status(
        self, ev: Evaluation
    ) -> tuple[NDArray[np.bool_], NDArray[np.bool_], list[str]]:
        """Per point: position within tolerance, orientation within tolerance, and the
        status of P-I Fig. 4: ``full`` (green), ``position`` (blue), ``orientation``
        (yellow) or ``neither`` (red). A 3-D point has no orientation requirement."""
        pos_ok = ev.position_error <= self.task.tol_position
        ori_ok = (ev.orientation_error <= self.task.tol_orientation) | (self.task.dims == 3)
        status = [
            "full" if p and o else "position" if p else "orientation" if o else "neither"
            for p, o in zip(pos_ok, ori_ok, strict=True)
        ]
        return pos_ok, ori_ok, status

    def within_bounds(self, z: Array, tol: float = 1e-12) -> bool:
        lo, hi = self.bounds
        return bool(np.all(z >= lo - tol) and np.all(z <= hi + tol))


def locked_from_spec(
    robot: Robot, spec: Sequence[int] | dict[int, float] | None
) -> dict[int, float]:
    """Locked joints: a mapping ``{q index: value}`` or a list of indices locked at 0
    (clipped into the limits)."""
    if spec is None:
        return {}
    if isinstance(spec, dict):
        return {int(k): float(v) for k, v in spec.items()}
    return {int(k): float(np.clip(0.0, robot.lower[int(k)], robot.upper[int(k)])) for k in spec}
