"""Viewer modes without a clock: a robot with joint sliders, a scenario at its start,
a synthesis result browsed point by point, a ranked topology design.

Each ``show_*`` function fills a cleared :class:`~reachwise.viz.viewer.Viewer`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.errors import InputError
from reachwise.viz.scene_data import (
    COLOUR_WORDS,
    joint_ranges,
    legend,
    node_name,
    skeleton_segments,
    status_colours,
    tunnel_wireframe,
)

if TYPE_CHECKING:
    from reachwise.kinematics.robot import Robot
    from reachwise.results.synthesis_out import SynthesisOutput
    from reachwise.sim.scenarios import Scenario
    from reachwise.tasks.task import Task
    from reachwise.viz.canvas import Canvas

__all__ = [
    "JointSliders",
    "SynthesisBrowser",
    "legend",
    "node_name",
    "robot_clouds",
    "show_robot",
    "show_scenario",
    "show_synthesis",
]


def robot_clouds(robot: Robot, points: int | None = None) -> tuple[dict[str, Any], str]:
    """Link clouds of ``robot`` (:func:`reachwise.link_clouds`), or
    none and the reason when its geometry cannot be read (the skeleton remains)."""
    from reachwise.io.robot_clouds import link_clouds

    try:
        return link_clouds(robot, points), ""
    except InputError as exc:
        return {}, f"link clouds unavailable: {exc}"


class JointSliders:
    """One slider per joint variable (revolute in degrees, prismatic in metres), within
    its limits; moving one calls ``on_change(q)`` with the whole joint vector (rad, m)."""

    def __init__(
        self,
        viewer: Canvas,
        robot: Robot,
        q: ArrayLike,
        on_change: Callable[[NDArray[np.float64]], None],
        title: str = "Joints",
        order: float = 10,
    ) -> None:
        self.robot = robot
        self.on_change = on_change
        self.q = np.asarray(q, dtype=float).reshape(-1).copy()
        self._quiet = False
        gui = viewer.server.gui
        ranges = joint_ranges(robot, self.q)
        self.factor = np.where(robot.prismatic, 1.0, 180.0 / math.pi)
        self.sliders = []
        with viewer.add_gui(gui.add_folder(title, order=order)):
            for i, j in enumerate(robot.movable_joints):
                joint = robot.joints[j]
                f = self.factor[i]
                lo, hi = ranges[i] * f
                step = 0.001 if robot.prismatic[i] else 0.1
                if not hi - lo > step:
                    hi = lo + step
                unit = "m" if robot.prismatic[i] else "°"
                tag = " passive" if joint.passive else ""
                label = f"q{i + 1} ({unit}{tag})"
                s = gui.add_slider(
                    label,
                    min=round(float(lo), 3),
                    max=round(float(hi), 3),
                    step=step,
                    initial_value=float(np.clip(round(self.q[i] * f, 3), lo, hi)),
                )
                s.on_update(self._mover(i))
                self.sliders.append(s)

    def _mover(self, i: int) -> Callable[[Any], None]:
        return lambda ev: self._moved(i, ev.target.value)

    def _moved(self, i: int, value: float) -> None:
        if self._quiet:
            return
        self.q[i] = float(value) / self.factor[i]
        self.on_change(self.q.copy())

    def set(self, q: ArrayLike, notify: bool = True) -> None:
        """Move every slider to ``q``; then one ``on_change(q)`` if ``notify``."""
        qv = np.asarray(q, dtype=float).reshape(-1)
        self._quiet = True
        try:
            for i, s in enumerate(self.sliders):
                s.value = float(np.clip(qv[i] * self.factor[i], s.min, s.max))  # type: ignore[misc]
        finally:
            self._quiet = False
        self.q = qv.copy()
        if notify:
            self.on_change(self.q.copy())


def show_robot(
    viewer: Canvas,
    robot: Robot,
    q: ArrayLike | None = None,
    task: Task | None = None,
    title: str | None = None,
) -> JointSliders:
    """A robot with its link clouds, skeleton and tool frame, and joint sliders; the
    task's points (grey: no status) when given."""
    q0 = np.clip(np.zeros(robot.n), robot.lower, robot.upper) if q is None else np.asarray(q)
    origins = np.asarray(robot.fk_all(q0))[:, :3, 3]
    content = origins if task is None else np.vstack([origins, task.positions])
    viewer.set_scale(content)
    clouds, note = robot_clouds(robot)
    view = viewer.add_robot(node_name(robot.name), robot, q0, clouds)
    if task is not None:
        viewer.add_task(task.positions, ["pending"] * len(task), task.axes, task.dims > 3)
        _tunnel(viewer, task, content)
    viewer.add_grid(content.mean(axis=0), z=min(0.0, float(content[:, 2].min())))
    sliders = JointSliders(viewer, robot, q0, view.set_q, title=f"Joints: {robot.name}")
    viewer.frame_camera(content)
    viewer.mode = "robot"
    text = f"**{title or robot.name}**: {robot.n} joint variables, {len(clouds)} link clouds"
    meshes = sum(len(v) for v in robot.visual.values())
    if meshes:
        text += f", {meshes} visual meshes"
    notes = [n for n in (note, *view.mesh_notes[:3]) if n]
    viewer.set_info(text + "".join(f"  \n{n}" for n in notes))
    viewer.activate(sliders)
    return sliders


def show_scenario(viewer: Canvas, scenario: Scenario | str) -> Any:
    """A scenario at its start: robots at ``q0`` with their clouds, the environment
    clouds, the goals and the closest-point lines of the watched pairs; the joint
    sliders move the robots and the lines follow."""
    from reachwise.sim.world import build_world
    from reachwise.viz.playback import SimScene

    world = build_world(scenario)
    sim = SimScene(viewer, world)
    sliders = []
    for k, (name, robot) in enumerate(world.robots.items()):

        def moved(q: NDArray[np.float64], name: str = name) -> None:
            sim.set_robot_q(name, q)
            sim.update_lines()

        sliders.append(
            JointSliders(viewer, robot, sim.q[name], moved, f"Joints: {name}", order=10 + k)
        )
    sim.update_lines()
    sim.sliders = sliders
    viewer.activate(sim)
    viewer.mode = "scenario"
    sc = world.scenario
    viewer.set_info(
        f"**{sc.name}** at its start: {len(world.robots)} robot(s), "
        f"{len(world.pairs)} watched pairs, {sim.n_goals} goals  \n"
        + "goals: red; closest-point lines: red within the margin, amber monitored"
    )
    return sim


def _tunnel(viewer: Canvas, task: Task, content: NDArray[np.float64]) -> None:
    env = task.envelope
    if env is None:
        return
    x0 = float(max(env.x_range[0], content[:, 0].min() - 1.0))
    x1 = float(min(env.x_end, content[:, 0].max() + 0.5))
    if not x1 > x0:
        return
    seg = tunnel_wireframe(env, np.linspace(x0, x1, 3))
    viewer.set_segments("/tunnel", seg, (170, 170, 170), "tunnel", thickness=1.5)


class SynthesisBrowser:
    """The configuration at each task point of a synthesis (P-I Figs. 4–5): a slider
    and a dropdown choose point ``i``, the robot shows ``q[i]``, the points are coloured
    by status; every configuration's skeleton is available ("configurations")."""

    def __init__(self, viewer: Canvas, out: SynthesisOutput) -> None:
        self.viewer = viewer
        self.out = out
        robot = out.robot
        K = len(out.q)
        F = np.asarray(robot.fk(out.q))
        content = np.vstack([out.positions, np.asarray(robot.fk_all(out.q[0]))[:, :3, 3]])
        viewer.set_scale(content)
        clouds, note = robot_clouds(robot)
        self.view = viewer.add_robot("design", robot, out.q[0], clouds)
        axes = out.target_axes
        viewer.add_task(out.positions, out.status, axes, out.dims > 3)
        allseg = np.concatenate([skeleton_segments(robot, q) for q in out.q])
        per = len(allseg) // K
        cols = np.repeat(status_colours(out.status), per, axis=0)
        viewer.set_segments(
            "/configurations", allseg, np.repeat(cols[:, None], 2, axis=1), "configurations", 1.0
        )
        if out.task is not None:
            _tunnel(viewer, out.task, content)
        viewer.add_grid(content.mean(axis=0), z=min(0.0, float(content[:, 2].min())))
        gui = viewer.server.gui
        self.labels = tuple(f"{k}: {out.names[k]} ({out.status[k]})" for k in range(K))
        self._busy = False
        with viewer.add_gui(gui.add_folder("Task point", order=5)):
            self.slider = gui.add_slider(
                "point", min=0, max=max(K - 1, 1), step=1, initial_value=0, disabled=K < 2
            )
            self.dropdown = gui.add_dropdown("name", self.labels, initial_value=self.labels[0])
            self.details = gui.add_markdown("")
        self.slider.on_update(lambda ev: self.select(int(ev.target.value)))
        self.dropdown.on_update(lambda ev: self.select(self.labels.index(str(ev.target.value))))
        self.sliders = JointSliders(viewer, robot, out.q[0], self.view.set_q, "Joints", order=20)
        self.marker = viewer.add_node(
            "/task/selected",
            viewer.server.scene.add_frame(
                "/task/selected",
                axes_length=0.05 * viewer.scale,
                axes_radius=0.003 * viewer.scale,
            ),
            "task points",
        )
        self._targets = F
        self.index = -1
        self.select(0)
        viewer.frame_camera(content)
        viewer.mode = "synthesis"
        s = out.summary
        counts = {k: out.status.count(k) for k in ("full", "position", "orientation", "neither")}
        viewer.set_info(
            f"**{robot.name}** for **{s.get('task', '?')}**: {int(out.reached.sum())}/{K} "
            f"points reached  \n"
            + ", ".join(f"{v} {k} ({COLOUR_WORDS[k]})" for k, v in counts.items())
            + (f"  \n{note}" if note else "")
        )

    def select(self, k: int) -> None:
        """Show task point ``k``: the robot at ``q[k]``, the target frame, the numbers."""
        if self._busy or k == self.index:
            return
        out = self.out
        k = int(np.clip(k, 0, len(out.q) - 1))
        self._busy = True
        try:
            self.index = k
            self.slider.value = k  # type: ignore[misc]  # (viser: settable, mypy: not)
            self.dropdown.value = self.labels[k]  # type: ignore[misc]
            self.sliders.set(out.q[k])
            T = np.eye(4)
            T[:3, 3] = out.positions[k]
            if out.task is not None:
                T = out.task.poses[k]
            from reachwise.viz.scene_data import wxyz_position

            wxyz, pos = wxyz_position(T)
            self.marker.wxyz, self.marker.position = wxyz, pos
            self.details.content = (
                f"{out.names[k]} · group {out.groups[k]} · {out.dims[k]}-D  \n"
                f"status **{out.status[k]}**: position error "
                f"{out.position_error[k] * 1e3:.3f} mm, orientation error "
                f"{out.orientation_error[k] * 1e3:.3f} mrad  \n"
                f"LCI {out.lci_initial[k]:.3f} → {out.lci_final[k]:.3f}"
            )
        finally:
            self._busy = False


def show_synthesis(viewer: Canvas, out: SynthesisOutput) -> SynthesisBrowser:
    """A synthesis result: the design at each task point (see :class:`SynthesisBrowser`)."""
    browser = SynthesisBrowser(viewer, out)
    viewer.activate(browser)
    return browser
