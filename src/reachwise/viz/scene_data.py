"""What the browser viewer draws, as plain arrays (no server, no files, no clock).

Everything :mod:`reachwise.viz.viewer` sends to the browser is computed here from the
kinematic model and the results, so it can be tested without a browser:

- the robot skeleton: one segment between the origins of consecutive frames of
  ``Robot.fk_all(q)`` (base, link_1 … link_N, tool — the stick figures of P-I Fig. 5);
- task-point colours by status, after P-I Fig. 4 (green: full pose reached; blue:
  position only; yellow: orientation only; red: neither), the same colours as
  ``reachwise.report.plots``;
- closest-point lines of the watched pairs of a :class:`~reachwise.distance.SceneResult`
  (``point_a``–``point_b`` in world frame, thesis §3.1 / P-V Fig. 4);
- tool paths, tool axes, clouds coloured by height, a tunnel wireframe, a camera that
  frames the content, slider ranges for joints without finite limits.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from reachwise.errors import InputError

if TYPE_CHECKING:
    from reachwise.distance.scene import SceneResult
    from reachwise.kinematics.robot import Robot
    from reachwise.tasks.workspace import TunnelEnvelope

__all__ = [
    "COLOUR_WORDS",
    "MEMORY_RGB",
    "STATUS_RGB",
    "axis_segments",
    "camera_view",
    "distance_colours",
    "height_colours",
    "joint_ranges",
    "legend",
    "node_name",
    "pair_segments",
    "polyline_segments",
    "skeleton_segments",
    "status_colours",
    "tunnel_wireframe",
    "voxel_centres",
    "wxyz_position",
]

U8 = NDArray[np.uint8]
F64 = NDArray[np.float64]


def _rgb(name: str) -> tuple[int, int, int]:
    from matplotlib.colors import to_rgb

    r, g, b = to_rgb(name)
    return round(r * 255), round(g * 255), round(b * 255)


def _status_rgb() -> dict[str, tuple[int, int, int]]:
    from reachwise.report.plots import STATUS_COLOURS

    out = {k: _rgb(v) for k, v in STATUS_COLOURS.items()}
    # simulation goals: reached (the full goal) or not yet
    out["reached"] = out["full"]
    out["unreached"] = out["neither"]
    out["pending"] = (150, 150, 150)
    return out


#: Status → RGB (0–255): P-I Fig. 4 colours (``full``, ``position``, ``orientation``,
#: ``neither``) plus ``reached``/``unreached`` for simulation goals and ``pending``.
STATUS_RGB: dict[str, tuple[int, int, int]] = _status_rgb()


def status_colours(status: Sequence[str]) -> U8:
    """``(K, 3)`` uint8 colours of ``status`` (keys of :data:`STATUS_RGB`)."""
    out = np.empty((len(status), 3), dtype=np.uint8)
    for k, s in enumerate(status):
        rgb = STATUS_RGB.get(s)
        if rgb is None:
            raise InputError("status", f"[{k}]", f"{s!r} is not one of {sorted(STATUS_RGB)}")
        out[k] = rgb
    return out


def wxyz_position(T: ArrayLike) -> tuple[F64, F64]:
    """A 4×4 pose as viser wants it: unit quaternion ``(w, x, y, z)`` and position."""
    M = np.asarray(T, dtype=float)
    if M.shape != (4, 4):
        raise InputError("pose", "shape", f"expected (4, 4), got {M.shape}")
    x, y, z, w = Rotation.from_matrix(M[:3, :3]).as_quat()
    return np.array([w, x, y, z]), M[:3, 3].copy()


def skeleton_segments(robot: Robot, q: ArrayLike) -> F64:
    """``(L - 1, 2, 3)`` segments joining the origins of consecutive frames of
    ``robot.fk_all(q)`` (base → link_1 → … → link_N → tool), world frame."""
    o = np.asarray(robot.fk_all(np.asarray(q, dtype=float)))[:, :3, 3]
    return polyline_segments(o)


def polyline_segments(points: ArrayLike) -> F64:
    """``(N - 1, 2, 3)`` segments of the polyline through ``points`` ``(N, 3)``."""
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    return np.stack([p[:-1], p[1:]], axis=1)


def axis_segments(positions: ArrayLike, axes: ArrayLike, length: float) -> F64:
    """``(K, 2, 3)`` segments from each position along its (unit) axis, ``length`` m."""
    p = np.asarray(positions, dtype=float).reshape(-1, 3)
    a = np.asarray(axes, dtype=float).reshape(-1, 3)
    return np.stack([p, p + length * a], axis=1)


def pair_segments(result: SceneResult) -> tuple[F64, F64, NDArray[np.intp]]:
    """Closest-point lines of the pairs of ``result`` that have an answer (within
    their scene margin): segments ``(M, 2, 3)`` from ``point_a`` to ``point_b`` (world
    frame), their distances ``(M,)`` and the pairs' indices in ``result.pairs``."""
    seg, dist, idx = [], [], []
    for i, p in enumerate(result.pairs):
        r = p.result
        if r.no_risk or not (np.isfinite(r.point_a).all() and np.isfinite(r.point_b).all()):
            continue
        seg.append(np.stack([r.point_a, r.point_b]))
        dist.append(r.distance)
        idx.append(i)
    if not seg:
        return np.zeros((0, 2, 3)), np.zeros(0), np.zeros(0, dtype=np.intp)
    return np.array(seg, dtype=float), np.array(dist), np.array(idx, dtype=np.intp)


def distance_colours(distance: ArrayLike, margin: ArrayLike) -> U8:
    """``(M, 2, 3)`` segment colours: red within the collision margin ρ_O (the
    avoidance acts), amber beyond it (monitored only)."""
    d = np.asarray(distance, dtype=float).reshape(-1)
    m = np.broadcast_to(np.asarray(margin, dtype=float), d.shape)
    rgb = np.where((d <= m)[:, None], [[220, 30, 30]], [[245, 170, 0]]).astype(np.uint8)
    return np.repeat(rgb[:, None, :], 2, axis=1)


def height_colours(points: ArrayLike, cmap: str = "viridis") -> U8:
    """``(N, 3)`` uint8 colours of world points by their height z (a colormap)."""
    import matplotlib

    p = np.asarray(points, dtype=float).reshape(-1, 3)
    if len(p) == 0:
        return np.zeros((0, 3), dtype=np.uint8)
    z = p[:, 2]
    span = float(z.max() - z.min())
    s = (z - z.min()) / span if span > 0 else np.full(len(z), 0.5)
    rgba = matplotlib.colormaps[cmap](0.15 + 0.8 * s)
    return np.round(rgba[:, :3] * 255).astype(np.uint8)


def joint_ranges(robot: Robot, q: ArrayLike | None = None, span: float = 2.0) -> F64:
    """``(n, 2)`` slider ranges: the joint limits, or ``q ± span`` (m) for a joint
    without finite limits (a free prismatic joint)."""
    lo = np.array(robot.lower, dtype=float)
    hi = np.array(robot.upper, dtype=float)
    q0 = np.zeros(robot.n) if q is None else np.asarray(q, dtype=float).reshape(-1)
    top = np.where(np.isfinite(hi), hi, q0)
    lo = np.where(np.isfinite(lo), lo, np.minimum(q0, top) - span)
    hi = np.where(np.isfinite(hi), hi, np.maximum(q0, lo) + span)
    return np.column_stack([lo, hi])


def camera_view(
    points: ArrayLike,
    direction: ArrayLike = (-1.0, -1.1, 0.75),
    distance: float = 1.5,
) -> tuple[F64, F64]:
    """Camera ``(position, look_at)`` framing ``points``: look at the centre of their
    bounding box from ``direction``, ``distance`` × the box's half-diagonal away."""
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    p = p[np.isfinite(p).all(axis=1)]
    if len(p) == 0:
        p = np.zeros((1, 3))
    lo, hi = p.min(axis=0), p.max(axis=0)
    centre = 0.5 * (lo + hi)
    radius = max(0.5 * float(np.linalg.norm(hi - lo)), 0.5)
    d = np.asarray(direction, dtype=float)
    d = d / np.linalg.norm(d)
    return centre + distance * radius * d, centre


def tunnel_wireframe(envelope: TunnelEnvelope, x: ArrayLike, spacing: float = 0.25) -> F64:
    """Segments ``(M, 2, 3)`` outlining a tunnel: its cross-section at every station
    in ``x`` and the lines along it at the profile's corners and crown."""
    yz = envelope.profile.boundary(spacing)
    xs = np.asarray(x, dtype=float).reshape(-1)
    ring = np.vstack([yz, yz[:1]])
    out = []
    for xi in xs:
        pts = np.column_stack([np.full(len(ring), xi), ring])
        out.append(polyline_segments(pts))
    if len(xs) > 1:
        corners = [0, int(np.argmax(yz[:, 1])), len(yz) // 4, 3 * len(yz) // 4]
        for c in corners:
            y, z = yz[c]
            out.append(np.array([[[xs.min(), y, z], [xs.max(), y, z]]]))
    return np.concatenate(out) if out else np.zeros((0, 2, 3))


def node_name(name: str) -> str:
    """A scene-node-safe version of ``name`` (no slashes or spaces)."""
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in name) or "robot"


def legend(keys: tuple[str, ...]) -> str:
    """The colours of the statuses ``keys`` in words (markdown)."""
    return ", ".join(f"{COLOUR_WORDS.get(k, '?')} = {k}" for k in keys)


#: Status → the colour's name, for legends in words.
COLOUR_WORDS = {
    "full": "green",
    "position": "blue",
    "orientation": "yellow",
    "neither": "red",
    "reached": "green",
    "unreached": "red",
    "pending": "grey",
}


#: Colours of a scene memory's voxels by state (``reachwise.distance.scene_memory``).
MEMORY_RGB: dict[str, tuple[int, int, int]] = {
    "occupied": (230, 70, 50),
    "shadow": (130, 80, 200),
    "free": (110, 200, 140),
}


def voxel_centres(
    state: NDArray[np.uint8], origin: ArrayLike, voxel: float, code: int, limit: int
) -> F64:
    """The centres ``(k, 3)`` (m) of the voxels of the grid ``state`` (its corner at
    ``origin``, edge ``voxel``) that hold ``code``; at most ``limit`` of them: every
    ⌈n / limit⌉-th in index order when there are more."""
    idx = np.flatnonzero(state.reshape(-1) == code)
    if len(idx) > limit:
        idx = idx[:: -(-len(idx) // max(1, limit))]
    ijk = np.column_stack(np.unravel_index(idx, state.shape)).astype(np.float64)
    return np.asarray(np.asarray(origin, dtype=np.float64) + (ijk + 0.5) * voxel)
