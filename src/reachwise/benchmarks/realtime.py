"""``reachwise bench realtime``: live clouds at camera rate and a 1 kHz control loop.

One run measures:

1. **Index builds** of a 300 000-point camera frame and a 1 000 000-point room scan,
   what the ingestion worker does per hand-over (check and copy the points, build the
   tree: :func:`reachwise.distance.ingest.ready_cloud`), against the path of commit
   9be9138 (a :class:`~reachwise.geometry.cloud.PointCloud` copy and NaN check,
   a second copy, the tree of commit 9be9138, an inverse map and a mean:
   :mod:`reachwise.benchmarks._baseline_build`), interleaved rep by rep. Wall time
   (``build.<n>.new`` / ``.old``) and the thread's CPU time (``..._cpu``): the
   machine is shared, and CPU time is what the build costs one core whatever else runs.
2. **The 1 kHz loop** on the real-arm scene: the example-robot-data Panda with every
   link a 1000-point cloud and its automatic self-collision pairs (the ``panda-shelf``
   scenario, with its scanned shelf), in a 1 000 000-point room (floor, walls,
   ceiling, a table), while a camera thread hands over a 307 200-point depth frame
   (640×480 rays cast into the room, the shelf, the table and a person walking past)
   30 times a second with :meth:`~reachwise.distance.scene.Scene.replace_cloud`. Links
   1–7 are watched against the room and the camera cloud (the base stands on the
   floor) with the scenario's 5 cm margin. Each tick at ``dt = 1 ms`` (paced in real
   time): joint state, every pair's distance (``Scene.query_all``), the avoidance
   points (``SceneConverter``) and the controller step, timed as one (``loop.tick``;
   the kinematic plant's integration is not part of it); the robot shuttles between
   the scenario's goals; ``loop.tick_cpu`` is the CPU time the loop's thread spent in
   the tick (wall time minus the time the machine gave to others). Also: each
   ``replace_cloud`` call on the camera thread
   (``handoff``: the hand-over only), the clouds swapped in per second
   (``loop.swaps_per_s``), the queries answered while a build was running
   (``loop.ticks_during_build``) and, of those, the ticks longer than the 1 ms period
   (``loop.slow_ticks_during_build``) and the ones among them in which the loop's
   thread was kept from running by what a build can cause
   (``loop.ticks_waited_for_build``: it blocked on a lock, the GIL or a page fault, or
   — at normal priority — another thread took its core: :func:`slow_tick_classes`;
   the scene itself never waits — it takes a built cloud only when the worker does
   not hold the lock, ``loop.swaps_deferred``).
   Every tick over 1 ms is put in one class by the thread's context switches over it
   (Linux): ``loop.slow.waited`` (it blocked), ``loop.slow.preempted`` (another thread
   ran on its core) or ``loop.slow.charged`` (never switched out: the tick's own work,
   or a stall of the machine that charges the thread for time it did not run — see
   ``machine.stall`` below). Across those classes, ``loop.slow.faulted`` counts the
   slow ticks in which the loop's thread took a page fault (a fault waits while
   something holds the process's memory map write-locked, as the kernel's huge-page
   collapsing did before :func:`~reachwise.runtime.realtime.realtime_settings` turned
   it off); ``loop.page_faults`` and ``loop.ticks_faulted`` count them over the loop.
   Without example-robot-data (the ``robots`` extra) the loop runs the built-in
   ``panda`` (the same kinematics, published DH) with capsule-shaped link clouds and
   says so in the notes.
3. **The machine's own stalls**: a bare busy loop of clock reads as long as the loop
   ran (:func:`stall_gaps`): the longest time the machine kept a running thread from
   running its code while charging it CPU time (a virtual CPU the hypervisor paused).
   No tick can be shorter than a stall that falls into it.
4. **The server** (``reachwise.benchmarks.server.streaming_figures``, when present):
   a camera process streaming to ``reachwise serve`` at 30 Hz while this process
   queries at 1 kHz, and the protocol's work beyond a bare ZeroMQ echo.

The whole run keeps freed memory for reuse (glibc's trim and mmap thresholds raised:
:func:`reachwise.runtime.realtime.keep_freed_memory`; builds otherwise spend a third of
their time on page faults), and the loop runs inside
:func:`reachwise.runtime.realtime.realtime_settings` (the garbage collector's existing
objects frozen after setup, the GIL switch interval left at 5 ms, the loop
thread under ``SCHED_FIFO`` at :data:`LOOP_PRIORITY` where the OS permits it, as
libfranka and ros2_control run theirs, transparent huge pages off for the process so
that the kernel never write-locks its memory map to collapse them under a tick): see
the README's realtime section.

Targets: tick median ≤ 300 µs, p99.9 ≤ 1 ms, max ≤ 3 ms; 0 ticks waited
for a build; ≥ 29 swaps/s; hand-off p99 ≤ 2 ms; builds: 300 k ≤ 20 ms, 1 M ≤ 80 ms.
"""

from __future__ import annotations

import importlib
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from reachwise.benchmarks._harness import BenchReport, Target
from reachwise.benchmarks.realtime_builds import index_builds
from reachwise.benchmarks.realtime_probes import (
    DT,
    STALL_GAP,
    slow_tick_classes,
    stall_gaps,
    thread_counters,
)
from reachwise.benchmarks.realtime_room import (
    CAMERA_AT,
    CAMERA_LOOKS_AT,
    CAMERA_SIZE,
    FRAMES,
    ROOM,
    ROOM_POINTS,
    SHELF_PLATES,
    TABLE,
    camera_depth,
    camera_frame,
    camera_pose,
    room_points,
)
from reachwise.control.avoidance import SceneConverter
from reachwise.control.controller import Controller, ControllerConfig, Goal
from reachwise.control.safety import SafetyConfig
from reachwise.distance.scene import OnLink, Scene
from reachwise.errors import MissingDependency
from reachwise.runtime.realtime import keep_freed_memory, realtime_settings

__all__ = [
    "CAMERA_AT",
    "CAMERA_HZ",
    "CAMERA_LOOKS_AT",
    "CAMERA_SIZE",
    "DT",
    "FRAMES",
    "LOOP_PRIORITY",
    "MARGIN",
    "ROOM",
    "ROOM_POINTS",
    "SHELF_PLATES",
    "STALL_GAP",
    "TABLE",
    "CameraFeed",
    "camera_depth",
    "camera_frame",
    "camera_pose",
    "loop_scene",
    "room_points",
    "run",
    "slow_tick_classes",
    "stall_gaps",
    "thread_counters",
]

CAMERA_HZ = 30.0
#: The loop thread's SCHED_FIFO priority where permitted (ros2_control's default, 50).
LOOP_PRIORITY = 50
MARGIN = 0.05  # m, the panda-shelf scenario's environment margin


# --------------------------------------------------------------------------- the loop


@dataclass
class _Arm:
    scene: Scene
    robot: Any
    controller: Controller
    converter: SceneConverter
    goals: list[Goal]
    q: NDArray[np.float64]
    real: bool
    #: The controller's margin of each of the scene's pairs where it differs from the
    #: scene's (a scenario watches its pairs out to margin + monitor range).
    margins: dict[tuple[str, str], float]


def _real_arm() -> _Arm:
    """The panda-shelf scenario's world (example-robot-data Panda, automatic pairs)."""
    from reachwise.sim.world import build_world

    world = build_world("panda-shelf", avoidance=True)
    if not isinstance(world.scene, Scene):
        raise TypeError("the panda-shelf world runs an in-process scene")
    agent = world.agents[0]
    cfg = agent.controller.config
    ctrl = Controller(agent.robot, replace(cfg, safety=replace(cfg.safety, dt=DT)))
    goals = [g for g, _ in agent.own]
    margins = {(p.a, p.b): float(m) for p, m in zip(world.scene.pairs, world.margins, strict=True)}
    return _Arm(
        world.scene,
        agent.robot,
        ctrl,
        agent.converter,
        goals,
        np.array(agent.plant.q),
        True,
        margins,
    )


def _builtin_arm() -> _Arm:
    """The built-in Panda (published DH) with capsule clouds around its links."""
    from reachwise.io.robot_file import load_robot

    robot = load_robot("panda")
    rng = np.random.default_rng(7)
    q0 = np.array([0.0, -0.6, 0.0, -2.2, 0.0, 1.7, 0.8])
    F = robot.fk_all(q0)
    scene = Scene()
    scene.add_robot(robot, q0)
    for k in range(1, len(robot.link_names) - 1):
        end = np.linalg.solve(F[k], F[k + 1][:, 3])[:3]
        t = rng.uniform(0.0, 1.0, size=(1000, 1))
        d = rng.normal(size=(1000, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        link = robot.link_names[k]
        scene.add_object(f"arm/{link}", t * end + 0.06 * d, robot=robot.name, link=link)
    scene.watch_self(robot.name, 0.025)
    ctrl = Controller(robot, ControllerConfig(safety=SafetyConfig(dt=DT)))
    goals = [Goal.at([0.45, -0.2, 0.45]), Goal.at([0.25, 0.3, 0.7])]
    return _Arm(scene, robot, ctrl, SceneConverter(scene, robot), goals, q0, False, {})


def _arm() -> tuple[_Arm, str]:
    try:
        return _real_arm(), "example-robot-data Panda (panda-shelf scenario)"
    except MissingDependency as exc:
        return _builtin_arm(), f"built-in panda with capsule clouds ({exc})"


def loop_scene(
    room: NDArray[np.float64], camera: NDArray[np.floating[Any]]
) -> tuple[_Arm, SceneConverter, str]:
    """The loop's world: the arm (:func:`_arm`), the ``room`` scan and a first
    ``camera`` frame, links 1–7 watched against both at :data:`MARGIN` (the base stands
    on the floor), and the converter that gives the controller each pair's own margin
    (the scenario's pairs are watched out to their margin plus its monitor range)."""
    arm, which = _arm()
    scene, robot = arm.scene, arm.robot
    scene.add_object("room", room)
    scene.add_object("camera", camera)
    for o in scene.robot_objects(robot.name):
        link = o.source.link if isinstance(o.source, OnLink) else ""
        if link == robot.link_names[0]:
            continue  # the base stands on the floor
        scene.watch(o.name, "room", MARGIN, kind="robot-environment")
        scene.watch(o.name, "camera", MARGIN, kind="robot-environment")
    converter = SceneConverter(
        scene, robot, tool_links=arm.converter.tool_links, margins=arm.margins
    )
    return arm, converter, which


#: What the camera thread hands over: ``feed(scene, k, stamp)`` puts frame ``k`` (taken
#: at ``stamp``, s) into the scene's ``camera`` object.
CameraFeed = Callable[[Scene, int, float], None]


def _loop(
    rep: BenchReport,
    quick: bool,
    feed: CameraFeed | None = None,
    first: NDArray[np.float64] | None = None,
) -> None:
    """The 1 kHz loop (module docstring, 2.); ``feed`` replaces the camera thread's
    hand-over of each frame's points, ``first`` the first frame's points."""
    frames = [camera_frame(k) for k in range(FRAMES)] if feed is None else []
    arm, converter, which = loop_scene(room_points(), frames[0] if first is None else first)
    scene, robot = arm.scene, arm.robot
    ctrl = arm.controller
    q = arm.q.copy()
    duration = 3.0 if quick else 10.0
    ticks = int(duration / DT)
    tick_us = np.empty(ticks)
    cpu_us = np.empty(ticks)
    during = np.zeros(ticks, np.bool_)
    # voluntary and involuntary context switches, page faults
    switched = np.zeros((ticks, 3), np.int64)
    handoff: list[float] = []
    goal_index = 0
    reached = 0
    stopped = 0
    stop = threading.Event()
    start = time.perf_counter()

    # warm up (compile, fill caches) before the settings freeze what exists
    scene.set_joints(robot.name, q, stamp=0.0)
    ctrl.step(q, arm.goals[0], converter(scene.query_all(), stamp=0.0), 0.0)
    ctrl.reset()
    thread = _camera_thread(scene, feed, frames, stop, handoff, lambda: start)
    swaps0, deferred0, during0 = scene.swaps, scene.swaps_deferred, scene.queries_during_build
    clock = time.perf_counter_ns
    cpu = time.thread_time_ns
    switches, counted = thread_counters()
    with realtime_settings(priority=LOOP_PRIORITY) as applied:
        thread.start()
        try:
            start = time.perf_counter()
            for k in range(ticks):
                due = start + k * DT
                pause = due - time.perf_counter()
                if pause > 0:
                    time.sleep(pause)
                now = time.perf_counter() - start
                goal = arm.goals[goal_index]
                building = scene.ingest.building is not None
                s0 = switches()
                c0 = cpu()
                t0 = clock()
                scene.set_joints(robot.name, q, stamp=now)
                res = scene.query_all()
                pts = converter(res, stamp=now)
                cmd, status = ctrl.step(q, goal, pts, now)
                tick_us[k] = (clock() - t0) * 1e-3
                cpu_us[k] = (cpu() - c0) * 1e-3
                switched[k] = np.subtract(switches(), s0)
                during[k] = building or scene.ingest.building is not None
                if status.state == "reached":
                    goal_index = (goal_index + 1) % len(arm.goals)
                    reached += 1
                elif status.state == "protective_stop":
                    stopped += 1
                q = np.clip(q + cmd * DT, robot.lower, robot.upper)
            elapsed = time.perf_counter() - start
        finally:
            stop.set()
            thread.join()
    scene.close()
    run = _LoopRun(
        tick_us, cpu_us, during, switched, handoff, reached, stopped, elapsed,
        scene.swaps - swaps0, scene.swaps_deferred - deferred0,
        scene.queries_during_build - during0, counted,
    )  # fmt: skip
    _report_loop(rep, run, scene, applied, which)


@dataclass(frozen=True)
class _LoopRun:
    """What the 1 kHz loop measured: per tick its wall and CPU time (µs), whether a
    build ran, its context switches and page faults; the hand-overs (µs); goals
    reached, protective stops, the loop's length (s); the scene's swaps, deferred
    swaps and queries answered during a build over the loop; whether the platform
    counts context switches."""

    tick_us: NDArray[np.float64]
    cpu_us: NDArray[np.float64]
    during: NDArray[np.bool_]
    switched: NDArray[np.int64]
    handoff: list[float]
    reached: int
    stopped: int
    elapsed: float
    swaps: int
    deferred: int
    during_build: int
    counted: bool


def _camera_thread(
    scene: Scene,
    feed: CameraFeed | None,
    frames: list[NDArray[np.float32]],
    stop: threading.Event,
    handoff: list[float],
    origin: Callable[[], float],
) -> threading.Thread:
    """The camera thread: at :data:`CAMERA_HZ` until ``stop``, the next of ``frames``
    into the scene's ``camera`` object (or ``feed``), stamped in seconds since
    ``origin()``, each hand-over's time (µs) appended to ``handoff``."""

    def camera() -> None:
        k = 1
        due = time.perf_counter()
        while not stop.is_set():
            due += 1.0 / CAMERA_HZ
            pause = due - time.perf_counter()
            if pause > 0:
                time.sleep(pause)
            t0 = time.perf_counter()
            if feed is None:
                scene.replace_cloud("camera", frames[k % FRAMES], stamp=t0 - origin())
            else:
                feed(scene, k, t0 - origin())
            handoff.append((time.perf_counter() - t0) * 1e6)
            k += 1

    return threading.Thread(target=camera, name="bench-camera", daemon=True)


def _report_loop(rep: BenchReport, run: _LoopRun, scene: Scene, applied: Any, which: str) -> None:
    """The loop's figures, targets and note into ``rep``."""
    tick_us, cpu_us, handoff, elapsed = run.tick_us, run.cpu_us, run.handoff, run.elapsed
    swaps = run.swaps
    rep.add_samples("loop.tick", tick_us)
    worst = int(np.argmax(tick_us))
    rep.metrics["loop.tick.max"] = float(tick_us[worst])
    # the worst tick's CPU time and place: our work (CPU ≈ wall) or the machine's
    rep.metrics["loop.tick.max_cpu"] = float(cpu_us[worst])
    rep.metrics["loop.tick.max_at"] = float(worst)
    rep.add_samples("loop.tick_cpu", cpu_us)
    rep.metrics["loop.pairs"] = float(len(scene.pairs))
    rep.metrics["loop.swaps"] = float(swaps)
    rep.metrics["loop.swaps_per_s"] = swaps / elapsed
    rep.metrics["loop.handoffs"] = float(len(handoff))
    rep.metrics["loop.swaps_deferred"] = float(run.deferred)
    rep.metrics["loop.ticks_during_build"] = float(run.during_build)
    classes = slow_tick_classes(
        tick_us, run.during, run.switched, fifo=applied.priority is not None, counted=run.counted
    )
    rep.metrics.update({f"loop.{k}": v for k, v in classes.items()})
    waited = int(classes["ticks_waited_for_build"])
    if not run.counted:
        rep.notes.append("loop: no per-thread context-switch counts on this platform")
    rep.metrics["loop.goals_reached"] = float(run.reached)
    rep.metrics["loop.fifo_priority"] = float(applied.priority or 0)
    rep.metrics["loop.huge_pages_off"] = float(applied.huge_pages_off)
    rep.metrics["loop.protective_stops"] = float(run.stopped)
    rep.metrics["loop.superseded"] = float(scene.ingest.superseded)
    rep.add_samples("handoff", np.array(handoff))
    rep.metrics["handoff.max"] = float(max(handoff))
    rep.targets["tick_median"] = Target(rep.metrics["loop.tick.median"], 300.0)
    rep.targets["tick_p99_9"] = Target(rep.metrics["loop.tick.p99_9"], 1000.0)
    rep.targets["tick_max"] = Target(rep.metrics["loop.tick.max"], 3000.0)
    rep.targets["ticks_waited_for_build"] = Target(float(waited), 0.0)
    rep.targets["swaps_per_s"] = Target(rep.metrics["loop.swaps_per_s"], 29.0, True)
    rep.targets["handoff_p99"] = Target(rep.metrics["handoff.p99"], 2000.0)
    rep.notes.append(
        f"loop: {which}; {len(scene.pairs)} pairs; {len(tick_us)} ticks at dt = 1 ms paced in real "
        f"time ({elapsed:.1f} s); a {CAMERA_SIZE[0]}x{CAMERA_SIZE[1]} camera frame handed "
        f"over {CAMERA_HZ:g} times a second from another thread; room {ROOM_POINTS} points; "
        + (
            f"the loop thread under SCHED_FIFO at priority {applied.priority}"
            if applied.priority is not None
            else f"the loop thread at normal priority (SCHED_FIFO {applied.refused})"
        )
        + ("; transparent huge pages off" if applied.huge_pages_off else "")
    )


# --------------------------------------------------------------------------- the machine


def _machine(rep: BenchReport, quick: bool) -> None:
    """How long the machine itself stops a running thread: a bare busy loop of clock
    reads (:func:`stall_gaps`), as long as the loop ran, right after it. A tick can
    never be shorter than a stall that falls into it."""
    seconds = 3.0 if quick else 10.0
    wall, cpu = stall_gaps(seconds)
    stalls = wall[cpu >= 0.9 * wall]
    rep.metrics["machine.seconds"] = seconds
    rep.metrics["machine.stall.max"] = float(stalls.max()) if stalls.size else 0.0
    rep.metrics["machine.stalls_over_1ms"] = float(np.count_nonzero(stalls > 1000.0))
    rep.metrics["machine.stalls_over_3ms"] = float(np.count_nonzero(stalls > 3000.0))
    rep.metrics["machine.preempted.max"] = float(wall[cpu < 0.9 * wall].max(initial=0.0))
    rep.notes.append(
        f"machine: a bare busy loop of clock reads for {seconds:g} s after the loop (no "
        "other work): the longest gap between two reads with the thread's CPU clock "
        "running (machine.stall.max: the virtual CPU not running it) and without "
        "(machine.preempted.max: another thread ran)"
    )


# --------------------------------------------------------------------------- server


def _server(rep: BenchReport, quick: bool) -> None:
    """The server section: ``reachwise.benchmarks.server.streaming_figures`` (the
    stream helper's: a camera process streaming 300 000-point clouds at 30 Hz to
    ``reachwise serve`` while this process queries at 1 kHz, and the protocol's own
    work beyond a bare ZeroMQ echo), its figures prefixed ``server.``."""
    server = importlib.import_module("reachwise.benchmarks.server")
    figures = getattr(server, "streaming_figures", None)
    if figures is None:
        rep.notes.append(
            "server section: not measured (reachwise.benchmarks.server has no "
            "streaming_figures on this branch); see `reachwise bench server`"
        )
        return
    got: dict[str, Any] = figures(quick=quick)
    for k, v in got.get("metrics", {}).items():
        rep.metrics[f"server.{k}"] = float(v)
    for k, v in got.get("ratios", {}).items():
        rep.ratios[f"server.{k}"] = float(v)
    for k, t in got.get("targets", {}).items():
        value, limit = float(t["value"]), float(t["limit"])
        at_least = bool(t["met"]) != (value <= limit)  # a "≥" target
        rep.targets[f"server.{k}"] = Target(value, limit, at_least)
    rep.notes.extend(n if n.startswith("server") else f"server: {n}" for n in got.get("notes", []))


def run(quick: bool = False) -> BenchReport:
    """Builds, the 1 kHz loop with a live camera cloud, and the server section (see
    the module docstring)."""
    rep = BenchReport("realtime")
    kept = keep_freed_memory()
    rep.notes.append(f"freed memory kept for reuse (glibc mallopt): {kept}")
    index_builds(rep, quick)
    _loop(rep, quick)
    _machine(rep, quick)
    _server(rep, quick)
    return rep
