"""Synthesis fixtures: tasks generated from a known design (recovery problems)."""

from __future__ import annotations

import numpy as np

from reachwise import load_robot
from reachwise.kinematics.robot import Robot
from reachwise.synthesis.problem import SynthesisProblem
from reachwise.tasks.task import Task


def recovery_task(
    template: Robot, rng: np.random.Generator, k: int, dims: int = 6
) -> tuple[Task, np.ndarray, np.ndarray]:
    """Poses of a random true design (inside the template's bounds) at ``k`` random
    joint vectors. Returns the task, the true design vector and the true joints."""
    probe = SynthesisProblem(template, Task.from_arrays("probe", np.zeros((1, 3)), dims=3))
    lo, hi = probe.bounds
    p = probe.p
    design = lo[:p] + (hi[:p] - lo[:p]) * rng.uniform(0.1, 0.9, p)
    Q = rng.uniform(template.lower, template.upper, (k, template.n))
    T = probe.robot_at(design).fk(Q)
    kw: dict = {"dims": dims}
    if dims == 6:
        kw["rotations"] = T[:, :3, :3]
    elif dims == 5:
        kw["axes"] = T[:, :3, 2]
    return Task.from_arrays("recovery", T[:, :3, 3], **kw), design, Q


def sb60() -> Robot:
    return load_robot("sb60")
