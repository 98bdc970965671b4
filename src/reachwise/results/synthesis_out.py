"""A synthesis result as files in a folder: design.yaml (with its bodies placed,
:mod:`reachwise.results.design_file`), design.urdf, summary.json and
points.csv, written and read back (the figures and the HTML report are
:mod:`reachwise.report.synthesis`'s)."""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from reachwise._version import __version__
from reachwise.io.atomic import atomic_open, atomic_write
from reachwise.io.ros.joint_state import robot_joint_names
from reachwise.kinematics.indices import gci, kci
from reachwise.results.design_file import save_design
from reachwise.synthesis.synthesize import SynthesisResult

if TYPE_CHECKING:
    from reachwise.kinematics.robot import Robot
    from reachwise.tasks.task import Task

STATUSES = ("full", "position", "orientation", "neither")


def summary(result: SynthesisResult) -> dict[str, Any]:
    """Key figures of a synthesis as plain JSON-able data."""
    best = result.best
    prob = result.problem
    runs = result.runs
    return {
        "reachwise": __version__,
        "task": prob.task.name,
        "template": prob.template.name,
        "solver": result.solver,
        "task_points": prob.K,
        "unknowns": prob.size,
        "residuals": prob.residual_rows,
        "design_parameters": list(prob.design_names),
        "locked_joints": {str(k): v for k, v in prob.locked.items()},
        "runs": len(runs),
        "runs_reaching_all": sum(bool(r.reached.all()) for r in runs),
        "best_seed": best.seed,
        "best": {
            "reached": best.n_reached,
            "all_reached": bool(best.reached.all()),
            "e_obj": best.e_obj,
            "max_position_error_m": float(best.position_error.max()),
            "max_orientation_error_rad": float(best.orientation_error.max()),
            "iterations": best.iterations,
            "design": dict(zip(prob.design_names, map(float, best.design), strict=True)),
            "gci_initial": gci(best.lci_initial),
            "kci_initial": kci(best.lci_initial),
            "gci": gci(best.lci_final),
            "kci": kci(best.lci_final),
            "status_counts": {s: best.status.count(s) for s in STATUSES},
            **_design_objectives(result),
        },
        "objective": dict(result.objective),
        **_clearance(result),
        "bound_hits": [h.as_dict() for h in result.bound_hits()],
        "unconstrained": list(result.unconstrained()),
        "table3": result.table3(),
        "table4": result.table4(),
        "per_run": [
            {
                "seed": r.seed,
                "reached": r.n_reached,
                "e_obj": r.e_obj,
                "iterations": r.iterations,
                "converged": r.converged,
            }
            for r in runs
        ],
    }


def _clearance(result: SynthesisResult) -> dict[str, Any]:
    """The bodies' clearance (m), the poses left out before the solve, and the best
    run's smallest clearance per pose with its pair; empty without a clearance."""
    if not result.clearance:
        return {}
    best = result.best
    per_pose: list[dict[str, Any]] = []
    smallest = None
    if best.clearance is not None:
        smallest = float(np.min(best.clearance))
        per_pose = [
            {"name": n, "clearance_m": float(c), "pair": list(p)}
            for n, c, p in zip(
                result.problem.task.names, best.clearance, best.clearance_pairs, strict=True
            )
        ]
    return {
        "clearance": {
            "required_m": result.clearance,
            "smallest_m": smallest,
            "unservable": [{"name": u.name, "reason": u.reason} for u in result.unservable],
            "per_pose": per_pose,
        }
    }


def _design_objectives(result: SynthesisResult) -> dict[str, Any]:
    """The best run's design objectives before (reach only) and after the improvement."""
    best = result.best
    if best.reach_design is None or best.lci_reach is None:
        return {}
    return {
        "reach_only": {
            "design": dict(zip(result.problem.design_names, map(float, best.reach_design),
                               strict=True)),
            **best.objective_start,
        },
        "objective_values": dict(best.objective_final),
        "kept": list(best.kept),
        "improve_iterations": best.improve_iterations,
    }  # fmt: skip


def joint_columns(robot: Robot, taken: list[str]) -> list[str]:
    """The ``points.csv`` column of each joint of ``robot``: its joint name (the robot
    file's or URDF's), or ``q0``, ``q1``, … when two names are equal or one is a column
    name already ``taken``."""
    names = list(robot_joint_names(robot))
    if len(set(names)) < len(names) or set(names) & set(taken):
        return [f"q{i}" for i in range(robot.n)]
    return names


def write_synthesis(result: SynthesisResult, out: str | Path) -> Path:
    """Write the files of ``result`` (module docstring) into folder ``out``; return it."""
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    best = result.best
    prob = result.problem
    save_design(best.robot, folder / "design.yaml", result.clearance)
    from reachwise.io.urdf import export_urdf

    export_urdf(best.robot, folder / "design.urdf")
    atomic_write(folder / "summary.json", json.dumps(summary(result), indent=2))
    task = prob.task
    with atomic_open(folder / "points.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        header = ["index", "name", "group", "dims", "x", "y", "z", "position_error_m",
                  "orientation_error_rad", "status", "lci_initial", "lci_final"]  # fmt: skip
        qcols = joint_columns(best.robot, header)
        clear = best.clearance
        # with the bodies' clearance: each pose's smallest clearance (m) and its pair
        extra = ["clearance_m", "clearance_pair"] if clear is not None else []
        w.writerow([*header, *qcols, *extra])
        for k in range(prob.K):
            more = (
                [repr(float(clear[k])), " ~ ".join(best.clearance_pairs[k])]
                if clear is not None
                else []
            )
            p = task.positions[k]
            w.writerow([k, task.names[k], task.groups[k], int(task.dims[k]),
                        *map(repr, map(float, p)), repr(float(best.position_error[k])),
                        repr(float(best.orientation_error[k])), best.status[k],
                        repr(float(best.lci_initial[k])), repr(float(best.lci_final[k])),
                        *map(repr, map(float, best.q[k])), *more])  # fmt: skip
    return folder


def design_rows(result: SynthesisResult) -> list[list[str]]:
    """Rows of the normalized design table (P-I Table 3) for printing."""
    return [
        [str(r["parameter"]), f"{r['initial']:.4f}", f"{r['optimized']:.4f}",
         f"{r['changed_percent']:+.2f}"]
        for r in result.table3()
    ]  # fmt: skip


# -- reading ---------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class SynthesisOutput:
    """A synthesis result read back from its folder (:func:`load_synthesis`).

    ``robot`` is the best design (``design.yaml``); per task point ``k``: ``q[k]`` its
    joint vector, ``status[k]`` (P-I Fig. 4: ``full``, ``position``, ``orientation``,
    ``neither``), ``reached[k]`` (``status == "full"``), the target ``positions[k]``,
    ``dims``, ``names``, ``groups``, the remaining errors and the LCI before/after.
    ``task`` is the task itself (with orientations and envelope) when it can be found:
    ``task.yaml`` in the folder, or the built-in task the summary names, matched point
    by point by name and position; else ``None``.
    """

    folder: Path
    robot: Robot
    q: NDArray[np.float64]
    status: tuple[str, ...]
    positions: NDArray[np.float64]
    dims: NDArray[np.int64]
    names: tuple[str, ...]
    groups: tuple[str, ...]
    position_error: NDArray[np.float64]
    orientation_error: NDArray[np.float64]
    lci_initial: NDArray[np.float64]
    lci_final: NDArray[np.float64]
    summary: dict[str, Any]
    task: Task | None = None

    @property
    def reached(self) -> NDArray[np.bool_]:
        return np.array([s == "full" for s in self.status], dtype=bool)

    @property
    def target_axes(self) -> NDArray[np.float64]:
        """Unit tool z axis wanted at every point: the task's when known, else the
        design's tool axis at ``q[k]`` (equal to it within tolerance where reached)."""
        if self.task is not None:
            return self.task.axes
        return self.robot.fk(self.q)[:, :3, 2]


def load_synthesis(folder: str | Path) -> SynthesisOutput:
    """Read a folder written by :func:`write_synthesis` (``design.yaml``,
    ``points.csv``, ``summary.json``). Missing files or columns raise
    :class:`~reachwise.errors.InputError` naming the file and field."""
    from reachwise.errors import InputError
    from reachwise.io.robot_file import load_robot

    src = Path(folder)
    paths = {n: src / n for n in ("design.yaml", "points.csv", "summary.json")}
    for p in paths.values():
        if not p.is_file():
            raise InputError(str(p), "", "missing: not a synthesis output folder")
    robot = load_robot(paths["design.yaml"])
    try:
        meta = json.loads(paths["summary.json"].read_text())
    except ValueError as exc:
        raise InputError(str(paths["summary.json"]), "", f"not JSON: {exc}") from None
    with paths["points.csv"].open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    where = str(paths["points.csv"])
    if not rows:
        raise InputError(where, "", "no task points")
    need = ["index", "name", "group", "dims", "x", "y", "z", "status", "position_error_m",
            "orientation_error_rad", "lci_initial", "lci_final"]  # fmt: skip
    qcols = joint_columns(robot, need)
    if qcols[0] not in rows[0] and "q0" in rows[0]:  # written before joints were named
        qcols = [f"q{i}" for i in range(robot.n)]
    need += qcols
    for c in need:
        if c not in rows[0]:
            raise InputError(where, c, f"missing column (the design has {robot.n} joints)")

    def col(name: str, cols: list[str] | None = None) -> NDArray[np.float64]:
        try:
            return np.array([[float(r[c]) for c in (cols or [name])] for r in rows])
        except ValueError as exc:
            raise InputError(where, name, f"not a number: {exc}") from None

    status = tuple(r["status"] for r in rows)
    for k, s in enumerate(status):
        if s not in STATUSES:
            raise InputError(where, f"points[{k}].status", f"{s!r} is not one of {STATUSES}")
    names = tuple(r["name"] for r in rows)
    positions = col("xyz", ["x", "y", "z"])
    task = _find_task(src, meta.get("task"), names, positions)
    return SynthesisOutput(
        folder=src,
        robot=robot,
        q=col("q", qcols),
        status=status,
        positions=positions,
        dims=col("dims")[:, 0].astype(np.int64),
        names=names,
        groups=tuple(r["group"] for r in rows),
        position_error=col("position_error_m")[:, 0],
        orientation_error=col("orientation_error_rad")[:, 0],
        lci_initial=col("lci_initial")[:, 0],
        lci_final=col("lci_final")[:, 0],
        summary=meta,
        task=task,
    )


def _find_task(
    folder: Path, name: object, names: tuple[str, ...], positions: NDArray[np.float64]
) -> Task | None:
    """The task of a synthesis folder, when it can be found (see SynthesisOutput)."""
    from reachwise.errors import InputError
    from reachwise.io.task_file import builtin_tasks, load_task

    candidates: list[Any] = []
    if (folder / "task.yaml").is_file():
        candidates.append(folder / "task.yaml")
    if isinstance(name, str) and name in builtin_tasks():
        candidates.append(name)
    for c in candidates:
        try:
            task = load_task(c)
        except InputError:
            continue
        where = {n: i for i, n in enumerate(task.names)}
        if len(where) != len(task.names) or any(n not in where for n in names):
            continue
        idx = np.array([where[n] for n in names])
        if np.allclose(task.positions[idx], positions, rtol=0.0, atol=1e-9):
            return task if np.array_equal(idx, np.arange(len(task))) else task.subset(idx)
    return None
