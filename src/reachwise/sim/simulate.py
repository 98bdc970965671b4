"""Closed-loop simulation of the thesis experiments (P-III, P-IV, P-V).

``simulate(scenario, avoidance=True) -> SimulationLog`` runs, at a fixed sample time
``dt`` (default 10 ms, P-V §V) in *simulated* time (no clock is read):

1. every robot's joint state, and every moving object's pose and cloud (objects
   with ``motion``, ``clouds`` or ``rescan``: :mod:`reachwise.sim.motion`), go into
   the distance scene, which answers every watched pair (P-IV/P-V collision server);
2. the answer (sequence number, stamped with the time of that joint state) is
   converted into each robot's avoidance points and fed, with the robot's current
   goal, to its :class:`~reachwise.control.Controller`;
3. the commands drive the plants (kinematic or hydraulic-like, passive grabber joints
   hanging); a robot at a goal with ``work`` time is locked there (P-IV drilling) and
   then takes its next goal, or the next free job of a shared job list.

``avoidance=False`` is the baseline: the same controller, gains and plants, without
avoidance (the conventional controller of P-III Fig. 3b). Either way every pair's
distance is logged, and the run records when the parts first overlap: a pair's
signed distance is its cloud distance, or ``−depth`` when a point of one object lies
inside the solid of a robot part (see :mod:`reachwise.sim.contact`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from reachwise.control.controller import ControlStatus
from reachwise.distance.scene import Scene, SceneResult
from reachwise.sim.log import Event, GoalRecord, SimulationLog
from reachwise.sim.plant import PlantName
from reachwise.sim.scenarios import EscapeSpec, Scenario
from reachwise.sim.world import (
    Agent,
    SimClock,
    World,
    build_world,
    close_scene,
    frozen_scene,
    move_objects,
)

if TYPE_CHECKING:
    from reachwise.server.client import ServerOptions
    from reachwise.sim.escape import Escape

__all__ = ["simulate"]


def simulate(
    scenario: Scenario | str | Path,
    avoidance: bool = True,
    *,
    duration: float | None = None,
    progress: Callable[[float, float], None] | None = None,
    on_tick: Callable[[float, dict[str, NDArray[np.float64]], SceneResult], None] | None = None,
    plant: PlantName = "scenario",
    static_world: bool = False,
    server: str | ServerOptions | None = None,
    escape: bool | EscapeSpec | None = None,
) -> SimulationLog:
    """Run ``scenario`` (a built-in name, a file or a :class:`Scenario`) in simulated
    time; ``avoidance=False`` runs the conventional controller (the baseline).
    ``duration`` overrides the scenario's; ``progress(t, duration)`` is called each
    tick; ``on_tick(t, {robot: q}, distances)`` too, after the distance query (a live
    viewer attaches here). ``plant="mujoco"`` runs every robot on its MuJoCo model
    (:mod:`reachwise.sim.mujoco_plant`, the ``sim`` extra) instead of the scenario's
    plants and records each robot's tracking error in ``extras["tracking"]``.
    ``static_world=True`` is the static-world baseline for moving obstacles: the
    controllers see every object where it was at the start, while the logged
    distances and the contact check follow the objects' true motion.
    ``server`` (an address or :class:`~reachwise.server.client.ServerOptions`) runs
    the distance queries on that collision server instead of in process: the
    simulation clears the server's scene and registers its own; a reply that misses
    its deadline (a server lost or restarting) reaches the controllers as missing
    data (protective stop), and the run goes on when the server answers again.
    ``escape`` (default: the scenario's ``escape:`` block; True: on, with its options
    or the defaults; False: off; or an :class:`EscapeSpec`): a robot whose controller
    stalls plans a path out with OMPL and follows it (:mod:`reachwise.sim.escape`);
    the plans are in ``extras["escape"]``."""
    clock = SimClock()
    world = build_world(scenario, avoidance, plant=plant, server=server, clock=clock)
    spec = world.scenario.spec
    dt = spec.dt
    T_end = spec.duration if duration is None else float(duration)
    ticks = math.floor(T_end / dt + 1e-9) + 1
    scene = world.scene
    agents = world.agents
    P = len(world.pairs)
    t_log = np.empty(ticks)
    dist = np.full((ticks, P), np.inf)
    signed = np.full((ticks, P), np.inf)
    q_log = {a.name: np.empty((ticks, a.robot.n)) for a in agents}
    qd_log = {a.name: np.empty((ticks, a.robot.n)) for a in agents}
    cmd_log = {a.name: np.empty((ticks, a.robot.n)) for a in agents}
    tool_log = {a.name: np.empty((ticks, 4, 4)) for a in agents}
    st_log = {a.name: np.empty(ticks, dtype="<U16") for a in agents}
    gi_log = {a.name: np.full(ticks, -1, dtype=np.int64) for a in agents}
    events: list[Event] = []
    esc = _escape(world, escape, events)
    records: list[GoalRecord] = []
    job_taken = [False] * len(world.jobs)
    first: float | None = None
    first_pair: str | None = None
    pair_objs = [(p.a, p.b) for p in scene.pairs]
    check = spec.contact_check
    obj_log = {m.spec.name: np.empty((ticks, 4, 4)) for m in world.movers if m.trajectory}
    seen = frozen_scene(scene) if static_world and world.movers else scene

    def next_goal(a: Agent, t: float) -> None:
        a.goal = None
        a.spec = None
        a.job = -1
        if a.own:
            a.goal, a.spec = a.own.pop(0)
        elif a.jobs:
            for j, taken in enumerate(job_taken):
                if not taken:
                    job_taken[j] = True
                    a.goal, a.spec = world.jobs[j]
                    a.job = j
                    break
        if a.goal is not None and a.spec is not None:
            a.record = len(records)
            name = a.spec.name or (f"job {a.job + 1}" if a.job >= 0 else f"goal {a.record + 1}")
            records.append(
                GoalRecord(a.name, a.record, name, a.spec.work, None, math.nan, math.nan)
            )
            events.append(Event(t, a.name, "goal", f"moving to {name}"))
            a.controller.reset()
            a.stalled = False

    for a in agents:
        next_goal(a, 0.0)

    k = 0
    for k in range(ticks):
        t = k * dt
        clock.now = t
        t_log[k] = t
        for a in agents:
            scene.set_joints(a.name, a.plant.q, stamp=t)
        twists = move_objects(world, t)
        for m in world.movers:
            if m.trajectory is not None:
                obj_log[m.spec.name][k] = m.trajectory.pose(t)
        res = scene.query_all()
        seen_res = res
        if seen is not scene:  # static-world baseline: the controllers' frozen view
            for a in agents:
                seen.set_joints(a.name, a.plant.q)
            seen_res = seen.query_all()
            twists = {}
        if on_tick is not None:
            on_tick(t, {a.name: a.plant.q.copy() for a in agents}, res)
        poses: dict[str, NDArray[np.float64]] | None = None
        for i, pr in enumerate(res.pairs):
            d = pr.result.distance
            dist[k, i] = d
            s = d
            if d <= check:
                if poses is None:
                    poses = scene.poses()
                depth = _overlap(world, scene, pair_objs[i], poses)
                if depth >= 0.0:
                    s = -depth
            signed[k, i] = s
            if s <= 0.0 and first is None:
                first = t
                first_pair = world.pairs[i]
                events.append(
                    Event(t, "", "collision", f"{first_pair} overlap ({-s * 1e3:.1f} mm)")
                )
        all_done = True
        for a in agents:
            name = a.name
            q = a.plant.q
            q_log[name][k] = q
            qd_log[name][k] = a.plant.qdot
            tool_log[name][k] = a.robot.fk(q)
            gi_log[name][k] = a.record if a.goal is not None else -1
            if t < a.locked_until:
                a.controller.locked = True
            elif a.controller.locked:
                a.controller.locked = False
                events.append(Event(t, name, "unlocked", "work done"))
                next_goal(a, t)
            if a.goal is None:
                cmd = np.zeros(a.robot.n)
                st = ControlStatus("reached", "no goal left")
                state = "done"
            else:
                all_done = False
                pts = a.converter(seen_res, stamp=t, twists=twists) if avoidance else None
                goal = a.goal if esc is None else esc.goal(a, q, dt)
                cmd, st = a.controller.step(q, goal, pts, t)  # type: ignore[arg-type]
                state = st.state
                _note(a, st, t, events)
                if esc is not None:  # hybrid: plan out of a stall, follow, resume
                    st = esc.status(a, q, st, t)
                    state = st.state
                if st.state == "reached" and not a.controller.locked:
                    rec = records[a.record]
                    records[a.record] = replace(
                        rec,
                        reached_at=t,
                        position_error=st.position_error,
                        orientation_error=st.orientation_error,
                    )
                    events.append(Event(t, name, "reached", f"{rec.name} reached"))
                    work = a.spec.work if a.spec is not None else 0.0
                    if work > 0.0:
                        a.locked_until = t + work
                        a.controller.locked = True
                        events.append(Event(t, name, "locked", f"working {work:g} s at {rec.name}"))
                        cmd = np.zeros(a.robot.n)
                    else:
                        next_goal(a, t)
                elif a.goal is not None and a.record >= 0 and st.state != "locked":
                    rec = records[a.record]
                    records[a.record] = replace(
                        rec,
                        position_error=st.position_error,
                        orientation_error=st.orientation_error,
                    )
            cmd_log[name][k] = cmd
            st_log[name][k] = state
            a.plant.step(cmd, dt)
        if progress is not None:
            progress(t, T_end)
        if all_done:
            break
    n = k + 1
    close_scene(scene)
    return SimulationLog(
        scenario=spec.name,
        avoidance=avoidance,
        dt=dt,
        t=t_log[:n],
        robots=tuple(a.name for a in agents),
        q={k_: v[:n] for k_, v in q_log.items()},
        qdot={k_: v[:n] for k_, v in qd_log.items()},
        command={k_: v[:n] for k_, v in cmd_log.items()},
        tool={k_: v[:n] for k_, v in tool_log.items()},
        state={k_: v[:n] for k_, v in st_log.items()},
        goal_index={k_: v[:n] for k_, v in gi_log.items()},
        pairs=world.pairs,
        distance=dist[:n],
        signed=signed[:n],
        margins=world.margins,
        lower={a.name: np.asarray(a.robot.lower) for a in agents},
        upper={a.name: np.asarray(a.robot.upper) for a in agents},
        vmax={a.name: np.asarray(a.robot.vmax) for a in agents},
        events=tuple(events),
        goals=tuple(records),
        first_collision=first,
        first_collision_pair=first_pair,
        object_poses={k_: v[:n] for k_, v in obj_log.items()},
        extras={"plant": plant, "static_world": static_world}
        | (
            {"tracking": {a.name: a.plant.tracking() for a in agents}}  # type: ignore[union-attr]
            if plant == "mujoco"
            else {}
        )
        | ({"escape": esc.summary()} if esc is not None else {}),
    )


def _escape(world: World, escape: bool | EscapeSpec | None, events: list[Event]) -> Escape | None:
    """The run's local-minimum escape (:mod:`reachwise.sim.escape`), or None when off."""
    spec = world.scenario.spec.escape
    if isinstance(escape, EscapeSpec):
        spec = escape
    elif escape is True:
        spec = spec or EscapeSpec()
    elif escape is False:
        spec = None
    if spec is None:
        return None
    from reachwise.sim.escape import Escape

    return Escape(world, spec, events)


def _note(a: Agent, st: ControlStatus, t: float, events: list[Event]) -> None:
    """Log state changes worth reading: stalls and protective stops."""
    if st.state == "stalled" and not a.stalled:
        a.stalled = True
        events.append(Event(t, a.name, "stalled", st.reason))
    elif st.state == "moving" and a.stalled:
        a.stalled = False
        events.append(Event(t, a.name, "moving", "progress again"))
    if st.state == "protective_stop" and not a.stopped:
        a.stopped = True
        events.append(Event(t, a.name, "protective_stop", st.reason))
    elif st.state != "protective_stop" and a.stopped:
        a.stopped = False


def _overlap(
    world: World, scene: Scene, pair: tuple[str, str], poses: dict[str, NDArray[np.float64]]
) -> float:
    """Deepest point of either object inside the other's solid (m), ``-inf`` if none."""
    objs = scene.objects
    best = -math.inf
    for mine, other in (pair, pair[::-1]):
        entry = world.solids.get(mine)
        if entry is None:
            continue
        solid = entry[0]
        src = objs[other]
        Po = poses[other]
        pts = src.cloud.points @ Po[:3, :3].T + Po[:3, 3]
        best = max(best, solid.depth(pts, poses[mine]))
    return best
