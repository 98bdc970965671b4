"""Task points and tasks: the poses a manipulator must reach (thesis §2.3, P-I §3–4).

A task point constrains the tool in a task space of 3, 5 or 6 dimensions (mission
item 2): position only (3-D); position and the direction of the tool z axis (5-D, an
axis-symmetric drill spindle whose roll does not matter, P-II §5); or the full pose
(6-D, as in the thesis's tunnel case, where the feed's roll matters near the walls,
P-I §4 and P-II §5). Each point carries its own position (m) and orientation (rad)
tolerances; the synthesis counts a point as reached when both hold (P-I Fig. 4).

Pure math: numpy in, numpy out; invalid input raises ``TaskError`` naming the field.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import TypedDict, Unpack

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.errors import TaskError
from reachwise.tasks.workspace import TunnelEnvelope

FloatArray = NDArray[np.float64]
DIMS: tuple[int, ...] = (3, 5, 6)
DEFAULT_TOL_POSITION = 1e-3  # m
DEFAULT_TOL_ORIENTATION = 1e-3  # rad
_ROT_TOL = 1e-6
_AXIS_MIN_NORM = 1e-9


def _readonly(a: FloatArray) -> FloatArray:
    a.setflags(write=False)
    return a


def frame_from_axis(axis: ArrayLike, roll: ArrayLike = 0.0) -> FloatArray:
    """Rotation(s) whose z column is ``axis``, with x/y completed deterministically.

    For ``roll = 0``: ``y = normalize(ẑ_world × axis)`` and ``x = y × axis`` (so a tool
    drilling straight ahead, ``axis = +x``, gets ``x = -z_world`` and ``y = +y_world``,
    the rotation ``Ry(π/2)``); when the axis is within ~0.06° of vertical, ``x̂_world``
    replaces ``ẑ_world``. ``roll`` (rad) then turns x and y about the axis. Batched:
    ``axis (..., 3)`` and ``roll (...)`` broadcast to ``(..., 3, 3)``.
    """
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    ref = np.broadcast_to(np.array([0.0, 0.0, 1.0]), a.shape)
    near_vertical = np.abs(a[..., 2]) > 1 - 5e-7
    ref = np.where(near_vertical[..., None], np.array([1.0, 0.0, 0.0]), ref)
    y = np.cross(ref, a)
    y = y / np.linalg.norm(y, axis=-1, keepdims=True)
    x = np.cross(y, a)
    r = np.asarray(roll, dtype=float)[..., None]
    x, y = np.cos(r) * x + np.sin(r) * y, -np.sin(r) * x + np.cos(r) * y
    x, y, a = np.broadcast_arrays(x, y, a)
    return np.stack([x, y, a], axis=-1)


def _vec3(value: ArrayLike, field_name: str) -> FloatArray:
    try:
        v = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise TaskError("task point", field_name, f"not numeric: {value!r}") from None
    if v.shape != (3,):
        raise TaskError("task point", field_name, f"expected 3 values, got shape {v.shape}")
    if not np.isfinite(v).all():
        raise TaskError("task point", field_name, f"contains NaN or inf: {v.tolist()}")
    return v


def _rotation(value: ArrayLike) -> FloatArray:
    try:
        R = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise TaskError("task point", "rotation", "not numeric") from None
    if R.shape != (3, 3):
        raise TaskError("task point", "rotation", f"expected a 3x3 matrix, got shape {R.shape}")
    if not np.isfinite(R).all():
        raise TaskError("task point", "rotation", "contains NaN or inf")
    err = float(np.abs(R.T @ R - np.eye(3)).max())
    if err > _ROT_TOL or np.linalg.det(R) <= 0:
        raise TaskError(
            "task point",
            "rotation",
            f"not a proper rotation (|RᵀR - I| = {err:.2g}, det = {np.linalg.det(R):.3g})",
        )
    # project onto SO(3) so downstream maths sees an exact rotation
    U, _, Vt = np.linalg.svd(R)
    return np.asarray(U @ Vt)


def _tolerance(value: float, field_name: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise TaskError("task point", field_name, f"must be a number, got {value!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise TaskError("task point", field_name, f"must be finite and > 0, got {v}")
    return v


@dataclass(frozen=True, eq=False)
class TaskPoint:
    """One pose to reach: position (m), optional orientation, task-space size, tolerances.

    ``rotation`` is a 3x3 rotation (world frame) of the tool; ``axis`` the unit
    direction of the tool z axis (normalized here; zero length is an error). When a
    rotation is given its z column is the axis, and a given ``axis`` must agree with it.
    ``dims`` is 3, 5 or 6 (0 infers it: 6 with a rotation, 5 with only an axis, 3
    otherwise); 6 needs a rotation, 5 an axis or a rotation. Tolerances are > 0:
    ``tol_position`` in m, ``tol_orientation`` in rad (defaults 1 mm and 1 mrad).
    ``name`` identifies the point (e.g. a drill-plan hole id), ``group`` its zone.
    """

    position: FloatArray
    rotation: FloatArray | None = None
    axis: FloatArray | None = None
    dims: int = 0
    tol_position: float = DEFAULT_TOL_POSITION
    tol_orientation: float = DEFAULT_TOL_ORIENTATION
    name: str = ""
    group: str = ""

    def __post_init__(self) -> None:
        put = object.__setattr__
        put(self, "position", _readonly(_vec3(self.position, "position")))
        R = None if self.rotation is None else _rotation(self.rotation)
        axis = None
        if self.axis is not None:
            axis = _vec3(self.axis, "axis")
            n = float(np.linalg.norm(axis))
            if n < _AXIS_MIN_NORM:
                raise TaskError("task point", "axis", "zero-length axis")
            axis = axis / n
        if R is not None:
            z = R[:, 2].copy()
            if axis is not None and float(np.dot(axis, z)) < 1 - _ROT_TOL:
                ang = math.degrees(math.acos(max(-1.0, min(1.0, float(np.dot(axis, z))))))
                raise TaskError(
                    "task point",
                    "axis",
                    f"disagrees with the rotation's z column by {ang:.3g}°",
                )
            axis = z
        put(self, "rotation", None if R is None else _readonly(R))
        put(self, "axis", None if axis is None else _readonly(axis))
        dims = self.dims
        if isinstance(dims, bool) or not isinstance(dims, int | np.integer):
            raise TaskError("task point", "dims", f"must be 3, 5 or 6, got {dims!r}")
        dims = int(dims)
        if dims == 0:
            dims = 6 if R is not None else 5 if axis is not None else 3
        if dims not in DIMS:
            raise TaskError("task point", "dims", f"must be 3, 5 or 6, got {dims}")
        if dims == 6 and R is None:
            raise TaskError("task point", "dims", "a 6-D point needs an orientation (rotation)")
        if dims == 5 and axis is None:
            raise TaskError("task point", "dims", "a 5-D point needs a tool axis or a rotation")
        put(self, "dims", dims)
        put(self, "tol_position", _tolerance(self.tol_position, "tol_position"))
        put(self, "tol_orientation", _tolerance(self.tol_orientation, "tol_orientation"))
        if not isinstance(self.name, str):
            raise TaskError("task point", "name", f"must be a string, got {self.name!r}")
        if not isinstance(self.group, str):
            raise TaskError("task point", "group", f"must be a string, got {self.group!r}")

    @property
    def pose(self) -> FloatArray:
        """4x4 pose of the point: the given rotation, else for a 5-D point the frame of
        ``frame_from_axis(axis)``, else the identity rotation."""
        T = np.eye(4)
        if self.rotation is not None:
            T[:3, :3] = self.rotation
        elif self.axis is not None:
            T[:3, :3] = frame_from_axis(self.axis)
        T[:3, 3] = self.position
        return T


def _tagged(index: int, exc: TaskError, source: str) -> TaskError:
    return TaskError(
        source, f"points[{index}].{exc.field}" if exc.field else f"points[{index}]", exc.reason
    )


@dataclass(frozen=True)
class PointArrays:
    """The per-point fields of a task built from arrays (:meth:`Task.from_arrays`),
    for ``m`` points: each a scalar for every point or one entry per point."""

    #: Tool orientations ``(m, 3, 3)`` (6-D points), or ``None``.
    rotations: ArrayLike | None = None
    #: Tool z axes ``(m, 3)`` (5-D points; normalized), or ``None``.
    axes: ArrayLike | None = None
    #: Task-space dimension 3, 5 or 6 per point (scalar or ``(m,)``); 0 infers it.
    dims: int | Sequence[int] = 0
    #: Position tolerance (m), scalar or ``(m,)``.
    tol_position: float | ArrayLike = DEFAULT_TOL_POSITION
    #: Orientation tolerance (rad), scalar or ``(m,)``.
    tol_orientation: float | ArrayLike = DEFAULT_TOL_ORIENTATION
    #: The points' names (``m`` entries), or ``None``.
    names: Sequence[str] | None = None
    #: The points' groups (``m`` entries), or ``None``.
    groups: Sequence[str] | None = None

    def points(self, positions: FloatArray, source: str) -> tuple[TaskPoint, ...]:
        """The task points at ``positions (m, 3)`` (m); a field of the wrong shape or
        a bad point is a ``TaskError`` naming it (``points[i].field``) in ``source``."""
        m = positions.shape[0]

        def per_point(value: object, label: str, shape: tuple[int, ...]) -> NDArray[np.generic]:
            a = np.asarray(value)
            if a.shape == shape:
                a = np.broadcast_to(a, (m, *shape))
            if a.shape != (m, *shape):
                raise TaskError(source, label, f"expected shape {(m, *shape)}, got {a.shape}")
            return a

        R = None if self.rotations is None else per_point(self.rotations, "rotations", (3, 3))
        A = None if self.axes is None else per_point(self.axes, "axes", (3,))
        D = per_point(self.dims, "dims", ())
        tp = per_point(self.tol_position, "tol_position", ())
        to = per_point(self.tol_orientation, "tol_orientation", ())
        for label, seq in (("names", self.names), ("groups", self.groups)):
            if seq is not None and len(seq) != m:
                raise TaskError(source, label, f"expected {m} entries, got {len(seq)}")
        pts = []
        for i in range(m):
            try:
                pts.append(
                    TaskPoint(
                        positions[i],
                        rotation=None if R is None else R[i],
                        axis=None if A is None else A[i],
                        dims=int(D[i]),
                        tol_position=float(tp[i]),
                        tol_orientation=float(to[i]),
                        name="" if self.names is None else self.names[i],
                        group="" if self.groups is None else self.groups[i],
                    )
                )
            except TaskError as exc:
                raise _tagged(i, exc, source) from None
        return tuple(pts)


class PointArrayKeywords(TypedDict, total=False):
    """:class:`PointArrays`'s fields as keywords (the same names and types)."""

    rotations: ArrayLike | None
    axes: ArrayLike | None
    dims: int | Sequence[int]
    tol_position: float | ArrayLike
    tol_orientation: float | ArrayLike
    names: Sequence[str] | None
    groups: Sequence[str] | None


@dataclass(frozen=True, eq=False)
class Task:
    """A named, non-empty sequence of task points, with vectorized accessors.

    ``envelope`` optionally carries the workspace constraint the task is drilled in
    (the tunnel, P-I §4.2); the synthesis keeps every link inside it. The thesis's
    tunnel task is 87 such points combined from 10 drill plans (P-I §4); see
    ``reachwise.tasks.drilling.tunnel_87`` for the public stand-in.
    """

    name: str
    points: tuple[TaskPoint, ...]
    envelope: TunnelEnvelope | None = field(default=None)

    def __post_init__(self) -> None:
        src = f"task {self.name!r}"
        if not isinstance(self.name, str):
            raise TaskError("task", "name", f"must be a string, got {self.name!r}")
        pts = tuple(self.points)
        if not pts:
            raise TaskError(src, "points", "a task needs at least one point (empty task)")
        for i, p in enumerate(pts):
            if not isinstance(p, TaskPoint):
                raise TaskError(src, f"points[{i}]", f"not a TaskPoint: {type(p).__name__}")
        object.__setattr__(self, "points", pts)
        if self.envelope is not None and not isinstance(self.envelope, TunnelEnvelope):
            raise TaskError(src, "envelope", "must be a TunnelEnvelope or None")

    @classmethod
    def from_arrays(
        cls,
        name: str,
        positions: ArrayLike,
        *,
        arrays: PointArrays | None = None,
        envelope: TunnelEnvelope | None = None,
        source: str = "task",
        **keywords: Unpack[PointArrayKeywords],
    ) -> Task:
        """Build a task from arrays: ``positions (m, 3)`` (m) and the per-point
        fields as one :class:`PointArrays` group ``arrays`` or as its fields one by one
        (``rotations``, ``axes``, ``dims``, ``tol_position``, ``tol_orientation``,
        ``names``, ``groups``), which override the group's. Errors name
        ``points[i].field``."""
        P = np.asarray(positions, dtype=float)
        if P.ndim != 2 or P.shape[1] != 3:
            raise TaskError(source, "positions", f"expected shape (m, 3), got {P.shape}")
        if P.shape[0] == 0:
            raise TaskError(source, "points", "a task needs at least one point (empty task)")
        a = replace(arrays or PointArrays(), **keywords)
        return cls(name, a.points(P, source), envelope)

    # -- sequence protocol ------------------------------------------------------------
    def __len__(self) -> int:
        return len(self.points)

    def __iter__(self) -> Iterator[TaskPoint]:
        return iter(self.points)

    def __getitem__(self, i: int) -> TaskPoint:
        return self.points[i]

    def __repr__(self) -> str:
        dims = ", ".join(
            f"{n}×{d}-D" for d, n in zip(*np.unique(self.dims, return_counts=True), strict=True)
        )
        return f"Task({self.name!r}, {len(self)} points: {dims})"

    # -- vectorized accessors ----------------------------------------------------------
    @cached_property
    def positions(self) -> FloatArray:
        """Positions ``(m, 3)`` (m)."""
        return _readonly(np.array([p.position for p in self.points]))

    @cached_property
    def poses(self) -> FloatArray:
        """Poses ``(m, 4, 4)`` (see ``TaskPoint.pose``)."""
        T = np.tile(np.eye(4), (len(self), 1, 1))
        T[:, :3, 3] = self.positions
        for i, p in enumerate(self.points):
            if p.rotation is not None:
                T[i, :3, :3] = p.rotation
        axis_only = [
            i for i, p in enumerate(self.points) if p.rotation is None and p.axis is not None
        ]
        if axis_only:
            A = np.array([self.points[i].axis for i in axis_only])
            T[axis_only, :3, :3] = frame_from_axis(A)
        return _readonly(T)

    @cached_property
    def rotations(self) -> FloatArray:
        """Rotations ``(m, 3, 3)`` of ``poses``."""
        return _readonly(self.poses[:, :3, :3].copy())

    @cached_property
    def axes(self) -> FloatArray:
        """Tool z axes ``(m, 3)``: the given axis, or the z column of ``poses`` (``+z``
        for a 3-D point without orientation, where it constrains nothing)."""
        return _readonly(self.poses[:, :3, 2].copy())

    @cached_property
    def dims(self) -> NDArray[np.int64]:
        """Task-space dimension per point ``(m,)``: 3, 5 or 6."""
        a = np.array([p.dims for p in self.points], dtype=np.int64)
        a.setflags(write=False)
        return a

    @cached_property
    def tol_position(self) -> FloatArray:
        """Position tolerance per point ``(m,)`` (m)."""
        return _readonly(np.array([p.tol_position for p in self.points]))

    @cached_property
    def tol_orientation(self) -> FloatArray:
        """Orientation tolerance per point ``(m,)`` (rad)."""
        return _readonly(np.array([p.tol_orientation for p in self.points]))

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.points)

    @property
    def groups(self) -> tuple[str, ...]:
        """Group (e.g. drilling zone) of every point, in order."""
        return tuple(p.group for p in self.points)

    def group_indices(self) -> dict[str, NDArray[np.intp]]:
        """Point indices of each group, groups in order of first appearance."""
        out: dict[str, list[int]] = {}
        for i, g in enumerate(self.groups):
            out.setdefault(g, []).append(i)
        return {g: np.array(ix, dtype=np.intp) for g, ix in out.items()}

    def subset(self, indices: ArrayLike, name: str | None = None) -> Task:
        """The task of the points at ``indices`` (integers or a boolean mask), in that
        order; keeps the envelope."""
        idx = np.asarray(indices)
        m = len(self)
        if idx.dtype == bool:
            if idx.shape != (m,):
                raise TaskError(f"task {self.name!r}", "indices", f"mask needs shape ({m},)")
            idx = np.flatnonzero(idx)
        if idx.size and not np.issubdtype(idx.dtype, np.integer):
            raise TaskError(f"task {self.name!r}", "indices", "must be integers or a mask")
        idx = idx.astype(np.intp).ravel()
        bad = (idx < -m) | (idx >= m)
        if bad.any():
            raise TaskError(
                f"task {self.name!r}", "indices", f"index {int(idx[bad][0])} out of range {m}"
            )
        return Task(
            self.name if name is None else name, tuple(self.points[i] for i in idx), self.envelope
        )


__all__ = [
    "DEFAULT_TOL_ORIENTATION",
    "DEFAULT_TOL_POSITION",
    "DIMS",
    "PointArrayKeywords",
    "PointArrays",
    "Task",
    "TaskPoint",
    "frame_from_axis",
]
