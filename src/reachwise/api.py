"""Top-level conveniences that need several layers (re-exported by ``reachwise``).

The math layers take objects: ``reachwise.synthesis.synthesize`` wants a ``Task`` and a
template ``Robot``. A user thinks in names and files (``"tunnel-87"``, ``"sb60"``,
``my-boom.yaml``); this facade resolves them with the ``io`` loaders and calls the math
layer, so nothing below ``io`` ever reads a file.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from reachwise.io.robot_file import load_robot
from reachwise.io.task_file import load_task
from reachwise.kinematics.robot import Robot
from reachwise.synthesis.synthesize import SynthesisResult
from reachwise.synthesis.synthesize import synthesize as synthesize_objects
from reachwise.tasks.task import Task

__all__ = ["synthesize"]


def synthesize(
    task: Task | str | Path,
    template: Robot | str | Path,
    *,
    runs: int = 10,
    seed: int = 0,
    objective: Mapping[str, float] | None = None,
    **options: Any,
) -> SynthesisResult:
    """Dimensional synthesis (P-I §3–4, P-II §4) of ``template`` for ``task``.

    ``task``: a ``Task``, a built-in task name (``tunnel-87``) or a task file;
    ``template``: a ``Robot`` with a ``design`` section, a built-in robot name (``sb60``)
    or a robot file. ``runs`` multi-start runs, run ``i`` with seed ``seed + i``.
    ``objective`` maps design objectives (``gci``, ``kci``, ``size``, ``limits``,
    ``bounds``; ``reachwise.synthesis.objectives``) to weights: a run that reaches every
    pose then improves its design for them, keeping every pose reached; ``None`` takes
    the template's ``design.objective``. Further ``options`` (``solver``, ``init_sets``,
    ``locked``, ``workspace``, ``options``, ``on_run``, ``improve_options``) go to
    ``reachwise.synthesis.synthesize.synthesize``.
    """
    t = task if isinstance(task, Task) else load_task(task)
    robot = template if isinstance(template, Robot) else load_robot(template)
    return synthesize_objects(t, robot, runs=runs, seed=seed, objective=objective, **options)
