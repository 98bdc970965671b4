"""The browser viewer (viser): robots, task points, clouds, distances, playback.

:class:`Viewer` wraps a :class:`viser.ViserServer` bound to 127.0.0.1 unless asked
(``host``); if ``port`` is taken the next free one is used (``viewer.url`` says which).
It keeps a registry of what it put in the scene (``viewer.nodes``: scene-node name →
viser handle, ``viewer.categories``: display category → names) so that the
"Display" checkboxes, tests and the modes can find them.

What it shows, one *mode* at a time, switched from a "Result" dropdown when
a folder holds several results (:func:`serve_results`):

- a robot with joint sliders (:func:`reachwise.viz.modes.show_robot`);
- a scenario at its start configuration, with live closest-point lines as the
  sliders move (:func:`reachwise.viz.modes.show_scenario`);
- a synthesis result, browsing the configuration at each task point, the points
  coloured by status after P-I Fig. 4 (:func:`reachwise.viz.modes.show_synthesis`);
- the playback of a simulation log, play/pause and a time slider, every robot, the
  scenario's clouds, the goals turning green when reached, the tool paths and the
  closest-point lines of the watched pairs at each tick
  (:class:`reachwise.viz.playback.Playback`);
- a live view of a running simulation (:class:`reachwise.viz.live.LiveRun`).

Ctrl-C in :meth:`Viewer.wait` stops the server (its port and threads are freed).
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from reachwise.viz.nodes import RobotView, robot_size
from reachwise.viz.scene_data import (
    axis_segments,
    camera_view,
    status_colours,
    wxyz_position,
)
from reachwise.viz.sources import find_results

if TYPE_CHECKING:
    import viser

__all__ = ["CATEGORIES", "Viewer", "serve_results"]

#: Display categories, each with a checkbox in the "Display" folder.
CATEGORIES = (
    "robot clouds",
    "robot meshes",
    "skeleton",
    "frames",
    "task points",
    "tool axes",
    "environment",
    "distance lines",
    "memory voxels",
    "free voxels",
    "tool paths",
    "configurations",
    "tunnel",
)
_HIDDEN_AT_START = frozenset({"configurations", "free voxels"})


class Viewer:
    """A viser server showing reachwise models and results (see the module doc)."""

    def __init__(self, host: str = "127.0.0.1", port: int = 8080, *, label: str = "reachwise"):
        import sys

        import viser

        with contextlib.redirect_stdout(sys.stderr):  # viser's banner: keep stdout clean
            self.server: viser.ViserServer = viser.ViserServer(
                host=host, port=port, label=label, verbose=False
            )
        self.lock = threading.RLock()
        self.nodes: dict[str, Any] = {}
        self.categories: dict[str, list[str]] = {c: [] for c in CATEGORIES}
        self.robots: dict[str, RobotView] = {}
        self.mode = "empty"
        self.title = ""
        self.active: Any = None  # the mode's controller (Playback, LiveRun, browser …)
        self._gui: list[Any] = []
        self._stopped = threading.Event()
        self._scale = 1.0
        self.results: Any = None
        with self.server.gui.add_folder("Display", expand_by_default=False, order=100):
            self.display = {
                c: self.server.gui.add_checkbox(c, initial_value=c not in _HIDDEN_AT_START)
                for c in CATEGORIES
            }
        for c, box in self.display.items():
            box.on_update(self._toggler(c))
        self.info = self.server.gui.add_markdown("", order=0)

    # ------------------------------------------------------------------ server
    @property
    def host(self) -> str:
        return self.server.get_host()

    @property
    def port(self) -> int:
        return self.server.get_port()

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}"

    @property
    def stopped(self) -> bool:
        return self._stopped.is_set()

    def stop(self) -> None:
        """Stop whatever the mode runs (playback, live simulation) and the server;
        frees the port and threads. Safe to call twice."""
        if self._stopped.is_set():
            return
        self._stop_active()
        self._stopped.set()
        self.server.stop()

    def wait(self, timeout: float | None = None) -> None:
        """Block until Ctrl-C, :meth:`stop` or ``timeout`` seconds; Ctrl-C (and the
        timeout) stop the server."""
        import time

        end = None if timeout is None else time.monotonic() + timeout
        try:
            while not self._stopped.wait(0.2):
                if end is not None and time.monotonic() >= end:
                    break
        except KeyboardInterrupt:
            pass
        self.stop()

    # ------------------------------------------------------------------ registry
    def add_node(self, name: str, handle: Any, category: str | None = None) -> Any:
        """Register a scene node (visible per its category's checkbox)."""
        with self.lock:
            self.nodes[name] = handle
            if category is not None:
                if name not in self.categories[category]:
                    self.categories[category].append(name)
                if not self.display[category].value:
                    handle.visible = False
        return handle

    def add_gui(self, handle: Any) -> Any:
        """Register a GUI element of the current mode (removed by :meth:`clear`)."""
        self._gui.append(handle)
        return handle

    def _toggler(self, category: str) -> Callable[[Any], None]:
        return lambda _: self._show_category(category)

    def _show_category(self, category: str) -> None:
        on = bool(self.display[category].value)
        with self.lock:
            for name in self.categories[category]:
                h = self.nodes.get(name)
                if h is not None:
                    h.visible = on

    def _stop_active(self) -> None:
        stop = getattr(self.active, "stop", None)
        if callable(stop):
            stop()
        self.active = None

    def activate(self, controller: Any) -> None:
        """Make ``controller`` (a playback, a live run …) the mode's; the previous one
        is stopped (its thread ended)."""
        if self.active is not None and self.active is not controller:
            self._stop_active()
        self.active = controller

    @contextlib.contextmanager
    def locked(self, halt: threading.Event) -> Iterator[bool]:
        """The viewer's lock for a worker thread: yields ``False`` (not holding it) if
        ``halt`` is set while waiting, so a stopping thread never waits forever."""
        while not halt.is_set():
            if self.lock.acquire(timeout=0.05):
                try:
                    yield True
                finally:
                    self.lock.release()
                return
        yield False

    def clear(self) -> None:
        """Remove the current mode: its scene nodes, its GUI, its threads."""
        self._stop_active()  # before the lock: its thread may be waiting for it
        with self.lock:
            roots = [n for n in self.nodes if n.rsplit("/", 1)[0] not in self.nodes]
            for n in roots:
                self.nodes[n].remove()
            self.nodes.clear()
            for names in self.categories.values():
                names.clear()
            for g in reversed(self._gui):
                g.remove()
            self._gui.clear()
            self.robots.clear()
            self.mode, self.title = "empty", ""
            self.info.content = ""

    # ------------------------------------------------------------------ building blocks
    @property
    def scale(self) -> float:
        """Length scale of the current content (m): sizes points, axes and lines."""
        return self._scale

    def set_scale(self, points: ArrayLike) -> float:
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        p = p[np.isfinite(p).all(axis=1)]
        if len(p):
            self._scale = max(float(np.linalg.norm(p.max(axis=0) - p.min(axis=0))), 0.5)
        return self._scale

    def add_robot(
        self,
        name: str,
        robot: Any,
        q: ArrayLike,
        clouds: Mapping[str, Any] | None = None,
        watched: set[str] | frozenset[str] = frozenset(),
    ) -> RobotView:
        """Add ``robot`` (its link clouds, skeleton and tool frame) as ``/robots/<name>``."""
        size = max(robot_size(robot, q), 0.25 * self.scale)
        view = RobotView(self, name, robot, q, clouds, watched, size=size)
        self.robots[name] = view
        return view

    def add_cloud(
        self,
        name: str,
        points: ArrayLike,
        colors: ArrayLike | tuple[int, int, int],
        pose: ArrayLike | None = None,
        point_size: float | None = None,
        category: str = "environment",
    ) -> Any:
        """A point cloud (points in its own frame, placed at ``pose``)."""
        wxyz, pos = wxyz_position(np.eye(4) if pose is None else pose)
        h = self.server.scene.add_point_cloud(
            name,
            np.asarray(points, dtype=np.float32),
            np.asarray(colors, dtype=np.uint8),
            point_size=0.004 * self.scale if point_size is None else point_size,
            precision="float32",
            wxyz=wxyz,
            position=pos,
        )
        return self.add_node(name, h, category)

    def set_segments(
        self,
        name: str,
        segments: ArrayLike,
        colors: ArrayLike | tuple[int, int, int],
        category: str,
        thickness: float = 2.5,
    ) -> Any:
        """Create or update line segments ``(M, 2, 3)``; hidden while ``M == 0``."""
        seg = np.asarray(segments, dtype=np.float32).reshape(-1, 2, 3)
        col = np.asarray(colors, dtype=np.uint8)
        if col.shape == (3,):
            col = np.broadcast_to(col, seg.shape).copy()
        with self.lock:
            h = self.nodes.get(name)
            if h is None or len(h.points) != len(seg):
                pts = seg if len(seg) else np.zeros((1, 2, 3), np.float32)
                cols = col if len(seg) else np.zeros((1, 2, 3), np.uint8)
                h = self.server.scene.add_line_segments(
                    name, pts, cols, thickness=thickness, thickness_units="screen"
                )
                self.add_node(name, h, category)
            else:
                with self.server.atomic():
                    h.points = seg
                    h.colors = col
            h.visible = bool(len(seg)) and bool(self.display[category].value)
        return h

    def set_points(
        self, name: str, points: ArrayLike, colors: ArrayLike, category: str, size: float
    ) -> Any:
        """Create or update a small point cloud (world frame); hidden while empty."""
        pts = np.asarray(points, dtype=np.float32).reshape(-1, 3)
        col = np.asarray(colors, dtype=np.uint8).reshape(-1, 3)
        with self.lock:
            h = self.nodes.get(name)
            if h is None or len(h.points) != len(pts):
                h = self.server.scene.add_point_cloud(
                    name,
                    pts if len(pts) else np.zeros((1, 3), np.float32),
                    col if len(pts) else np.zeros((1, 3), np.uint8),
                    point_size=size,
                    precision="float32",
                    point_shape="circle",
                )
                self.add_node(name, h, category)
            else:
                with self.server.atomic():
                    h.points = pts
                    h.colors = col
            h.visible = bool(len(pts)) and bool(self.display[category].value)
        return h

    def add_task(
        self,
        positions: ArrayLike,
        status: list[str] | tuple[str, ...],
        axes: ArrayLike | None = None,
        show_axis: ArrayLike | None = None,
        name: str = "/task",
    ) -> None:
        """Task points coloured by status (P-I Fig. 4) and their tool axes."""
        p = np.asarray(positions, dtype=float).reshape(-1, 3)
        self.add_cloud(
            f"{name}/points",
            p,
            status_colours(status),
            point_size=0.007 * self.scale,
            category="task points",
        )
        if axes is not None:
            a = np.asarray(axes, dtype=float).reshape(-1, 3)
            keep = np.ones(len(p), bool) if show_axis is None else np.asarray(show_axis, bool)
            seg = axis_segments(p[keep], a[keep], 0.04 * self.scale)
            self.set_segments(f"{name}/axes", seg, (90, 90, 90), "tool axes", thickness=2.0)

    def set_task_status(self, status: list[str] | tuple[str, ...], name: str = "/task") -> None:
        h = self.nodes.get(f"{name}/points")
        if h is not None:
            h.colors = status_colours(status)

    def frame_camera(self, points: ArrayLike, direction: ArrayLike | None = None) -> None:
        """Point the camera (initial and of connected browsers) at ``points``."""
        pos, look = camera_view(points) if direction is None else camera_view(points, direction)
        cam = self.server.initial_camera
        cam.position, cam.look_at = pos, look
        for client in self.server.get_clients().values():
            client.camera.position, client.camera.look_at = pos, look

    def add_grid(self, centre: ArrayLike, z: float = 0.0) -> None:
        c = np.asarray(centre, dtype=float)
        size = float(np.ceil(1.5 * self.scale))
        cell = 10.0 ** np.floor(np.log10(max(size / 8.0, 1e-3)))
        self.add_node(
            "/grid",
            self.server.scene.add_grid(
                "/grid",
                width=size,
                height=size,
                cell_size=cell,
                section_size=10 * cell,
                position=(float(c[0]), float(c[1]), z),
            ),
        )

    def set_info(self, text: str) -> None:
        self.info.content = text

    # ------------------------------------------------------------------ what to show
    def show(self, path: str | Path, scenario: str | Path | None = None) -> None:
        """Show what ``path`` is: a robot or scenario (built-in name or file), a
        simulation or synthesis output folder, or a folder of such results (a
        "Result" dropdown chooses one). See :mod:`reachwise.viz.sources`."""
        entries = find_results(path, scenario=scenario)
        self.show_entries(entries)

    def show_entries(self, entries: Mapping[str, Callable[[Viewer], None]]) -> None:
        """A dropdown of results (when more than one); shows the first."""
        from reachwise.errors import InputError

        if not entries:
            raise InputError("viewer", "results", "nothing to show")
        labels = list(entries)
        if self.results is not None:
            self.results.remove()
            self.results = None
        if len(labels) > 1:
            self.results = self.server.gui.add_dropdown(
                "Result", tuple(labels), initial_value=labels[0], order=1
            )

            def pick(_: Any) -> None:
                self.open_entry(entries, str(self.results.value))

            self.results.on_update(pick)
        self.open_entry(entries, labels[0])

    def open_entry(self, entries: Mapping[str, Callable[[Viewer], None]], label: str) -> None:
        """Clear the viewer and show result ``label`` of ``entries``."""
        self._stop_active()  # outside the lock: its thread may be waiting for it
        with self.lock:
            self.clear()
            try:
                entries[label](self)
            except Exception as exc:  # a broken result must not kill the server
                from reachwise.errors import ReachwiseError

                if not isinstance(exc, ReachwiseError):
                    raise
                self.set_info(f"**{label}**: cannot show it: {exc}")
                return
            self.title = label


def serve_results(
    path: str | Path,
    host: str = "127.0.0.1",
    port: int = 8080,
    block: bool = True,
    scenario: str | Path | None = None,
    echo: Callable[[str], None] | None = print,
) -> Viewer:
    """Open a viewer on ``path`` (see :meth:`Viewer.show`) and print its URL. With
    ``block`` wait until Ctrl-C, then stop the server (the returned viewer is
    stopped); else return the running viewer (call ``viewer.stop()``)."""
    viewer = Viewer(host, port)
    try:
        viewer.show(path, scenario=scenario)
    except BaseException:
        viewer.stop()
        raise
    if echo is not None:
        echo(f"viewer at {viewer.url} (Ctrl-C to stop)")
    if block:
        viewer.wait()
    return viewer
