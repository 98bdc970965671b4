"""A scene memory's voxels in the viewer: its occupied (red), shadow (purple) and free
(green, hidden at first) voxels as three point layers, the same for a simulation
(:class:`~reachwise.viz.playback.SimScene`, live and in playback) and a replayed
recording (:class:`~reachwise.viz.replay_view.ReplayPlayback`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.distance.scene_memory import STATES
from reachwise.viz.scene_data import MEMORY_RGB, node_name, voxel_centres

if TYPE_CHECKING:
    from reachwise.viz.canvas import Canvas

__all__ = ["MAX_VOXELS_SHOWN", "SHOWN_STATES", "memory_node", "show_memory_voxels"]

#: Most voxels drawn per memory and state (every n-th beyond).
MAX_VOXELS_SHOWN = {"occupied": 150_000, "shadow": 150_000, "free": 60_000}
#: The states drawn, each its own node.
SHOWN_STATES = ("occupied", "shadow", "free")


def memory_node(name: str, state: str) -> str:
    """The viewer node of memory ``name``'s voxels in ``state``."""
    return f"/memory/{node_name(name)}/{state}"


def show_memory_voxels(
    viewer: Canvas, name: str, state: NDArray[np.uint8], origin: ArrayLike, voxel: float
) -> None:
    """Draw memory ``name``'s voxel grid ``state`` (its corner at ``origin``, edge
    ``voxel``, m): each of :data:`SHOWN_STATES` as points at the voxels' centres (at
    most :data:`MAX_VOXELS_SHOWN` of them), in the layer "memory voxels" (occupied,
    shadow) or "free voxels"."""
    for s in SHOWN_STATES:
        pts = voxel_centres(state, origin, voxel, STATES[s], MAX_VOXELS_SHOWN[s])
        viewer.set_points(
            memory_node(name, s),
            pts,
            np.broadcast_to(np.array(MEMORY_RGB[s], np.uint8), pts.shape),
            "free voxels" if s == "free" else "memory voxels",
            (0.35 if s == "free" else 0.8) * voxel,
        )
