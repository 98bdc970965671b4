"""Fingerprints: the sweep id a store keys its items by.

Task, subset, seed and solver settings — not ``runs``, ``top`` or the rank key, so more
runs or a larger ``K`` reuse what is done.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict

import numpy as np
from numpy.typing import NDArray

from reachwise.kinematics.robot import Robot
from reachwise.synthesis.sweep.config import SweepConfig
from reachwise.tasks.task import Task


def _h(*parts: bytes) -> str:
    h = hashlib.sha256()
    for p in parts:
        h.update(len(p).to_bytes(8, "little"))
        h.update(p)
    return h.hexdigest()


def task_fingerprint(task: Task) -> str:
    """Hash of everything about a task that changes a synthesis."""
    return _h(
        np.ascontiguousarray(task.poses, dtype="<f8").tobytes(),
        np.ascontiguousarray(task.dims, dtype="<i8").tobytes(),
        np.ascontiguousarray(task.tol_position, dtype="<f8").tobytes(),
        np.ascontiguousarray(task.tol_orientation, dtype="<f8").tobytes(),
        repr(task.envelope).encode(),
    )


def template_fingerprint(robot: Robot) -> str:
    """Hash of a template's kinematics, limits and design space."""
    joints = [(j.type, j.a, j.alpha, j.d, j.theta, j.limits, j.passive) for j in robot.joints]
    d = robot.design
    design: tuple[object, ...] = (
        [(j, sorted(d.joints[j].items())) for j in sorted(d.joints)],
        sorted(d.base.items()),
    )
    if d.min_length or d.margin != 0.05 or d.objective:  # else: the id of earlier stores
        design += (d.min_length, d.margin, sorted(d.objective.items()))
    if d.bodies:  # likewise: the bodies a clearance keeps apart
        design += (d.bodies,)
    return _h(
        repr((robot.convention, joints, design)).encode(),
        np.ascontiguousarray(robot.base, dtype="<f8").tobytes(),
        np.ascontiguousarray(robot.tool, dtype="<f8").tobytes(),
    )


def sweep_fingerprint(task: Task, subset: NDArray[np.intp] | None, config: SweepConfig) -> str:
    """The sweep id: task, subset, seed and solver settings (not runs, top, rank key)."""
    opts = None if config.options is None else asdict(config.options)
    spec: dict[str, object] = {
        "task": task_fingerprint(task),
        "subset": None if subset is None else [int(i) for i in subset],
        "seed": config.seed,
        "solver": config.solver,
        "init_sets": config.init_sets,
        "workspace": config.workspace,
        "options": opts,
    }
    if config.objective:  # only then: sweeps stored before objectives keep their id
        spec["objective"] = dict(sorted(config.objective.items()))
    if config.clearance:  # likewise
        spec["clearance"] = config.clearance
    return _h(json.dumps(spec, sort_keys=True).encode())[:16]
