"""A scenario built for running: :func:`build_world` turns a
:class:`~reachwise.sim.scenarios.Scenario` into robots, plants, controllers, the distance
scene (in process or on a collision server), solids, watched pairs and moving objects."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from reachwise.control.avoidance import SceneConverter
from reachwise.control.controller import Controller, ControllerConfig, Goal
from reachwise.control.safety import SafetyConfig
from reachwise.distance.scene import Scene, SceneLike, WatchedPair
from reachwise.distance.scene_memories import memory_margin
from reachwise.errors import InputError, check_choice
from reachwise.kinematics.robot import Robot
from reachwise.sim.contact import Solid
from reachwise.sim.memory_feed import MemoryFeed, body_pieces
from reachwise.sim.movers import MovingObject, moving_object, object_cloud
from reachwise.sim.plant import PLANT_NAMES, Plant, PlantConfig, PlantName
from reachwise.sim.resolve import (
    ResolvedScenario,
    box_solid,
    resolve_scenario,
    unknown,
)
from reachwise.sim.scenarios import (
    GoalSpec,
    RobotSpec,
    Scenario,
    WatchSpec,
)
from reachwise.sim.sensors import BodySurface, DepthSensor, ObjectSurface, Sight

if TYPE_CHECKING:
    from reachwise.sim.mujoco_plant import MujocoPlant


__all__ = ["Agent", "SceneFactory", "Twists", "World", "build_world"]

#: Makes the distance scene a world is built in, given the clock that stamps its inputs
#: and answers (``None``: its own). The caller chooses: an in-process
#: :class:`~reachwise.distance.scene.Scene` by default, or a client of a collision
#: server that owns the server's scene (``reachwise.server.client.owned_scene``), which
#: has the same interface (``SceneLike``), so the world, the converters and the
#: controllers use it unchanged.
SceneFactory = Callable[[Callable[[], float] | None], SceneLike]

#: The moving objects' twists at one tick, ``{name: (v, ω, origin)}`` (world frame).
Twists = dict[str, tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]]


@dataclass(eq=False)
class Agent:
    """One robot's run-time state in the simulation."""

    name: str
    robot: Robot
    controller: Controller
    plant: Plant | MujocoPlant
    converter: SceneConverter
    own: list[tuple[Goal, GoalSpec]]
    jobs: bool
    goal: Goal | None = None
    spec: GoalSpec | None = None
    record: int = -1
    job: int = -1
    locked_until: float = -math.inf
    stalled: bool = False
    stopped: bool = False


@dataclass(eq=False)
class World:
    """A built scenario: robots, scene, solids and watched pairs, ready to run."""

    scenario: Scenario
    scene: SceneLike
    robots: dict[str, Robot]
    agents: list[Agent]
    pairs: tuple[str, ...]
    margins: NDArray[np.float64]
    solids: dict[str, tuple[Solid, str, str]]  # object -> (solid, robot, link)
    jobs: list[tuple[Goal, GoalSpec]]
    movers: list[MovingObject] = field(default_factory=list)
    sensors: list[DepthSensor] = field(default_factory=list)
    memories: list[MemoryFeed] = field(default_factory=list)  # fed by the sensors
    sight: Sight | None = None  # what the sensors see (None: no sensors, no hidden objects)
    truth: tuple[tuple[str, str], ...] = ()  # (robot link, object outside the scene) pairs
    resolved: ResolvedScenario | None = None  # what the world was built from
    avoidance: bool = True  # the controllers avoid collisions (False: the baseline)
    plant: PlantName = "scenario"  # every robot's own plant, or "mujoco" for all


def _controller_config(spec: RobotSpec, dt: float, avoidance: bool) -> ControllerConfig:
    c = spec.controller.model_dump(exclude_none=True)
    safety = {k: c.pop(k) for k in ("max_age_ticks", "stop_ticks") if k in c}
    return ControllerConfig(avoidance=avoidance, safety=SafetyConfig(dt=dt, **safety), **c)


def build_world(
    scenario: ResolvedScenario | Scenario | str | Path,
    avoidance: bool = True,
    *,
    plant: PlantName = "scenario",
    make_scene: SceneFactory | None = None,
    clock: Callable[[], float] | None = None,
) -> World:
    """The second stage of a run: the world of a resolved scenario
    (:func:`reachwise.sim.resolve.resolve_scenario`, called here on a name, a file or
    a ``Scenario``), built from that object alone: no file is read here.

    Robots, clouds (links, meshes, files, the scanner), scene, controllers, plants
    (``plant``: ``"scenario"`` — each robot's own — or ``"mujoco"``, see
    :mod:`reachwise.sim.mujoco_plant`). The distance scene is ``make_scene(clock)``
    (:data:`SceneFactory`; default: in process); ``clock`` stamps its inputs and answers.

    The steps: the scene, the robots and their link clouds
    (:func:`_add_robots`), the other objects (:func:`_add_objects`), the sensors and
    what they see (:func:`_add_sensors`), the watched pairs (:func:`_watch_pairs`), one
    agent per robot (:func:`_make_agent`) and the shared jobs (:func:`_shared_jobs`)."""
    plant = check_choice(plant, PLANT_NAMES, source="simulate", kind="plant")
    res = resolve_scenario(scenario)
    scene = Scene(clock=clock) if make_scene is None else make_scene(clock)
    return _assemble(scene, res, avoidance, plant)


def _assemble(scene: SceneLike, res: ResolvedScenario, avoidance: bool, plant: PlantName) -> World:
    """Fill ``scene`` with the scenario and make the agents (see :func:`build_world`)."""
    sc = res.scenario
    robots, solids = _add_robots(scene, res)
    movers = _add_objects(scene, res, solids)
    sight, sensors, memories = _add_sensors(scene, res, movers)
    inflation = {m.name: m.inflation for m in memories}
    for obj, (cloud, _) in res.link_clouds.items():  # conservative by the cloud's coverage
        if cloud.resolution > 0.0:
            inflation[obj] = cloud.resolution
    control = _watch_pairs(scene, res, inflation)
    job_robots = set(sc.spec.jobs.robots) if sc.spec.jobs is not None else set()
    agents = [
        _make_agent(
            scene,
            sc,
            rs,
            robots[rs.name],
            control,
            avoidance,
            plant,
            job_robots,
            res.link_meshes.get(rs.name),
        )
        for rs in sc.spec.robots
    ]
    jobs = _shared_jobs(sc, robots)
    pairs = tuple(f"{p.a}|{p.b}" for p in scene.pairs)
    margins = np.array([control[(p.a, p.b)] for p in scene.pairs], dtype=float)
    hidden = [o.name for o in sc.spec.objects if not o.scene]
    truth = tuple((b, o) for b in (sight.bodies if sight else {}) for o in hidden)
    return World(
        sc, scene, robots, agents, pairs, margins, solids, jobs, movers, sensors, memories,
        sight, truth, res, avoidance, plant,
    )  # fmt: skip


def _add_robots(
    scene: SceneLike, res: ResolvedScenario
) -> tuple[dict[str, Robot], dict[str, tuple[Solid, str, str]]]:
    """Every robot of the scenario with its joint state and one cloud per link (named
    ``robot/link``), and the solid of each link cloud for the contact check."""
    robots: dict[str, Robot] = {}
    solids: dict[str, tuple[Solid, str, str]] = {}
    for rs in res.scenario.spec.robots:
        robot = robots[rs.name] = res.robots[rs.name]
        scene.add_robot(robot, rs.start)
        prefix = f"{rs.name}/"
        for obj, (cloud, solid) in res.link_clouds.items():
            if obj.startswith(prefix):
                link = obj[len(prefix) :]
                scene.add_object(obj, cloud, robot=rs.name, link=robot.frame_of(link))
                solids[obj] = (solid, rs.name, link)
    return robots, solids


def _add_objects(
    scene: SceneLike, res: ResolvedScenario, solids: dict[str, tuple[Solid, str, str]]
) -> list[MovingObject]:
    """The clouds not on a robot (a box also gets its solid); returns the ones that
    move or change their cloud during the run."""
    movers: list[MovingObject] = []
    for os_ in res.scenario.spec.objects:
        mover = moving_object(os_, res)
        if not os_.scene:  # only the sensors see it
            if mover is not None:
                movers.append(mover)
            continue
        moving = mover is not None and mover.trajectory is not None
        pose = mover.trajectory.pose(0.0) if moving else os_.pose.matrix()  # type: ignore[union-attr]
        scene.add_object(os_.name, object_cloud(res, os_, os_.seed), pose, dynamic=moving)
        solid = box_solid(os_.box)
        if solid is not None:
            solids[os_.name] = (solid, "", "")
        if mover is not None:
            movers.append(mover)
    return movers


def _add_sensors(
    scene: SceneLike, res: ResolvedScenario, movers: list[MovingObject]
) -> tuple[Sight | None, list[DepthSensor], list[MemoryFeed]]:
    """What the sensors see (:class:`~reachwise.sim.sensors.Sight`: the surfaces of the
    objects and of the robots' links), and the sensors, each with its object in the
    scene holding frame 0. Nothing when the scenario has no sensors and no object
    outside the scene."""
    sc = res.scenario
    spec = sc.spec
    if not spec.sensors and all(o.scene for o in spec.objects):
        return None, [], []
    robots = dict(res.robots)
    trajectories = {m.spec.name: m.trajectory for m in movers}
    objects = {}
    for os_ in spec.objects:
        found = tuple(
            (t, mesh, solid) for t, (mesh, solid) in res.object_surfaces.get(os_.name, ())
        )
        if found:
            objects[os_.name] = ObjectSurface(
                os_.name, found, os_.pose.matrix(), trajectories.get(os_.name)
            )
    bodies = {}
    for name, (mesh, solid) in res.link_surfaces.items():
        rname, link = name.split("/", 1)
        index = robots[rname].link_index(link)
        bodies[name] = BodySurface(name, rname, link, index, mesh, solid)
    sight = Sight(robots, objects, bodies)
    qs = {rs.name: np.asarray(rs.start, dtype=float) for rs in spec.robots}
    pieces = body_pieces(sight.bodies.values()) if spec.memory else ()
    feeds = {m.name: MemoryFeed(m, pieces) for m in spec.memory}
    feed_of = {s: feeds[m.name] for m in spec.memory for s in m.sensors}
    sensors = []
    for i, ss in enumerate(spec.sensors):
        mount = robots[ss.link.robot] if ss.link is not None else None
        if ss.link is not None and mount is not None:
            if ss.link.link not in {*mount.body_names, *mount.link_names}:
                what = f"robot {ss.link.robot!r} has no link {ss.link.link!r}"
                where = f"sensors[{i}].link.link"
                raise unknown(sc.source, where, what, ss.link.link, mount.body_names)
        sensor = DepthSensor(ss, spec.dt, robots)
        sensor.feed = feed_of.get(ss.name)
        _check_outside(sc, i, sensor, sight, qs)
        sensor.start(scene, sight, qs)
        sensors.append(sensor)
    fk = sight.frames(qs)
    for feed in feeds.values():
        feed.flush(scene, fk)
    return sight, sensors, list(feeds.values())


def _check_outside(
    sc: Scenario, i: int, sensor: DepthSensor, sight: Sight, qs: dict[str, NDArray[np.float64]]
) -> None:
    """A camera inside a robot's link (at the start) would see nothing but that link."""
    fk = sight.frames(qs)
    origin = sensor.pose(fk)[:3, 3][None]
    for b in sight.bodies.values():
        if b.solid.depth(origin, fk[b.robot][b.index]) > 0.0:
            raise InputError(
                sc.source,
                f"sensors[{i}]",
                f"the camera {sensor.name!r} sits inside {b.name}: move it out of the link",
            )


def _watch_pairs(
    scene: SceneLike, res: ResolvedScenario, inflation: dict[str, float]
) -> dict[tuple[str, str], float]:
    """Watch the scenario's pairs: the scene's margin is rho_O + the monitor range (the
    log sees the pairs approach); returns each pair's rho_O, the controller's margin. A
    pair adds to both the ``inflation`` of each of its objects: a scene memory's (its
    voxels' reach beyond the points seen) and a link cloud's ``resolution`` (a cloud
    distance overstates the surface distance by up to that much), so the controller's
    distance is conservative: measured distance less the inflation against rho_O."""
    spec = res.scenario.spec
    control: dict[tuple[str, str], float] = {}
    for i, w in enumerate(spec.watch):
        listed = res.self_pairs.get(i)
        own = res.self_margins.get(i, {})
        margins = None if listed is None else {p: own.get(p, w.margin) for p in listed}
        made = _watch_rule(scene, res.scenario, margins, w, spec.monitor, f"watch[{i}]", inflation)
        for pair in made:
            rho = w.margin
            if margins is not None and w.self_ is not None:
                la, lb = pair.a[len(w.self_) + 1 :], pair.b[len(w.self_) + 1 :]
                rho = margins.get((la, lb), margins.get((lb, la), w.margin))
            control[(pair.a, pair.b)] = memory_margin(inflation, pair.a, pair.b, rho)
    return control


def _watch_rule(
    scene: SceneLike,
    sc: Scenario,
    listed: Mapping[tuple[str, str], float] | None,
    w: WatchSpec,
    monitor: float,
    where: str,
    inflation: dict[str, float],
) -> list[WatchedPair]:
    """The pairs one ``watch`` entry makes (self: the resolved link pairs ``listed``
    with their margins, or every non-adjacent pair; robot-environment or robot-robot),
    watched with margin + ``monitor`` (plus the ``inflation`` in the pair)."""
    made = []
    qm = w.margin + monitor
    if w.self_ is not None:
        if listed is not None:
            for (la, lb), rho in listed.items():
                a, b = f"{w.self_}/{la}", f"{w.self_}/{lb}"
                for o in (a, b):
                    if o not in scene.objects:
                        raise InputError(sc.source, where, f"no cloud {o!r}")
                qs = memory_margin(inflation, a, b, rho + monitor)
                made.append(scene.watch(a, b, qs, kind="self"))
        else:
            own = scene.robot_objects(w.self_)
            keep = {o.name for o in own}
            if w.links is not None:
                keep = {f"{w.self_}/{link}" for link in w.links}
            excl = [(o.name, p.name) for o in own for p in own if not {o.name, p.name} <= keep]
            made.extend(scene.watch_self(w.self_, qm, exclude=excl))
    elif w.environment is not None and w.robot is not None:
        mine = _robot_objects(scene, w.robot, w.links, sc.source, where)
        for o in mine:
            for e in w.environment:
                qe = memory_margin(inflation, o, e, qm)
                made.append(scene.watch(o, e, qe, kind="robot-environment"))
    elif w.robots is not None:
        ra, rb = w.robots
        for o in _robot_objects(scene, ra, w.links, sc.source, where):
            for p in _robot_objects(scene, rb, w.links, sc.source, where):
                made.append(scene.watch(o, p, qm, kind="robot-robot"))
    return made


def _make_agent(
    scene: SceneLike,
    sc: Scenario,
    rs: RobotSpec,
    robot: Robot,
    control: dict[tuple[str, str], float],
    avoidance: bool,
    plant: PlantName,
    job_robots: set[str],
    meshes: Mapping[str, Any] | None = None,
) -> Agent:
    """One robot's controller, scene converter, plant (a MuJoCo plant's link inertias
    from the resolved ``meshes``) and own goals."""
    try:
        cfg = _controller_config(rs, sc.spec.dt, avoidance)
    except InputError as exc:  # the controller's own checks name the scenario field
        where = f"robots.{rs.name}.controller.{exc.field}".rstrip(".")
        raise InputError(sc.source, where, exc.reason) from None
    except ValueError as exc:
        raise InputError(sc.source, f"robots.{rs.name}.controller", str(exc)) from None
    try:
        tl = rs.tool_links
        conv = SceneConverter(scene, robot, tool_links=tl, margins=control)
    except InputError as exc:
        raise InputError(sc.source, f"robots.{rs.name}.tool_links", str(exc)) from None
    pc = PlantConfig(**rs.plant.model_dump())
    own = [(_goal(g, robot), g) for g in rs.goals]
    return Agent(
        rs.name,
        robot,
        Controller(robot, cfg),
        _make_plant(plant, robot, rs.start, pc, meshes),
        conv,
        own,
        rs.name in job_robots,
    )


def _shared_jobs(sc: Scenario, robots: dict[str, Robot]) -> list[tuple[Goal, GoalSpec]]:
    """The scenario's shared job list (goals of the first job robot; a job without its
    own ``work`` time takes the list's)."""
    if sc.spec.jobs is None:
        return []
    first = robots[sc.spec.jobs.robots[0]]
    work = sc.spec.jobs.work
    return [
        (_goal(g, first), g if g.work > 0 else g.model_copy(update={"work": work}))
        for g in sc.spec.jobs.goals
    ]


def close_scene(scene: SceneLike) -> None:
    """Disconnect from a collision server (an in-process scene has nothing to close)."""
    scene.close()


class SimClock:
    """The simulated time (s); the scene stamps joint states and answers with it."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def _make_plant(
    kind: PlantName, robot: Robot, q0: list[float], pc: PlantConfig,
    meshes: Mapping[str, Any] | None = None,
) -> Plant | MujocoPlant:  # fmt: skip
    if kind == "mujoco":
        from reachwise.sim.mujoco_plant import MujocoPlant, MujocoPlantConfig

        return MujocoPlant(robot, q0, MujocoPlantConfig.like(pc), meshes)
    return Plant(robot, q0, pc)


def _robot_objects(
    scene: SceneLike, robot: str, links: list[str] | None, source: str, where: str
) -> list[str]:
    objs = [o for o in scene.robot_objects(robot)]
    if links is None:
        return [o.name for o in objs]
    have = {o.name.removeprefix(f"{robot}/"): o.name for o in objs}  # link (body) -> object
    out = []
    for link in links:
        if link not in have:
            what = f"robot {robot!r} has no cloud on {link!r}"
            raise unknown(source, f"{where}.links", what, link, list(have))
        out.append(have[link])
    return out


def _goal(g: GoalSpec, robot: Robot) -> Goal:
    return Goal(
        g.pose(robot.fk),
        g.dims,
        position_tolerance=g.position_tolerance,
        orientation_tolerance=g.orientation_tolerance,
    )


# --------------------------------------------------------------------------- moving objects


def move_objects(world: World, t: float) -> Twists:
    """Per tick, before the distance query: each moving object's pose at ``t``, and
    the clouds due by ``t`` (scheduled, or a re-scan with the next seed). Returns the
    moving objects' twists ``{name: (v, ω, origin)}`` for the controllers. Objects
    outside the scene (``scene: false``) are left to the sensors: no pose, no cloud
    and no twist of theirs reaches the scene or the controllers."""
    scene = world.scene
    twists = {}
    for m in world.movers:
        name = m.spec.name
        if not m.in_scene:  # the sensors see it where it is; the controllers do not
            continue
        if m.trajectory is not None:
            pose = m.trajectory.pose(t)
            scene.set_pose(name, pose, stamp=t)
            twists[name] = (*m.trajectory.twist(t), pose[:3, 3])
        due = None
        while m.next_cloud < len(m.clouds) and m.clouds[m.next_cloud][0] <= t + 1e-9:
            _, due, solid = m.clouds[m.next_cloud]
            m.next_cloud += 1
            world.solids.pop(name, None)
            if solid is not None:  # the contact check follows the new shape
                world.solids[name] = (solid, "", "")
        if m.rescan is not None and t >= (m.scans + 1) * m.rescan - 1e-9:
            m.scans += 1
            res = world.resolved if world.resolved is not None else resolve_scenario(world.scenario)
            due = object_cloud(res, m.spec, m.spec.seed + m.scans)
        if due is not None:
            scene.replace_cloud(name, due, block=True)
    return twists
