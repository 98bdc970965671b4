"""What a scenario reads from outside itself: robot files, packages it needs, scan scenes
of its own meshes, automatic self-collision pairs.

- :func:`check_requirements` — a scenario's ``requires: {package: extra}``: a missing
  package is one clear :class:`~reachwise.errors.MissingDependency` line (the real-arm
  scenarios need ``example-robot-data``, the ``robots`` extra).
- the robot files themselves (``robot: {file, tip, package_dirs, lenient}``) are read
  by :func:`reachwise.sim.robots.robot_of`.
- :func:`scan_target` — ``scanner: NAME | {meshes, pose, …}``: a built-in scan scene,
  or a :class:`~reachwise.geometry.scanner.ScanScene` of the scenario's own meshes.
- :func:`watched_self_pairs` — the link pairs of a ``self`` watch, ``pairs: auto``
  through :func:`reachwise.sim.self_pairs.auto_self_pairs`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from importlib import metadata
from typing import TYPE_CHECKING

import numpy as np

from reachwise.errors import InputError, MissingDependency
from reachwise.kinematics.robot import Robot
from reachwise.sim.scenarios import RobotSpec, ScanSpec, Scenario, SrdfPairsSpec, WatchSpec

if TYPE_CHECKING:
    from reachwise.geometry.cloud import PointCloud
    from reachwise.geometry.scan_scene import ScanScene

__all__ = ["check_requirements", "scan_target", "watched_self_pairs"]


def check_requirements(sc: Scenario) -> None:
    """Raise :class:`MissingDependency` for the first package of ``requires`` that is
    not installed."""
    for package, extra in sc.spec.requires.items():
        try:
            metadata.distribution(package)
        except metadata.PackageNotFoundError:
            raise MissingDependency(package, extra, f"the scenario {sc.name!r}") from None


def scan_target(scanner: str | ScanSpec, sc: Scenario, name: str) -> ScanScene:
    """What :func:`reachwise.geometry.scan_scene.scan_scene` scans for an object's
    ``scanner``: a built-in scene (:mod:`reachwise.sim.p5_scenes`) or the scene of a
    :class:`ScanSpec`."""
    if isinstance(scanner, str):
        from reachwise.sim.p5_scenes import get_scene

        return get_scene(scanner)
    import trimesh

    from reachwise.geometry.scan_scene import ScanScene
    from reachwise.geometry.scanner import LaserScanner
    from reachwise.io.meshes import load_mesh

    meshes = []
    for i, m in enumerate(scanner.meshes):
        try:
            mesh = load_mesh(sc.path(m.mesh), scale=m.scale)
        except InputError as exc:
            raise InputError(
                sc.source, f"objects.{name}.scanner.meshes[{i}].mesh", str(exc)
            ) from None
        mesh.apply_transform(m.pose.matrix())
        meshes.append(mesh)
    if scanner.floor is not None:
        z, h = float(scanner.floor), 50.0
        meshes.append(
            trimesh.Trimesh(
                vertices=[[-h, -h, z], [h, -h, z], [h, h, z], [-h, h, z]],
                faces=[[0, 1, 2], [0, 2, 3]],
                process=False,
            )
        )
    res = math.radians(scanner.resolution_deg)
    laser = LaserScanner(
        pose=scanner.pose.matrix(),
        angular_resolution=res,
        tilt_rate=math.radians(scanner.line_step_deg) * 25.0,
        azimuth_range=(math.radians(scanner.azimuth_deg[0]), math.radians(scanner.azimuth_deg[1])),
        tilt_range=(math.radians(scanner.tilt_deg[0]), math.radians(scanner.tilt_deg[1])),
    )
    return ScanScene(
        name=name,
        meshes=tuple(meshes),
        scanner=laser,
        crop_min=np.asarray(scanner.crop[0], dtype=float),
        crop_max=np.asarray(scanner.crop[1], dtype=float),
        voxel=scanner.voxel,
        description=f"scenario {sc.name}: {len(scanner.meshes)} mesh(es) scanned",
        ground=scanner.floor,
    )


def watched_self_pairs(
    w: WatchSpec,
    robot: Robot,
    spec: RobotSpec,
    clouds: Mapping[str, PointCloud],
    sc: Scenario,
    where: str,
) -> dict[tuple[str, str], float] | None:
    """The link pairs a ``self`` watch lists, or picks with ``pairs: auto`` (or all but
    an SRDF's disabled ones, ``pairs: {srdf: FILE}``) among the robot's link ``clouds``
    (link → cloud in the link frame; restricted to ``links``), each with its margin
    (m, between the surfaces: the watch's, or a pair's own that ``pairs: auto`` gave
    it); ``None`` when the watch lists none (every non-adjacent pair)."""
    if w.pairs is None:
        return None
    keep = set(w.links) if w.links is not None else None
    if isinstance(w.pairs, SrdfPairsSpec):
        from reachwise.sim.srdf_inputs import srdf_of, srdf_watched_pairs

        srdf = srdf_of(sc, w.pairs, where)
        mine = {k: c for k, c in clouds.items() if keep is None or k in keep}
        listed = srdf_watched_pairs(srdf, robot, mine, sc.source, f"{where}.pairs.srdf")
        return dict.fromkeys(listed, w.margin)
    if w.pairs != "auto":
        return {(a, b): w.margin for a, b in w.pairs}
    from reachwise.sim.self_pairs import auto_self_pairs

    mine = {k: c for k, c in clouds.items() if keep is None or k in keep}
    if len(mine) < 2:
        raise InputError(sc.source, where, "pairs: auto needs at least two link clouds")
    try:
        pairs = auto_self_pairs(
            robot, mine, w.margin, home=np.asarray(spec.start, dtype=float), samples=w.samples,
            seed=w.seed, cache_dir=sc.cache_dir, label=spec.name,
        )  # fmt: skip
    except InputError as exc:
        raise InputError(sc.source, where, str(exc)) from None
    return pairs.margins
