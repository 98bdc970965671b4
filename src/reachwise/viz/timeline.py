"""The controls of a playback in the viewer: play / pause, a time slider (scrub), the
speed and loop, over frames at given times.

:class:`Timeline` owns the controls and the thread that advances the shown frame
while playing (in the recording's time, times the speed); what a frame shows is the
subclass's :meth:`Timeline.show`. A simulation log
(:class:`~reachwise.viz.playback.Playback`) and a replayed recording
(:class:`~reachwise.viz.replay_view.ReplayPlayback`) are the two.
"""

from __future__ import annotations

import threading
import time
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

if TYPE_CHECKING:
    from reachwise.viz.canvas import Canvas

__all__ = ["Timeline"]


def _icon(name: str) -> Any:
    import viser

    return getattr(viser.Icon, name)


class Timeline:
    """Frames at increasing ``times`` (s) shown in ``viewer``, one at a time (see the
    module docstring). A subclass draws its scene, calls :meth:`add_controls`, shows
    the first frame (:meth:`seek`) and then :meth:`start`."""

    SPEEDS = ("0.25x", "0.5x", "1x", "2x", "4x")

    def __init__(self, viewer: Canvas, times: ArrayLike, fps: float = 30.0) -> None:
        self.viewer = viewer
        self.times = np.asarray(times, dtype=float).reshape(-1)
        self.T = int(self.times.size)
        self.fps = fps
        self.index = -1
        self.playing = False
        self.speed = 1.0
        self._k0, self._t0 = 0, time.monotonic()
        self._halt = threading.Event()
        self._seek_lock = threading.Lock()
        self._thread: threading.Thread | None = None

    def show(self, k: int) -> None:
        """Draw frame ``k`` (the subclass's)."""
        raise NotImplementedError

    def add_controls(self, step: float, order: int = 5) -> None:
        """The Playback folder: play button, time slider (``step`` s), speed, loop and
        a status line (its ``status``)."""
        gui = self.viewer.server.gui
        start, end = float(self.times[0]), float(self.times[-1])
        with self.viewer.add_gui(gui.add_folder("Playback", order=order)):
            self.button = gui.add_button("Play", icon=_icon("PLAYER_PLAY"))
            self.slider = gui.add_slider(
                "time (s)",
                min=min(0.0, start),
                max=max(end, step),
                step=step,
                initial_value=start,
                disabled=self.T < 2,
            )
            self.speed_box = gui.add_dropdown("speed", self.SPEEDS, initial_value="1x")
            self.loop = gui.add_checkbox("loop", initial_value=False)
            self.status = gui.add_markdown("")
        self.button.on_click(lambda _: self.toggle())
        self.slider.on_update(self._slid)
        self.speed_box.on_update(lambda ev: self._set_speed(str(ev.target.value)))

    def start(self) -> None:
        """Make this the viewer's active playback and start the thread that plays."""
        self.viewer.mode = "playback"
        self.viewer.activate(self)
        self._thread = threading.Thread(target=self._run, name="reachwise-playback", daemon=True)
        self._thread.start()

    # ------------------------------------------------------------------ controls
    def tick_of(self, t: float) -> int:
        """The frame nearest to time ``t``."""
        k = int(np.searchsorted(self.times, float(t)))
        if k >= self.T:
            return self.T - 1
        if k > 0 and float(t) - self.times[k - 1] <= self.times[k] - float(t):
            return k - 1
        return k

    def seek(self, k: int) -> None:
        """Show frame ``k`` (clipped to the frames), unless it is shown already."""
        k = int(np.clip(k, 0, self.T - 1))
        with self._seek_lock, self.viewer.locked(self._halt) as ok:
            if not ok or k == self.index:
                return
            self.show(k)
            self.index = k

    def _slid(self, ev: Any) -> None:
        k = self.tick_of(ev.target.value)
        if getattr(ev, "client", None) is not None:  # the user dragged: re-anchor
            self._k0, self._t0 = k, time.monotonic()
        self.seek(k)

    def _set_speed(self, label: str) -> None:
        self._k0, self._t0 = max(self.index, 0), time.monotonic()
        self.speed = float(label.rstrip("x"))

    def play(self) -> None:
        if self.index >= self.T - 1:
            self.slider.value = float(self.times[0])  # type: ignore[misc]  # (viser: settable)
        self._k0, self._t0 = max(self.index, 0), time.monotonic()
        self.playing = True
        self.button.label, self.button.icon = "Pause", _icon("PLAYER_PAUSE")

    def pause(self) -> None:
        self.playing = False
        self.button.label, self.button.icon = "Play", _icon("PLAYER_PLAY")

    def toggle(self) -> None:
        self.pause() if self.playing else self.play()

    def _frame_now(self) -> int:
        """The last frame at or before the time reached since playing began."""
        t = self.times[self._k0] + (time.monotonic() - self._t0) * self.speed
        return int(np.searchsorted(self.times, t, side="right")) - 1

    def _run(self) -> None:
        while not self._halt.wait(1.0 / self.fps):
            if not self.playing:
                continue
            k = max(self._frame_now(), 0)
            if k >= self.T - 1:
                if self.loop.value:
                    self._k0, self._t0, k = 0, time.monotonic(), 0
                else:
                    k = self.T - 1
                    self.pause()
            if k != self.index:
                self.slider.value = float(self.times[k])  # type: ignore[misc]  # → seek

    def stop(self) -> None:
        self.playing = False
        self._halt.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=5.0)
