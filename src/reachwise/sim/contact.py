"""Ground truth for the simulator: do two parts actually overlap?

Point clouds sample surfaces, so two clouds whose solids interpenetrate can still be a
few centimetres apart point to point (1000 points on a 6 m feed beam are about 9 cm
apart). To decide whether a simulated run collides, the simulator also tests the
*solid* of each robot part: a pair collides when a point of the other object's cloud
lies inside the part's solid (box, cylinder, capsule, sphere, closed mesh, or the union
of a link's several shapes). Its signed distance is
then ``−depth`` (how deep the deepest point lies), else the cloud distance. Objects
without a solid (a scan) are tested only as points against the robot's solids.

An object that only sensors see (``scene: false``: the controllers get its sensed
cloud, never its shape) is judged on its true surface: :func:`true_clearance` is the
exact distance between a robot part's surface and the object's
(:func:`reachwise.geometry.mesh_distance.mesh_distance`), or ``−depth`` when the solids
overlap (the surfaces cross, or one lies inside the other).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    import trimesh

    from reachwise.kinematics.robot import LinkGeometry

__all__ = ["Solid", "solid_of_geometry", "solid_of_link", "solid_of_mesh", "true_clearance"]


@dataclass(frozen=True, eq=False)
class Solid:
    """A closed solid in its part's frame: ``kind`` box (``half`` extents), cylinder
    (``radius``, ``half[2]`` half length, axis z), capsule (``radius``, ``half[2]`` half
    the length of its axis segment, along z), sphere (``radius``) or convex mesh
    (``planes`` rows ``n, d`` with ``n·x ≤ d`` inside); ``origin`` places it in the part
    frame; ``mesh`` for a non-convex closed mesh (``trimesh`` containment, depth 0);
    ``union`` of ``parts`` (a link with several shapes: the deepest of them)."""

    kind: str
    origin: NDArray[np.float64]
    half: NDArray[np.float64]
    radius: float = 0.0
    planes: NDArray[np.float64] | None = None
    mesh: trimesh.Trimesh | None = None
    parts: tuple[Solid, ...] = ()

    def depth(self, points_world: NDArray[np.float64], pose: NDArray[np.float64]) -> float:
        """Deepest penetration (m, ≥ 0) of ``points_world`` into the solid placed at
        ``pose`` (part frame → world); ``-inf`` when no point is inside."""
        if self.kind == "union":
            return max((p.depth(points_world, pose) for p in self.parts), default=-np.inf)
        T = pose @ self.origin
        R = T[:3, :3]
        x = (points_world - T[:3, 3]) @ R  # into the solid's frame
        if self.kind == "box":
            m = self.half[None, :] - np.abs(x)
            d = m.min(axis=1)
        elif self.kind == "cylinder":
            radial = self.radius - np.hypot(x[:, 0], x[:, 1])
            d = np.minimum(radial, self.half[2] - np.abs(x[:, 2]))
        elif self.kind == "capsule":
            z = np.clip(x[:, 2], -self.half[2], self.half[2])
            d = self.radius - np.hypot(np.hypot(x[:, 0], x[:, 1]), x[:, 2] - z)
        elif self.kind == "sphere":
            d = self.radius - np.linalg.norm(x, axis=1)
        elif self.planes is not None:
            d = (self.planes[:, 3][None, :] - x @ self.planes[:, :3].T).min(axis=1)
        elif self.mesh is not None:
            inside = self.mesh.contains(x)
            return 0.0 if bool(np.any(inside)) else -np.inf
        else:
            return -np.inf
        inside = d >= 0.0
        return float(d[inside].max()) if inside.any() else -np.inf


def solid_of_mesh(mesh: trimesh.Trimesh, origin: NDArray[np.float64] | None = None) -> Solid:
    """A solid from a closed mesh (already in the part frame unless ``origin``)."""
    o = np.eye(4) if origin is None else np.asarray(origin, dtype=float)
    if mesh.is_convex:
        n = np.asarray(mesh.face_normals, dtype=float)
        v = np.asarray(mesh.triangles[:, 0], dtype=float)
        d = np.einsum("ij,ij->i", n, v)
        return Solid("convex", o, np.zeros(3), planes=np.column_stack([n, d]))
    return Solid("mesh", o, np.zeros(3), mesh=mesh)


def solid_of_geometry(g: LinkGeometry, mesh: trimesh.Trimesh | None = None) -> Solid:
    """The solid of a link's geometry; ``mesh`` is the loaded mesh of a mesh geometry
    (in the link frame, origin applied)."""
    o = g.origin_matrix
    if g.shape == "box" and g.size is not None:
        return Solid("box", o, 0.5 * np.asarray(g.size, dtype=float))
    if g.shape in ("cylinder", "capsule") and g.radius is not None and g.length is not None:
        return Solid(g.shape, o, np.array([0.0, 0.0, 0.5 * g.length]), radius=g.radius)
    if g.shape == "sphere" and g.radius is not None:
        return Solid("sphere", o, np.zeros(3), radius=g.radius)
    if mesh is None:
        raise ValueError("a mesh geometry needs its loaded mesh")
    return solid_of_mesh(mesh)


def solid_of_link(
    shapes: tuple[LinkGeometry, ...], meshes: list[trimesh.Trimesh] | None = None
) -> Solid:
    """The solid of a link's shapes (their union when there are several); ``meshes``
    are the shapes' surfaces in the link frame (needed for mesh shapes)."""
    solids = [
        solid_of_geometry(g, None if meshes is None else meshes[i]) for i, g in enumerate(shapes)
    ]
    if len(solids) == 1:
        return solids[0]
    return Solid("union", np.eye(4), np.zeros(3), parts=tuple(solids))


def true_clearance(
    a: tuple[NDArray[np.float64], NDArray[np.int64]],
    solid_a: Solid,
    pose_a: NDArray[np.float64],
    b: tuple[NDArray[np.float64], NDArray[np.int64]],
    solid_b: Solid,
    pose_b: NDArray[np.float64],
) -> float:
    """Signed distance of two parts by their true surfaces: meshes ``a``, ``b``
    (``(vertices, faces)`` in their part frames, placed at ``pose_a``, ``pose_b``) and
    their solids. Disjoint: the exact surface distance (m, > 0). Overlapping — the
    surfaces touch or cross, or a vertex of one lies inside the other's solid (then the
    piece of it does) —: ``−depth`` of the deepest vertex inside the other solid (≤ 0;
    0 when only edges and faces cross)."""
    from reachwise.geometry.mesh_distance import mesh_distance

    d = mesh_distance(a, b, pose_a, pose_b)
    va = a[0] @ pose_a[:3, :3].T + pose_a[:3, 3]
    vb = b[0] @ pose_b[:3, :3].T + pose_b[:3, 3]
    depth = max(solid_b.depth(va, pose_b), solid_a.depth(vb, pose_a))
    if d > 0.0 and depth < 0.0:
        return d
    return -max(depth, 0.0)
