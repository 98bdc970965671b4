"""A scenario built for running: :func:`build_world` turns a
:class:`~reachwise.sim.scenarios.Scenario` into robots, plants, controllers, the distance
scene (in process or on a collision server), solids, watched pairs and moving objects."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from reachwise.control.avoidance import SceneConverter
from reachwise.control.controller import Controller, ControllerConfig, Goal
from reachwise.control.safety import SafetyConfig
from reachwise.distance.scene import OnLink, Scene, SceneLike, WatchedPair
from reachwise.errors import InputError, check_choice
from reachwise.geometry.cloud import PointCloud
from reachwise.kinematics.robot import Robot
from reachwise.sim.contact import Solid, solid_of_link, solid_of_mesh
from reachwise.sim.motion import Trajectory
from reachwise.sim.plant import PLANT_NAMES, Plant, PlantConfig, PlantName
from reachwise.sim.robots import robot_of
from reachwise.sim.scenario_inputs import check_requirements, scan_target, watched_self_pairs
from reachwise.sim.scenarios import (
    GoalSpec,
    ObjectSpec,
    RobotSpec,
    Scenario,
    WatchSpec,
    load_scenario,
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
    movers: list[_Mover] = field(default_factory=list)
    sensors: list[DepthSensor] = field(default_factory=list)
    sight: Sight | None = None  # what the sensors see (None: no sensors, no hidden objects)
    truth: tuple[tuple[str, str], ...] = ()  # (robot link, object outside the scene) pairs


def _controller_config(spec: RobotSpec, dt: float, avoidance: bool) -> ControllerConfig:
    c = spec.controller.model_dump(exclude_none=True)
    safety = {k: c.pop(k) for k in ("max_age_ticks", "stop_ticks") if k in c}
    return ControllerConfig(avoidance=avoidance, safety=SafetyConfig(dt=dt, **safety), **c)


def build_world(
    scenario: Scenario | str | Path,
    avoidance: bool = True,
    *,
    plant: PlantName = "scenario",
    make_scene: SceneFactory | None = None,
    clock: Callable[[], float] | None = None,
) -> World:
    """Robots, clouds (links, meshes, files, the scanner), scene, controllers, plants
    (``plant``: ``"scenario"`` — each robot's own — or ``"mujoco"``, see
    :mod:`reachwise.sim.mujoco_plant`). The distance scene is ``make_scene(clock)``
    (:data:`SceneFactory`; default: in process); ``clock`` stamps its inputs and answers.

    The steps: the scene, the robots and their link clouds
    (:func:`_add_robots`), the other objects (:func:`_add_objects`), the sensors and
    what they see (:func:`_add_sensors`), the watched pairs (:func:`_watch_pairs`), one
    agent per robot (:func:`_make_agent`) and the shared jobs (:func:`_shared_jobs`)."""
    plant = check_choice(plant, PLANT_NAMES, source="simulate", kind="plant")
    sc = load_scenario(scenario)
    check_requirements(sc)
    scene = Scene(clock=clock) if make_scene is None else make_scene(clock)
    return _assemble(scene, sc, avoidance, plant)


def _assemble(scene: SceneLike, sc: Scenario, avoidance: bool, plant: PlantName) -> World:
    """Fill ``scene`` with the scenario and make the agents (see :func:`build_world`)."""
    robots, solids = _add_robots(scene, sc)
    movers = _add_objects(scene, sc, solids)
    sight, sensors = _add_sensors(scene, sc, robots, movers)
    control = _watch_pairs(scene, sc, robots)
    job_robots = set(sc.spec.jobs.robots) if sc.spec.jobs is not None else set()
    agents = [
        _make_agent(scene, sc, rs, robots[rs.name], control, avoidance, plant, job_robots)
        for rs in sc.spec.robots
    ]
    jobs = _shared_jobs(sc, robots)
    pairs = tuple(f"{p.a}|{p.b}" for p in scene.pairs)
    margins = np.array([control[(p.a, p.b)] for p in scene.pairs], dtype=float)
    hidden = [o.name for o in sc.spec.objects if not o.scene]
    truth = tuple((b, o) for b in (sight.bodies if sight else {}) for o in hidden)
    return World(
        sc, scene, robots, agents, pairs, margins, solids, jobs, movers, sensors, sight, truth
    )


def _add_robots(
    scene: SceneLike, sc: Scenario
) -> tuple[dict[str, Robot], dict[str, tuple[Solid, str, str]]]:
    """Every robot of the scenario with its joint state and one cloud per link (named
    ``robot/link``), and the solid of each link cloud for the contact check."""
    robots: dict[str, Robot] = {}
    solids: dict[str, tuple[Solid, str, str]] = {}
    for rs in sc.spec.robots:
        robot = robot_of(rs, sc)
        if len(rs.q0) != robot.n:
            raise InputError(sc.source, f"robots.{rs.name}.q0", f"expected {robot.n} values")
        robots[rs.name] = robot
        scene.add_robot(robot, rs.q0)
        links = rs.links if rs.links is not None else list(robot.geometry)
        _check_link_clouds(sc, rs, robot, links)
        for link in links:
            if link not in robot.link_names:
                raise InputError(sc.source, f"robots.{rs.name}.links", f"no link {link!r}")
            obj = f"{rs.name}/{link}"
            cloud, solid = _link_cloud(sc, rs, robot, link, obj)
            scene.add_object(obj, cloud, robot=rs.name, link=link)
            solids[obj] = (solid, rs.name, link)
    return robots, solids


def _check_link_clouds(sc: Scenario, rs: RobotSpec, robot: Robot, links: list[str]) -> None:
    """Each ``link_clouds`` entry names a link that is given a cloud: an entry that would
    never be used (a misspelt link, one outside ``links``) is an error."""
    for link in rs.link_clouds:
        where = f"robots.{rs.name}.link_clouds.{link}"
        if link not in robot.link_names:
            valid = ", ".join(robot.link_names)
            raise InputError(sc.source, where, f"no link {link!r}; valid: {valid}")
        if link not in links:
            raise InputError(
                sc.source, where,
                f"{link!r} is not among the links given clouds ({', '.join(links)}); "
                "add it to links",
            )  # fmt: skip


def _link_mesh(sc: Scenario, rs: RobotSpec, link: str) -> Any:
    """The scenario's ``link_clouds`` mesh of ``link``, placed in the link frame (a
    trimesh.Trimesh); InputError naming the scenario field if it does not load."""
    from reachwise.io.meshes import load_mesh

    over = rs.link_clouds[link]
    try:
        mesh = load_mesh(sc.path(over.mesh))
    except InputError as exc:
        where = f"robots.{rs.name}.link_clouds.{link}.mesh"
        raise InputError(sc.source, where, str(exc)) from None
    mesh.apply_transform(over.pose.matrix())
    return mesh


def _link_cloud(
    sc: Scenario, rs: RobotSpec, robot: Robot, link: str, obj: str
) -> tuple[PointCloud, Solid]:
    """The cloud of ``link`` (the scenario's ``link_clouds`` mesh, or the robot's own
    geometry) and its solid."""
    from reachwise.io.robot_clouds import link_cloud, shape_meshes

    over = rs.link_clouds.get(link)
    if over is not None:
        from reachwise.geometry.cloud import sample_mesh_surface

        mesh = _link_mesh(sc, rs, link)
        rng = np.random.default_rng([rs.seed, robot.link_index(link)])
        cloud = sample_mesh_surface(mesh, n=over.points, seed=rng, frame=link, name=obj)
        return cloud, solid_of_mesh(mesh)
    if link not in robot.geometry:
        raise InputError(sc.source, f"robots.{rs.name}.links", f"link {link!r} has no geometry")
    cloud = link_cloud(robot, link, rs.points, rs.seed, density=rs.density)
    shapes = robot.geometry[link]
    has_mesh = any(g.shape == "mesh" for g in shapes)
    return cloud, solid_of_link(shapes, shape_meshes(robot, link) if has_mesh else None)


def _add_objects(
    scene: SceneLike, sc: Scenario, solids: dict[str, tuple[Solid, str, str]]
) -> list[_Mover]:
    """The clouds not on a robot (a box also gets its solid); returns the ones that
    move or change their cloud during the run."""
    movers: list[_Mover] = []
    for os_ in sc.spec.objects:
        mover = _mover(os_, sc)
        if not os_.scene:  # only the sensors see it
            if mover is not None:
                movers.append(mover)
            continue
        moving = mover is not None and mover.trajectory is not None
        pose = mover.trajectory.pose(0.0) if moving else os_.pose.matrix()  # type: ignore[union-attr]
        scene.add_object(os_.name, _object_cloud(os_, sc), pose, dynamic=moving)
        box_solid = _box_solid(os_.box)
        if box_solid is not None:
            solids[os_.name] = (box_solid, "", "")
        if mover is not None:
            movers.append(mover)
    return movers


def _add_sensors(
    scene: SceneLike, sc: Scenario, robots: dict[str, Robot], movers: list[_Mover]
) -> tuple[Sight | None, list[DepthSensor]]:
    """What the sensors see (:class:`~reachwise.sim.sensors.Sight`: the surfaces of the
    objects and of the robots' links), and the sensors, each with its object in the
    scene holding frame 0. Nothing when the scenario has no sensors and no object
    outside the scene."""
    spec = sc.spec
    if not spec.sensors and all(o.scene for o in spec.objects):
        return None, []
    trajectories = {m.spec.name: m.trajectory for m in movers}
    objects = {}
    for os_ in spec.objects:
        shapes = [(0.0, os_)] + [(c.t, c) for c in os_.clouds]
        found = [
            (t, *_surface(item, sc, f"objects.{os_.name}"))
            for t, item in shapes
            if item.mesh is not None or item.box is not None
        ]
        if found:
            objects[os_.name] = ObjectSurface(
                os_.name, tuple(found), os_.pose.matrix(), trajectories.get(os_.name)
            )
    bodies = {}
    for rs in spec.robots:
        robot = robots[rs.name]
        for link in robot.link_names:
            if link in rs.link_clouds or link in robot.geometry:
                mesh, solid = _link_surface(sc, rs, robot, link)
                name = f"{rs.name}/{link}"
                bodies[name] = BodySurface(name, rs.name, link, robot.link_index(link), mesh, solid)
    sight = Sight(robots, objects, bodies)
    qs = {rs.name: np.asarray(rs.q0, dtype=float) for rs in spec.robots}
    sensors = []
    for i, ss in enumerate(spec.sensors):
        if ss.link is not None and ss.link.link not in robots[ss.link.robot].link_names:
            raise InputError(
                sc.source,
                f"sensors[{i}].link.link",
                f"robot {ss.link.robot!r} has no link {ss.link.link!r}; "
                f"links: {list(robots[ss.link.robot].link_names)}",
            )
        sensor = DepthSensor(ss, spec.dt, robots)
        _check_outside(sc, i, sensor, sight, qs)
        sensor.start(scene, sight, qs)
        sensors.append(sensor)
    return sight, sensors


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


def _surface(item: Any, sc: Scenario, where: str) -> tuple[Any, Solid]:
    """The mesh ``(vertices, faces)`` and solid of a ``mesh`` or ``box`` spec, in the
    object frame."""
    import trimesh

    from reachwise.io.meshes import load_mesh

    if item.box is not None:
        mesh = trimesh.creation.box(extents=item.box)
        solid = _box_solid(item.box)
    else:
        try:
            mesh = load_mesh(sc.path(item.mesh))
        except InputError as exc:
            raise InputError(sc.source, f"{where}.mesh", str(exc)) from None
        solid = solid_of_mesh(mesh)
    v = np.asarray(mesh.vertices, dtype=np.float64)
    f = np.asarray(mesh.faces, dtype=np.int64)
    return (v, f), solid  # type: ignore[return-value]


def _link_surface(
    sc: Scenario, rs: RobotSpec, robot: Robot, link: str
) -> tuple[tuple[NDArray[np.float64], NDArray[np.int64]], Solid]:
    """A link's collision surface in the link frame (the scenario's ``link_clouds``
    mesh, or the union of the robot's shapes of that link) and its solid."""
    import trimesh

    from reachwise.io.robot_clouds import shape_meshes

    if link in rs.link_clouds:
        mesh = _link_mesh(sc, rs, link)
        solid = solid_of_mesh(mesh)
    else:
        parts = shape_meshes(robot, link)
        solid = solid_of_link(robot.geometry[link], parts)
        joined = parts[0] if len(parts) == 1 else trimesh.util.concatenate(parts)
        if not isinstance(joined, trimesh.Trimesh):  # pragma: no cover - meshes join
            raise InputError(sc.source, f"robots.{rs.name}.links", f"{link}: shapes do not join")
        mesh = joined
    v = np.asarray(mesh.vertices, dtype=np.float64)
    return (v, np.asarray(mesh.faces, dtype=np.int64)), solid


def _watch_pairs(
    scene: SceneLike, sc: Scenario, robots: dict[str, Robot]
) -> dict[tuple[str, str], float]:
    """Watch the scenario's pairs: the scene's margin is rho_O + the monitor range (the
    log sees the pairs approach); returns each pair's rho_O, the controller's margin."""
    spec = sc.spec
    control: dict[tuple[str, str], float] = {}
    for i, w in enumerate(spec.watch):
        made = _watch_rule(scene, sc, robots, w, w.margin + spec.monitor, f"watch[{i}]")
        for pair in made:
            control[(pair.a, pair.b)] = w.margin
    return control


def _watch_rule(
    scene: SceneLike, sc: Scenario, robots: dict[str, Robot], w: WatchSpec, qm: float, where: str
) -> list[WatchedPair]:
    """The pairs one ``watch`` entry makes (self, robot-environment or robot-robot),
    watched with margin ``qm``."""
    made = []
    if w.self_ is not None:
        r = robots[w.self_]
        if w.links is not None:  # each a link with a cloud
            _robot_objects(scene, w.self_, w.links, sc.source, where)
        rspec = next(x for x in sc.spec.robots if x.name == w.self_)
        listed = watched_self_pairs(w, r, rspec, scene, sc, where)
        if listed is not None:
            for la, lb in listed:
                a, b = f"{w.self_}/{la}", f"{w.self_}/{lb}"
                for o in (a, b):
                    if o not in scene.objects:
                        raise InputError(sc.source, where, f"no cloud {o!r}")
                made.append(scene.watch(a, b, qm, kind="self"))
        else:
            keep = set(w.links) if w.links is not None else set(r.link_names)
            excl = [
                (o.name, p.name)
                for o in scene.robot_objects(w.self_)
                for p in scene.robot_objects(w.self_)
                if o.source.link not in keep or p.source.link not in keep  # type: ignore[union-attr]
            ]
            made.extend(scene.watch_self(w.self_, qm, exclude=excl))
    elif w.environment is not None and w.robot is not None:
        mine = _robot_objects(scene, w.robot, w.links, sc.source, where)
        for o in mine:
            for e in w.environment:
                made.append(scene.watch(o, e, qm, kind="robot-environment"))
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
) -> Agent:
    """One robot's controller, scene converter, plant and own goals."""
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
        _make_plant(plant, robot, rs.q0, pc),
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
    kind: PlantName, robot: Robot, q0: list[float], pc: PlantConfig
) -> Plant | MujocoPlant:
    if kind == "mujoco":
        from reachwise.sim.mujoco_plant import MujocoPlant, MujocoPlantConfig

        return MujocoPlant(robot, q0, MujocoPlantConfig.like(pc))
    return Plant(robot, q0, pc)


def _robot_objects(
    scene: SceneLike, robot: str, links: list[str] | None, source: str, where: str
) -> list[str]:
    objs = [o for o in scene.robot_objects(robot)]
    if links is None:
        return [o.name for o in objs]
    have = {o.source.link: o.name for o in objs}  # type: ignore[union-attr]
    out = []
    for link in links:
        if link not in have:
            raise InputError(source, f"{where}.links", f"robot {robot!r} has no cloud on {link!r}")
        out.append(have[link])
    return out


def _goal(g: GoalSpec, robot: Robot) -> Goal:
    return Goal(
        g.pose(robot.fk),
        g.dims,
        position_tolerance=g.position_tolerance,
        orientation_tolerance=g.orientation_tolerance,
    )


def _object_cloud(
    spec: Any, sc: Scenario, name: str | None = None, seed: int | None = None
) -> PointCloud:
    """The cloud of an object spec (or of a scheduled :class:`CloudAtSpec` of object
    ``name``); ``seed`` overrides the spec's (a re-scan)."""
    from reachwise.io.clouds import load_cloud, load_mesh_cloud

    name = name or spec.name
    seed = getattr(spec, "seed", 0) if seed is None else seed
    where = f"objects.{name}"
    if getattr(spec, "scanner", None) is not None:
        from reachwise.geometry.occlusion import OcclusionFill
        from reachwise.geometry.scan_scene import scan_scene

        occ = spec.occlusion
        fill = (
            OcclusionFill(occ.depth, occ.spacing, occ.ground)
            if occ is not None and occ.fill
            else None
        )
        try:
            target = scan_target(spec.scanner, sc, name)
            _, cloud = scan_scene(target, rng=seed, noise=spec.noise, occlusion=fill)
        except InputError as exc:
            raise InputError(sc.source, f"{where}.scanner", str(exc)) from None
        return PointCloud(cloud.points, name=name)
    if spec.box is not None:
        import trimesh

        from reachwise.geometry.cloud import sample_mesh_surface

        box = trimesh.creation.box(extents=spec.box)
        return sample_mesh_surface(box, n=spec.points, seed=seed, name=name)
    try:
        if spec.mesh is not None:
            return load_mesh_cloud(sc.path(spec.mesh), spec.points, seed, name=name)
        return load_cloud(sc.path(spec.file))
    except InputError as exc:
        raise InputError(sc.source, where, str(exc)) from None


# --------------------------------------------------------------------------- moving objects


@dataclass(eq=False)
class _Mover:
    """An object that moves (``trajectory``) or changes its cloud (``clouds`` at
    times, or a re-scan every ``rescan`` s) during the run."""

    spec: ObjectSpec
    trajectory: Trajectory | None
    clouds: list[tuple[float, PointCloud, Solid | None]]
    rescan: float | None
    next_cloud: int = 0
    scans: int = 0

    @property
    def in_scene(self) -> bool:
        """False for an object only the sensors see (``scene: false``)."""
        return self.spec.scene


def _mover(spec: ObjectSpec, sc: Scenario) -> _Mover | None:
    if spec.motion is None and spec.rescan is None and not spec.clouds:
        return None
    traj = spec.motion.trajectory(spec.pose.matrix()) if spec.motion is not None else None
    clouds = [
        (c.t, _object_cloud(c, sc, spec.name, spec.seed + k + 1), _box_solid(c.box))
        for k, c in enumerate(spec.clouds)
    ]
    every = spec.rescan.every if spec.rescan is not None else None
    return _Mover(spec, traj, clouds, every)


def _box_solid(box: Any) -> Solid | None:
    """The solid of a ``box`` object (centred on its frame), for the contact check."""
    return None if box is None else Solid("box", np.eye(4), 0.5 * np.asarray(box, dtype=float))


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
            due = _object_cloud(m.spec, world.scenario, seed=m.spec.seed + m.scans)
        if due is not None:
            scene.replace_cloud(name, due, block=True)
    return twists


def frozen_scene(scene: SceneLike) -> Scene:
    """A copy of ``scene`` in which every object not on a robot stays where it is now,
    with its current cloud: the world a static-world controller believes in."""
    frozen = Scene(strategy=scene.strategy)
    for r in scene.robots.values():
        frozen.add_robot(r)
    now = scene.poses()
    for name, obj in scene.objects.items():
        src = obj.source
        if isinstance(src, OnLink):
            frozen.add_object(name, obj.cloud, src.offset, robot=src.robot, link=src.link)
        else:
            frozen.add_object(name, obj.cloud, now[name])
    for pair in scene.pairs:
        frozen.watch(pair.a, pair.b, pair.margin, kind=pair.kind)
    return frozen
