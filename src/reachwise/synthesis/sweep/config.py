"""How a sweep runs: ``SweepConfig`` and the two rounds of P-II Fig. 1."""

from __future__ import annotations

import math
from dataclasses import dataclass

from reachwise.errors import InputError, check_choice
from reachwise.synthesis.objectives import check_objective
from reachwise.synthesis.rank import RankKey, check_key
from reachwise.synthesis.solvers import SolverOptions
from reachwise.synthesis.synthesize import SOLVERS, SolverName

ROUND_SUBSET = 1
ROUND_FULL = 2


# ---- configuration and work items --------------------------------------------------------
@dataclass(frozen=True)
class SweepConfig:
    """How a sweep runs (P-II Fig. 1).

    ``subset``: size of the descriptive subset for round 1 (``tasks.select``), ``None``
    for one round on the complete task; ``top``: how many feasible topologies go on to
    the complete task; ``runs``: multi-start runs per topology and round (seeds
    ``seed … seed + runs − 1``); ``rank_key``: one of ``rank.RANK_KEYS``; ``workspace``:
    keep the links inside the task's envelope (the tunnel); ``batch_size``: runs per
    submitted batch; ``objective``: weights of the design objectives every run then
    improves (``synthesis.objectives``), ``None`` for reach only; ``clearance`` (m, 0:
    none): every run keeps the templates' design bodies that clear at every pose
    (``synthesize.clearance_setup``; a template without bodies is rejected).
    """

    subset: int | None = None
    top: int = 3
    runs: int = 3
    seed: int = 0
    solver: SolverName = "dls"
    init_sets: int = 8
    rank_key: RankKey = "mean"
    workspace: bool = True
    options: SolverOptions | None = None
    batch_size: int = 1
    objective: dict[str, float] | None = None
    clearance: float = 0.0

    def __post_init__(self) -> None:
        if self.subset is not None and self.subset < 1:
            raise InputError("sweep", "subset", "must be >= 1 (or None for no subset)")
        if self.top < 1:
            raise InputError("sweep", "top", "must be >= 1")
        if self.runs < 1:
            raise InputError("sweep", "runs", "must be >= 1")
        check_choice(self.solver, SOLVERS, source="sweep", kind="solver")
        if self.init_sets < 1:
            raise InputError("sweep", "init_sets", "must be >= 1")
        if self.batch_size < 1:
            raise InputError("sweep", "batch_size", "must be >= 1")
        check_key(self.rank_key)
        if not (math.isfinite(self.clearance) and self.clearance >= 0):
            raise InputError("sweep", "clearance", f"must be >= 0, got {self.clearance}")
        if self.objective is not None:
            object.__setattr__(self, "objective", check_objective(self.objective, "sweep") or None)
