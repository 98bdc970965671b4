"""Global planning for the hybrid controller: escape a local minimum.

The reactive controller reports ``stalled`` in a local minimum (thesis Fig. 3.3);
:func:`plan_path` plans a collision-free joint path with OMPL's RRT-Connect (the
optional ``plan`` extra) against the distance scene (:class:`ClearanceChecker`),
:func:`time_path` times it within the speed limits, and ``PathFollower`` feeds it
to the same controller as intermediate goals. Pure computation: no files, no clocks
(OMPL's planning budget is wall time, given as a parameter).
"""

from reachwise.planning.escape import (
    MISSING,
    PlannerConfig,
    PlanResult,
    goal_configurations,
    ompl_available,
    plan_path,
    require_ompl,
)
from reachwise.planning.timing import TimedPath, time_path
from reachwise.planning.validity import ClearanceChecker, WatchedPart, sweep_bounds

__all__ = [
    "MISSING",
    "ClearanceChecker",
    "PlanResult",
    "PlannerConfig",
    "TimedPath",
    "WatchedPart",
    "goal_configurations",
    "ompl_available",
    "plan_path",
    "require_ompl",
    "sweep_bounds",
    "time_path",
]
