"""Simulations in the viewer: the scene of a scenario and the playback of a log
(the live view is :mod:`reachwise.viz.live`).

:class:`SimScene` draws a built ``reachwise.sim.world.World``: every robot
(the scene's link clouds — watched links in orange — plus light clouds of its other
links, the skeleton, the tool frame), the environment clouds, the goals (red until
reached, then green) and the closest-point lines of the watched pairs (thesis §3.1,
P-V Fig. 4: red within the collision margin ρ_O, amber in the monitored band). A depth
camera's live cloud is its environment cloud, replaced as frames arrive (each frame
rendered again from the state at its capture, ``reachwise.sim.sensors``); an object
only the cameras see (``scene: false``) is drawn as grey points on its true surface.
A scene memory fed by cameras is rebuilt from their frames
(:class:`~reachwise.viz.memory_replay.MemoryReplay`) and drawn as its occupied (red),
shadow (purple) and free (green, hidden at first) voxels.

:class:`Playback` replays a :class:`~reachwise.sim.log.SimulationLog`: a play /
pause button and a time slider (scrub), the speed, the tool paths; at each shown tick
the robots take the logged ``q``, moving objects their logged poses, and the
closest-point lines are recomputed from the rebuilt scene (the same clouds, seeds and
poses as the run, so the same answer).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.errors import InputError
from reachwise.viz.memory_replay import MemoryReplay
from reachwise.viz.memory_voxels import show_memory_voxels
from reachwise.viz.scene_data import (
    distance_colours,
    height_colours,
    legend,
    node_name,
    pair_segments,
    polyline_segments,
    wxyz_position,
)
from reachwise.viz.timeline import Timeline

if TYPE_CHECKING:
    from reachwise.distance.scene import SceneResult
    from reachwise.sim.log import SimulationLog
    from reachwise.sim.world import World
    from reachwise.viz.canvas import Canvas

__all__ = ["GoalEntry", "Playback", "SimScene", "goal_reached_at", "goal_table"]

PATH_RGB = (200, 60, 160)
HIDDEN_RGB = (150, 150, 150)  # the true surface of an object only the sensors see


@dataclass(frozen=True)
class GoalEntry:
    """A goal of a scenario: its robot, name (``""`` unnamed), world pose, dims and
    the index of the shared job it is (``-1`` for a robot's own goal)."""

    robot: str
    name: str
    pose: NDArray[np.float64]
    dims: int
    job: int = -1


def goal_table(world: World) -> list[GoalEntry]:
    """Every goal of ``world``: each robot's own goals in order, then the shared jobs."""
    out = []
    for a in world.agents:
        out += [GoalEntry(a.name, s.name, g.pose, g.dims) for g, s in a.own]
    out += [GoalEntry("", s.name, g.pose, g.dims, j) for j, (g, s) in enumerate(world.jobs)]
    return out


def goal_reached_at(log: SimulationLog, goals: list[GoalEntry]) -> NDArray[np.float64]:
    """When each goal of :func:`goal_table` was reached in ``log`` (``inf``: never).

    A robot's goal records follow its own goals in order, then the jobs it took (named
    by the job's name, or ``job k``)."""
    out = np.full(len(goals), np.inf)
    own: dict[str, list[int]] = {}
    jobs = [i for i, g in enumerate(goals) if g.job >= 0]
    for i, g in enumerate(goals):
        if g.job < 0:
            own.setdefault(g.robot, []).append(i)
    taken: set[int] = set()
    seen: dict[str, int] = {}
    for rec in log.goals:
        n = seen.get(rec.robot, 0)
        seen[rec.robot] = n + 1
        mine = own.get(rec.robot, [])
        if n < len(mine):
            i = mine[n]
        else:
            match = [
                j
                for j in jobs
                if j not in taken
                and (goals[j].name == rec.name or f"job {goals[j].job + 1}" == rec.name)
            ]
            if not match:
                continue
            i = match[0]
            taken.add(i)
        out[i] = math.inf if rec.reached_at is None else rec.reached_at
    return out


class SimScene:
    """A built world in the viewer (see the module doc); ``link_points`` samples the
    links without a cloud in the scene (display only)."""

    def __init__(self, viewer: Canvas, world: World, link_points: int = 400) -> None:
        from reachwise.distance.scene import OnLink, Runtime
        from reachwise.io.robot_clouds import link_cloud

        self.viewer, self.world = viewer, world
        scene = world.scene
        objs = scene.objects
        spec = world.scenario.spec
        self.q = {rs.name: np.asarray(rs.start, dtype=float) for rs in spec.robots}
        for name, q in self.q.items():
            scene.set_joints(name, q)
        poses = scene.poses()
        watched: dict[str, set[str]] = {n: set() for n in world.robots}
        for p in scene.pairs:
            for o in (p.a, p.b):
                src = objs[o].source
                if isinstance(src, OnLink):  # the link (body) is the name after "robot/"
                    watched[src.robot].add(o.removeprefix(f"{src.robot}/"))
        self.env = [o for o in objs.values() if not isinstance(o.source, OnLink)]
        self.dynamic = {o.name for o in self.env if isinstance(o.source, Runtime)}
        world_env = {o.name: _place(o.cloud.points, poses[o.name]) for o in self.env}
        content = [np.asarray(r.fk_all(self.q[n]))[:, :3, 3] for n, r in world.robots.items()]
        content += [w[:: max(1, len(w) // 2000)] for w in world_env.values()]
        self.goals = goal_table(world)
        if self.goals:
            content.append(np.array([g.pose[:3, 3] for g in self.goals]))
        allpts = np.vstack(content)
        viewer.set_scale(allpts)
        for name, robot in world.robots.items():
            clouds: dict[str, Any] = {}
            for part in scene.robot_objects(name):
                on = part.source
                if isinstance(on, OnLink):
                    clouds[part.name.removeprefix(f"{name}/")] = _place(
                        part.cloud.points, on.offset
                    )
            for link in robot.geometry:
                if link not in clouds:
                    try:
                        clouds[link] = link_cloud(robot, link, link_points).points
                    except InputError:
                        pass
            viewer.add_robot(name, robot, self.q[name], _Points.wrap(clouds), watched[name])
        self.env_nodes: dict[str, Any] = {}
        for obj in self.env:
            self.env_nodes[obj.name] = viewer.add_cloud(
                f"/env/{node_name(obj.name)}",
                obj.cloud.points,
                height_colours(world_env[obj.name]),
                pose=poses[obj.name],
            )
        self._cloud_version: dict[str, int] = {}
        self._frame = {sensor.name: 0 for sensor in getattr(world, "sensors", [])}
        sensors = getattr(world, "sensors", [])
        self.memories = [
            MemoryReplay(feed, [s for s in sensors if s.feed is feed])
            for feed in getattr(world, "memories", [])
        ]
        self.hidden_nodes = self._add_hidden(world)
        self.n_goals = len(self.goals)
        if self.goals:
            P = np.array([g.pose for g in self.goals])
            dims = np.array([g.dims for g in self.goals])
            viewer.add_task(P[:, :3, 3], ["unreached"] * len(P), P[:, :3, 2], dims > 3)
        floor = min(0.0, float(allpts[:, 2].min()))
        viewer.add_grid(allpts.mean(axis=0), z=floor)
        viewer.frame_camera(allpts, direction=(0.9, -1.2, 0.8))  # from the front right
        self.margins = np.asarray(world.margins, dtype=float)
        self.sliders: list[Any] = []  # joint sliders, when a mode adds them

    # ------------------------------------------------------------------ updates
    def set_robot_q(self, name: str, q: ArrayLike) -> None:
        self.q[name] = np.asarray(q, dtype=float).reshape(-1).copy()
        self.viewer.robots[name].set_q(self.q[name])

    def set_objects_at(self, t: float, poses: dict[str, NDArray[np.float64]] | None) -> None:
        """Moving objects at time ``t``: ``poses`` (logged) or their trajectories, and
        the clouds scheduled by then (``clouds:`` of the scenario)."""
        for m in getattr(self.world, "movers", []):
            name = m.spec.name
            T = None
            if poses is not None and name in poses:
                T = poses[name]
            elif getattr(m, "trajectory", None) is not None:
                T = m.trajectory.pose(t)
            if name in self.hidden_nodes:  # not in the scene: only its view moves
                if T is not None:
                    h = self.hidden_nodes[name]
                    h.wxyz, h.position = wxyz_position(T)
                continue
            if T is not None and name in self.dynamic:
                self.world.scene.set_pose(name, T)
                h = self.env_nodes.get(name)
                if h is not None:
                    h.wxyz, h.position = wxyz_position(T)
            sched = getattr(m, "clouds", [])
            v = sum(1 for ti, _ in sched if ti <= t + 1e-9)
            if v != self._cloud_version.get(name, 0):
                cloud = sched[v - 1][1] if v > 0 else self._original(name)
                self.world.scene.replace_cloud(name, cloud, block=True)
                h = self.env_nodes.get(name)
                if h is not None:
                    T0 = self.world.scene.poses()[name]
                    h.points = np.asarray(cloud.points, dtype=np.float32)
                    h.colors = height_colours(_place(cloud.points, T0))
                self._cloud_version[name] = v

    def _add_hidden(self, world: World) -> dict[str, Any]:
        """Grey points on the true surface of each object only the sensors see."""
        import trimesh

        from reachwise.geometry.cloud import sample_mesh_surface

        sight = getattr(world, "sight", None)
        out: dict[str, Any] = {}
        for os_ in world.scenario.spec.objects:
            if os_.scene or sight is None or os_.name not in sight.objects:
                continue
            surface = sight.objects[os_.name]
            v, f = surface.shape_at(0.0)[0]
            pts = sample_mesh_surface(trimesh.Trimesh(v, f, process=False), n=1500, seed=0).points
            out[os_.name] = self.viewer.add_cloud(
                f"/env/{node_name(os_.name)}", pts, HIDDEN_RGB, pose=surface.pose_at(0.0)
            )
        return out

    def set_sensor_frames(
        self, tick: int, q_at: Callable[[int], dict[str, NDArray[np.float64]] | None]
    ) -> None:
        """The sensors' clouds in the scene at ``tick``: each frame in use then,
        rendered again from the state at its capture (``q_at(capture tick)``: the
        robots' joints then, or None if unknown), into the view and the viewer's scene
        (for the closest-point lines)."""
        sight = getattr(self.world, "sight", None)
        for sensor in getattr(self.world, "sensors", []):
            if sensor.feed is not None:  # its frames go into a memory
                continue
            k = sensor.frame_in_use(tick)
            qs = q_at(sensor.capture_tick(k))
            if sight is None or k == self._frame.get(sensor.name) or qs is None:
                continue
            cloud = sensor.cloud(sensor.render(k, sight, qs))
            self.world.scene.replace_cloud(sensor.name, cloud, block=True)
            h = self.env_nodes.get(sensor.name)
            if h is not None:
                h.points = np.asarray(cloud.points, dtype=np.float32)
                h.colors = height_colours(cloud.points)
            self._frame[sensor.name] = k
        if sight is not None:
            for replay in self.memories:
                if replay.advance(tick, q_at, sight):
                    replay.feed.flush(self.world.scene, sight.frames(self.q))
                    self._show_memory(replay)

    def _show_memory(self, replay: MemoryReplay) -> None:
        """The occupied, shadow and free voxels of a memory now."""
        memory = replay.feed.memory
        show_memory_voxels(
            self.viewer, replay.feed.name, memory.state, memory.origin, memory.config.voxel
        )

    def memory_needs(self) -> int | None:
        """The earliest tick whose joints the memories' replays may still ask for."""
        return min((r.needs() for r in self.memories), default=None)

    def _original(self, name: str) -> Any:
        for o in self.env:
            if o.name == name:
                return o.cloud
        raise KeyError(name)

    def update_lines(self, result: SceneResult | None = None) -> SceneResult:
        """Closest-point lines of the watched pairs: from ``result`` (a live tick) or
        a fresh query of the world's scene at the robots' current ``q``."""
        if result is None:
            for name, q in self.q.items():
                self.world.scene.set_joints(name, q)
            result = self.world.scene.query_all()
        seg, dist, idx = pair_segments(result)
        margins = self.margins[idx] if len(self.margins) == len(result.pairs) else np.inf
        cols = distance_colours(dist, margins)
        self.viewer.set_segments("/distance/lines", seg, cols, "distance lines", 5.0)
        self.viewer.set_points(
            "/distance/ends", seg.reshape(-1, 3), cols.reshape(-1, 3), "distance lines",
            0.012 * self.viewer.scale,
        )  # fmt: skip
        return result

    def set_goal_status(self, reached: NDArray[np.bool_]) -> None:
        if self.goals:
            self.viewer.set_task_status(["reached" if r else "unreached" for r in reached])

    def set_path(self, robot: str, points: ArrayLike) -> None:
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        if len(p) > 2000:
            p = p[np.unique(np.linspace(0, len(p) - 1, 2000).round().astype(int))]
        self.viewer.set_segments(
            f"/paths/{node_name(robot)}", polyline_segments(p), PATH_RGB, "tool paths", 2.0
        )


class _Points:
    """Adapter: an ``(N, 3)`` array with a ``points`` attribute (what RobotView reads)."""

    def __init__(self, points: NDArray[np.float64]) -> None:
        self.points = points

    @staticmethod
    def wrap(clouds: dict[str, Any]) -> dict[str, Any]:
        return {k: _Points(np.asarray(v)) for k, v in clouds.items()}


def _place(points: ArrayLike, T: ArrayLike) -> NDArray[np.float64]:
    P = np.asarray(points, dtype=float)
    M = np.asarray(T, dtype=float)
    return np.asarray(P @ M[:3, :3].T + M[:3, 3])


def status_text(sim: SimScene, t: float, md: float, states: dict[str, str]) -> str:
    """The status line of a shown tick: time, smallest distance, robot states."""
    d = f"{md * 100:.1f} cm" if math.isfinite(md) else "beyond the monitored range"
    st = ", ".join(f"{r}: {s}" for r, s in states.items())
    return f"t = {t:.2f} s · min distance {d}  \n{st}"


class Playback(Timeline):
    """Replay of a simulation log in ``viewer`` (see the module doc; the controls are
    :class:`~reachwise.viz.timeline.Timeline`'s)."""

    def __init__(self, viewer: Canvas, log: SimulationLog, world: World, fps: float = 30.0):
        for r in log.robots:
            robot = world.robots.get(r)
            if robot is None or log.q[r].shape[1] != robot.n:
                raise InputError(
                    f"log of {log.scenario}", f"robots.{r}", "does not match the scenario's robots"
                )
        if log.t.size == 0:
            raise InputError(f"log of {log.scenario}", "t", "the log has no ticks")
        super().__init__(viewer, log.t, fps)
        self.log, self.world = log, world
        self.sim = SimScene(viewer, world)
        for r in log.robots:
            self.sim.set_path(r, log.tool[r][:, :3, 3])
        self.reached_at = goal_reached_at(log, self.sim.goals)
        self.min_distance = log.min_distance
        self.add_controls(log.dt)
        self.seek(0)
        coll = (
            f", first overlap at {log.first_collision:.2f} s ({log.first_collision_pair})"
            if log.first_collision is not None
            else ", no overlap"
        )
        n_ok = sum(g.reached_at is not None for g in log.goals)
        viewer.set_info(
            f"**{log.scenario}** {'with' if log.avoidance else 'without'} avoidance: "
            f"{self.T} ticks, {n_ok}/{len(log.goals)} goals reached{coll}  \n"
            + "goals: "
            + legend(("unreached", "reached"))
            + "; closest-point lines: red within the margin, amber monitored"
        )
        self.start()

    def show(self, k: int) -> None:
        """Tick ``k``: robots, moving objects, lines, goal colours, status."""
        log = self.log
        t = float(log.t[k])
        for r in log.robots:
            self.sim.set_robot_q(r, log.q[r][k])
        poses = {n: p[k] for n, p in getattr(log, "object_poses", {}).items()}
        self.sim.set_objects_at(t, poses)
        self.sim.set_sensor_frames(k, self._q_at)
        self.sim.update_lines()
        self.sim.set_goal_status(self.reached_at <= t + 1e-9)
        states = {r: str(log.state[r][k]) for r in log.robots}
        self.status.content = status_text(self.sim, t, float(self.min_distance[k]), states)

    def _q_at(self, k: int) -> dict[str, NDArray[np.float64]] | None:
        """The robots' logged joint states at tick ``k`` (None outside the log)."""
        if not 0 <= k < self.T:
            return None
        return {r: self.log.q[r][k] for r in self.log.robots}
