"""``reachwise bench control``: the cost of one control tick of the thesis experiments.

For ``p3-self-collision`` and ``p5-crane-obstacle`` the closed loop runs for 10 000
ticks (``--quick``: 1 000) with avoidance, the robots shuttling between their goals
(each reached goal is followed by the next one, cyclically). Per tick we time

- ``<scenario>.tick``: the whole tick — forward kinematics and every watched pair's
  distance (``Scene.query_all``), the conversion into avoidance points and the
  controller step (the plant integration and the logging are not part of it);
- ``<scenario>.controller``: the controller step alone.

Targets: tick median ≤ 1 ms and p99.9 ≤ 10 ms (P-V's 10 ms sample time),
controller median ≤ 100 µs.

``panda-shelf`` (when the ``robots`` extra is installed): a real arm, the
example-robot-data Panda with its collision meshes, every link a 1000-point cloud (the
scenario pins the count its margins were tuned on), automatic self-collision pairs and
a ≈2800-point scan of a shelf. Targets: tick median
≤ 300 µs, p99.9 ≤ 1 ms.
"""

from __future__ import annotations

import time

import numpy as np

from reachwise.benchmarks._harness import BenchReport, Target

SCENARIOS = ("p3-self-collision", "p5-crane-obstacle")
#: The real-arm scenario and its tick targets (µs): median, p99.9.
REAL_ARM = ("panda-shelf", 300.0, 1000.0)


def _run(name: str, ticks: int) -> tuple[np.ndarray, np.ndarray, int]:
    from reachwise.sim.world import build_world

    world = build_world(name, avoidance=True)
    agents = world.agents
    cycle = {a.name: [g for g, _ in a.own] for a in agents}
    idx = dict.fromkeys(cycle, 0)
    dt = world.scenario.spec.dt
    scene = world.scene
    tick_us = np.empty(ticks)
    ctrl_us = np.empty(ticks)
    clock = time.perf_counter_ns
    reached = 0
    # warm-up: compile and fill caches outside the timed loop
    for a in agents:
        scene.set_joints(a.name, a.plant.q)
    res = scene.query_all()
    for a in agents:
        if cycle[a.name]:
            a.controller.step(a.plant.q, cycle[a.name][0], a.converter(res, stamp=0.0), 0.0)
            a.controller.reset()
    for k in range(ticks):
        t = (k + 1) * dt
        cmds = []
        t0 = clock()
        for a in agents:
            scene.set_joints(a.name, a.plant.q)
        res = scene.query_all()
        c_ns = 0
        for a in agents:
            goals = cycle[a.name]
            if not goals:
                cmds.append(np.zeros(a.robot.n))
                continue
            pts = a.converter(res, stamp=t)
            c0 = clock()
            cmd, st = a.controller.step(a.plant.q, goals[idx[a.name]], pts, t)
            c_ns += clock() - c0
            cmds.append(cmd)
            if st.state == "reached":
                idx[a.name] = (idx[a.name] + 1) % len(goals)
                reached += 1
        tick_us[k] = (clock() - t0) * 1e-3
        ctrl_us[k] = c_ns * 1e-3
        for a, cmd in zip(agents, cmds, strict=True):
            a.plant.step(cmd, dt)
    return tick_us, ctrl_us, reached


def run(quick: bool = False) -> BenchReport:
    """Time the control tick of the P-III, P-V and real-arm scenarios (see the module
    docstring)."""
    from reachwise.errors import MissingDependency

    ticks = 1_000 if quick else 10_000
    rep = BenchReport("control")
    real, real_median, real_p999 = REAL_ARM
    for name in (*SCENARIOS, real):
        try:
            tick, ctrl, reached = _run(name, ticks)
        except MissingDependency as exc:
            rep.notes.append(f"{name} left out: {exc}")
            continue
        median, p999 = (real_median, real_p999) if name == real else (1000.0, 10_000.0)
        rep.add_samples(f"{name}.tick", tick)
        rep.add_samples(f"{name}.controller", ctrl)
        rep.metrics[f"{name}.goals_reached"] = float(reached)
        rep.targets[f"{name}.tick.median"] = Target(rep.metrics[f"{name}.tick.median"], median)
        rep.targets[f"{name}.tick.p99_9"] = Target(rep.metrics[f"{name}.tick.p99_9"], p999)
        rep.targets[f"{name}.controller.median"] = Target(
            rep.metrics[f"{name}.controller.median"], 100.0
        )
    rep.notes.append(
        f"{ticks} closed-loop ticks per scenario with avoidance, robots shuttling between "
        "their goals; tick = FK + all pair distances + conversion + controller step"
    )
    return rep
