"""``/tf`` and ``/tf_static``: a tree of frames whose edges move in time.

Each ``geometry_msgs/TransformStamped`` says where ``child_frame_id`` is in
``header.frame_id`` (its parent) at ``header.stamp``: a translation and a unit
quaternion ``(x, y, z, w)``, i.e. the 4 × 4 transform ``T_parent_child`` that maps
points in the child frame to the parent frame. A static edge (``/tf_static``) holds at
all times; a dynamic edge (``/tf``) is known at its stamps and, between two of them,
interpolated: the translation linearly, the rotation by spherical linear interpolation
(slerp, along the shorter arc). Outside its stamps it is not known (no extrapolation,
as tf2), unless within ``tolerance`` seconds (plus 1 ns, the stamps' resolution) of
the first or last stamp, where the end value holds.

:meth:`TransformTree.lookup` follows the tree from the source frame up to the common
ancestor and down to the target: ``T_target_source = (T_root_target)⁻¹ · T_root_source``.
A frame that is not in the tree, or an edge not known at the time, raises
:class:`~reachwise.errors.InputError` naming both frames and the time.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation, Slerp

from reachwise.errors import InputError
from reachwise.io.ros.recording_error import stamp_text
from reachwise.io.ros.stamps import seconds

__all__ = ["TransformTree"]

F64 = NDArray[np.float64]
#: Stamps are whole nanoseconds; times within one of an edge's ends are at its end.
_STAMP_RESOLUTION = 1e-9


@dataclass
class _Edge:
    """One parent → child edge: its samples (time, translation, quaternion xyzw)."""

    parent: str
    static: bool
    times: list[float] = field(default_factory=list)
    xyz: list[F64] = field(default_factory=list)
    quat: list[F64] = field(default_factory=list)
    _cache: tuple[F64, F64, F64, Slerp | None] | None = None

    def add(self, t: float, xyz: F64, quat: F64) -> None:
        if self.static:  # the latest static transform replaces the earlier one
            self.times, self.xyz, self.quat = [t], [xyz], [quat]
        else:
            self.times.append(t)
            self.xyz.append(xyz)
            self.quat.append(quat)
        self._cache = None

    def _arrays(self) -> tuple[F64, F64, F64, Slerp | None]:
        if self._cache is None:
            t = np.asarray(self.times)
            order = np.argsort(t, kind="stable")
            t = t[order]
            keep = np.ones(t.size, bool)
            keep[:-1] = t[1:] != t[:-1]  # the last sample of equal stamps wins
            order, t = order[keep], t[keep]
            xyz = np.asarray(self.xyz)[order]
            rot = Rotation.from_quat(np.asarray(self.quat)[order])
            slerp = Slerp(t, rot) if t.size > 1 else None
            self._cache = (t, xyz, rot[0].as_matrix(), slerp)
        return self._cache

    def at(self, t: float, tolerance: float) -> F64 | None:
        """``T_parent_child`` at ``t`` (s), or None outside the known times."""
        T = np.eye(4)
        times, xyz, R0, slerp = self._arrays()
        if self.static:
            T[:3, :3] = R0
            T[:3, 3] = xyz[0]
            return T
        lo, hi = times[0], times[-1]
        slack = tolerance + _STAMP_RESOLUTION
        if t < lo - slack or t > hi + slack:
            return None
        tc = min(max(t, lo), hi)
        if slerp is None:
            T[:3, :3] = R0
            T[:3, 3] = xyz[0]
            return T
        T[:3, :3] = slerp([tc]).as_matrix()[0]
        T[:3, 3] = [np.interp(tc, times, xyz[:, j]) for j in range(3)]
        return T


class TransformTree:
    """Frames and the transforms between them over time (see the module docstring).

    ``tolerance`` (s, default 0): how far beyond a dynamic edge's first or last stamp
    its end value is still used."""

    def __init__(self, *, tolerance: float = 0.0) -> None:
        if not (np.isfinite(tolerance) and tolerance >= 0.0):
            raise InputError("transform tree", "tolerance", f"must be >= 0 s, got {tolerance}")
        self.tolerance = float(tolerance)
        self._edges: dict[str, _Edge] = {}

    @property
    def frames(self) -> tuple[str, ...]:
        """Every frame named by an edge, sorted."""
        names = set(self._edges) | {e.parent for e in self._edges.values()}
        return tuple(sorted(names))

    def add(
        self,
        parent: str,
        child: str,
        t: float,
        translation: ArrayLike,
        quaternion: ArrayLike,
        *,
        static: bool = False,
    ) -> None:
        """The edge ``parent`` → ``child`` at ``t`` (s): ``translation`` (m) and unit
        ``quaternion`` ``(x, y, z, w)`` of the child in the parent."""
        parent, child = parent.lstrip("/"), child.lstrip("/")
        where = f"transform {parent} -> {child} ({stamp_text(t)})"
        xyz = np.asarray(translation, dtype=np.float64).reshape(3)
        q = np.asarray(quaternion, dtype=np.float64).reshape(4)
        if not (np.isfinite(xyz).all() and np.isfinite(q).all()):
            raise InputError(where, "transform", "not finite")
        norm = float(np.linalg.norm(q))
        if abs(norm - 1.0) > 1e-3:
            raise InputError(where, "rotation", f"quaternion norm {norm:.6g} is not 1")
        if parent == child:
            raise InputError(where, "child_frame_id", "equals its parent frame")
        edge = self._edges.get(child)
        if edge is None:
            edge = self._edges[child] = _Edge(parent, static)
            self._check_cycle(child, where)
        elif edge.parent != parent or edge.static != static:
            kind = "static" if edge.static else "dynamic"
            raise InputError(
                where, "header.frame_id", f"{child} already has the {kind} parent {edge.parent}"
            )
        edge.add(float(t), xyz, q / norm)

    def add_message(self, msg: Any, *, static: bool = False) -> None:
        """Every ``TransformStamped`` of a ``tf2_msgs/TFMessage``."""
        for ts in msg.transforms:
            tr, rot = ts.transform.translation, ts.transform.rotation
            self.add(
                str(ts.header.frame_id),
                str(ts.child_frame_id),
                seconds(ts.header.stamp),
                (tr.x, tr.y, tr.z),
                (rot.x, rot.y, rot.z, rot.w),
                static=static,
            )

    def _check_cycle(self, child: str, where: str) -> None:
        seen = {child}
        frame = self._edges[child].parent
        while frame in self._edges:
            if frame in seen:
                del self._edges[child]
                raise InputError(where, "child_frame_id", f"closes a loop through {frame}")
            seen.add(frame)
            frame = self._edges[frame].parent

    def _chain(self, frame: str) -> list[str]:
        """``frame`` and its ancestors up to the root."""
        out = [frame]
        while out[-1] in self._edges:
            out.append(self._edges[out[-1]].parent)
        return out

    def _to_ancestor(self, chain: list[str], stop: str, t: float, target: str, source: str) -> F64:
        """``T_stop_frame`` for ``chain[0]`` along ``chain`` up to ``stop``."""
        T = np.eye(4)
        for frame in chain:
            if frame == stop:
                return T
            edge = self._edges[frame]
            E = edge.at(t, self.tolerance)
            if E is None:
                lo, hi = min(edge.times), max(edge.times)
                raise InputError(
                    f"transform {target} <- {source} ({stamp_text(t)})",
                    f"{edge.parent} -> {frame}",
                    f"not known at that time: this edge has stamps from {lo:.9f} s to {hi:.9f} s",
                )
            T = E @ T
        return T

    def lookup(self, target: str, source: str, t: float) -> F64:
        """``T_target_source`` at ``t`` (s): the 4 × 4 transform that maps points in frame
        ``source`` to frame ``target``."""
        target, source = target.lstrip("/"), source.lstrip("/")
        if target == source:
            return np.eye(4)
        up_s, up_t = self._chain(source), self._chain(target)
        common = next((f for f in up_s if f in set(up_t)), None)
        if common is None:
            known = ", ".join(self.frames) or "none"
            raise InputError(
                f"transform {target} <- {source} ({stamp_text(t)})",
                "tf",
                f"no path between frames {target!r} and {source!r} (frames known: {known})",
            )
        A = self._to_ancestor(up_s, common, t, target, source)
        B = self._to_ancestor(up_t, common, t, target, source)
        B_inv = np.eye(4)
        B_inv[:3, :3] = B[:3, :3].T
        B_inv[:3, 3] = -B[:3, :3].T @ B[:3, 3]
        return np.asarray(B_inv @ A)
