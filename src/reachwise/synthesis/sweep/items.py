"""Work items: one multi-start run ``(topology, round, run)`` and what it produced.

A ``WorkItem`` is picklable and self-contained (template and task travel with it), so
it runs in any worker; ``run_item`` is pure apart from its wall-time record
(``ItemResult.wall_s``): nothing below this layer reads a clock.
"""

from __future__ import annotations

import math
import os
import platform
import time
from collections.abc import Sequence
from dataclasses import astuple, dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from reachwise._version import __version__, source_fingerprint
from reachwise.errors import ReachwiseError
from reachwise.kinematics.robot import Robot
from reachwise.synthesis.objectives import evaluate_terms
from reachwise.synthesis.problem import SynthesisProblem
from reachwise.synthesis.rank import Measures
from reachwise.synthesis.rank import measures as design_measures
from reachwise.synthesis.solvers import SolverOptions
from reachwise.synthesis.synthesize import SolverName, clearance_setup, run_once
from reachwise.tasks.task import Task

Array = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class WorkItem:
    """One run to do: picklable and self-contained (template and task travel with it)."""

    topology: str
    round: int
    run: int
    seed: int
    template: Robot
    task: Task
    solver: SolverName = "dls"
    init_sets: int = 8
    options: SolverOptions | None = None
    workspace: bool = True
    objective: dict[str, float] | None = None
    clearance: float = 0.0


@dataclass(frozen=True, eq=False)
class ItemResult:
    """What one run produced (stored as one row). ``error`` is non-empty when the
    synthesis raised; then ``measures`` is ``None`` and nothing is reached."""

    topology: str
    round: int
    run: int
    seed: int
    n_points: int
    n_reached: int
    e_obj: float
    iterations: int
    converged: bool
    measures: Measures | None
    design_names: tuple[str, ...]
    design: tuple[float, ...]
    q: Array
    status: tuple[str, ...]
    max_position_error: float
    max_orientation_error: float
    error: str = ""
    wall_s: float = 0.0
    worker: str = ""
    versions: dict[str, str] = field(default_factory=dict)

    @property
    def feasible(self) -> bool:
        return not self.error and self.n_reached == self.n_points

    @property
    def key(self) -> tuple[str, int, int]:
        return (self.topology, self.round, self.run)

    def same_outcome(self, other: ItemResult) -> bool:
        """Equal apart from timing, worker and versions (the deterministic part)."""
        return (
            self.key == other.key
            and self.seed == other.seed
            and self.n_reached == other.n_reached
            and _same_float(self.e_obj, other.e_obj)
            and self.iterations == other.iterations
            and self.converged == other.converged
            and _same_measures(self.measures, other.measures)
            and self.design_names == other.design_names
            and self.design == other.design
            and self.status == other.status
            and np.array_equal(self.q, other.q)
            and self.error == other.error
        )


def _same_float(a: float, b: float) -> bool:
    return a == b or (math.isnan(a) and math.isnan(b))


def _same_measures(a: Measures | None, b: Measures | None) -> bool:
    """Equal measures, a NaN (a measure not taken) equal to a NaN."""
    if a is None or b is None:
        return a is b
    return all(_same_float(float(x), float(y)) for x, y in zip(astuple(a), astuple(b), strict=True))


def versions() -> dict[str, str]:
    """Versions the results were computed with (stored per item): reachwise, its source
    (``source_fingerprint``), numpy, scipy and Python."""
    import scipy

    return {
        "reachwise": __version__,
        "source": source_fingerprint(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "python": platform.python_version(),
    }


#: The source this process imported, hashed when the sweep's items are first loaded: in a
#: worker, when it unpickles its first item; later edits do not change what it runs.
source_fingerprint()


def run_item(item: WorkItem) -> ItemResult:
    """One synthesis run of one topology (``synthesize.run_once``) and its measures
    (P-II Eq. 38–39, ``rank.measures``); with a clearance, the poses no design can serve
    are left out first and a pose less clear than the clearance is not reached. Pure
    apart from its wall-time record."""
    t0 = time.perf_counter()
    problem: SynthesisProblem | None = None
    try:
        ws = item.task.envelope if item.workspace else None
        model, task, _ = clearance_setup(item.template, item.task, ws, item.clearance)
        problem = SynthesisProblem(item.template, task)
        r = run_once(
            problem, item.seed, item.solver, item.init_sets, item.options, ws, item.objective,
            clearance=model,
        )  # fmt: skip
        terms = evaluate_terms(
            problem, problem.pack(r.design, r.q), ("size", "limits", "bounds"),
            margin=problem.template.design.margin,
        ).values  # fmt: skip
        m = replace(
            design_measures(r.robot, r.q),
            size=terms["size"],
            limits=terms["limits"],
            bounds=terms["bounds"],
            clearance=float(np.min(r.clearance)) if r.clearance is not None else math.nan,
        )
        res = ItemResult(
            topology=item.topology,
            round=item.round,
            run=item.run,
            seed=item.seed,
            n_points=problem.K,
            n_reached=r.n_reached,
            e_obj=r.e_obj,
            iterations=r.iterations,
            converged=r.converged,
            measures=m,
            design_names=problem.design_names,
            design=tuple(float(v) for v in r.design),
            q=np.asarray(r.q, dtype=np.float64),
            status=r.status,
            max_position_error=float(np.max(r.position_error)),
            max_orientation_error=float(np.max(r.orientation_error)),
        )
    except (ReachwiseError, ValueError, ArithmeticError) as exc:
        res = ItemResult(
            topology=item.topology,
            round=item.round,
            run=item.run,
            seed=item.seed,
            n_points=len(item.task),
            n_reached=0,
            e_obj=math.inf,
            iterations=0,
            converged=False,
            measures=None,
            design_names=() if problem is None else problem.design_names,
            design=(),
            q=np.zeros((0, 0)),
            status=(),
            max_position_error=math.inf,
            max_orientation_error=math.inf,
            error=f"{type(exc).__name__}: {exc}",
        )
    wall = time.perf_counter() - t0
    return replace(res, wall_s=wall, worker=f"{platform.node()}:{os.getpid()}", versions=versions())


def run_batch(items: Sequence[WorkItem]) -> list[ItemResult]:
    """Run a batch of items in order (the unit submitted to an executor)."""
    return [run_item(it) for it in items]
