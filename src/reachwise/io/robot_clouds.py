"""Point clouds of a robot's links from its collision geometry (P-III §5, P-V §V).

The thesis turns every CAD part that could collide into a cloud of 1000 surface points
(P-III §5: "each containing 1000 points"; P-V §V: the grabber, 1000 points). Here each
link's :class:`~reachwise.kinematics.robot.LinkGeometry` — a box, a cylinder (axis z,
centred) or a mesh file — is turned into a closed triangle mesh (``trimesh.creation``
or the file), placed by the geometry's ``origin`` and sampled uniformly over its
surface (area-weighted, :func:`reachwise.geometry.cloud.sample_mesh_surface`).

Clouds are expressed in the link's own frame (``frame="link_k"``), so a
:class:`~reachwise.distance.scene.Scene` attaches them with ``robot=..., link=...``.
Mesh paths are relative to the robot file's folder (built-in robots: the package's
``data/robots`` folder). Sampling is reproducible: link ``k`` draws from
``numpy.random.default_rng([seed, k])``.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from reachwise.errors import InputError
from reachwise.geometry.cloud import PointCloud, sample_mesh_surface

if TYPE_CHECKING:
    import trimesh

    from reachwise.kinematics.robot import LinkGeometry, Robot

__all__ = ["geometry_folder", "link_cloud", "link_clouds", "link_mesh"]

_BUILTIN = "built-in robot "


def geometry_folder(robot: Robot, base_dir: str | Path | None = None) -> Path:
    """Folder that mesh paths of ``robot``'s geometry are relative to.

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


def link_mesh(robot: Robot, link: str, base_dir: str | Path | None = None) -> trimesh.Trimesh:
    """The closed surface of ``link``'s geometry as a trimesh, in the link frame."""
    import trimesh

    g = _geometry(robot, link)
    if g.shape == "box":
        if g.size is None:
            raise InputError(robot.name, f"geometry.{link}", "box without size")
        mesh = trimesh.creation.box(extents=np.asarray(g.size, dtype=float))
    elif g.shape == "cylinder":
        if g.radius is None or g.length is None:
            raise InputError(robot.name, f"geometry.{link}", "cylinder without radius/length")
        mesh = trimesh.creation.cylinder(radius=g.radius, height=g.length, sections=48)
    else:
        if g.mesh is None:
            raise InputError(robot.name, f"geometry.{link}", "mesh without a file")
        path = geometry_folder(robot, base_dir) / g.mesh
        if not path.is_file():
            raise InputError(
                robot.source or robot.name, f"geometry.{link}.mesh", f"no such file {path}"
            )
        try:
            loaded = trimesh.load(str(path), force="mesh", process=True)
        except Exception as exc:  # trimesh raises many kinds
            raise InputError(str(path), f"geometry.{link}.mesh", f"unreadable: {exc}") from None
        if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
            raise InputError(str(path), f"geometry.{link}.mesh", "no triangles")
        mesh = loaded
    mesh = mesh.copy()
    mesh.apply_transform(g.origin_matrix)
    return mesh


def link_cloud(
    robot: Robot,
    link: str,
    points: int | None = None,
    seed: int = 0,
    base_dir: str | Path | None = None,
) -> PointCloud:
    """``points`` surface samples (default: the geometry's ``points``, 1000 in the
    thesis) of ``link``'s geometry, in the link frame, named ``"<robot>/<link>"``."""
    g = _geometry(robot, link)
    n = g.points if points is None else int(points)
    if n <= 0:
        raise InputError(robot.name, f"geometry.{link}.points", f"must be > 0, got {n}")
    mesh = link_mesh(robot, link, base_dir)
    k = robot.link_index(link)
    rng = np.random.default_rng([int(seed), k])
    return sample_mesh_surface(mesh, n=n, seed=rng, frame=link, name=f"{robot.name}/{link}")


def link_clouds(
    robot: Robot,
    points: int | None = None,
    seed: int = 0,
    base_dir: str | Path | None = None,
) -> dict[str, PointCloud]:
    """A cloud for every link that has geometry, base to tool (see :func:`link_cloud`)."""
    order = [name for name in robot.link_names if name in robot.geometry]
    return {name: link_cloud(robot, name, points, seed, base_dir) for name in order}


def _geometry(robot: Robot, link: str) -> LinkGeometry:
    g = robot.geometry.get(link)
    if g is None:
        raise InputError(
            robot.name, f"geometry.{link}", f"no geometry; links with one: {list(robot.geometry)}"
        )
    return g
