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

import csv
import json
import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np
from numpy.typing import NDArray

from reachwise.control.avoidance import SceneConverter
from reachwise.control.controller import Controller, ControllerConfig, ControlStatus, Goal
from reachwise.control.safety import SafetyConfig
from reachwise.distance.scene import OnLink, Scene, SceneResult
from reachwise.errors import InputError
from reachwise.geometry.cloud import PointCloud
from reachwise.kinematics.robot import Robot
from reachwise.sim.contact import Solid, solid_of_geometry, solid_of_mesh
from reachwise.sim.motion import Trajectory
from reachwise.sim.plant import Plant, PlantConfig
from reachwise.sim.scenarios import (
    EscapeSpec,
    GoalSpec,
    ObjectSpec,
    RobotSpec,
    Scenario,
    load_scenario,
)

if TYPE_CHECKING:
    from reachwise.server.client import ServerOptions
    from reachwise.sim.escape import Escape
    from reachwise.sim.mujoco_plant import MujocoPlant

__all__ = ["Event", "GoalRecord", "SimulationLog", "World", "build_world", "simulate"]


@dataclass(frozen=True)
class Event:
    """Something that happened at time ``t`` (s) to ``robot`` (or ``""``)."""

    t: float
    robot: str
    kind: str
    text: str


@dataclass(frozen=True)
class GoalRecord:
    """One goal of one robot: when it was reached (``None``: never) and the remaining
    errors at the end of the run or when reached."""

    robot: str
    index: int
    name: str
    work: float
    reached_at: float | None
    position_error: float
    orientation_error: float


@dataclass(frozen=True, eq=False)
class SimulationLog:
    """Everything a run recorded, one row per tick.

    ``t`` (T,); per robot (dicts keyed by robot name): ``q``, ``qdot`` (actual),
    ``command`` (T, n), ``tool`` (T, 4, 4), ``state`` (T,) strings, ``goal_index``
    (T,); per pair (``pairs`` names ``"a|b"``): ``distance`` (T, P) cloud distance
    (``inf`` beyond margin + monitor range), ``signed`` (T, P) the same or ``−depth``
    when the solids overlap, ``margins`` (P,) the collision margins ρ_O. ``events``,
    ``goals``; ``first_collision`` (s) and its pair, or ``None``. ``object_poses``:
    per moving object (``motion``), its world pose at each tick (T, 4, 4), for replay.
    """

    scenario: str
    avoidance: bool
    dt: float
    t: NDArray[np.float64]
    robots: tuple[str, ...]
    q: dict[str, NDArray[np.float64]]
    qdot: dict[str, NDArray[np.float64]]
    command: dict[str, NDArray[np.float64]]
    tool: dict[str, NDArray[np.float64]]
    state: dict[str, NDArray[np.str_]]
    goal_index: dict[str, NDArray[np.int64]]
    pairs: tuple[str, ...]
    distance: NDArray[np.float64]
    signed: NDArray[np.float64]
    margins: NDArray[np.float64]
    lower: dict[str, NDArray[np.float64]]
    upper: dict[str, NDArray[np.float64]]
    vmax: dict[str, NDArray[np.float64]]
    events: tuple[Event, ...] = ()
    goals: tuple[GoalRecord, ...] = ()
    first_collision: float | None = None
    first_collision_pair: str | None = None
    extras: dict[str, Any] = field(default_factory=dict)
    object_poses: dict[str, NDArray[np.float64]] = field(default_factory=dict)

    @property
    def min_distance(self) -> NDArray[np.float64]:
        """Smallest signed distance over all pairs at each tick (inf without pairs)."""
        if self.signed.shape[1] == 0:
            return np.full(self.t.shape, np.inf)
        return np.asarray(self.signed.min(axis=1))

    @property
    def all_goals_reached(self) -> bool:
        return all(g.reached_at is not None for g in self.goals)

    def limits_held(self, tol: float = 1e-9) -> dict[str, bool]:
        """Per robot: every joint inside its limits at every tick (a joint that starts
        outside must not move farther out)."""
        out = {}
        for r in self.robots:
            q = self.q[r]
            lo = np.minimum(self.lower[r], q[0])
            hi = np.maximum(self.upper[r], q[0])
            ok = bool(np.all(q >= lo - tol) & np.all(q <= hi + tol))
            # a joint outside at the start: monotone back inward
            out[r] = ok
        return out

    def speeds_held(self, tol: float = 1e-9) -> dict[str, bool]:
        """Per robot: |command| and |actual velocity| ≤ v_max at every tick."""
        return {
            r: bool(
                np.all(np.abs(self.command[r]) <= self.vmax[r] + tol)
                and np.all(np.abs(self.qdot[r]) <= self.vmax[r] + tol)
            )
            for r in self.robots
        }

    def summary(self) -> dict[str, Any]:
        """A JSON-ready summary of the outcome."""
        md = self.min_distance
        finite = md[np.isfinite(md)]
        per_pair = {
            p: float(np.min(self.signed[:, i])) if self.signed.shape[0] else math.inf
            for i, p in enumerate(self.pairs)
        }
        stalls = [e for e in self.events if e.kind == "stalled"]
        return {
            "scenario": self.scenario,
            "avoidance": self.avoidance,
            "dt": self.dt,
            "duration": float(self.t[-1]) if self.t.size else 0.0,
            "ticks": int(self.t.size),
            "all_goals_reached": self.all_goals_reached,
            "goals": [
                {
                    "robot": g.robot,
                    "index": g.index,
                    "name": g.name,
                    "work": g.work,
                    "reached_at": g.reached_at,
                    "position_error": g.position_error,
                    "orientation_error": g.orientation_error,
                }
                for g in self.goals
            ],
            "min_distance": float(finite.min()) if finite.size else None,
            "min_distance_by_pair": {
                k: (v if math.isfinite(v) else None) for k, v in per_pair.items()
            },
            "first_collision": self.first_collision,
            "first_collision_pair": self.first_collision_pair,
            "limits_held": self.limits_held(),
            "speeds_held": self.speeds_held(),
            "stalls": [{"t": e.t, "robot": e.robot, "text": e.text} for e in stalls],
            "extras": self.extras,
            "events": [
                {"t": e.t, "robot": e.robot, "kind": e.kind, "text": e.text} for e in self.events
            ],
        }

    def save(self, folder: str | Path) -> Path:
        """Write ``log.npz`` (every array), ``log.csv`` (t, joints, tool xyz, min
        distance per tick) and ``summary.json`` into ``folder``; returns it."""
        out = Path(folder)
        out.mkdir(parents=True, exist_ok=True)
        arrays: dict[str, Any] = {
            "t": self.t,
            "distance": self.distance,
            "signed": self.signed,
            "margins": self.margins,
            "pairs": np.array(self.pairs, dtype=str),
            "min_distance": self.min_distance,
        }
        for r in self.robots:
            arrays[f"{r}.q"] = self.q[r]
            arrays[f"{r}.qdot"] = self.qdot[r]
            arrays[f"{r}.command"] = self.command[r]
            arrays[f"{r}.tool"] = self.tool[r]
            arrays[f"{r}.state"] = self.state[r]
            arrays[f"{r}.goal_index"] = self.goal_index[r]
        for name, poses in self.object_poses.items():
            arrays[f"object.{name}.pose"] = poses
        np.savez_compressed(out / "log.npz", **arrays)
        with (out / "log.csv").open("w", newline="") as fh:
            w = csv.writer(fh)
            head = ["t"]
            for r in self.robots:
                n = self.q[r].shape[1]
                head += [f"{r}.q{k + 1}" for k in range(n)]
                head += [f"{r}.tool_{c}" for c in "xyz"] + [f"{r}.state"]
            head.append("min_distance")
            w.writerow(head)
            md = self.min_distance
            for i in range(self.t.size):
                row: list[Any] = [f"{self.t[i]:.4f}"]
                for r in self.robots:
                    row += [f"{v:.6g}" for v in self.q[r][i]]
                    row += [f"{v:.6g}" for v in self.tool[r][i, :3, 3]]
                    row.append(self.state[r][i])
                row.append(f"{md[i]:.6g}")
                w.writerow(row)
        (out / "summary.json").write_text(json.dumps(self.summary(), indent=2))
        return out


# --------------------------------------------------------------------------- world


@dataclass(eq=False)
class _Agent:
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
    scene: Scene
    robots: dict[str, Robot]
    agents: list[_Agent]
    pairs: tuple[str, ...]
    margins: NDArray[np.float64]
    solids: dict[str, tuple[Solid, str, str]]  # object -> (solid, robot, link)
    jobs: list[tuple[Goal, GoalSpec]]
    movers: list[_Mover] = field(default_factory=list)


def _robot_of(spec: RobotSpec, scenario: Scenario) -> Robot:
    from reachwise.io.robot_file import builtin_robots, load_robot

    try:
        r = load_robot(spec.robot if spec.robot in builtin_robots() else scenario.path(spec.robot))
    except InputError as exc:
        raise InputError(scenario.source, f"robots.{spec.name}.robot", str(exc)) from None
    if spec.base is not None:
        r = r.with_parameters(base=spec.base.matrix())
    return replace(r, name=spec.name)


def _controller_config(spec: RobotSpec, dt: float, avoidance: bool) -> ControllerConfig:
    c = spec.controller.model_dump(exclude_none=True)
    safety = {k: c.pop(k) for k in ("max_age_ticks", "stop_ticks") if k in c}
    return ControllerConfig(avoidance=avoidance, safety=SafetyConfig(dt=dt, **safety), **c)


def build_world(
    scenario: Scenario | str | Path,
    avoidance: bool = True,
    plant: str = "scenario",
    *,
    server: str | ServerOptions | None = None,
    clock: Callable[[], float] | None = None,
) -> World:
    """Robots, clouds (links, meshes, files, the scanner), scene, controllers, plants
    (``plant``: ``"scenario"`` — each robot's own — or ``"mujoco"``, see
    :mod:`reachwise.sim.mujoco_plant`). The scene is in process, or with ``server``
    (an address or :class:`~reachwise.server.client.ServerOptions`) on a collision
    server (:func:`_server_scene`); ``clock`` stamps its inputs and answers."""
    if plant not in ("scenario", "mujoco"):
        raise InputError("simulate", "plant", f"scenario or mujoco, got {plant!r}")
    from reachwise.io.robot_clouds import link_cloud, link_mesh

    sc = load_scenario(scenario)
    spec = sc.spec
    scene = Scene(clock=clock) if server is None else _server_scene(server, clock)
    robots: dict[str, Robot] = {}
    solids: dict[str, tuple[Solid, str, str]] = {}
    for rs in spec.robots:
        robot = _robot_of(rs, sc)
        if len(rs.q0) != robot.n:
            raise InputError(sc.source, f"robots.{rs.name}.q0", f"expected {robot.n} values")
        robots[rs.name] = robot
        scene.add_robot(robot, rs.q0)
        links = rs.links if rs.links is not None else list(robot.geometry)
        for link in links:
            if link not in robot.link_names:
                raise InputError(sc.source, f"robots.{rs.name}.links", f"no link {link!r}")
            obj = f"{rs.name}/{link}"
            over = rs.link_clouds.get(link)
            if over is not None:
                import trimesh

                from reachwise.geometry.cloud import sample_mesh_surface

                path = sc.path(over.mesh)
                try:
                    mesh = trimesh.load(str(path), force="mesh", process=True)
                except Exception as exc:
                    raise InputError(
                        sc.source, f"robots.{rs.name}.link_clouds.{link}.mesh", f"{exc}"
                    ) from None
                if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
                    raise InputError(
                        sc.source, f"robots.{rs.name}.link_clouds.{link}.mesh", "no triangles"
                    )
                mesh.apply_transform(over.pose.matrix())
                rng = np.random.default_rng([rs.seed, robot.link_index(link)])
                cloud = sample_mesh_surface(mesh, n=over.points, seed=rng, frame=link, name=obj)
                solid = solid_of_mesh(mesh)
            else:
                if link not in robot.geometry:
                    raise InputError(
                        sc.source, f"robots.{rs.name}.links", f"link {link!r} has no geometry"
                    )
                cloud = link_cloud(robot, link, rs.points, rs.seed)
                g = robot.geometry[link]
                solid = solid_of_geometry(g, link_mesh(robot, link) if g.shape == "mesh" else None)
            scene.add_object(obj, cloud, robot=rs.name, link=link)
            solids[obj] = (solid, rs.name, link)
    movers: list[_Mover] = []
    for os_ in spec.objects:
        mover = _mover(os_, sc)
        moving = mover is not None and mover.trajectory is not None
        pose = mover.trajectory.pose(0.0) if moving else os_.pose.matrix()  # type: ignore[union-attr]
        scene.add_object(os_.name, _object_cloud(os_, sc), pose, dynamic=moving)
        box_solid = _box_solid(os_.box)
        if box_solid is not None:
            solids[os_.name] = (box_solid, "", "")
        if mover is not None:
            movers.append(mover)
    # watched pairs: scene margin = rho_O + monitor range; the controller uses rho_O
    control: dict[tuple[str, str], float] = {}
    for i, w in enumerate(spec.watch):
        where = f"watch[{i}]"
        qm = w.margin + spec.monitor
        made = []
        if w.self_ is not None:
            r = robots[w.self_]
            if w.pairs is not None:
                for la, lb in w.pairs:
                    a, b = f"{w.self_}/{la}", f"{w.self_}/{lb}"
                    for o in (a, b):
                        if o not in scene.objects:
                            raise InputError(sc.source, where, f"no cloud {o!r}")
                    made.append(scene.watch(a, b, qm, "self"))
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
                    made.append(scene.watch(o, e, qm, "robot-environment"))
        elif w.robots is not None:
            ra, rb = w.robots
            for o in _robot_objects(scene, ra, w.links, sc.source, where):
                for p in _robot_objects(scene, rb, w.links, sc.source, where):
                    made.append(scene.watch(o, p, qm, "robot-robot"))
        for pair in made:
            control[(pair.a, pair.b)] = w.margin
    agents = []
    job_robots = set(spec.jobs.robots) if spec.jobs is not None else set()
    for rs in spec.robots:
        robot = robots[rs.name]
        cfg = _controller_config(rs, spec.dt, avoidance)
        try:
            tl = rs.tool_links
            conv = SceneConverter(scene, robot, tool_links=tl, margins=control)
        except InputError as exc:
            raise InputError(sc.source, f"robots.{rs.name}.tool_links", str(exc)) from None
        pc = PlantConfig(**rs.plant.model_dump())
        own = [(_goal(g, robot), g) for g in rs.goals]
        agents.append(
            _Agent(
                rs.name,
                robot,
                Controller(robot, cfg),
                _make_plant(plant, robot, rs.q0, pc),
                conv,
                own,
                rs.name in job_robots,
            )
        )
    jobs: list[tuple[Goal, GoalSpec]] = []
    if spec.jobs is not None:
        first = robots[spec.jobs.robots[0]]
        work = spec.jobs.work
        jobs = [
            (_goal(g, first), g if g.work > 0 else g.model_copy(update={"work": work}))
            for g in spec.jobs.goals
        ]
    pairs = tuple(f"{p.a}|{p.b}" for p in scene.pairs)
    margins = np.array([control[(p.a, p.b)] for p in scene.pairs], dtype=float)
    return World(sc, scene, robots, agents, pairs, margins, solids, jobs, movers)


def _server_scene(server: str | ServerOptions, clock: Callable[[], float] | None) -> Scene:
    """A client of the collision server at ``server`` that owns its scene (cleared,
    mirrored locally, inputs sent with each query; :func:`reachwise.server.client.
    owned_scene`). It has the in-process scene's interface (``SceneLike``), so the
    world, the converters and the controllers use it unchanged; a reply that misses
    its deadline is an invalid result (missing data: a protective stop)."""
    import time

    from reachwise.server.client import owned_scene

    return cast(Scene, owned_scene(server, clock or time.monotonic))


def _close_scene(scene: object) -> None:
    """Disconnect from a collision server (an in-process scene has nothing to close)."""
    close = getattr(scene, "close", None)
    if callable(close):
        close()


class _SimClock:
    """The simulated time (s); the scene stamps joint states and answers with it."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def _make_plant(kind: str, robot: Robot, q0: list[float], pc: PlantConfig) -> Plant | MujocoPlant:
    if kind == "mujoco":
        from reachwise.sim.mujoco_plant import MujocoPlant, MujocoPlantConfig

        return MujocoPlant(robot, q0, MujocoPlantConfig.like(pc))
    return Plant(robot, q0, pc)


def _robot_objects(
    scene: Scene, robot: str, links: list[str] | None, source: str, where: str
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
        from reachwise.geometry.scanner import OcclusionFill, scan_scene

        occ = spec.occlusion
        fill = (
            OcclusionFill(occ.depth, occ.spacing, occ.ground)
            if occ is not None and occ.fill
            else None
        )
        try:
            _, cloud = scan_scene(spec.scanner, rng=seed, noise=spec.noise, occlusion=fill)
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


def _move_objects(
    world: World, t: float
) -> dict[str, tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]]:
    """Per tick, before the distance query: each moving object's pose at ``t``, and
    the clouds due by ``t`` (scheduled, or a re-scan with the next seed). Returns the
    moving objects' twists ``{name: (v, ω, origin)}`` for the controllers."""
    scene = world.scene
    twists = {}
    for m in world.movers:
        name = m.spec.name
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
            scene.replace_cloud(name, due)
    return twists


def _frozen_scene(scene: Scene) -> Scene:
    """A copy of ``scene`` in which every object not on a robot stays where it is now,
    with its current cloud: the world a static-world controller believes in."""
    frozen = Scene(scene.strategy)
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
        frozen.watch(pair.a, pair.b, pair.margin, pair.kind)
    return frozen


# --------------------------------------------------------------------------- run


def simulate(
    scenario: Scenario | str | Path,
    avoidance: bool = True,
    *,
    duration: float | None = None,
    progress: Callable[[float, float], None] | None = None,
    on_tick: Callable[[float, dict[str, NDArray[np.float64]], SceneResult], None] | None = None,
    plant: str = "scenario",
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
    clock = _SimClock()
    world = build_world(scenario, avoidance, plant, server=server, clock=clock)
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
    seen = _frozen_scene(scene) if static_world and world.movers else scene

    def next_goal(a: _Agent, t: float) -> None:
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
        twists = _move_objects(world, t)
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
    _close_scene(scene)
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


def _note(a: _Agent, st: ControlStatus, t: float, events: list[Event]) -> None:
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


# --------------------------------------------------------------------------- reading


def load_log(folder: str | Path, scenario: Scenario | str | Path | None = None) -> SimulationLog:
    """Read a log written by :meth:`SimulationLog.save` (``log.npz`` and
    ``summary.json`` in ``folder``) back into a :class:`SimulationLog`.

    The joint limits and speed bounds come from ``log.npz`` when it has them
    (``<robot>.lower``, ``.upper``, ``.vmax``), else from the robots of ``scenario``
    (default: the scenario the log names, when it is a built-in one); without either
    they are unbounded (``±inf``) and ``extras["limits"]`` says so. Missing or
    unreadable files raise :class:`~reachwise.errors.InputError` naming the file.
    """
    src = Path(folder)
    npz_path, sum_path = src / "log.npz", src / "summary.json"
    for p in (npz_path, sum_path):
        if not p.is_file():
            raise InputError(str(p), "", "missing: not a simulation log folder")
    try:
        meta = json.loads(sum_path.read_text())
    except (OSError, ValueError) as exc:
        raise InputError(str(sum_path), "", f"unreadable: {exc}") from None
    for key in ("scenario", "avoidance", "dt"):
        if not isinstance(meta, dict) or key not in meta:
            raise InputError(str(sum_path), key, "missing")
    try:
        with np.load(npz_path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except (OSError, ValueError) as exc:
        raise InputError(str(npz_path), "", f"unreadable: {exc}") from None
    for key in ("t", "distance", "signed", "margins", "pairs"):
        if key not in arrays:
            raise InputError(str(npz_path), key, "missing")
    robots = tuple(k[: -len(".q")] for k in arrays if k.endswith(".q"))
    per: dict[str, dict[str, NDArray[Any]]] = {}
    for field_ in ("q", "qdot", "command", "tool", "state", "goal_index"):
        per[field_] = {}
        for r in robots:
            key = f"{r}.{field_}"
            if key not in arrays:
                raise InputError(str(npz_path), key, "missing")
            per[field_][r] = arrays[key]
    objects = {
        k[len("object.") : -len(".pose")]: arrays[k]
        for k in arrays
        if k.startswith("object.") and k.endswith(".pose")
    }
    extras: dict[str, Any] = dict(meta.get("extras") or {})
    lower: dict[str, NDArray[np.float64]] = {}
    upper: dict[str, NDArray[np.float64]] = {}
    vmax: dict[str, NDArray[np.float64]] = {}
    robot_models: dict[str, Robot] = {}
    sc: Scenario | None = None
    from reachwise.sim.scenarios import builtin_scenarios

    if scenario is not None:
        sc = load_scenario(scenario)
    elif meta["scenario"] in builtin_scenarios():
        sc = load_scenario(meta["scenario"])
    if sc is not None:
        robot_models = {rs.name: _robot_of(rs, sc) for rs in sc.spec.robots}
    for r in robots:
        n = per["q"][r].shape[1] if per["q"][r].ndim == 2 else 0
        model = robot_models.get(r)
        if all(f"{r}.{k}" in arrays for k in ("lower", "upper", "vmax")):  # saved in the log
            lower[r], upper[r] = arrays[f"{r}.lower"], arrays[f"{r}.upper"]
            vmax[r] = arrays[f"{r}.vmax"]
        elif model is not None and model.n == n:
            lower[r], upper[r] = np.asarray(model.lower), np.asarray(model.upper)
            vmax[r] = np.asarray(model.vmax)
        else:
            lower[r], upper[r] = np.full(n, -np.inf), np.full(n, np.inf)
            vmax[r] = np.full(n, np.inf)
            extras["limits"] = "unknown: the log's scenario was not found; limits are ±inf"
    events = tuple(
        Event(float(e["t"]), str(e["robot"]), str(e["kind"]), str(e["text"]))
        for e in meta.get("events", [])
    )
    goals = tuple(
        GoalRecord(
            str(g["robot"]),
            int(g["index"]),
            str(g["name"]),
            float(g["work"]),
            None if g["reached_at"] is None else float(g["reached_at"]),
            float(g["position_error"]),
            float(g["orientation_error"]),
        )
        for g in meta.get("goals", [])
    )
    fc = meta.get("first_collision")
    return SimulationLog(
        scenario=str(meta["scenario"]),
        avoidance=bool(meta["avoidance"]),
        dt=float(meta["dt"]),
        t=arrays["t"],
        robots=robots,
        q=per["q"],
        qdot=per["qdot"],
        command=per["command"],
        tool=per["tool"],
        state=per["state"],
        goal_index=per["goal_index"],
        pairs=tuple(str(p) for p in arrays["pairs"]),
        distance=arrays["distance"],
        signed=arrays["signed"],
        margins=arrays["margins"],
        lower=lower,
        upper=upper,
        vmax=vmax,
        events=events,
        goals=goals,
        first_collision=None if fc is None else float(fc),
        first_collision_pair=meta.get("first_collision_pair"),
        extras=extras,
        object_poses=objects,
    )
