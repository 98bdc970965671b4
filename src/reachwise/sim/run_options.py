"""The options of a run's third stage (the loop over a built world), as one typed
group: :class:`RunOptions`. :func:`reachwise.simulate`,
:func:`reachwise.sim.simulate.simulate` and :func:`reachwise.sim.simulate.run_world`
take it as ``options=``, or its fields one by one as keywords
(:class:`RunKeywords`); a keyword given overrides the group's field."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Protocol, TypedDict

import numpy as np
from numpy.typing import NDArray

from reachwise.distance.scene import SceneResult
from reachwise.sim.scenarios import EscapeSpec

if TYPE_CHECKING:
    from reachwise.sim.world import World

__all__ = ["RunKeywords", "RunOptions", "RunRecorder", "TickHook", "run_options"]

#: ``on_tick(t, {robot: q}, distances)``: time (s), each robot's joint vector (rad or
#: m per joint) and the scene's answer at that tick.
TickHook = Callable[[float, dict[str, NDArray[np.float64]], SceneResult], None]


class RunRecorder(Protocol):
    """Something that records a run: started with the built world, told each tick
    (index, time) after the distance query, closed at the end."""

    def start(self, world: World) -> None: ...

    def tick(self, k: int, t: float, world: World) -> None: ...

    def close(self) -> None: ...


@dataclass(frozen=True)
class RunOptions:
    """How the loop runs a built world; every field's default leaves the scenario as
    it is written."""

    #: Simulated time to run (s); ``None``: the scenario's ``duration``.
    duration: float | None = None
    #: ``progress(t, duration)`` (s, s), called after each tick.
    progress: Callable[[float, float], None] | None = None
    #: Called each tick after the distance query (a live viewer attaches here).
    on_tick: TickHook | None = None
    #: The static-world baseline for moving obstacles: the controllers see every
    #: object where it was at the start, while the logged distances and the contact
    #: check follow the objects' true motion.
    static_world: bool = False
    #: ``None``: the scenario's ``escape:`` block; True: on (its options or the
    #: defaults); False: off; or an ``EscapeSpec``. A robot whose controller stalls
    #: plans a path out with OMPL and follows it (``reachwise.sim.escape``).
    escape: bool | EscapeSpec | None = None
    #: Started with the built world, told each tick after the distance query and
    #: closed at the end (e.g. a ``reachwise.sim.bag_recorder.BagRecorder``).
    recorder: RunRecorder | None = None


class RunKeywords(TypedDict, total=False):
    """:class:`RunOptions`'s fields as keywords (the same names and types)."""

    duration: float | None
    progress: Callable[[float, float], None] | None
    on_tick: TickHook | None
    static_world: bool
    escape: bool | EscapeSpec | None
    recorder: RunRecorder | None


def run_options(options: RunOptions | None, keywords: RunKeywords) -> RunOptions:
    """``options`` (default: all defaults) with the fields given as ``keywords``
    replaced (an unknown keyword is a ``TypeError``, as for any function)."""
    return replace(options or RunOptions(), **keywords)
