"""Top-level conveniences that need several layers (re-exported by ``reachwise``).

The math layers take objects: ``reachwise.synthesis.synthesize`` wants a ``Task`` and a
template ``Robot``. A user thinks in names and files (``"tunnel-87"``, ``"sb60"``,
``my-boom.yaml``); this facade resolves them with the ``io`` loaders and calls the math
layer, so nothing below ``io`` ever reads a file.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, Unpack

from reachwise.errors import InputError
from reachwise.geometry.cloud import PointCloud
from reachwise.io.robot_clouds import link_clouds as link_clouds_of
from reachwise.io.robot_file import load_robot
from reachwise.io.ros.replay import ReplayResult, ReplaySpec, replay_recording
from reachwise.io.task_file import load_task
from reachwise.kinematics.robot import Robot
from reachwise.report.replay import write_replay_outputs
from reachwise.server.client.owned import ServerOptions, owned_scene
from reachwise.sim.bag_recorder import BagRecorder
from reachwise.sim.log import SimulationLog
from reachwise.sim.plant import PlantName
from reachwise.sim.resolve import ResolvedScenario, resolve_scenario
from reachwise.sim.run_options import RunKeywords, RunOptions, run_options
from reachwise.sim.scenarios import Scenario
from reachwise.sim.simulate import run_world
from reachwise.sim.world import SceneFactory, SimClock, build_world
from reachwise.synthesis.synthesize import SynthesisResult
from reachwise.synthesis.synthesize import synthesize as synthesize_objects
from reachwise.tasks.task import Task

__all__ = ["replay", "resolve_design", "server_scene", "simulate", "synthesize"]


def synthesize(
    task: Task | str | Path,
    template: Robot | str | Path,
    *,
    runs: int = 10,
    seed: int = 0,
    objective: Mapping[str, float] | None = None,
    **options: Any,
) -> SynthesisResult:
    """Dimensional synthesis (P-I §3–4, P-II §4) of ``template`` for ``task``.

    ``task``: a ``Task``, a built-in task name (``tunnel-87``) or a task file;
    ``template``: a ``Robot`` with a ``design`` section, a built-in robot name (``sb60``)
    or a robot file. ``runs`` multi-start runs, run ``i`` with seed ``seed + i``.
    ``objective`` maps design objectives (``gci``, ``kci``, ``size``, ``limits``,
    ``bounds``; ``reachwise.synthesis.objectives``) to weights: a run that reaches every
    pose then improves its design for them, keeping every pose reached; ``None`` takes
    the template's ``design.objective``. Further ``options`` (``solver``, ``init_sets``,
    ``locked``, ``workspace``, ``options``, ``on_run``, ``improve_options``, or all of
    them as one ``settings`` group, ``SynthesisSettings``) go to
    ``reachwise.synthesis.synthesize.synthesize``; with ``settings``, ``runs``, ``seed``
    and ``objective`` override its fields only when given other than their defaults.
    """
    t, robot = resolve_design(task, template)
    keywords: dict[str, Any] = {"runs": runs, "seed": seed, "objective": objective}
    if options.get("settings") is not None:
        # with a settings group, only the keywords given other than their defaults
        # override its fields
        defaults = {"runs": 10, "seed": 0, "objective": None}
        keywords = {k: v for k, v in keywords.items() if v != defaults[k]}
    return synthesize_objects(t, robot, **keywords, **options)


def resolve_design(task: Task | str | Path, template: Robot | str | Path) -> tuple[Task, Robot]:
    """The resolve stage of a synthesis, as ``reachwise.sim.resolve.resolve_scenario``
    is a simulation's: the task and the template robot read and checked once (a
    built-in name or a file; objects pass through), so that the synthesis itself
    reads no file."""
    t = task if isinstance(task, Task) else load_task(task)
    robot = template if isinstance(template, Robot) else load_robot(template)
    return t, robot


def replay(
    bag: str | Path,
    robot: Robot | str | Path,
    *,
    clouds: str | Sequence[str],
    joints: str = "/joint_states",
    margin: float = 0.05,
    out: str | Path | None = None,
    tip: str | None = None,
    link_clouds: Mapping[str, PointCloud] | None = None,
    results_bag: str | None = "auto",
    **spec: Any,
) -> ReplayResult:
    """Replay a recorded cell (a ROS 1 ``.bag``, a ROS 2 bag folder or ``.db3``/``.mcap``
    file; the ``ros`` extra) through the distance scene: per frame the smallest distance
    of every pair of a robot link and a cloud topic.

    ``robot``: a ``Robot``, a built-in name or a robot file (``tip`` for a branched
    URDF); its joints are matched by name on the ``joints`` topic. ``clouds``: the
    PointCloud2 or depth-image topics. ``link_clouds`` (link → cloud in the link frame;
    default ``reachwise.link_clouds(robot)``). Frames closer than ``margin`` (m) are
    near. With ``out``, the files of ``reachwise replay`` are written there
    (``distances.csv``, ``near.csv``, ``summary.json``, ``report.html`` and the
    ``results_bag``: ``.bag`` ROS 1, ``.mcap`` MCAP, else ROS 2 sqlite3; ``"auto"``:
    ``results.bag`` for a ROS 1 recording, else ``results.mcap``; None: none).
    Further ``spec`` options (``frame``, ``camera_info``, ``links``, ``every``,
    ``block``, ``rate``, ``voxel``, ``tf_tolerance``) go to
    ``reachwise.io.ros.replay.ReplaySpec``.
    """
    model = robot if isinstance(robot, Robot) else load_robot(robot, tip=tip)
    topics = (clouds,) if isinstance(clouds, str) else tuple(clouds)
    options = ReplaySpec(joints=joints, clouds=topics, margin=margin, **spec)
    carried = link_clouds_of(model) if link_clouds is None else link_clouds
    result = replay_recording(bag, model, options, link_clouds=carried)
    if out is not None:
        inputs = {"joints": joints, "clouds": list(topics), "robot": model.name}
        write_replay_outputs(result, out, inputs, results_bag=results_bag)
    return result


def server_scene(server: str | ServerOptions) -> SceneFactory:
    """A ``SceneFactory`` (``reachwise.sim.world``) for a simulation on the collision
    server ``server`` (an address or ``reachwise.server.client.ServerOptions``):
    a client that owns the server's scene (it clears it, registers the scenario's and
    sends the inputs with each query), stamped with the simulation's clock."""

    def make(clock: Callable[[], float] | None) -> Any:
        return owned_scene(server, clock or time.monotonic)

    return make


def simulate(
    scenario: ResolvedScenario | Scenario | str | Path,
    avoidance: bool = True,
    *,
    plant: PlantName = "scenario",
    server: str | ServerOptions | None = None,
    bag: str | Path | None = None,
    options: RunOptions | None = None,
    **keywords: Unpack[RunKeywords],
) -> SimulationLog:
    """Run ``scenario`` (a built-in name, a file, a ``Scenario`` or a resolved one) in
    simulated time, in three stages, each once: *resolve* (every file read and checked,
    ``reachwise.sim.resolve.resolve_scenario``), *build* (the world from that object
    alone, ``reachwise.sim.world.build_world``) and *run* (the loop,
    ``reachwise.sim.simulate.run_world``). ``plant`` and the run's options (one
    ``options`` group, ``reachwise.sim.run_options.RunOptions``: ``duration``,
    ``progress``, ``on_tick``, ``static_world``, ``escape``, ``recorder``; or its
    fields as keywords, which override the group's) are those of
    ``reachwise.sim.simulate.simulate``; ``server`` (an address or
    ``reachwise.server.client.ServerOptions``) runs the distance queries on that
    collision server instead of in process (:func:`~reachwise.api.server_scene`).

    ``bag`` (a path that does not exist yet: ``.bag`` for ROS 1, ``.mcap`` for MCAP,
    else ROS 2 sqlite3; the ``ros`` extra) also writes the run as a recording, as
    ``reachwise simulate --bag`` does (``reachwise.sim.bag_recorder.BagRecorder``: joint states, the
    cameras' depth images, CameraInfo and clouds, TF), for :func:`replay` to read
    back; it replaces ``recorder``, so give one or the other."""
    run = run_options(options, keywords)
    if bag is not None:
        if run.recorder is not None:
            raise InputError("simulate", "bag", "give bag or recorder, not both")
        if Path(bag).exists():
            raise InputError(str(bag), "bag", "exists already; not overwriting a recording")
    resolved = resolve_scenario(scenario)
    clock = SimClock()
    make_scene = None if server is None else server_scene(server)
    world = build_world(resolved, avoidance, plant=plant, make_scene=make_scene, clock=clock)
    writer = BagRecorder(bag) if bag is not None else None
    try:
        return run_world(world, clock, run, recorder=writer or run.recorder)
    finally:
        if writer is not None:
            writer.close()
