"""Point clouds of a robot's links from its collision shapes (P-III §5, P-V §V).

The thesis turns every CAD part that could collide into a cloud of 1000 surface points
(P-III §5: "each containing 1000 points"; P-V §V: the grabber, 1000 points). Here a
link's part is the union of all its collision shapes
(:class:`~reachwise.kinematics.link_geometry.LinkGeometry`: boxes, cylinders, capsules,
spheres, meshes), each placed by its own ``origin``; the link's cloud samples that
union uniformly over its surface, so each shape gets points in proportion to its area
(:func:`reachwise.geometry.cloud.sample_mesh_surface`). The number of points is
``points`` when given, else ``density × area`` (points per m²) when a density is
given, else the link's own count (the largest ``points`` among its shapes: 1000 by
default). A cloud with a ``resolution`` covers the union instead: every point of its
surface lies within ``resolution`` of a cloud point, checked when the cloud is made
(:func:`covering_points`); that is the default for a robot read from a URDF
(:data:`RESOLUTION`, 1 cm). A cloud distance then overstates the surface distance by at
most the two clouds' resolutions; the pair rules
(:mod:`reachwise.distance.self_pairs`) and the simulation's controller add them to the
margins, so their distances are conservative.

Clouds are keyed by body (:attr:`Robot.body_names <reachwise.kinematics.robot.Robot.
body_names>`: a URDF link, or a frame of a DH robot) and expressed in the frame the body
rides on (``frame=robot.frame_of(body)``), so a :class:`~reachwise.distance.scene.Scene`
attaches them with ``robot=..., link=cloud.frame``.
Mesh files are read by the one mesh reader, :func:`reachwise.io.meshes.load_mesh`:
a robot loaded from a URDF carries each mesh's resolved file; otherwise a mesh name is
resolved like a URDF's (:func:`reachwise.io.mesh_uri.resolve_uri`), relative to the
robot file's folder (built-in robots: the package's ``data/robots`` folder). A mesh
that cannot be read is a :class:`~reachwise.errors.RobotFileError` naming the robot
file, the link, the shape and the URI. Sampling is reproducible: link ``k`` draws from
``numpy.random.default_rng([seed, k])``, ``k`` the body's place in ``body_names``.
"""

from __future__ import annotations

import difflib
import math
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from reachwise.errors import CloudError, InputError, RobotFileError
from reachwise.geometry.cloud import PointCloud, sample_mesh_surface
from reachwise.geometry.covering import greedy_cover
from reachwise.io.mesh_uri import resolve_uri
from reachwise.io.meshes import load_mesh

if TYPE_CHECKING:
    import trimesh

    from reachwise.kinematics.robot import LinkGeometry, Robot

__all__ = [
    "RESOLUTION",
    "covering_points",
    "default_resolution",
    "geometry_folder",
    "link_cloud",
    "link_clouds",
    "link_mesh",
    "shape_mesh",
    "shape_meshes",
]

_BUILTIN = "built-in robot "
#: Default coverage (m) of a URDF robot's link clouds: every point of a link's shapes
#: lies within 1 cm of its cloud (:func:`covering_points`).
RESOLUTION = 0.01
#: Share of the resolution the subdivided mesh's vertices cover (the rest is the greedy
#: cover's radius). Smaller keeps fewer points but subdivides longer (Panda at 1 cm: 1/2
#: keeps 18 000 points, 1/3 about 10 000, 1/4 9 200 in 1.4 times the time of 1/3).
_SUBDIVIDE = 1.0 / 3.0
#: Facets of the round shapes' surface meshes (the sampled surface lies within
#: ``r (1 - cos(π / 64))`` = 0.12 % of the radius inside the true one).
_SECTIONS = 64


def geometry_folder(robot: Robot, base_dir: str | Path | None = None) -> Path:
    """Folder that relative mesh paths of ``robot``'s geometry start from.

    ``base_dir`` wins when given; else the folder of the robot file (``robot.source``),
    the package's built-in robot folder for built-in robots, or the working directory.
    """
    if base_dir is not None:
        return Path(base_dir)
    src = robot.source or ""
    if src.startswith(_BUILTIN):
        return Path(str(resources.files("reachwise.data") / "robots"))
    p = Path(src)
    if src and p.is_file():
        return p.parent
    return Path.cwd()


def _describe(link: str, i: int, g: LinkGeometry) -> str:
    what = f"link {link!r} shape {i + 1} ({g.shape}"
    what += f", {g.label})" if g.label else ")"
    if g.shape == "mesh":
        what += f" mesh {g.mesh!r}"
    return what


def shape_mesh(
    robot: Robot, link: str, i: int, g: LinkGeometry, base_dir: str | Path | None = None
) -> trimesh.Trimesh:
    """Shape ``i`` (``g``) of ``link`` as a closed triangle surface, placed in the link
    frame. Errors name the robot file, the link, the shape and its URI."""
    import trimesh

    if g.shape == "box":
        mesh = trimesh.creation.box(extents=np.asarray(g.size, dtype=float))
    elif g.shape == "cylinder":
        mesh = trimesh.creation.cylinder(
            radius=float(g.radius or 0.0), height=float(g.length or 0.0), sections=_SECTIONS
        )
    elif g.shape == "capsule":
        mesh = trimesh.creation.capsule(
            height=float(g.length or 0.0), radius=float(g.radius or 0.0),
            count=[_SECTIONS, _SECTIONS],
        )  # fmt: skip
    elif g.shape == "sphere":
        mesh = trimesh.creation.icosphere(subdivisions=4, radius=float(g.radius or 0.0))
    else:
        source = robot.source or robot.name
        field = _describe(link, i, g)
        path = g.path
        if path is None:
            folder = geometry_folder(robot, base_dir)
            rf = robot.source if robot.source and Path(robot.source).is_file() else None
            path = str(
                resolve_uri(str(g.mesh), robot_file=rf, source=source, field=field, folder=folder)
            )
        try:
            mesh = load_mesh(path, scale=g.scale)
        except CloudError as exc:
            reason = exc.reason if exc.field in ("file", "format") else f"{exc.field}: {exc.reason}"
            raise RobotFileError(source, field, f"{path}: {reason}") from None
    mesh.apply_transform(g.origin_matrix)
    return mesh


def shape_meshes(
    robot: Robot, link: str, base_dir: str | Path | None = None
) -> list[trimesh.Trimesh]:
    """Every collision shape of ``link`` as a surface mesh in the link frame."""
    return [shape_mesh(robot, link, i, g, base_dir) for i, g in enumerate(_shapes(robot, link))]


def link_mesh(robot: Robot, link: str, base_dir: str | Path | None = None) -> trimesh.Trimesh:
    """The union (one mesh, not merged) of ``link``'s collision shapes, in the link frame."""
    import trimesh

    parts = shape_meshes(robot, link, base_dir)
    if len(parts) == 1:
        return parts[0]
    joined = trimesh.util.concatenate(parts)
    if not isinstance(joined, trimesh.Trimesh):  # pragma: no cover - meshes join to a mesh
        raise RobotFileError(robot.source or robot.name, f"link {link!r}", "shapes do not join")
    return joined


def link_cloud(
    robot: Robot,
    link: str,
    points: int | None = None,
    seed: int = 0,
    base_dir: str | Path | None = None,
    *,
    density: float | None = None,
    resolution: float | None = None,
) -> PointCloud:
    """A cloud of all of ``link``'s collision shapes, in the link frame, named
    ``"<robot>/<link>"``. With ``resolution`` (m) it covers the surface: every point of
    the shapes' surface meshes lies within ``resolution`` of a cloud point
    (:func:`covering_points`; the cloud's :attr:`~reachwise.geometry.cloud.PointCloud.
    resolution` says so). Else it samples the shapes by area: ``points`` of them, or
    ``density`` per m² of surface. With none of the three, a robot read from a URDF
    gets :data:`RESOLUTION` (:func:`default_resolution`), a robot of reachwise's own
    format its link's count (the largest ``points`` of its shapes, 1000 by default)."""
    shapes = _shapes(robot, link)
    where = f"geometry.{link}"
    given = [x for x in (points, density, resolution) if x is not None]
    if len(given) > 1:
        raise InputError(
            robot.source or robot.name, where, "give one of points, density and resolution"
        )
    if not given:
        resolution = default_resolution(robot)
    mesh = link_mesh(robot, link, base_dir)
    if resolution is not None:
        pts = covering_points(mesh, resolution, source=robot.source or robot.name, field=where)
        return PointCloud(
            pts, frame=robot.frame_of(link), name=f"{robot.name}/{link}", resolution=resolution
        )
    if density is not None:
        if isinstance(density, bool) or not math.isfinite(density) or not density > 0:
            raise InputError(
                robot.source or robot.name, "density", f"must be finite and > 0, got {density!r}"
            )
        n = max(1, math.ceil(float(mesh.area) * float(density)))
    else:
        n = max(g.points for g in shapes) if points is None else int(points)
    if n <= 0:
        raise InputError(robot.source or robot.name, f"{where}.points", f"must be > 0, got {n}")
    k = robot.body_names.index(link)
    rng = np.random.default_rng([int(seed), k])
    frame = robot.frame_of(link)
    return sample_mesh_surface(mesh, n=n, seed=rng, frame=frame, name=f"{robot.name}/{link}")


def default_resolution(robot: Robot) -> float | None:
    """The coverage (m) a link cloud of ``robot`` gets when no count is asked for:
    :data:`RESOLUTION` for a robot read from a URDF (its shapes are the real robot's
    surface and a URDF cannot state a count), ``None`` for a robot of reachwise's own
    format, whose shapes state their ``points`` (the thesis' 1000 per part, on parts
    metres long)."""
    return RESOLUTION if robot.frame_names else None


def covering_points(
    mesh: trimesh.Trimesh, resolution: float, *, source: str = "mesh", field: str = ""
) -> np.ndarray:
    """Few points of ``mesh`` such that every point of its surface lies within
    ``resolution`` ``r`` (m) of one. Two steps, each with a bound:

    1. the mesh is subdivided until no edge is longer than ``√3 · r / 3``: every point
       of a triangle whose edges are at most ``e`` lies within ``a = e / √3`` of a
       vertex (the circumradius bounds it for an acute triangle, whose largest angle is
       at least 60°; half the longest edge for an obtuse one), so within ``r / 3``;
    2. of those vertices, a greedy cover (:func:`~reachwise.geometry.covering.
       greedy_cover`) keeps a vertex when none kept so far is within ``r - a`` of it.

    So every surface point is within ``a + (r - a) = r`` of a kept point, and a fine
    mesh (vertices much closer than ``r``) keeps about one point per ``r²`` of area, not
    all its vertices. Checked when made: 20 000 points sampled on the surface are each
    within ``r`` of the result, else :class:`~reachwise.errors.InputError`."""
    import trimesh
    from scipy.spatial import cKDTree

    if isinstance(resolution, bool) or not math.isfinite(resolution) or not resolution > 0:
        raise InputError(
            source, f"{field}.resolution", f"must be finite and > 0, got {resolution!r}"
        )
    r = float(resolution)
    v, f = trimesh.remesh.subdivide_to_size(
        mesh.vertices,
        mesh.faces,
        max_edge=_SUBDIVIDE * math.sqrt(3.0) * r * (1.0 - 1e-9),
        max_iter=60,
    )
    v, inverse = np.unique(np.asarray(v, dtype=float), axis=0, return_inverse=True)
    f = inverse.reshape(-1)[np.asarray(f, dtype=np.int64)]
    edges = v[f[:, [1, 2, 0]]] - v[f] if len(f) else np.zeros((0, 3, 3))
    reach = float(np.sqrt((edges**2).sum(axis=2)).max()) / math.sqrt(3.0) if len(f) else 0.0
    pts = v[greedy_cover(v, max(r - reach, 0.0))]
    check = np.asarray(mesh.sample(20_000, seed=0), dtype=float)
    gap = float(cKDTree(pts).query(check)[0].max())
    if gap > r * (1.0 + 1e-9):
        raise InputError(source, field, f"cloud misses the surface by {gap:.4g} m > {r:g} m")
    return pts


def link_clouds(
    robot: Robot,
    points: int | None = None,
    seed: int = 0,
    base_dir: str | Path | None = None,
    *,
    density: float | None = None,
    resolution: float | None = None,
) -> dict[str, PointCloud]:
    """A cloud for every body that has collision shapes, base to tool, keyed by body
    (``link_0`` … ``tool``, or a URDF robot's link names), each in the frame its body
    rides on (see ``reachwise.io.robot_clouds.link_cloud``: a URDF robot's clouds cover
    their shapes within ``RESOLUTION`` = 1 cm unless a count or density is asked for,
    and say so in their ``resolution``)."""
    order = [name for name in robot.body_names if name in robot.geometry]
    return {
        name: link_cloud(
            robot, name, points, seed, base_dir, density=density, resolution=resolution
        )
        for name in order
    }


def _shapes(robot: Robot, link: str) -> tuple[LinkGeometry, ...]:
    g = robot.geometry.get(link)
    if not g:
        close = difflib.get_close_matches(link, list(robot.geometry), n=1)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        raise InputError(
            robot.source or robot.name,
            f"geometry.{link}",
            f"no geometry; links with one: {list(robot.geometry)}{hint}",
        )
    return g
