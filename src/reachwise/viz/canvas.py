"""What a viewer mode draws on: :class:`Canvas`, the part of
:class:`reachwise.viz.viewer.Viewer` the modes (:mod:`reachwise.viz.modes`), the
playback (:mod:`reachwise.viz.playback`) and the result sources
(:mod:`reachwise.viz.sources`) use. They are typed against it, so the viewer (which
opens them) and they do not import each other in a circle."""

from __future__ import annotations

import threading
from collections.abc import Mapping
from contextlib import AbstractContextManager
from typing import TYPE_CHECKING, Any, Protocol

from numpy.typing import ArrayLike

from reachwise.viz.nodes import RobotView

if TYPE_CHECKING:
    import viser

__all__ = ["Canvas"]


class Canvas(Protocol):
    """A browser scene with a registry of nodes, a GUI panel and one active mode."""

    server: viser.ViserServer
    robots: dict[str, RobotView]
    mode: str

    @property
    def scale(self) -> float:
        """Length scale of the current content (m)."""
        ...

    def set_scale(self, points: ArrayLike) -> float: ...

    def add_node(self, name: str, handle: Any, category: str | None = None) -> Any: ...

    def add_gui(self, handle: Any) -> Any: ...

    def activate(self, controller: Any) -> None: ...

    def locked(self, halt: threading.Event) -> AbstractContextManager[bool]: ...

    def add_robot(
        self,
        name: str,
        robot: Any,
        q: ArrayLike,
        clouds: Mapping[str, Any] | None = None,
        watched: set[str] | frozenset[str] = frozenset(),
    ) -> RobotView: ...

    def add_cloud(
        self,
        name: str,
        points: ArrayLike,
        colors: ArrayLike | tuple[int, int, int],
        pose: ArrayLike | None = None,
        point_size: float | None = None,
        category: str = "environment",
    ) -> Any: ...

    def set_segments(
        self,
        name: str,
        segments: ArrayLike,
        colors: ArrayLike | tuple[int, int, int],
        category: str,
        thickness: float = 2.5,
    ) -> Any: ...

    def set_points(
        self, name: str, points: ArrayLike, colors: ArrayLike, category: str, size: float
    ) -> Any: ...

    def add_task(
        self,
        positions: ArrayLike,
        status: list[str] | tuple[str, ...],
        axes: ArrayLike | None = None,
        show_axis: ArrayLike | None = None,
        name: str = "/task",
    ) -> None: ...

    def set_task_status(self, status: list[str] | tuple[str, ...], name: str = "/task") -> None: ...

    def frame_camera(self, points: ArrayLike, direction: ArrayLike | None = None) -> None: ...

    def add_grid(self, centre: ArrayLike, z: float = 0.0) -> None: ...

    def set_info(self, text: str) -> None: ...
