"""Settling a Pareto sweep: each level's design the best one the sweep can reach.

The sweep of ``pareto`` solves each ε-level (and each end) once, from one start: the
previous level's design. The improvement is a local method, and on the SB60 family the
basin it ends in depends on rounding — from the same start (1e-6 apart), the first end
of the (gci, size) front came out 6–13 % apart in GCI with numpy 2.4/scipy 1.17/numba
0.68 and with the minor releases before them. So a design of the front was the first
basin a solve fell in, not a property of the problem.

Settling treats every level as a problem of its own, with the scalarised cost the
improvement lowers there (``Objective.cost``: the first objective, the second held at
the level by the penalty; an end: its objective alone). A design's terms do not depend
on the level, so any design the sweep found can be scored at any level. Each pass goes
over the ends and then the levels in order of value; a level is solved again from

- the best design known at it (the lowest cost over every reaching design found, at any
  level: a neighbour's design may beat the level's own),
- the best designs known at the levels next to it (a basin found at one level is
  carried along the front, level by level, pass by pass), and, for an end, the front's
  two best designs in its objective,

each start once per level (a design solved at a level counts as started from there). An
end that improves is polished lexicographically again (``pareto``, step 3). The passes
stop at a fixed point — a pass in which no level's best cost fell by more than
``IMPROVES`` (relative) — or when the solve budget is spent. Which design is the best at
a level never depends on the order designs were found: the lowest cost, ties broken by
the other objective and then by the decision vector itself. Pure math.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Generic, Protocol, TypeVar

import numpy as np
from numpy.typing import NDArray

from reachwise.synthesis.objectives import OBJECTIVES, Objective, Terms


class Design(Protocol):
    """What settling reads of a design of the sweep (``pareto.ParetoPoint``)."""

    @property
    def index(self) -> int: ...
    @property
    def weights(self) -> Mapping[str, float]: ...
    @property
    def values(self) -> Mapping[str, float]: ...
    @property
    def level(self) -> float | None: ...
    @property
    def stage(self) -> str: ...
    @property
    def z(self) -> NDArray[np.float64]: ...
    @property
    def all_reached(self) -> bool: ...


Array = NDArray[np.float64]
P = TypeVar("P", bound=Design)
#: A level's best cost must fall by more than this fraction for a pass to count as
#: an improvement (below it, a new pass would only polish within the solves' tolerance).
IMPROVES = 1e-4
#: A level as a key: levels of the two continuations that differ in the last bits are one.
_DIGITS = 10


@dataclass(frozen=True)
class Level:
    """A scalarised problem of the sweep: improve ``name`` (holding the other objective
    at ``level``, or alone for an end)."""

    name: str
    level: float | None

    @property
    def key(self) -> tuple[str, float | None]:
        return self.name, None if self.level is None else float(f"{self.level:.{_DIGITS}g}")


@dataclass
class Settler(Generic[P]):
    """The settling passes of the module docstring over the designs ``found`` by a sweep
    of objectives ``a`` and ``b``: ``objective(name, level)`` builds the referenced
    scalarised objective, ``terms(point)`` evaluates a design's terms, ``solve(z, name,
    level)`` improves and records a design, ``front()`` gives the current front."""

    a: str
    b: str
    found: list[P]
    objective: Callable[[str, float | None], Objective]
    terms: Callable[[P], Terms]
    solve: Callable[[Array, str, float | None], P]
    front: Callable[[], Sequence[P]]
    level_of: Callable[[P, str], float]
    _terms: dict[int, Terms] = field(default_factory=dict)
    _used: set[tuple[tuple[str, float | None], int]] = field(default_factory=set)

    def score(self, p: P, task: Level) -> tuple[float, float, tuple[float, ...]]:
        """The order of designs at ``task``: its cost, then the other objective (better
        first), then the decision vector — never the order of arrival."""
        if p.index not in self._terms:
            self._terms[p.index] = self.terms(p)
        cost = self.objective(task.name, task.level).cost(self._terms[p.index])
        other = self.b if task.name == self.a else self.a
        return cost, -OBJECTIVES[other] * p.values[other], tuple(p.z.tolist())

    def best(self, task: Level) -> P | None:
        """The best reaching design known at ``task``."""
        ok = [p for p in self.found if p.all_reached]
        return min(ok, key=lambda p: self.score(p, task)) if ok else None

    def tasks(self) -> list[Level]:
        """The two ends, then every level of the first objective the sweep solved, by
        value (the lexicographic polish of an end is not a level of its own)."""
        levels = {
            Level(self.a, p.level).key: Level(self.a, p.level)
            for p in self.found
            if p.level is not None and p.stage in ("level", "gap", "settle")
            and p.weights.get(self.a) == 1.0
        }  # fmt: skip
        ordered = sorted(levels.values(), key=lambda t: float(t.level or 0.0))
        return [Level(self.a, None), Level(self.b, None), *filter(self.binds, ordered)]

    def binds(self, task: Level) -> bool:
        """Does the level of ``task`` bind? One that the best design known for the
        first objective alone already meets is that end's problem, not a level."""
        end = self.best(Level(self.a, None))
        if end is None or task.level is None:
            return True
        return bool(OBJECTIVES[self.b] * (self.level_of(end, self.b) - task.level) < 0)

    def starts(self, task: Level, tasks: Sequence[Level]) -> list[P]:
        """The designs to solve ``task`` from, each not yet started from (or found) at
        it: the best known at ``task``, the best known at the levels next to it in
        ``tasks`` (an end's neighbour: the loosest level for the first objective's end,
        the tightest for the second's) and, for an end, the front's two best designs in
        its objective."""
        levels = [t for t in tasks if t.level is not None]
        if task.level is None:
            sense = OBJECTIVES[task.name]
            near = sorted(self.front(), key=lambda p: -sense * p.values[task.name])[:2]
            pick = -OBJECTIVES[self.b] if task.name == self.a else OBJECTIVES[self.b]
            nxt = sorted(levels, key=lambda t: pick * float(t.level or 0.0))[-1:]
        else:
            i = next(k for k, t in enumerate(levels) if t.key == task.key)
            nxt, near = levels[max(i - 1, 0) : i] + levels[i + 1 : i + 2], []
        bests = [self.best(t) for t in [task, *nxt]]
        out: list[P] = []
        for p in [*(q for q in bests if q is not None), *near]:
            if (task.key, p.index) not in self._used and all(p is not q for q in out):
                out.append(p)
        return out

    def run(self, budget: int) -> int:
        """Passes until a fixed point or ``budget`` solves; returns the solves spent."""
        for p in self.found:  # every level's (and end's) own designs count as started
            name = next((n for n, w in p.weights.items() if w == 1.0), None)
            if name is not None and (p.level is None or name == self.a):
                self._used.add((Level(name, p.level).key, p.index))
        spent = 0
        while spent < budget:
            improved = False
            tasks = self.tasks()
            for task in tasks:
                before = self.best(task)
                for s in self.starts(task, tasks):
                    if spent >= budget:
                        return spent
                    self._used.add((task.key, s.index))
                    new = self.solve(s.z, task.name, task.level)
                    spent += 1
                    self._used.add((task.key, new.index))
                if before is None or spent >= budget:
                    continue
                after = self.best(task)
                if after is None:
                    continue
                c0, c1 = self.score(before, task)[0], self.score(after, task)[0]
                if c1 < c0 - IMPROVES * max(abs(c0), 1e-12):
                    improved = True
                    if task.level is None:  # an end: its lexicographic polish again
                        other = self.b if task.name == self.a else self.a
                        self.solve(after.z, other, self.level_of(after, task.name))
                        spent += 1
            if not improved:
                break
        return spent
