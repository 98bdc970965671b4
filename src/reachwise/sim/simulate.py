"""Closed-loop simulation of the thesis experiments (P-III, P-IV, P-V).

``simulate(scenario, avoidance=True) -> SimulationLog`` runs, at a fixed sample time
``dt`` (default 10 ms, P-V §V) in *simulated* time (no clock is read):

1. every robot's joint state, and every moving object's pose and cloud (objects
   with ``motion``, ``clouds`` or ``rescan``: :mod:`reachwise.sim.motion`), and the
   sensors' frames due by now (depth cameras: :mod:`reachwise.sim.sensors`) go into
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
inside the solid of a robot part (see :mod:`reachwise.sim.contact`). Objects only the
sensors see (``scene: false``) are judged on their true surfaces: every robot link's
exact distance to them (:func:`reachwise.sim.contact.true_clearance`) is logged
(``true_distance``) and counts for the first overlap too.
"""

from __future__ import annotations

import logging
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any, Unpack

import numpy as np
from numpy.typing import NDArray

from reachwise.control.controller import ControlStatus
from reachwise.distance.scene import SceneLike, SceneResult
from reachwise.sim.contact import true_clearance
from reachwise.sim.log import Event, SimulationLog
from reachwise.sim.movers import frozen_scene
from reachwise.sim.plant import PlantName
from reachwise.sim.resolve import ResolvedScenario, resolve_scenario
from reachwise.sim.run_options import RunKeywords, RunOptions, RunRecorder, run_options
from reachwise.sim.run_records import GoalQueue, TickRecorder
from reachwise.sim.scenarios import EscapeSpec, Scenario
from reachwise.sim.world import (
    Agent,
    SceneFactory,
    SimClock,
    Twists,
    World,
    build_world,
    close_scene,
    move_objects,
)

if TYPE_CHECKING:
    from reachwise.sim.escape import Escape

__all__ = [
    "RunKeywords",
    "RunOptions",
    "RunRecorder",
    "SimulationInterrupted",
    "run_world",
    "simulate",
]


class SimulationInterrupted(KeyboardInterrupt):
    """A run stopped by :class:`KeyboardInterrupt` (Ctrl-C, or raised by a ``progress``
    or ``on_tick`` callback): :attr:`log` holds every tick finished before it (maybe
    none), with ``extras["interrupted"]`` set."""

    def __init__(self, log: SimulationLog) -> None:
        super().__init__("simulation interrupted")
        #: The log of the ticks finished before the interruption.
        self.log = log


logger = logging.getLogger("reachwise.sim")


def simulate(
    scenario: ResolvedScenario | Scenario | str | Path,
    avoidance: bool = True,
    *,
    plant: PlantName = "scenario",
    make_scene: SceneFactory | None = None,
    options: RunOptions | None = None,
    **keywords: Unpack[RunKeywords],
) -> SimulationLog:
    """Run ``scenario`` (a built-in name, a file, a ``Scenario`` or a
    :class:`~reachwise.sim.resolve.ResolvedScenario`) in simulated time, in three
    stages: resolve (every file read once,
    :func:`~reachwise.sim.resolve.resolve_scenario`), build
    (:func:`~reachwise.sim.world.build_world`, no file read) and run
    (:func:`run_world`). ``avoidance=False`` runs the conventional controller (the
    baseline).
    ``plant="mujoco"`` runs every robot on its MuJoCo model
    (``reachwise.sim.mujoco_plant``, the ``sim`` extra) instead of the scenario's
    plants and records each robot's tracking error in ``extras["tracking"]``.
    The run's options (``duration``, ``progress``, ``on_tick``, ``static_world``,
    ``escape``, ``recorder``) come as one group, ``options``
    (:class:`~reachwise.sim.run_options.RunOptions`, whose fields say what each
    does), or one by one as keywords, which override the group's fields.
    ``make_scene`` makes the distance scene (:data:`reachwise.sim.world.SceneFactory`;
    default: in process); :func:`reachwise.simulate` passes a collision server's
    client here for its ``server`` option. With a server, a reply that misses its
    deadline (a server lost or restarting) reaches the controllers as missing data
    (protective stop), and the run goes on when the server answers again. Escape
    plans are in ``extras["escape"]``."""
    clock = SimClock()
    world = build_world(
        resolve_scenario(scenario), avoidance, plant=plant, make_scene=make_scene, clock=clock
    )
    return run_world(world, clock, options, **keywords)


def run_world(
    world: World,
    clock: SimClock,
    options: RunOptions | None = None,
    **keywords: Unpack[RunKeywords],
) -> SimulationLog:
    """The third stage of a run: the loop over a built ``world`` (whose scene is
    stamped by ``clock``) until every goal is done or the run's ``duration`` (default:
    the scenario's) has passed; ``options`` and ``keywords`` as :func:`simulate`'s. It
    reads no file.

    Each tick is three named steps: ``_sense`` (joint states and moving objects
    into the scene, the distance query, the controllers' view), ``_check_contact``
    (distances and the first overlap into the ``TickRecorder``) and ``_act``
    (each robot's goal bookkeeping in ``GoalQueue``, controller and plant)."""
    o = run_options(options, keywords)
    progress, on_tick, recorder = o.progress, o.on_tick, o.recorder
    avoidance, plant = world.avoidance, world.plant
    spec = world.scenario.spec
    dt = spec.dt
    T_end = spec.duration if o.duration is None else float(o.duration)
    ticks = math.floor(T_end / dt + 1e-9) + 1
    scene = world.scene
    rec = TickRecorder(world, ticks)
    goals = GoalQueue(world)
    esc = _escape(world, o.escape, goals.events)
    seen = frozen_scene(scene) if o.static_world and world.movers else scene
    pair_objs = [(p.a, p.b) for p in scene.pairs]
    for a in world.agents:
        goals.next_goal(a, 0.0)
    if recorder is not None:
        recorder.start(world)
    n = 0  # ticks finished
    interrupted = False
    try:
        for k in range(ticks):
            t = k * dt
            clock.now = t
            rec.t[k] = t
            res, seen_res, twists = _sense(world, seen, t)
            rec.object_poses(k, t)
            if on_tick is not None:
                on_tick(t, {a.name: a.plant.q.copy() for a in world.agents}, res)
            if recorder is not None:
                recorder.tick(k, t, world)
            _check_contact(world, pair_objs, res, k, t, rec, goals.events)
            if k == 0:
                _note_inside_margins(world, rec.distance[0], goals.events)
            all_done = True
            for a in world.agents:
                rec.robot_state(k, a)
                cmd, state = _act(a, seen_res, twists, t, dt, avoidance, goals, esc)
                if state != "done":
                    all_done = False
                rec.command(k, a.name, cmd, state)
                a.plant.step(cmd, dt)
            n = k + 1
            if progress is not None:
                progress(t, T_end)
            if all_done:
                break
    except KeyboardInterrupt:  # a callback or Ctrl-C: the finished ticks are kept
        interrupted = True
    close_scene(scene)
    if recorder is not None:
        recorder.close()
    extras: dict[str, Any] = {"plant": plant, "static_world": o.static_world}
    if plant == "mujoco":
        extras["tracking"] = {a.name: a.plant.tracking() for a in world.agents}  # type: ignore[union-attr]
    if esc is not None:
        extras["escape"] = esc.summary()
    if interrupted:
        extras["interrupted"] = True
        raise SimulationInterrupted(rec.log(n, avoidance, goals, extras))
    return rec.log(n, avoidance, goals, extras)


def _sense(world: World, seen: SceneLike, t: float) -> tuple[SceneResult, SceneResult, Twists]:
    """Step 1: every robot's joint state and every moving object's pose and cloud into
    the scene, which answers every watched pair. Returns that answer, the controllers'
    view of it (``seen``: the frozen scene of the static-world baseline, which sees no
    motion) and the moving objects' twists."""
    scene = world.scene
    for a in world.agents:
        scene.set_joints(a.name, a.plant.q, stamp=t)
    twists = move_objects(world, t)
    if world.sensors and world.sight is not None:
        tick = round(t / world.scenario.spec.dt)
        qs = {a.name: a.plant.q for a in world.agents}
        for sensor in world.sensors:
            sensor.step(scene, tick, world.sight, qs)
        if any(feed.dirty for feed in world.memories):
            fk = world.sight.frames(qs)  # the robots' bodies leave the map
            for feed in world.memories:
                feed.flush(scene, fk)
    res = scene.query_all()
    if seen is scene:
        return res, res, twists
    for a in world.agents:  # static-world baseline: the controllers' frozen view
        seen.set_joints(a.name, a.plant.q)
    return res, seen.query_all(), {}


def _check_contact(
    world: World,
    pair_objs: list[tuple[str, str]],
    res: SceneResult,
    k: int,
    t: float,
    rec: TickRecorder,
    events: list[Event],
) -> None:
    """Step 2: each pair's distance and signed distance (``−depth`` when a point of one
    object of pair ``i`` (``pair_objs[i]``) lies inside the solid of the other) into
    the log, and the first overlap."""
    check = world.scenario.spec.contact_check
    scene = world.scene
    poses: dict[str, NDArray[np.float64]] | None = None
    for i, pr in enumerate(res.pairs):
        d = pr.result.distance
        rec.distance[k, i] = d
        s = d
        if d <= check:
            if poses is None:
                poses = scene.poses()
            depth = _overlap(world, scene, pair_objs[i], poses)
            if depth >= 0.0:
                s = -depth
        rec.signed[k, i] = s
        if s <= 0.0 and rec.first is None:
            rec.first = t
            rec.first_pair = world.pairs[i]
            events.append(
                Event(t, "", "collision", f"{rec.first_pair} overlap ({-s * 1e3:.1f} mm)")
            )
    for sensor in world.sensors:
        rec.frames[sensor.name][k] = sensor.in_use
    _check_truth(world, k, t, rec, events)


def _note_inside_margins(world: World, d: NDArray[np.float64], events: list[Event]) -> None:
    """At the start of a run, name every watched pair already within its collision
    margin ρ_O (distances ``d``), with its distance and margin, in an ``inside margin``
    event and a warning: its repulsion (Eq. 3.17) acts from the first tick and pushes
    it out (the guard's damper stops it at half its margin at the latest,
    :func:`reachwise.control.potential.stop_within`)."""
    for i, pair in enumerate(world.pairs):
        if d[i] < world.margins[i]:
            robot = pair.split("/", 1)[0] if "/" in pair else ""
            text = (
                f"{pair} starts {d[i]:.4f} m apart, within its {world.margins[i]:g} m margin: "
                "its repulsion pushes it out"
            )
            events.append(Event(0.0, robot, "inside margin", text))
            logger.warning("%s: %s", world.scenario.spec.name, text)


def _check_truth(world: World, k: int, t: float, rec: TickRecorder, events: list[Event]) -> None:
    """The true signed distance of every robot link to every object only the sensors
    see (``world.truth``), measured on their surfaces when their bounding boxes come
    within the largest margin plus the monitor range; the first overlap."""
    sight = world.sight
    if not world.truth or sight is None:
        return
    reach = float(world.margins.max(initial=0.0)) + world.scenario.spec.monitor
    fk = sight.frames({a.name: a.plant.q for a in world.agents})
    placed = {name: sight.objects[name].pose_at(t) for name in {o for _, o in world.truth}}
    for j, (body_name, obj_name) in enumerate(world.truth):
        body = sight.bodies[body_name]
        Pb = fk[body.robot][body.index]
        Po = placed[obj_name]
        (mesh, solid) = sight.objects[obj_name].shape_at(t)
        gap = _box_gap(body.mesh[0], Pb, mesh[0], Po)
        if gap > reach:
            continue
        d = true_clearance(body.mesh, body.solid, Pb, mesh, solid, Po)
        rec.true_distance[k, j] = d
        if d <= 0.0 and rec.first is None:
            rec.first = t
            rec.first_pair = f"{body_name}|{obj_name}"
            events.append(
                Event(t, "", "collision", f"{rec.first_pair} overlap ({-d * 1e3:.1f} mm)")
            )


F64 = NDArray[np.float64]


def _box_gap(va: F64, Pa: F64, vb: F64, Pb: F64) -> float:
    """A lower bound of the distance of two meshes (vertices in their frames, placed at
    ``Pa``, ``Pb``): the gap between the boxes about their world vertices."""
    wa = va @ Pa[:3, :3].T + Pa[:3, 3]
    wb = vb @ Pb[:3, :3].T + Pb[:3, 3]
    lo = np.maximum(wa.min(axis=0) - wb.max(axis=0), wb.min(axis=0) - wa.max(axis=0))
    return float(np.linalg.norm(np.maximum(0.0, lo)))


def _act(
    a: Agent,
    seen_res: SceneResult,
    twists: Twists,
    t: float,
    dt: float,
    avoidance: bool,
    goals: GoalQueue,
    esc: Escape | None,
) -> tuple[NDArray[np.float64], str]:
    """Step 3, per robot: end its work at a goal when the time is up, then compute its
    command toward its goal (with avoidance of what it sees) and keep its goal record.
    Returns the command and the state to log (``"done"``: no goal left)."""
    q = a.plant.q
    if t < a.locked_until:
        a.controller.locked = True
    elif a.controller.locked:
        a.controller.locked = False
        goals.events.append(Event(t, a.name, "unlocked", "work done"))
        goals.next_goal(a, t)
    if a.goal is None:
        return np.zeros(a.robot.n), "done"
    pts = a.converter(seen_res, stamp=t, twists=twists) if avoidance else None
    goal = a.goal if esc is None else esc.goal(a, q, dt)
    cmd, st = a.controller.step(q, goal, pts, t)  # type: ignore[arg-type]
    state = st.state
    _note(a, st, t, goals.events)
    if esc is not None:  # hybrid: plan out of a stall, follow, resume
        st = esc.status(a, q, st, t)
        state = st.state
    if st.state == "reached" and not a.controller.locked:
        if goals.reached(a, st, t):
            cmd = np.zeros(a.robot.n)
    elif a.goal is not None and a.record >= 0 and st.state != "locked":
        goals.errors(a, st)
    return cmd, state


def _escape(world: World, escape: bool | EscapeSpec | None, events: list[Event]) -> Escape | None:
    """The run's local-minimum escape (``reachwise.sim.escape``), or None when off."""
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
    world: World, scene: SceneLike, pair: tuple[str, str], poses: dict[str, NDArray[np.float64]]
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
