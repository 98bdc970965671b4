"""The objects that move or change their cloud during a run: each one's
:class:`MovingObject` (its trajectory, scheduled clouds and re-scans), the cloud an object
starts with or is re-scanned to (:func:`object_cloud`), and the frozen copy of a scene a
static-world controller believes in (:func:`frozen_scene`). The world moves them each
tick with :func:`reachwise.sim.world.move_objects`."""

from __future__ import annotations

from dataclasses import dataclass

from reachwise.distance.scene import OnLink, Scene, SceneLike
from reachwise.errors import InputError
from reachwise.geometry.cloud import PointCloud
from reachwise.sim.contact import Solid
from reachwise.sim.motion import Trajectory
from reachwise.sim.resolve import ResolvedScenario, box_solid, cloud_key
from reachwise.sim.scenarios import ObjectSpec

__all__ = ["MovingObject", "frozen_scene", "moving_object", "object_cloud"]


def object_cloud(
    res: ResolvedScenario, spec: ObjectSpec, seed: int, k: int | None = None
) -> PointCloud:
    """The cloud of object ``spec`` (or of its ``k``-th scheduled cloud): resolved, or
    for a scanned object its scan with ``seed`` (a re-scan takes the next seed)."""
    if spec.scanner is None or k is not None:
        return res.object_clouds[cloud_key(spec.name, k)]
    from reachwise.geometry.occlusion import OcclusionFill
    from reachwise.geometry.scan_scene import scan_scene

    occ = spec.occlusion
    fill = (
        OcclusionFill(occ.depth, occ.spacing, occ.ground) if occ is not None and occ.fill else None
    )
    try:
        _, cloud = scan_scene(
            res.scan_targets[spec.name], rng=seed, noise=spec.noise, occlusion=fill
        )
    except InputError as exc:
        raise InputError(res.scenario.source, f"objects.{spec.name}.scanner", str(exc)) from None
    return PointCloud(cloud.points, name=spec.name)


@dataclass(eq=False)
class MovingObject:
    """An object that moves (``trajectory``) or changes its cloud (``clouds`` at
    times, or a re-scan every ``rescan`` s) during the run."""

    spec: ObjectSpec
    trajectory: Trajectory | None
    clouds: list[tuple[float, PointCloud, Solid | None]]
    rescan: float | None
    next_cloud: int = 0
    scans: int = 0

    @property
    def in_scene(self) -> bool:
        """False for an object only the sensors see (``scene: false``)."""
        return self.spec.scene


def moving_object(spec: ObjectSpec, res: ResolvedScenario) -> MovingObject | None:
    if spec.motion is None and spec.rescan is None and not spec.clouds:
        return None
    traj = spec.motion.trajectory(spec.pose.matrix()) if spec.motion is not None else None
    clouds = [
        (c.t, object_cloud(res, spec, spec.seed + k + 1, k), box_solid(c.box))
        for k, c in enumerate(spec.clouds)
    ]
    every = spec.rescan.every if spec.rescan is not None else None
    return MovingObject(spec, traj, clouds, every)


def frozen_scene(scene: SceneLike) -> Scene:
    """A copy of ``scene`` in which every object not on a robot stays where it is now,
    with its current cloud: the world a static-world controller believes in."""
    frozen = Scene(strategy=scene.strategy)
    for r in scene.robots.values():
        frozen.add_robot(r)
    now = scene.poses()
    for name, obj in scene.objects.items():
        src = obj.source
        if isinstance(src, OnLink):
            frozen.add_object(name, obj.cloud, src.offset, robot=src.robot, link=src.link)
        else:
            frozen.add_object(name, obj.cloud, now[name])
    for pair in scene.pairs:
        frozen.watch(pair.a, pair.b, pair.margin, kind=pair.kind)
    return frozen
