"""What a run keeps while it runs (:func:`reachwise.sim.simulate.run_world`): the log's
arrays, one row per tick (:class:`TickRecorder`), and which goal each robot pursues with
the record of every goal and the run's events (:class:`GoalQueue`)."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from reachwise.control.controller import ControlStatus
from reachwise.sim.log import Event, GoalRecord, SimulationLog, joint_names_of
from reachwise.sim.world import Agent, World

__all__ = ["GoalQueue", "TickRecorder"]


class TickRecorder:
    """The arrays of the log, one row per tick, and the first overlap."""

    def __init__(self, world: World, ticks: int) -> None:
        self.world = world
        agents = world.agents
        P = len(world.pairs)
        self.t = np.empty(ticks)
        self.distance = np.full((ticks, P), np.inf)
        self.signed = np.full((ticks, P), np.inf)
        self.q = {a.name: np.empty((ticks, a.robot.n)) for a in agents}
        self.qdot = {a.name: np.empty((ticks, a.robot.n)) for a in agents}
        self.cmd = {a.name: np.empty((ticks, a.robot.n)) for a in agents}
        self.tool = {a.name: np.empty((ticks, 4, 4)) for a in agents}
        self.state = {a.name: np.empty(ticks, dtype="<U16") for a in agents}
        self.goal_index = {a.name: np.full(ticks, -1, dtype=np.int64) for a in agents}
        self.objects = {m.spec.name: np.empty((ticks, 4, 4)) for m in world.movers if m.trajectory}
        self.true_distance = np.full((ticks, len(world.truth)), np.inf)
        self.frames = {s.name: np.zeros(ticks, dtype=np.int64) for s in world.sensors}
        self.first: float | None = None
        self.first_pair: str | None = None

    def object_poses(self, k: int, t: float) -> None:
        """The moving objects' poses at tick ``k`` (time ``t``)."""
        for m in self.world.movers:
            if m.trajectory is not None:
                self.objects[m.spec.name][k] = m.trajectory.pose(t)

    def robot_state(self, k: int, a: Agent) -> None:
        """The robot's joint state, tool pose and goal at the start of tick ``k``."""
        q = a.plant.q
        self.q[a.name][k] = q
        self.qdot[a.name][k] = a.plant.qdot
        self.tool[a.name][k] = a.robot.fk(q)
        self.goal_index[a.name][k] = a.record if a.goal is not None else -1

    def command(self, k: int, name: str, cmd: NDArray[np.float64], state: str) -> None:
        """The command and the controller state of tick ``k``."""
        self.cmd[name][k] = cmd
        self.state[name][k] = state

    def log(
        self, n: int, avoidance: bool, goals: GoalQueue, extras: dict[str, Any]
    ) -> SimulationLog:
        """The log of the first ``n`` ticks."""
        world = self.world
        agents = world.agents
        return SimulationLog(
            scenario=world.scenario.spec.name,
            avoidance=avoidance,
            dt=world.scenario.spec.dt,
            t=self.t[:n],
            robots=tuple(a.name for a in agents),
            q={k_: v[:n] for k_, v in self.q.items()},
            qdot={k_: v[:n] for k_, v in self.qdot.items()},
            command={k_: v[:n] for k_, v in self.cmd.items()},
            tool={k_: v[:n] for k_, v in self.tool.items()},
            state={k_: v[:n] for k_, v in self.state.items()},
            goal_index={k_: v[:n] for k_, v in self.goal_index.items()},
            pairs=world.pairs,
            distance=self.distance[:n],
            signed=self.signed[:n],
            margins=world.margins,
            lower={a.name: np.asarray(a.robot.lower) for a in agents},
            upper={a.name: np.asarray(a.robot.upper) for a in agents},
            vmax={a.name: np.asarray(a.robot.vmax) for a in agents},
            events=tuple(goals.events),
            goals=tuple(goals.records),
            first_collision=self.first,
            first_collision_pair=self.first_pair,
            object_poses={k_: v[:n] for k_, v in self.objects.items()},
            extras=extras,
            true_pairs=tuple(f"{a}|{b}" for a, b in world.truth),
            true_distance=self.true_distance[:n],
            frames={k_: v[:n] for k_, v in self.frames.items()},
            joint_names=joint_names_of({a.name: a.robot for a in agents}),
        )


class GoalQueue:
    """Which goal each robot pursues (its own list, then free jobs of the shared list),
    the record of every goal and the run's events."""

    def __init__(self, world: World) -> None:
        self.world = world
        self.records: list[GoalRecord] = []
        self.events: list[Event] = []
        self.job_taken = [False] * len(world.jobs)

    def next_goal(self, a: Agent, t: float) -> None:
        """Give ``a`` its next goal (or none left) at time ``t``."""
        a.goal = None
        a.spec = None
        a.job = -1
        if a.own:
            a.goal, a.spec = a.own.pop(0)
        elif a.jobs:
            for j, taken in enumerate(self.job_taken):
                if not taken:
                    self.job_taken[j] = True
                    a.goal, a.spec = self.world.jobs[j]
                    a.job = j
                    break
        if a.goal is not None and a.spec is not None:
            a.record = len(self.records)
            name = a.spec.name or (f"job {a.job + 1}" if a.job >= 0 else f"goal {a.record + 1}")
            self.records.append(
                GoalRecord(a.name, a.record, name, a.spec.work, None, math.nan, math.nan)
            )
            self.events.append(Event(t, a.name, "goal", f"moving to {name}"))
            a.controller.reset()
            a.stalled = False

    def reached(self, a: Agent, st: ControlStatus, t: float) -> bool:
        """Record ``a``'s goal as reached; True when it now works there (locked)."""
        rec = self.records[a.record]
        self.records[a.record] = replace(
            rec,
            reached_at=t,
            position_error=st.position_error,
            orientation_error=st.orientation_error,
        )
        self.events.append(Event(t, a.name, "reached", f"{rec.name} reached"))
        work = a.spec.work if a.spec is not None else 0.0
        if work > 0.0:
            a.locked_until = t + work
            a.controller.locked = True
            self.events.append(Event(t, a.name, "locked", f"working {work:g} s at {rec.name}"))
            return True
        self.next_goal(a, t)
        return False

    def errors(self, a: Agent, st: ControlStatus) -> None:
        """The remaining errors of ``a``'s goal so far."""
        rec = self.records[a.record]
        self.records[a.record] = replace(
            rec, position_error=st.position_error, orientation_error=st.orientation_error
        )
