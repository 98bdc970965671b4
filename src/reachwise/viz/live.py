"""A live view attached to a running simulation.

:class:`LiveRun` runs :func:`reachwise.simulate` with an ``on_tick``
hook that pushes each tick's ``q`` and the scene's answer (``res.pairs[i].result``,
``point_a``/``point_b`` in world frame: the closest-point lines) to the browser, at
most ``fps`` times per second, paced at ``speed`` × real time (0: as fast as it
runs); the last tick is always shown, and when the run ends the viewer switches to
the playback of its log. :class:`LiveSession` is the same for ``reachwise simulate
--view``, whose runs happen in the command's own thread.
"""

from __future__ import annotations

import math
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from reachwise.viz.playback import Playback, SimScene, status_text

if TYPE_CHECKING:
    from reachwise.distance.scene import SceneResult
    from reachwise.sim.log import SimulationLog
    from reachwise.sim.scenarios import Scenario
    from reachwise.sim.world import World
    from reachwise.viz.viewer import Viewer

__all__ = ["LiveRun", "LiveSession", "LiveStopped"]


class LiveStopped(Exception):
    """Raised inside ``on_tick`` to end a live simulation early."""


class LiveRun:
    """A simulation shown while it runs (see the module doc). ``on_tick`` is the hook
    for :func:`reachwise.simulate`; :meth:`start` runs it in a thread."""

    def __init__(
        self,
        viewer: Viewer,
        scenario: Scenario | str | Path,
        avoidance: bool = True,
        *,
        duration: float | None = None,
        speed: float = 1.0,
        fps: float = 30.0,
        label: str | None = None,
    ) -> None:
        from reachwise.sim.world import build_world

        self.viewer = viewer
        self.world = build_world(scenario, avoidance)
        self.scenario = self.world.scenario
        self.avoidance, self.duration, self.speed, self.fps = avoidance, duration, speed, fps
        self.label = label or ("avoidance" if avoidance else "baseline")
        self.sim = SimScene(viewer, self.world)
        self.paths: dict[str, list[NDArray[np.float64]]] = {r: [] for r in self.world.robots}
        self.log: SimulationLog | None = None
        self.error: BaseException | None = None
        self.ticks = 0
        self.pushed = 0
        self.t = 0.0
        self._halt = threading.Event()
        self.done = threading.Event()
        self._wall0: float | None = None
        self._last = -math.inf
        self._pending: tuple[Any, ...] | None = None
        self._thread: threading.Thread | None = None
        self._history: dict[int, dict[str, NDArray[np.float64]]] = {}  # tick -> q (sensors)
        viewer.mode = "live"
        viewer.activate(self)
        viewer.set_info(f"**{self.scenario.name}** ({self.label}), live: starting …")

    def on_tick(self, t: float, qs: dict[str, NDArray[np.float64]], res: SceneResult) -> None:
        """The simulation's hook: pace, record the tool paths, push at most ``fps``/s."""
        if self._halt.is_set() or self.viewer.stopped:
            raise LiveStopped
        now = time.monotonic()
        if self._wall0 is None:
            self._wall0 = now - (t / self.speed if self.speed > 0 else 0.0)
        if self.speed > 0:
            wait = self._wall0 + t / self.speed - now
            if wait > 0 and self._halt.wait(wait):
                raise LiveStopped
        self.ticks += 1
        self.t = t
        for r, q in qs.items():
            self.paths[r].append(np.asarray(self.world.robots[r].fk(q))[:3, 3])
        if self.world.sensors:  # the joints since the oldest capture still to be shown
            tick = round(t / self.scenario.spec.dt)
            self._history[tick] = {r: np.array(q) for r, q in qs.items()}
            oldest = min(s.capture_tick(s.frame_in_use(tick)) for s in self.world.sensors)
            needs = self.sim.memory_needs()  # frames a memory has still to fuse
            oldest = oldest if needs is None else min(oldest, needs)
            for old in [k for k in self._history if k < oldest]:
                del self._history[old]
        now = time.monotonic()
        self._pending = (t, qs, res)
        if now - self._last >= 1.0 / self.fps:
            self._last = now
            self.push(t, qs, res)

    def flush(self) -> None:
        """Show the last tick if the rate limit held it back (the end of a run)."""
        if self._pending is not None:
            self.push(*self._pending)

    def push(self, t: float, qs: dict[str, NDArray[np.float64]], res: SceneResult) -> None:
        """Show one tick: robots, moving objects, the scene's closest-point lines."""
        with self.viewer.locked(self._halt) as ok:
            if not ok or self.viewer.active is not self:
                return
            for r, q in qs.items():
                self.sim.set_robot_q(r, q)
            self.sim.set_objects_at(t, None)
            self.sim.set_sensor_frames(round(t / self.scenario.spec.dt), self._history.get)
            self.sim.update_lines(res)
            for r, pts in self.paths.items():
                if len(pts) > 1:
                    self.sim.set_path(r, np.array(pts))
            d = [p.result.distance for p in res.pairs]
            md = min(d) if d else math.inf
            self.viewer.set_info(
                f"**{self.scenario.name}** ({self.label}), live  \n"
                + status_text(self.sim, t, md, {})
            )
            self.pushed += 1
            self._pending = None

    def run(self) -> SimulationLog | None:
        """Run the simulation here (blocking); ``None`` if stopped early."""
        from reachwise.sim.simulate import simulate

        try:
            self.log = simulate(
                self.scenario, self.avoidance, duration=self.duration, on_tick=self.on_tick
            )
            self.flush()
        except LiveStopped:
            return None
        except Exception as exc:  # shown in the browser and kept for the caller
            self.error = exc
            self.viewer.set_info(f"**{self.scenario.name}**: the simulation failed: {exc}")
            return None
        finally:
            self.done.set()
        return self.log

    def start(self, replay: bool = True) -> None:
        """Run in a thread; with ``replay`` switch to the log's playback at the end."""

        def work() -> None:
            log = self.run()
            if log is not None and replay and not self._halt.is_set():
                world = self.world

                def show(v: Viewer) -> None:
                    Playback(v, log, world)

                self.viewer.show_entries({self.label: show})

        self._thread = threading.Thread(target=work, name="reachwise-live", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._halt.set()
        th = self._thread
        if th is not None and th is not threading.current_thread():
            th.join(timeout=10.0)


class LiveSession:
    """For ``reachwise simulate --view``: one viewer that shows each run of a scenario
    live (:meth:`hook`), then replays the logs (:meth:`replay`)."""

    def __init__(
        self,
        scenario: Scenario | str | Path,
        host: str = "127.0.0.1",
        port: int = 8080,
        speed: float = 1.0,
        echo: Any = print,
    ) -> None:
        from reachwise.sim.scenarios import load_scenario
        from reachwise.viz.viewer import Viewer

        self.scenario = load_scenario(scenario)
        self.viewer = Viewer(host, port)
        self.speed = speed
        self.worlds: dict[bool, World] = {}
        self.run: LiveRun | None = None  # the current run
        if echo is not None:
            echo(f"viewer at {self.viewer.url} (Ctrl-C to stop)")

    def hook(self, avoidance: bool = True, label: str | None = None) -> Any:
        """A fresh live view of the next run; returns its ``on_tick``."""
        if self.run is not None:
            self.run.flush()
        self.viewer.clear()
        with self.viewer.lock:
            self.run = LiveRun(self.viewer, self.scenario, avoidance, speed=self.speed, label=label)
        self.worlds[avoidance] = self.run.world
        return self.run.on_tick

    def replay(self, logs: dict[str, SimulationLog], block: bool = True) -> None:
        """Switch to the playback of ``logs`` (a dropdown when several); with
        ``block`` wait for Ctrl-C, then stop the server."""
        from reachwise.sim.world import build_world

        def entry(log: SimulationLog) -> Any:
            def show(v: Viewer) -> None:
                w = self.worlds.get(log.avoidance) or build_world(self.scenario, log.avoidance)
                Playback(v, log, w)

            return show

        self.viewer.show_entries({label: entry(log) for label, log in logs.items()})
        if block:
            self.viewer.wait()

    def stop(self) -> None:
        self.viewer.stop()
