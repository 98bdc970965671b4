"""Task files (YAML, JSON, CSV): load with validation, save, built-in tasks.

YAML and JSON share one schema (DESIGN.md, "Task file")::

    name: tunnel-87                                   # optional (default: file stem)
    description: ...                                  # optional
    tolerance: {position: 0.001, orientation: 0.001}  # m, rad; default for every point
    envelope:                                         # optional workspace constraint
      tunnel: {width: 11.5, height: 9.3, arch_height: 3.0, y_center: 0.0, floor_z: 0.0}
      face_x: 9.0                                     # optional face plane (rock beyond)
      x_range: [null, null]                           # optional [x_min, x_max], null = open
    points:
      - {xyz: [6.0, 0.5, 1.8], quat: [0, 0.7071, 0, 0.7071]}   # 6-D, quaternion (x, y, z, w)
      - {xyz: [6.0, 1.0, 2.4], axis: [1, 0, 0], dims: 5}        # 5-D: position + tool z axis
      - {xyz: [6.0, 1.5, 3.0], dims: 3}                         # position only
      - {xyz: [6.0, 2.0, 3.0], rpy_deg: [0, 90, 0], tolerance: {position: 0.01},
         name: P01/cut03, group: cut}

Per point: ``xyz`` (m); at most one of ``quat`` (x, y, z, w), ``rpy`` (rad, URDF fixed
axes ``R = Rz(yaw) Ry(pitch) Rx(roll)``), ``rpy_deg`` (degrees) or ``axis`` (the tool z
direction); ``dims`` 3, 5 or 6 (default 6 with a quaternion or rpy, 5 with only an
axis, 3 with neither); ``tolerance`` overrides the file's; ``name``; ``group``. A
quaternion whose norm is within ``QUAT_NORM_TOL`` of 1 is normalized (so hand-written
4-decimal quaternions such as the one above load), otherwise it is an error; an axis
is normalized, zero length is an error.

CSV: one point per row, a header naming the columns. ``x, y, z`` are required; the
optional orientation columns come in complete groups — ``qx, qy, qz, qw`` or ``ax, ay,
az`` or ``roll, pitch, yaw`` (rad) or ``roll_deg, pitch_deg, yaw_deg`` — and a row may
fill at most one group (empty cells mean "not given"); optional ``dims``,
``tol_position`` (m), ``tol_orientation`` (rad), ``name``, ``group``. Lines starting
with ``#`` before the header are comments; ``# name: NAME`` names the task. The
envelope is YAML/JSON only.

Every mistake is a ``TaskError`` naming the file, the field (``points[12].quat``; for
CSV the data row ``points[i]`` is also given as its line) and the reason.
"""

from __future__ import annotations

import json
import math
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal

import numpy as np
import yaml
from pydantic import ConfigDict, Field, ValidationError, field_validator
from scipy.spatial.transform import Rotation

from reachwise.errors import TaskError
from reachwise.io._builtin import builtin_names, load_named
from reachwise.io.atomic import atomic_write
from reachwise.io.task_csv import (
    CSV_COLUMNS,
    csv_to_dict,
    file_floats,
    quaternion_xyzw,
    render_csv,
)
from reachwise.io.text_input import parse_text, read_text
from reachwise.io.validation import StrictModel, input_error
from reachwise.tasks.task import (
    DEFAULT_TOL_ORIENTATION,
    DEFAULT_TOL_POSITION,
    Task,
    TaskPoint,
)
from reachwise.tasks.workspace import TunnelEnvelope, TunnelProfile

#: A quaternion is normalized when ``|‖q‖ - 1| ≤ QUAT_NORM_TOL``, rejected otherwise.
QUAT_NORM_TOL = 1e-3
_STRICT = ConfigDict(extra="forbid", allow_inf_nan=False, strict=False)
Vec3 = tuple[float, float, float]
Format = Literal["yaml", "json", "csv"]
_LENGTHS = {"xyz": 3, "quat": 4, "rpy": 3, "rpy_deg": 3, "axis": 3, "x_range": 2}
_SUFFIX: dict[str, Format] = {".yaml": "yaml", ".yml": "yaml", ".json": "json", ".csv": "csv"}


class ToleranceModel(StrictModel):
    model_config = _STRICT
    position: float | None = Field(default=None, gt=0)
    orientation: float | None = Field(default=None, gt=0)


class PointModel(StrictModel):
    model_config = _STRICT
    xyz: Vec3
    quat: tuple[float, float, float, float] | None = None
    rpy: Vec3 | None = None
    rpy_deg: Vec3 | None = None
    axis: Vec3 | None = None
    dims: Literal[3, 5, 6] | None = None
    tolerance: ToleranceModel | None = None
    name: str = ""
    group: str = ""

    @field_validator("quat")
    @classmethod
    def _unit_quaternion(
        cls, q: tuple[float, float, float, float] | None
    ) -> tuple[float, float, float, float] | None:
        if q is None:
            return None
        n = math.sqrt(sum(c * c for c in q))
        if abs(n - 1.0) > QUAT_NORM_TOL:
            raise ValueError(
                f"quaternion (x, y, z, w) must have unit norm, got {n:.6g}"
                f" (normalized only within {QUAT_NORM_TOL:g})"
            )
        return (q[0] / n, q[1] / n, q[2] / n, q[3] / n)

    @field_validator("axis")
    @classmethod
    def _nonzero_axis(cls, a: Vec3 | None) -> Vec3 | None:
        if a is not None and math.sqrt(sum(c * c for c in a)) < 1e-9:
            raise ValueError("zero-length axis")
        return a


class ProfileModel(StrictModel):
    model_config = _STRICT
    width: float
    height: float
    arch_height: float | None = None
    arch_radius: float | None = None
    y_center: float = 0.0
    floor_z: float = 0.0


class EnvelopeModel(StrictModel):
    model_config = _STRICT
    tunnel: ProfileModel
    face_x: float | None = None
    x_range: tuple[float | None, float | None] | None = None


class TaskModel(StrictModel):
    model_config = _STRICT
    name: str | None = None
    description: str = ""
    tolerance: ToleranceModel = ToleranceModel()
    envelope: EnvelopeModel | None = None
    points: list[PointModel]


def _envelope(m: EnvelopeModel, source: str) -> TunnelEnvelope:
    t = m.tunnel
    try:
        if t.arch_height is not None and t.arch_radius is not None:
            raise TaskError(source, "arch_radius", "give arch_height or arch_radius, not both")
        if t.arch_radius is not None:
            prof = TunnelProfile.from_arch_radius(
                t.width, t.height, t.arch_radius, t.y_center, t.floor_z
            )
        else:
            prof = TunnelProfile(t.width, t.height, t.arch_height or 0.0, t.y_center, t.floor_z)
    except TaskError as exc:
        raise TaskError(source, f"envelope.tunnel.{exc.field}", exc.reason) from None
    lo, hi = m.x_range if m.x_range is not None else (None, None)
    x_range = (-math.inf if lo is None else lo, math.inf if hi is None else hi)
    try:
        return TunnelEnvelope(prof, x_range, m.face_x)
    except TaskError as exc:
        raise TaskError(source, f"envelope.{exc.field}", exc.reason) from None


def _point(i: int, p: PointModel, default: ToleranceModel, source: str) -> TaskPoint:
    here = f"points[{i}]"
    given = [k for k in ("quat", "rpy", "rpy_deg", "axis") if getattr(p, k) is not None]
    if len(given) > 1:
        raise TaskError(
            source,
            f"{here}.{given[1]}",
            f"give one of quat, rpy, rpy_deg or axis, not both {given[0]} and {given[1]}",
        )
    R = None
    if p.quat is not None:
        R = Rotation.from_quat(p.quat).as_matrix()
    elif p.rpy is not None:
        R = Rotation.from_euler("xyz", p.rpy).as_matrix()
    elif p.rpy_deg is not None:
        R = Rotation.from_euler("xyz", p.rpy_deg, degrees=True).as_matrix()
    dims = p.dims if p.dims is not None else 6 if R is not None else 5 if p.axis is not None else 3
    if dims == 6 and R is None:
        raise TaskError(source, f"{here}.dims", "dims 6 needs an orientation: quat, rpy or rpy_deg")
    if dims == 5 and R is None and p.axis is None:
        raise TaskError(source, f"{here}.dims", "dims 5 needs an axis (or quat, rpy, rpy_deg)")
    tol = p.tolerance or ToleranceModel()
    tol_p = tol.position or default.position or DEFAULT_TOL_POSITION
    tol_o = tol.orientation or default.orientation or DEFAULT_TOL_ORIENTATION
    try:
        return TaskPoint(
            np.array(p.xyz),
            rotation=R,
            axis=None if p.axis is None else np.array(p.axis),
            dims=dims,
            tol_position=tol_p,
            tol_orientation=tol_o,
            name=p.name,
            group=p.group,
        )
    except TaskError as exc:
        raise TaskError(source, f"{here}.{exc.field}", exc.reason) from None


def task_from_dict(data: Any, source: str = "task", default_name: str = "task") -> Task:
    """Build a Task from parsed YAML/JSON, raising ``TaskError`` naming ``source``."""
    if not isinstance(data, dict):
        raise TaskError(source, "", "a task file must be a mapping with a 'points' list")
    if isinstance(data.get("points"), list) and not data["points"]:
        raise TaskError(source, "points", "empty task: give at least one point")
    try:
        m = TaskModel.model_validate(data)
    except ValidationError as exc:
        raise input_error(exc, source, TaskError, _LENGTHS, model=TaskModel) from None
    points = tuple(_point(i, p, m.tolerance, source) for i, p in enumerate(m.points))
    envelope = None if m.envelope is None else _envelope(m.envelope, source)
    return Task(m.name if m.name is not None else default_name, points, envelope)


def _tolerances(task: Task) -> tuple[float, float]:
    """The most common (position, orientation) tolerance pair: the file default."""
    pairs = Counter(zip(task.tol_position.tolist(), task.tol_orientation.tolist(), strict=True))
    return pairs.most_common(1)[0][0]


def _point_dict(p: TaskPoint, default: tuple[float, float], decimals: int | None) -> dict[str, Any]:
    row: dict[str, Any] = {"xyz": file_floats(p.position, decimals)}
    if p.rotation is not None:
        row["quat"] = file_floats(quaternion_xyzw(p.rotation), decimals)
    elif p.axis is not None:
        row["axis"] = file_floats(p.axis, decimals)
    row["dims"] = p.dims
    tol: dict[str, float] = {}
    if p.tol_position != default[0]:
        tol["position"] = p.tol_position
    if p.tol_orientation != default[1]:
        tol["orientation"] = p.tol_orientation
    if tol:
        row["tolerance"] = tol
    if p.name:
        row["name"] = p.name
    if p.group:
        row["group"] = p.group
    return row


def _envelope_dict(env: TunnelEnvelope) -> dict[str, Any]:
    pr = env.profile
    out: dict[str, Any] = {
        "tunnel": {
            "width": pr.width,
            "height": pr.height,
            "arch_height": pr.arch_height,
            "y_center": pr.y_center,
            "floor_z": pr.floor_z,
        }
    }
    if env.face_x is not None:
        out["face_x"] = env.face_x
    lo, hi = env.x_range
    if math.isfinite(lo) or math.isfinite(hi):
        out["x_range"] = [lo if math.isfinite(lo) else None, hi if math.isfinite(hi) else None]
    return out


def task_to_dict(task: Task, decimals: int | None = None) -> dict[str, Any]:
    """The YAML/JSON mapping of a task (inverse of ``task_from_dict``). ``decimals``
    rounds coordinates, quaternions and axes (the loader renormalizes)."""
    default = _tolerances(task)
    out: dict[str, Any] = {
        "name": task.name,
        "tolerance": {"position": default[0], "orientation": default[1]},
    }
    if task.envelope is not None:
        out["envelope"] = _envelope_dict(task.envelope)
    out["points"] = [_point_dict(p, default, decimals) for p in task.points]
    return out


def _render_yaml(data: dict[str, Any], comment: str | None) -> str:
    head = {k: v for k, v in data.items() if k != "points"}
    lines = [f"# {line}".rstrip() for line in comment.splitlines()] if comment else []
    text = "\n".join(lines) + ("\n" if lines else "")
    text += yaml.safe_dump(head, sort_keys=False, default_flow_style=None, width=100)
    text += "points:\n"
    for row in data["points"]:
        flow = yaml.safe_dump(row, sort_keys=False, default_flow_style=True, width=10**6)
        text += f"  - {flow.strip()}\n"
    return text


def _csv_task(text: str, source: str, default_name: str) -> Task:
    data, line_of = csv_to_dict(text, source, default_name)
    if not data["points"]:
        raise TaskError(source, "points", "empty task: no data rows")
    # CSV cells are strings: let pydantic's lax mode parse numbers, then point at lines
    try:
        return task_from_dict(data, source, default_name)
    except TaskError as exc:
        if exc.field.startswith("points["):
            i = int(exc.field[7 : exc.field.index("]")])
            raise TaskError(source, exc.field, f"{exc.reason} (CSV line {line_of[i]})") from None
        raise


def _format(path: Path, fmt: str | None) -> Format:
    if fmt is not None:
        if fmt not in ("yaml", "json", "csv"):
            raise TaskError(str(path), "", f"unknown format {fmt!r}; use yaml, json or csv")
        return fmt  # type: ignore[return-value]
    try:
        return _SUFFIX[path.suffix.lower()]
    except KeyError:
        raise TaskError(
            str(path), "", f"unknown task file type {path.suffix!r}; use .yaml, .yml, .json or .csv"
        ) from None


def render_task(
    task: Task, fmt: Format = "yaml", *, comment: str | None = None, decimals: int | None = None
) -> str:
    """The text of ``task`` as a YAML, JSON or CSV task file (see ``save_task``)."""
    if fmt == "csv":
        return render_csv(task, decimals)
    data = task_to_dict(task, decimals)
    if fmt == "json":
        return json.dumps(data, indent=1) + "\n"
    return _render_yaml(data, comment)


def save_task(
    task: Task,
    path: str | Path,
    *,
    comment: str | None = None,
    decimals: int | None = None,
    fmt: Format | None = None,
) -> None:
    """Write ``task`` as YAML, JSON or CSV (by extension, or ``fmt``). Loading the file
    gives the same points (rotations as unit quaternions, so equal to ~1e-15).
    ``comment`` heads a YAML file; ``decimals`` rounds coordinates, quaternions and
    axes. The envelope is kept in YAML and JSON only."""
    p = Path(path)
    atomic_write(p, render_task(task, _format(p, fmt), comment=comment, decimals=decimals))


def load_task_file(path: str | Path) -> Task:
    """Load a YAML, JSON or CSV task file (by extension)."""
    p = Path(path)
    fmt = _format(p, None)
    if not p.is_file():
        raise TaskError(str(p), "", "no such file")
    text = read_text(p, str(p), TaskError)
    if fmt == "csv":
        return _csv_task(text, str(p), p.stem)
    return task_from_dict(parse_text(text, str(p), fmt, TaskError), str(p), p.stem)


# -- built-in tasks -------------------------------------------------------------------
def _tunnel_87() -> Task:
    from reachwise.tasks.drilling import tunnel_87

    return tunnel_87()


#: Built-in tasks that are generated: name -> (generator, header comment). The shipped
#: file ``reachwise/data/tasks/NAME.yaml`` must equal ``builtin_task_text(NAME)``.
GENERATED: dict[str, tuple[Callable[[], Task], str]] = {
    "tunnel-87": (
        _tunnel_87,
        "tunnel-87: public stand-in for the thesis's 87 task points from 10 customer drill\n"
        "plans (Kivelä 2017, P-I §4). Generated by reachwise.tasks.drilling.tunnel_87(seed=2017)\n"
        "- do not edit; regenerate with `reachwise task generate tunnel-87 --out FILE`.\n"
        "Machine frame: x toward the face, y left, z up, origin on the floor (m, rad).",
    ),
}
BUILTIN_DECIMALS = 9


def builtin_task_text(name: str) -> str:
    """The exact YAML text of the generated built-in task ``name``."""
    if name not in GENERATED:
        raise TaskError(name, "", f"not a generated built-in task; have {sorted(GENERATED)}")
    make, comment = GENERATED[name]
    return render_task(make(), "yaml", comment=comment, decimals=BUILTIN_DECIMALS)


def builtin_tasks() -> list[str]:
    """Names of the tasks shipped with reachwise."""
    return builtin_names("tasks")


def load_task(name_or_path: str | Path) -> Task:
    """A built-in task by name (``tunnel-87``) or a YAML/JSON/CSV task file."""
    return load_named(
        "tasks",
        name_or_path,
        from_builtin=lambda b: task_from_dict(yaml.safe_load(b.text()), b.label, b.name),
        from_file=load_task_file,
        suffixes=tuple(_SUFFIX),
    )


__all__ = [
    "CSV_COLUMNS",
    "QUAT_NORM_TOL",
    "builtin_task_text",
    "builtin_tasks",
    "load_task",
    "load_task_file",
    "render_task",
    "save_task",
    "task_from_dict",
    "task_to_dict",
]
