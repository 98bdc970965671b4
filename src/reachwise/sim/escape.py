"""The hybrid controller in simulation: reactive control, and a planned escape from a stall.

:func:`reachwise.sim.simulate.simulate` with ``escape`` on (the scenario's ``escape:``
block or ``simulate(..., escape=True)``) gives each tick's goal and status to an
:class:`Escape`:

1. a robot's controller reports ``stalled`` (a local minimum, thesis Fig. 3.3) — the
   stall event is logged as without escape;
2. :func:`reachwise.planning.plan_escape` plans, from the current joint values, an
   RRT-Connect path (OMPL, the ``plan`` extra) to a collision-free configuration at
   the goal, in a snapshot of the distance scene at the controller's margins, with
   the joints a task-space follower cannot pin down held (a 7-joint arm following
   6-D goals holds one); event ``planning`` (OMPL's planning and shortcutting times,
   waypoints, joint and tool path lengths, held joints) or ``escape_failed`` (why);
3. the path, timed within the joint speed limits and the controller's tool speed
   bounds (:func:`reachwise.planning.time_path`, at ``speed`` × those bounds), is
   followed by the robot's controller — the same law, gains, margins and avoidance,
   with the held joints locked (``Controller(..., locked_joints=...)``) — through
   intermediate goals (:class:`reachwise.planning.PathFollower`); an intermediate goal
   reached is not the goal reached, and the state stays ``moving``;
4. at the path's end, event ``escaped``, and reactive control to the original goal
   resumes with every joint. A follower held back for the controller's stall time
   gives up (``escape_failed``) and reactive control resumes; a goal gets at most
   ``attempts`` plans.

``extras["escape"]`` of the log lists every plan (times in s, ``held_q_indices``
0-based entries of ``q``). Planning happens between two ticks: simulated time does not
advance while OMPL plans (its wall-clock time is reported, not simulated). Without
OMPL the stall stands and an ``escape_failed`` event says which extra is missing.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from reachwise.control.controller import Controller, ControlStatus, Goal
from reachwise.sim.scenarios import EscapeSpec

if TYPE_CHECKING:
    from reachwise.planning.follow import PathFollower
    from reachwise.sim.log import Event
    from reachwise.sim.world import Agent, World

__all__ = ["Escape"]


@dataclass(eq=False)
class _Following:
    goal: Goal
    follower: PathFollower
    since: float
    controller: Controller  # the robot's own, back in charge when the escape ends


class Escape:
    """Plans and follows escapes for the agents of one run (see the module doc)."""

    def __init__(self, world: World, spec: EscapeSpec, events: list[Event]) -> None:
        from reachwise.planning.escape import ompl_available

        self.world = world
        self.spec = spec
        self.events = events
        self.available = ompl_available()
        self.plans: list[dict[str, Any]] = []
        self._following: dict[str, _Following] = {}
        self._tries: dict[tuple[str, int], int] = {}
        self._margins = {
            (p.a, p.b): float(m) for p, m in zip(world.scene.pairs, world.margins, strict=True)
        }

    def _event(self, t: float, robot: str, kind: str, text: str) -> None:
        from reachwise.sim.log import Event

        self.events.append(Event(t, robot, kind, text))

    # ------------------------------------------------------------------ per tick
    def goal(self, a: Agent, q: NDArray[np.float64], dt: float) -> Goal | None:
        """The goal ``a``'s controller gets this tick: the escape path's intermediate
        goal while following one, else the robot's own."""
        f = self._following.get(a.name)
        if f is None or a.goal is None:
            return a.goal
        if f.goal is not a.goal:  # the goal changed: the path is moot
            self._end(a)
            return a.goal
        return f.follower.goal(q, dt)

    def status(
        self, a: Agent, q: NDArray[np.float64], st: ControlStatus, t: float
    ) -> ControlStatus:
        """The status to act on after the controller's tick: plans on a stall, hides
        an intermediate goal's ``reached``, ends a finished or stuck escape."""
        f = self._following.get(a.name)
        if f is not None:
            if f.follower.done(q):
                self._end(a)
                self._event(
                    t, a.name, "escaped", f"end of the escape path after {t - f.since:.2f} s"
                )
            elif f.follower.stuck:
                self._end(a)
                self._event(
                    t,
                    a.name,
                    "escape_failed",
                    f"the escape path was not followed: held back for "
                    f"{f.follower.waited:.2f} s at {f.follower.s:.2f} of "
                    f"{f.follower.path.duration:.2f} s; reactive control resumes",
                )
            if st.state == "reached":
                return replace(st, state="moving", reason="on the escape path")
            return st
        if st.state != "stalled" or a.goal is None:
            return st
        key = (a.name, a.record)
        tries = self._tries.get(key, 0)
        if tries >= self.spec.attempts:
            return st
        self._tries[key] = tries + 1
        if not self.available:
            from reachwise.planning.escape import MISSING

            self._tries[key] = self.spec.attempts
            self._event(t, a.name, "escape_failed", f"{MISSING}; the stall stands")
            return st
        self._plan(a, q, t, tries)
        return st

    def _end(self, a: Agent) -> None:
        """Hand ``a`` back to its own controller (fresh stall clock)."""
        f = self._following.pop(a.name)
        a.controller = f.controller
        a.controller.reset()

    # ------------------------------------------------------------------ planning
    def _plan(self, a: Agent, q: NDArray[np.float64], t: float, tries: int) -> None:
        from reachwise.planning.escape import PlannerConfig, plan_escape
        from reachwise.planning.follow import PathFollower
        from reachwise.planning.timing import time_path
        from reachwise.planning.validity import ClearanceChecker

        if a.goal is None:
            return
        robot = a.robot
        spec = self.spec
        checker = ClearanceChecker(self.world.scene, robot, a.name, self._margins)
        cfg = PlannerConfig(time_limit=spec.time_limit, seed=spec.seed + tries, step=spec.step)
        dims = 6 if int(np.count_nonzero(robot.actuated)) >= 6 else 3
        res = plan_escape(
            checker, q, a.goal, cfg, dims=dims, sigma_floor=a.controller.config.epsilon
        )
        record: dict[str, Any] = {
            "t": t,
            "robot": a.name,
            "success": res.success,
            "reason": res.reason,
            "status": res.status,
            "planning_time_s": res.planning_time,
            "simplify_time_s": res.simplify_time,
            "raw_states": res.raw_states,
            "waypoints": int(res.path.shape[0]),
            "joint_path_length": res.length,
            "goal_configurations": int(res.goals.shape[0]),
            "validity_checks": res.checks,
            "resolution": res.resolution,
            "plans": res.plans,
            "held_q_indices": list(res.held),
        }
        self.plans.append(record)
        if not res.success:
            self._event(t, a.name, "escape_failed", f"planning failed: {res.reason}")
            return
        cc = a.controller.config
        timed = time_path(
            res.path,
            robot.vmax,  # a joint without a speed limit is bounded by the tool's
            speed=spec.speed,
            fk=robot.fk,
            tool_speed=spec.speed * cc.v_max,
            tool_rate=spec.speed * cc.w_max,
        )
        dense = np.array([timed.at(s) for s in np.linspace(0.0, timed.duration, 200)])
        tool_len = float(np.linalg.norm(np.diff(robot.fk(dense)[:, :3, 3], axis=0), axis=1).sum())
        record.update(path_duration_s=timed.duration, tool_path_length=tool_len)
        self._event(
            t,
            a.name,
            "planning",
            f"RRT-Connect (OMPL): {res.status.lower()} in {res.planning_time:.3f} s "
            f"({res.plans} run(s)), shortcut in {res.simplify_time:.3f} s; "
            f"{res.path.shape[0]} waypoints, joint path {res.length:.2f}, tool path "
            f"{tool_len:.2f} m, {timed.duration:.1f} s"
            + (f"; joints {[k + 1 for k in res.held]} held" if res.held else ""),
        )
        follower = PathFollower(
            robot,
            timed,
            lead=1.0 / cc.kv,
            turn_lead=2.0 / cc.kw,
            stall_time=cc.stall_time,
            dims=dims,
        )
        # the same control law, gains and avoidance, with the held joints locked
        own = a.controller
        a.controller = Controller(robot, cc, locked_joints=res.held) if res.held else own
        a.controller.reset()
        self._following[a.name] = _Following(a.goal, follower, t, own)

    def summary(self) -> dict[str, Any]:
        """JSON-ready: the options and every plan made."""
        return {
            "planner": "ompl-rrtconnect",
            "available": self.available,
            "options": self.spec.model_dump(),
            "plans": list(self.plans),
        }
