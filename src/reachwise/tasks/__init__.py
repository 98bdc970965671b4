"""reachwise.tasks: what a manipulator must reach, and where it may move (pure math).

``TaskPoint`` / ``Task`` hold 3-, 5- or 6-D poses with tolerances (thesis §2.3, P-II §5),
built from arrays with a ``PointArrays`` group;
``drilling_pattern`` builds a tunnel-face drill plan from a ``DrillLayout`` and
``tunnel_87`` the public stand-in for the thesis's 87-point task from 10 customer plans
(P-I §4);
``TunnelProfile`` / ``TunnelEnvelope`` give the tunnel as a workspace constraint with
an exact signed distance (P-I §4.2). File I/O lives in ``reachwise.io.task_file``.
"""

from __future__ import annotations

from reachwise.tasks.drill_layout import (
    ContourLayout,
    CutLayout,
    DrillLayout,
    LayoutKeywords,
    LifterLayout,
    StopingLayout,
)
from reachwise.tasks.drilling import (
    TUNNEL_87_LARGEST,
    TUNNEL_87_SEED,
    ZONES,
    combine_plans,
    drilling_pattern,
    farthest_point_selection,
    plan_extremes,
    roll_rotations,
    tunnel_87,
    tunnel_plans,
)
from reachwise.tasks.task import PointArrayKeywords, PointArrays, Task, TaskPoint, frame_from_axis
from reachwise.tasks.workspace import TunnelEnvelope, TunnelProfile

__all__ = [
    "TUNNEL_87_LARGEST",
    "TUNNEL_87_SEED",
    "ZONES",
    "ContourLayout",
    "CutLayout",
    "DrillLayout",
    "LayoutKeywords",
    "LifterLayout",
    "PointArrayKeywords",
    "PointArrays",
    "StopingLayout",
    "Task",
    "TaskPoint",
    "TunnelEnvelope",
    "TunnelProfile",
    "combine_plans",
    "drilling_pattern",
    "farthest_point_selection",
    "frame_from_axis",
    "plan_extremes",
    "roll_rotations",
    "tunnel_87",
    "tunnel_plans",
]
